"""Independent simulators used as fake hardware and to generate test data (MuJoCo).

``mujoco_loop``: a URDF arm holding the contract's closed flexible loop (CONTRACTS.md section 2), driven through a
smooth joint reference by a computed-torque + PD controller, recorded as a contract joint log (section 1).
Nothing here imports flex_ident: the simulator shares no code with the model it is used to test.
"""
