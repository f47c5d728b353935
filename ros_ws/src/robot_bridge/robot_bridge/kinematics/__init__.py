"""Arm kinematics for the arm-command bridge (pure algorithm, no rclpy).

``arm``: a serial arm from a URDF as a Pinocchio model (built once) with its gripper frame; ``gripper_path``: the
contract's gripper trajectory (CONTRACTS.md section 4) and its validation; ``ik``: damped least-squares inverse
kinematics along a path with a null-space posture task; ``timing``: joint velocity/acceleration limits and time
parameterisation; ``planner``: the whole chain, path in the table frame -> timed joint trajectory (or a rejection that
names the first bad pose).
"""
