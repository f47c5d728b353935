"""Inverse kinematics along a path: damped least squares with a null-space posture task, warm-started pose to pose.

For a target gripper pose T (base frame) and joint positions q, the error is e = log6(G(q)^-1 T) (6-vector in G's
frame, Pinocchio's SE(3) log) and its Jacobian J_e = -Jlog6(T^-1 G(q)) J_G(q) (J_G in G's frame). One iteration:

    dq = -J_e^T (J_e J_e^T + lambda I)^-1 e  +  (I - J_e^+ J_e) (k_null (q_posture - q) + k_limit r(q)),
    lambda = lambda_0 + |e|^2          (damping that vanishes at the solution, Sugihara 2011),

where r(q) pushes each joint that is within ``limit_margin`` (a fraction of its range) of a position limit back
towards the inside, linearly in how deep it is in the margin (the redundancy is spent on staying off the limits),

with the step clipped to ``max_step_rad`` and q clipped to the joint position limits. Each pose starts from the
previous pose's solution (the first from ``q_seed``); a pose that does not converge is retried once from the posture.
A pose still missed is classified: if the same iteration without position limits reaches it, it needs a joint beyond
its limit (named); otherwise it is out of reach (the residual is given).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .arm import ArmKinematics


@dataclass
class IKSettings:
    """position_tolerance_m / orientation_tolerance_rad: a pose counts as reached below both; iterations stop
    earlier, at ``convergence_factor`` times them. max_iterations per attempt; damping lambda_0; k_null: gain of the
    posture task per iteration; max_step_rad: largest joint step per iteration; max_jump_rad: largest joint change
    between consecutive poses before the solution is reported as a jump between IK branches."""
    position_tolerance_m: float = 1e-4
    orientation_tolerance_rad: float = 1e-3
    convergence_factor: float = 1e-3
    max_iterations: int = 100
    damping: float = 1e-10
    k_null: float = 0.05
    k_limit: float = 0.2
    limit_margin: float = 0.1
    max_step_rad: float = 0.3
    max_jump_rad: float = 0.5


@dataclass
class IKFailure:
    index: int
    reason: str


@dataclass
class PathIKResult:
    """q (K, nq) joint positions per pose; position_error_m (K,) and orientation_error_rad (K,) of G(q_k) from the
    target; iterations (K,); failure: the first pose that could not be solved (then q holds only the poses before)."""
    q: np.ndarray
    position_error_m: np.ndarray
    orientation_error_rad: np.ndarray
    iterations: np.ndarray
    failure: IKFailure | None = None

    def tracking_error(self) -> dict:
        p, r = self.position_error_m, self.orientation_error_rad
        if len(p) == 0:
            return {}
        return {'position_max_m': float(p.max()), 'position_rms_m': float(np.sqrt(np.mean(p ** 2))),
                'orientation_max_rad': float(r.max()), 'orientation_rms_rad': float(np.sqrt(np.mean(r ** 2)))}


class PathIK:
    """DLS inverse kinematics for one arm (see the module docstring); the arm's Pinocchio Data is reused."""

    def __init__(self, arm: ArmKinematics, posture: np.ndarray, settings: IKSettings | None = None):
        self.arm = arm
        self.settings = settings or IKSettings()
        lo, hi = arm.limits.lower, arm.limits.upper
        self.posture = np.clip(np.asarray(posture, dtype=float), lo, hi)
        self._eye = np.eye(arm.nq)
        bounded = np.isfinite(lo) & np.isfinite(hi)
        self._margin = np.where(bounded, self.settings.limit_margin * (hi - lo), 0.0)
        self._lo_in = np.where(bounded, lo + self._margin, -np.inf)
        self._hi_in = np.where(bounded, hi - self._margin, np.inf)

    def _secondary(self, q) -> np.ndarray:
        """Joint velocity wanted by the null-space task: toward the posture, away from nearby limits."""
        s = self.settings
        push = np.maximum(self._lo_in - q, 0.0) - np.maximum(q - self._hi_in, 0.0)
        return s.k_null * (self.posture - q) + s.k_limit * push

    def _errors(self, q, target: pin.SE3):
        current = self.arm.gripper_se3(q)
        err = pin.log6(current.actInv(target)).vector
        pos = float(np.linalg.norm(target.translation - current.translation))
        return err, pos, float(np.linalg.norm(err[3:])), current

    def solve_pose(self, target: pin.SE3, q0, limits: bool = True) -> tuple[np.ndarray, float, float, int]:
        """Iterate from q0 toward target; return (q, position error [m], orientation error [rad], iterations)."""
        s, arm = self.settings, self.arm
        lo, hi = (arm.limits.lower, arm.limits.upper) if limits else (-np.inf, np.inf)
        q = np.clip(np.asarray(q0, dtype=float), lo, hi)
        stop_p = s.position_tolerance_m * s.convergence_factor
        stop_r = s.orientation_tolerance_rad * s.convergence_factor
        err, pos, rot, current = self._errors(q, target)
        it = 0
        while it < s.max_iterations and not (pos < stop_p and rot < stop_r):
            jac = -pin.Jlog6(target.actInv(current)) @ arm.gripper_jacobian(q)
            lam = s.damping + float(err @ err)
            jpinv = jac.T @ np.linalg.inv(jac @ jac.T + lam * np.eye(6))
            dq = -jpinv @ err + (self._eye - jpinv @ jac) @ self._secondary(q)
            step = np.max(np.abs(dq))
            if step > s.max_step_rad:
                dq *= s.max_step_rad / step
            q = np.clip(q + dq, lo, hi)
            err, pos, rot, current = self._errors(q, target)
            it += 1
        return q, pos, rot, it

    def _reached(self, pos, rot) -> bool:
        return pos <= self.settings.position_tolerance_m and rot <= self.settings.orientation_tolerance_rad

    def _diagnose(self, target: pin.SE3, q_best, pos, rot) -> str:
        """Why a pose was missed: a joint beyond its limit (if reachable without limits) or out of reach."""
        lo, hi = self.arm.limits.lower, self.arm.limits.upper
        for start in (q_best, self.posture):
            q_free, p_free, r_free, _ = self.solve_pose(target, start, limits=False)
            if self._reached(p_free, r_free):
                over = np.maximum(lo - q_free, q_free - hi)
                j = int(np.argmax(over))
                name = self.arm.joint_names[j]
                return (f'needs joint {name} at {q_free[j]:.3f} rad, beyond its limits [{lo[j]:.3f}, {hi[j]:.3f}] '
                        f'(within the limits the closest pose misses by {pos * 1e3:.1f} mm / '
                        f'{np.degrees(rot):.1f} deg)')
        return (f'unreachable: the closest pose the arm reaches misses by {pos * 1e3:.1f} mm and '
                f'{np.degrees(rot):.1f} deg (tolerance {self.settings.position_tolerance_m * 1e3:.2g} mm, '
                f'{np.degrees(self.settings.orientation_tolerance_rad):.2g} deg)')

    def solve_path(self, targets, q_seed) -> PathIKResult:
        """IK for each target pose (K, 4, 4) in the base frame, in order; stops at the first pose it cannot reach."""
        targets = np.asarray(targets, dtype=float)
        k_total, nq = len(targets), self.arm.nq
        q_out = np.empty((k_total, nq))
        p_err, r_err, iters = np.empty(k_total), np.empty(k_total), np.zeros(k_total, dtype=int)
        q_prev = np.asarray(q_seed, dtype=float)
        for k in range(k_total):
            target = pin.SE3(targets[k])
            q, pos, rot, it = self.solve_pose(target, q_prev)
            failure = None
            if not self._reached(pos, rot):
                why = self._diagnose(target, q, pos, rot)
                q2, pos2, rot2, it2 = self.solve_pose(target, self.posture)
                it += it2
                if not self._reached(pos2, rot2):
                    failure = IKFailure(k, why)
                elif k and np.max(np.abs(q2 - q_prev)) > self.settings.max_jump_rad:
                    j = int(np.argmax(np.abs(q2 - q_prev)))
                    failure = IKFailure(k, f'continuing from the previous pose: {why}; '
                                           f'a solution from the posture exists but jumps by '
                                           f'{abs(q2[j] - q_prev[j]):.2f} rad on joint {self.arm.joint_names[j]} '
                                           f'(the path leaves this IK branch)')
                q, pos, rot = q2, pos2, rot2
            if failure is None and k and np.max(np.abs(q - q_prev)) > self.settings.max_jump_rad:
                j = int(np.argmax(np.abs(q - q_prev)))
                failure = IKFailure(k, f'joint {self.arm.joint_names[j]} would swing by {abs(q[j] - q_prev[j]):.2f} '
                                       f'rad from the previous pose (more than {self.settings.max_jump_rad} rad): the '
                                       f'path passes at or near a singularity of the arm')
            if failure is not None:
                return PathIKResult(q_out[:k], p_err[:k], r_err[:k], iters[:k], failure)
            q_out[k], p_err[k], r_err[k], iters[k] = q, pos, rot, it
            q_prev = q
        return PathIKResult(q_out, p_err, r_err, iters)
