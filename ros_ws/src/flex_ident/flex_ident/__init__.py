"""Flexible-object stiffness identification: variational-integrator model, discrete adjoint, logger and identifier nodes."""
