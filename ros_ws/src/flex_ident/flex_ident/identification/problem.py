"""The identification problem: named parameters -> simulated recording -> cost, residual Jacobian, gradient.

One evaluation at parameters c (a subset of the model's named coefficients, the rest fixed):

1. static equilibrium of the object with the arm at its first measured angles (the recording starts at rest), and
   its sensitivity dq_0/dc;
2. simulation driven by the measured torques with the fixed LQR proportional feedback on the measured angles;
3. the tracking cost; on request the residual Jacobian (forward sensitivities) or the gradient (adjoint, Lemma 1).

The optimizer sees transformed parameters z: z = log(c) for parameters whose lower bound is positive (stiffnesses,
damping), z = c otherwise (biases), which makes the problem well scaled without user tuning.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..mechanics.linearization import adjoint_gradient_along, forward_sensitivities_along
from ..mechanics.static_equilibrium import EquilibriumError, static_equilibrium
from ..mechanics.variational_integrator import SimulationError, required_substeps, rest_momentum, simulate
from .adjoint import cost_state_gradient, initial_state_sensitivity, residual_jacobian
from .cost import TrackingCost


@dataclass
class MeasuredData:
    """A recording on a uniform time grid: t_s (T,), theta (T, na) rad, tau (T, na) N m, in model input order."""
    t_s: np.ndarray
    names: list
    theta: np.ndarray
    tau: np.ndarray

    @property
    def dt(self) -> float:
        return float(self.t_s[1] - self.t_s[0])


@dataclass
class Evaluation:
    params: np.ndarray          # (np,) coefficient values of the free parameters
    cost: float
    residual: np.ndarray        # (T, d)
    traj: object = None
    equilibrium: object = None
    jacobian: np.ndarray | None = None      # dr/dc (T*d, np)
    gradient: np.ndarray | None = None      # dJ/dc (np,)
    ok: bool = True
    failure: str = ''


@dataclass
class ParameterTransform:
    """z = log(c) where lower > 0, else z = c."""
    lower: np.ndarray
    upper: np.ndarray
    log: np.ndarray = field(init=False)

    def __post_init__(self):
        self.log = np.asarray(self.lower) > 0

    def to_z(self, c):
        c = np.asarray(c, float)
        return np.where(self.log, np.log(np.where(self.log, c, 1.0)), c)

    def to_c(self, z):
        z = np.asarray(z, float)
        return np.where(self.log, np.exp(np.where(self.log, z, 0.0)), z)

    def dc_dz(self, z):
        return np.where(self.log, self.to_c(z), 1.0)

    def z_bounds(self):
        lo = np.where(self.log, np.log(np.where(self.log, self.lower, 1.0)), self.lower)
        hi = np.where(self.log, np.log(np.where(self.log & np.isfinite(self.upper), self.upper, 1.0)), self.upper)
        hi = np.where(self.log & ~np.isfinite(self.upper), np.inf, hi)
        return lo, hi


class IdentificationProblem:
    """Simulation-based identification of the named coefficients ``free`` of ``model`` from ``data``."""

    def __init__(self, model, data: MeasuredData, free: list[str], lower, upper, feedback, substeps: int = 1,
                 cost_kind: str = 'end_effector', torque_hold: str = 'midpoint', max_substeps: int = 6):
        self.model = model
        self.data = data
        self.free = list(free)
        self.free_idx = np.array([model.coef_index(name) for name in free], dtype=np.int64)
        self.base_coef = model.coef_values()
        self.transform = ParameterTransform(np.asarray(lower, float), np.asarray(upper, float))
        self.feedback = feedback
        self.substeps = int(substeps)
        self.max_substeps = int(max_substeps)
        self.discretization_changed = False
        self.cost = TrackingCost.create(model, data.theta, cost_kind)
        self.torque_hold = torque_hold
        tau = np.asarray(data.tau, float)
        self.tau_interval = tau[:-1] if torque_hold == 'zoh' else 0.5 * (tau[:-1] + tau[1:])
        self._q_guess = np.zeros(model.n)
        self._q_guess[model.measured_coords] = data.theta[0]
        self.evaluations = 0

    def truncated(self, samples: int) -> 'IdentificationProblem':
        """The same problem on the first ``samples`` samples of the recording (same feedback and discretization)."""
        d = self.data
        short = MeasuredData(d.t_s[:samples], d.names, d.theta[:samples], d.tau[:samples])
        return IdentificationProblem(self.model, short, self.free, self.transform.lower, self.transform.upper,
                                     self.feedback, substeps=self.substeps, cost_kind=self.cost.kind,
                                     torque_hold=self.torque_hold, max_substeps=self.max_substeps)

    def coef(self, params) -> np.ndarray:
        c = self.base_coef.copy()
        c[self.free_idx] = params
        return c

    def _failed(self, params, exc) -> Evaluation:
        return Evaluation(params=np.asarray(params, float), cost=np.inf, residual=np.full((self.cost.T, 3), np.nan),
                          ok=False, failure=str(exc))

    def equilibrium(self, params):
        eq = static_equilibrium(self.model, self.coef(params), self._q_guess)
        return eq

    def evaluate(self, params, jacobian: bool = False, gradient: bool = False) -> Evaluation:
        """Cost at coefficient values ``params`` of the free parameters; optionally dr/dc and dJ/dc."""
        self.evaluations += 1
        params = np.asarray(params, float)
        coef = self.coef(params)
        model = self.model
        try:
            eq = static_equilibrium(model, coef, self._q_guess)
        except EquilibriumError as exc:
            return self._failed(params, exc)
        u0 = self.tau_interval[0]
        tried = self.substeps
        while True:
            h = self.data.dt / tried
            p0 = rest_momentum(model, coef, h, eq.q, u0)
            try:
                traj = simulate(model, coef, self.data.dt, eq.q, p0, self.tau_interval, self.data.theta,
                                self.feedback, substeps=tried)
                needed = required_substeps(model, traj, max_substeps=self.max_substeps)
                if needed <= tried:
                    break
                tried = needed
                continue
            except SimulationError as exc:
                # the constrained midpoint rule integrates the welds' curvature stiffness explicitly: a loop under
                # more tension than at the start may need a finer VI step (see stable_substeps); if a finer step
                # does not help either, these parameters really make the model diverge
                if tried >= self.max_substeps:
                    return self._failed(params, exc)
                tried += 1
        if tried != self.substeps:
            self.substeps = tried
            self.discretization_changed = True
        r, C = self.cost.residual_and_output_jacobian(traj.q)
        ev = Evaluation(params=params, cost=float(np.sum(r * r)), residual=r, traj=traj, equilibrium=eq)
        if jacobian or gradient:
            S0 = initial_state_sensitivity(model, coef, h, eq.q, u0, eq.dq_dcoef)[:, self.free_idx]
            if jacobian:
                S = forward_sensitivities_along(model, traj, self.free_idx, S0)
                ev.jacobian = residual_jacobian(S, C, model.n)
            if gradient:
                ev.gradient = adjoint_gradient_along(model, traj, self.free_idx, S0, cost_state_gradient(r, C, model.n))
        return ev
