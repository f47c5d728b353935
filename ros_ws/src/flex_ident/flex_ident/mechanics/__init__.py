"""Mechanics of an arm handling a flexible object, in generalized coordinates (paper Sec. II, IV-B..D).

* ``urdf``: URDF -> serial chain (joints, composite bodies, declared damping);
* ``experiment``: experiment YAML (CONTRACTS.md section 2) -> validated dataclasses;
* ``model``: the tree of coordinates, bodies, welds, named coefficients and model terms; ``assembly`` builds it
  from an experiment, ``loop_geometry`` adds the contract loop, ``examples`` holds small test systems;
* ``tree_kinematics``: compiled recursions (kinematics, Lagrangian and constraint derivatives, forces);
* ``variational_integrator``: the midpoint VI with welds, solved by Newton with the exact Jacobian;
* ``linearization``: the one-step map's linearization, parameter derivatives, forward and adjoint sensitivities;
* ``static_equilibrium``: the object at rest with the arm held, and its parameter sensitivity.
"""
