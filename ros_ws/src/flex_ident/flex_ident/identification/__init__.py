"""Identification of model coefficients from a recorded bag (paper Sec. III, IV-C, IV-E).

* ``measurement``: contract bag -> uniform-grid measured angles and torques;
* ``feedback``: the stabilizing feedback of the measured-torque simulation, gains from a finite-horizon LQR;
* ``cost``: the paper's end-effector cost and the joint-angle variant;
* ``problem``: parameters -> simulation -> cost, residual Jacobian (forward sensitivities), gradient (adjoint);
* ``adjoint``: Lemma 1 and the initial-state sensitivity;
* ``optimizers``: Levenberg-Marquardt, L-BFGS-B, the paper's projected steepest descent with Armijo steps;
* ``identify``: the whole job (``run_identification``), ``report`` and ``plots`` its outputs;
* ``synthetic``: recordings from our own model at known coefficients.
"""
