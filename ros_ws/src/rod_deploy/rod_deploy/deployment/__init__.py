"""Deployment of a rod along a gripper trajectory: simulation in our DER (``simulate``) and the paper's Eq. 17
error (``metrics``)."""
