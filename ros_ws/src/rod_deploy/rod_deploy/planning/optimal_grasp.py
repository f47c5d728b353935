"""Optimal grasp of a deploying rod (paper Sec. 3.2.3, 4.1-4.2, Alg. 1-3, Eq. 9, 13-15).

Input (ls_bar, kappa_bar, ks_bar); output the gripper position q_bar = (q_M - q_C) / L_gb and orientation R
(rotation vector) relative to the connective node, in the published local frame: x along the pattern tangent,
y = z_hat x tangent, z up.

Sign convention of kappa_bar: the released code's.  kappa_bar > 0 is a pattern turning towards -y (clockwise seen
from above), which puts the gripper at y < 0 (about -4.1 kappa_bar at ls_bar = 13.7); a pattern turning towards +y
is kappa_bar < 0 and mirrors y (and the x, z components of the rotation vector).  The released planner passes
|kappa| L_gb and mirrors y itself; passing the signed value here gives the same result.

Optimality.  The released numeric solver drives the clamp reaction at the connective node to
(0, kappa EI / dl, 0): no force along the tangent, no bending moment in the vertical plane and the pattern's bending
moment about the vertical, i.e. the rod lifts off the table with the pattern's curvature and without pulling on the
deployed part; the table supplies the normal force (Eq. 12 requires it to push, F_z >= 0) and, for curved
patterns, friction (Eq. 8).  The gripper holds the rod by position only (moment free, zero curvature there).
``method='bvp'`` solves these conditions directly as one boundary value problem (``suspended_rod``) - no outer
optimisation loop; ``method='alg2'`` is the paper's Alg. 2-3 (Newton on the gripper position with a
finite-difference Jacobian and halving line search) on top of the forward problem Eq. 7, kept as an independent
cross-check; both give the mesh-converged continuum answer.  ``method='der'`` is Alg. 2-3 on a discrete elastic rod,
as the released code does it (seconds per grasp).  Alg. 1 is :func:`discover_manifold_boundary`, the stability
check of Sec. 4.1.2 :func:`elastic_stability` (second variation of the DER energy) and :func:`perturbation_response`
(the paper's lateral-perturbation test), the curvature / pattern continuation :func:`grasp_sequence`.

How this compares with the released C++ solver (benchmarks/results/rod_grasp_accuracy.md):

* it reports the grasp relative to its *second* clamped node, one edge (dl = 13.68/232 L_gb in the published run)
  beyond the point where the rod lifts off, and counts ls_bar from there; ``connective_offset=dl`` (CLI
  ``--convention released``) reproduces that convention: x and z of its published run to 0.12 %, against 2.3 %
  for the continuum answer (x) - the difference is that one edge, not physics;
* its lateral offset y is 1.8 % smaller than the continuum one: the first-order discretisation error of its discrete
  reaction target.  ``method='der'`` runs the released method on our DER: with the released mesh it reproduces the
  published run to 0.02 %, and refined it converges (at first order in dl) to this module's BVP answer.
"""
from dataclasses import dataclass, field
import time

import numpy as np
from scipy.spatial.transform import Rotation

from .suspended_rod import SHEAR_RELEASES, BVPError, SuspendedRodSolution, default_mesh, solve_suspended_rod
from .scaling import GRAVITY_NUMBER

#: released solver's clamp edge in the published run: 232 edges over ls_bar = 13.68 (reproduces it to 5 digits)
RELEASED_CONNECTIVE_OFFSET = 13.68 / 232


@dataclass
class Grasp:
    """Optimal grasp in the published local frame (lengths in L_gb, forces in k_b / L_gb^2)."""

    ls_bar: float
    ks_bar: float
    kappa_bar: float
    position: np.ndarray
    rotvec: np.ndarray
    force_residual: float
    stable: object
    time_s: float
    clamp_force: np.ndarray
    method: str = 'bvp'
    stability: dict = None
    solution: SuspendedRodSolution = field(default=None, repr=False)

    @property
    def rotation(self):
        return Rotation.from_rotvec(self.rotvec).as_matrix()

    def as_dict(self):
        out = {'position': [float(v) for v in self.position],
               'rotvec': [float(v) for v in self.rotvec],
               'force_residual': float(self.force_residual),
               'stable': self.stable if self.stable is None else bool(self.stable),
               'time_s': float(self.time_s)}
        return out


def _bvp_kappa(kappa_bar):
    """m_z(0) in the BVP for the published sign convention (t'(0) = -kappa_bar y_hat)."""
    return -float(kappa_bar)


def _free_length(ls_bar, offset):
    return float(ls_bar) + float(offset)


def _solve_planar(L, ks, guess=None):
    """kappa = 0 solution, with a continuation in length from ls = 8 when a direct solve fails."""
    try:
        return solve_suspended_rod('optimal', L, ks, 0.0, guess=guess)
    except BVPError:
        if guess is not None:
            try:
                return solve_suspended_rod('optimal', L, ks, 0.0)
            except BVPError:
                pass
    sol = solve_suspended_rod('optimal', 8.0, ks, 0.0)
    for Lk in np.geomspace(8.0, L, int(abs(np.log(L / 8.0)) / 0.25) + 2)[1:]:
        sol = solve_suspended_rod('optimal', Lk, ks, 0.0, guess=sol)
    return sol


def continue_in_kappa(sol, kappa_target, ks, first_step=None, min_step=1e-3, max_step=0.4):
    """Adaptive continuation of a solution in kappa_bar (BVP sign) from sol.kappa_bar to kappa_target.

    Steps of at most ``max_step``: at tight curvatures a long jump can land on another (snapping) branch.
    """
    k = sol.kappa_bar
    step = kappa_target - k if first_step is None else np.sign(kappa_target - k) * abs(first_step)
    while abs(kappa_target - k) > 1e-14:
        step = np.sign(kappa_target - k) * min(abs(step), abs(kappa_target - k))
        try:
            new = solve_suspended_rod('optimal', sol.ls_bar, ks, k + step, guess=sol, s=sol.s)
        except BVPError:
            step /= 2
            if abs(step) < min_step:
                raise
            continue
        # reject branch jumps: the gripper must move continuously
        if np.linalg.norm(new.gripper_position - sol.gripper_position) > 2.0 * max(abs(step), 0.05) * 10:
            step /= 2
            if abs(step) < min_step:
                raise BVPError('continuation in kappa jumped branches')
            continue
        sol, k = new, k + step
        step = np.sign(step) * min(2 * abs(step), max_step)
    return sol


def solve_optimal_configuration(ls_bar, kappa_bar, ks_bar, guess=None, connective_offset=0.0):
    """The suspended part at the optimal grasp (a :class:`SuspendedRodSolution`), cold or from a guess."""
    L = _free_length(ls_bar, connective_offset)
    ks = np.inf if ks_bar is None else float(ks_bar)
    kb = _bvp_kappa(kappa_bar)
    s = default_mesh(L)
    if guess is not None:
        # a continuation step may not jump to another branch of Eq. 14 (e.g. a looped, unstable one)
        reach = 2.0 + 15.0 * abs(guess.kappa_bar - kb) + 1.5 * abs(guess.ls_bar - L)

        def same_branch(new):
            return np.linalg.norm(new.gripper_position - guess.gripper_position) <= reach

        try:
            new = solve_suspended_rod('optimal', L, ks, kb, guess=guess, s=s)
            if same_branch(new):
                return new
        except BVPError:
            pass
        if abs(guess.kappa_bar - kb) > 0:
            try:
                g = solve_suspended_rod('optimal', L, ks, guess.kappa_bar, guess=guess, s=s)
                new = continue_in_kappa(g, kb, ks)
                if same_branch(new):
                    return new
            except BVPError:
                pass
    sol = _solve_planar(L, ks)
    if kb != 0.0:
        # from the straight-line optimum (the paper's seed, Sec. 4.1) by continuation in the curvature
        sol = continue_in_kappa(sol, kb, ks, first_step=min(abs(kb), 0.4))
    return sol


def grasp_from_solution(sol, connective_offset=0.0, t0=None, method='bvp', kappa_bar=None):
    R = sol.gripper_rotation
    pos = sol.gripper_position - np.array([connective_offset, 0.0, 0.0])
    kb = -sol.kappa_bar if kappa_bar is None else kappa_bar
    res = max(float(np.linalg.norm(optimality_residual(sol))), sol.residual_norm)
    return Grasp(ls_bar=sol.ls_bar - connective_offset, ks_bar=sol.ks_bar, kappa_bar=kb, position=pos,
                 rotvec=Rotation.from_matrix(R).as_rotvec(), force_residual=res,
                 stable=None, time_s=0.0 if t0 is None else time.perf_counter() - t0,
                 clamp_force=sol.clamp_force, method=method, solution=sol)


def optimality_residual(sol):
    """(F_x, M_y, M_z - M_z target) at the connective node and |m(ls)|: zero at an optimal grasp."""
    n0 = sol.Y[0, 9:12]
    m0 = sol.Y[0, 6:9]
    return np.array([n0[0], m0[1], m0[2] - sol.kappa_bar, *sol.Y[-1, 6:9]])


def optimal_grasp(ls_bar, kappa_bar=0.0, ks_bar=np.inf, *, method='bvp', guess=None, check_stability=True,
                  connective_offset=0.0):
    """Optimal grasp for (ls_bar, kappa_bar, ks_bar) (Eq. 11).  See the module docstring for conventions.

    guess: a previous :class:`Grasp` or :class:`SuspendedRodSolution` (curvature / pattern continuation).
    """
    _validate(ls_bar, kappa_bar, ks_bar)
    t0 = time.perf_counter()
    gsol = guess.solution if isinstance(guess, Grasp) else guess
    if method == 'bvp':
        sol = solve_optimal_configuration(ls_bar, kappa_bar, ks_bar, gsol, connective_offset)
        grasp = grasp_from_solution(sol, connective_offset, None, 'bvp', kappa_bar)
    elif method == 'alg2':
        grasp = optimal_grasp_alg2(ls_bar, kappa_bar, ks_bar, guess=gsol, connective_offset=connective_offset)
    elif method == 'der':
        grasp = optimal_grasp_der(ls_bar, kappa_bar, ks_bar, released_layout=connective_offset > 0)
    else:
        raise ValueError(f'unknown method {method!r} (bvp, alg2, der)')
    if check_stability:
        grasp.stability = elastic_stability(grasp.solution)
        grasp.stable = grasp.stability['stable']
    grasp.time_s = time.perf_counter() - t0
    return grasp


# ------------------------------------------------------------------------ shear-matched grasps (issue #10)
def shear_residual(sol, lateral_force, release):
    """The ``shear`` problem's boundary conditions at a solution: (n0_y - target, m_y(0), m_z(0) - kappa, and
    n0_x, m_x(0) and the kept gripper moment for the gripper releases, m(ls) for ``'tangential'``); zero at a
    shear-matched grasp."""
    n0, m0, m1 = sol.Y[0, 9:12], sol.Y[0, 6:9], sol.Y[-1, 6:9]
    common = [n0[1] - lateral_force, m0[1], m0[2] - sol.kappa_bar]
    if release.startswith('gripper'):
        return np.array(common + [n0[0], m0[0], m1[1 if release == 'gripper_out_of_plane' else 0]])
    return np.array(common + list(m1))


def shear_matched_grasp(ls_bar, kappa_bar, ks_bar, lateral_force, *, release='tangential', guess=None,
                        moment_free=None, check_stability=False, max_step=0.05, min_step=1e-4):
    """The grasp that applies the lateral force ``lateral_force`` = n0_y [k_b / L_gb^2] to the laid rod at q_C
    (the ``shear`` problem of ``suspended_rod``; y = z_hat x tangent, the force of the suspended part on the laid
    one), with the pattern's moment there; ``release``: the optimal-grasp condition given up for it
    (``SHEAR_RELEASES``: a gripper moment out of or in the lift-off plane, or the force along the tangent).

    Solved from ``guess`` (a previous shear-matched :class:`Grasp`, the pattern continuation) when that converges
    on the same branch, else by continuation in n0_y (steps of at most ``max_step``, halved on failure) from the
    moment-free optimal grasp (``moment_free``: that grasp when the caller has it).  Returns (grasp, moment-free
    grasp); the grasp's ``clamp_force`` is F_ext = -n0, its ``force_residual`` the largest :func:`shear_residual`.
    """
    _validate(ls_bar, kappa_bar, ks_bar)
    if release not in SHEAR_RELEASES:
        raise ValueError(f'unknown release {release!r} (one of {", ".join(SHEAR_RELEASES)})')
    if not np.isfinite(lateral_force):
        raise ValueError(f'lateral_force must be finite, got {lateral_force}')
    t0 = time.perf_counter()
    ks = np.inf if ks_bar is None else float(ks_bar)
    kb = _bvp_kappa(kappa_bar)
    sol = None
    if isinstance(guess, Grasp) and guess.solution is not None and guess.solution.kind == 'shear':
        s = default_mesh(ls_bar)
        try:
            new = solve_suspended_rod('shear', ls_bar, ks, kb, guess=guess.solution, s=s,
                                      lateral_force=lateral_force, shear_release=release)
            reach = 2.0 + 15.0 * abs(guess.solution.kappa_bar - kb) + 1.5 * abs(guess.ls_bar - ls_bar) \
                + 15.0 * abs(guess.clamp_force[1] + lateral_force)
            if np.linalg.norm(new.gripper_position - guess.solution.gripper_position) <= reach:
                sol = new
        except BVPError:
            pass
    if moment_free is None:
        moment_free = optimal_grasp(ls_bar, kappa_bar, ks_bar, check_stability=False)
    if sol is None:
        cur, f = moment_free.solution, float(moment_free.solution.Y[0, 10])
        step = max_step
        while True:
            nxt = f + np.clip(lateral_force - f, -step, step)
            try:
                cur = solve_suspended_rod('shear', ls_bar, ks, kb, guess=cur, s=cur.s, lateral_force=nxt,
                                          shear_release=release)
                f = nxt
                if f == lateral_force:
                    break
            except BVPError:
                step /= 2
                if step < min_step:
                    raise BVPError(f'continuation in the lateral force stopped at n0_y = {f:.4g} '
                                   f'(target {lateral_force:.4g}, ls_bar {ls_bar:.3g}, kappa_bar {kappa_bar:.3g}, '
                                   f'release {release})') from None
        sol = cur
    grasp = grasp_from_solution(sol, 0.0, t0, f'shear_{release}', kappa_bar)
    grasp.force_residual = max(float(np.max(np.abs(shear_residual(sol, lateral_force, release)))),
                               sol.residual_norm)
    if check_stability:
        grasp.stability = elastic_stability(sol, gripper='clamp' if release.startswith('gripper') else 'position')
        grasp.stable = grasp.stability['stable']
    return grasp, moment_free


def closest_shear_grasp(ls_bar, kappa_bar, ks_bar, lateral_force, *, moment_free=None, steps=8):
    """The moment-free grasp (gripper by position) whose horizontal force at q_C is closest to the laid rod's need
    (n0_x, n0_y) = (0, ``lateral_force``): the exact match is out of reach (the tangential release needs |n0_x|
    0.36-0.5 for it and is singular at kappa_bar -> 0, the gripper releases are singular for a vertical hanging part;
    ``benchmarks/shear_matched_grasp.py``), so the tangential family n0_y -> (n0_x, n0_y) is scanned by continuation
    from the moment-free grasp towards n0_y = lateral_force in ``steps`` steps (stopping where it fails) and the
    mismatch |(n0_x, n0_y - lateral_force)| minimised (the best step refined by a parabola through its neighbours).
    Returns (grasp, moment-free grasp); the moment-free grasp itself when it is the closest."""
    _validate(ls_bar, kappa_bar, ks_bar)
    if moment_free is None:
        moment_free = optimal_grasp(ls_bar, kappa_bar, ks_bar, check_stability=False)
    sol0 = moment_free.solution
    f0 = float(sol0.Y[0, 10])
    if abs(lateral_force - f0) < 1e-6:
        return moment_free, moment_free
    ks = np.inf if ks_bar is None else float(ks_bar)

    def mismatch(sol):
        return float(np.hypot(sol.Y[0, 9], sol.Y[0, 10] - lateral_force))

    def solve(f, guess):
        return solve_suspended_rod('shear', ls_bar, ks, sol0.kappa_bar, guess=guess, s=guess.s, lateral_force=f,
                                   shear_release='tangential')

    fs, sols = [f0], [sol0]
    for f in np.linspace(f0, lateral_force, steps + 1)[1:]:
        try:
            sols.append(solve(f, sols[-1]))
            fs.append(f)
        except BVPError:
            break
    d = [mismatch(x) for x in sols]
    k = int(np.argmin(d))
    if k == 0:
        return moment_free, moment_free
    best = sols[k]
    if k + 1 < len(sols):            # a parabola through the best step and its neighbours
        a, b, c = d[k - 1], d[k], d[k + 1]
        den = a - 2 * b + c
        if den > 0:
            f = fs[k] + 0.5 * (fs[k + 1] - fs[k]) * (a - c) / den
            try:
                trial = solve(f, best)
                if mismatch(trial) < d[k]:
                    best = trial
            except BVPError:
                pass
    grasp = grasp_from_solution(best, 0.0, None, 'shear_closest', kappa_bar)
    grasp.force_residual = max(float(np.max(np.abs(shear_residual(best, float(best.Y[0, 10]), 'tangential')))),
                               best.residual_norm)
    return grasp, moment_free


def least_force_sequence(inputs, progress=None):
    """:func:`closest_shear_grasp` with no lateral force asked (the least horizontal force at q_C) along a pattern:
    ``inputs`` rows (ls_bar, ks_bar, kappa_bar) as for :func:`grasp_sequence`; the moment-free grasps are continued
    from node to node and each node's family scanned from its own."""
    out, prev_free = [], None
    for row in inputs:
        ls, ks, kap = (float(v) for v in row)
        free = optimal_grasp(ls, kap, ks, guess=prev_free, check_stability=False)
        g, _ = closest_shear_grasp(ls, kap, ks, 0.0, moment_free=free)
        out.append(g)
        prev_free = free
        if progress is not None:
            progress(len(out))
    return out


def _validate(ls_bar, kappa_bar, ks_bar):
    if not (np.isfinite(ls_bar) and ls_bar > 0):
        raise ValueError(f'ls_bar must be positive, got {ls_bar}')
    if not np.isfinite(kappa_bar):
        raise ValueError(f'kappa_bar must be finite, got {kappa_bar}')
    if ks_bar is not None and not (ks_bar > 0):
        raise ValueError(f'ks_bar must be positive (or inf for an inextensible rod), got {ks_bar}')


# -------------------------------------------------------------------------------- forward problem, Alg. 1-3
def forward_solve(q_target, ls_bar, ks_bar, guess):
    """Eq. 7: the suspended part clamped at q_C with the gripper at q_target (moment free)."""
    ks = np.inf if ks_bar is None else float(ks_bar)
    s = guess.s if isinstance(guess, SuspendedRodSolution) else None
    try:
        return solve_suspended_rod('forward', ls_bar, ks, 0.0, q_target=q_target, guess=guess, s=s)
    except BVPError:
        if not isinstance(guess, SuspendedRodSolution):
            raise
    # continuation of the gripper position from the guess's own end point
    start = guess.gripper_position
    sol = guess
    for a in np.linspace(0.0, 1.0, 9)[1:]:
        sol = solve_suspended_rod('forward', ls_bar, ks, 0.0, q_target=start + a * (np.asarray(q_target) - start),
                                  guess=sol, s=s)
    return sol


def _alg2_residual(sol, kappa_bvp):
    """Clamp reaction minus target, the continuum limit of the released solver's (0, kappa EI / dl, 0) condition."""
    F = sol.clamp_force
    M = -sol.Y[0, 6:9]                          # moment of the clamp on the rod
    return np.array([F[0], -M[1], -M[2] - kappa_bvp])


def optimal_grasp_alg2(ls_bar, kappa_bar, ks_bar, guess=None, connective_offset=0.0, tol=1e-9, delta=1e-6,
                       max_iter=50):
    """Paper Alg. 2 (finite-difference Jacobian Eq. 15, Newton step) with Alg. 3 (halving line search)."""
    t0 = time.perf_counter()
    L = _free_length(ls_bar, connective_offset)
    kb = _bvp_kappa(kappa_bar)
    if guess is None:
        guess = solve_optimal_configuration(ls_bar, 0.0, ks_bar, None, connective_offset)  # straight-line seed
    q = guess.gripper_position.copy()        # the straight-line optimum seeds curved patterns (Sec. 4.1)
    sol = forward_solve(q, L, ks_bar, guess)
    f = _alg2_residual(sol, kb)
    for it in range(max_iter):
        if np.linalg.norm(f) < tol:
            break
        J = np.zeros((3, 3))
        for k in range(3):
            dq = np.zeros(3)
            dq[k] = delta
            J[:, k] = (_alg2_residual(forward_solve(q + dq, L, ks_bar, sol), kb) - f) / delta
        step = np.linalg.solve(J, f)
        alpha, f0 = 1.0, np.linalg.norm(f)
        while True:                               # Alg. 3
            try:
                trial = forward_solve(q - alpha * step, L, ks_bar, sol)
                ft = _alg2_residual(trial, kb)
                if np.linalg.norm(ft) < f0:
                    break
            except BVPError:
                pass
            alpha *= 0.5
            if alpha < 1e-6:
                raise BVPError('Alg. 3 line search failed')
        q, sol, f = q - alpha * step, trial, ft
    grasp = grasp_from_solution(sol, connective_offset, t0, 'alg2', kappa_bar)
    grasp.force_residual = float(np.linalg.norm(f))
    return grasp


def optimal_grasp_der(ls_bar, kappa_bar, ks_bar, n_edges=None, h=0.06, released_layout=False, tol=1e-9,
                      delta=1e-6, max_iter=30):
    """The released numeric solver's method on our DER (paper Sec. 4.2, Alg. 2-3, Eq. 15).

    The connective end is clamped by two nodes and the first edge's twist, the gripper node is held by position
    only; Newton with a finite-difference 3x3 Jacobian drives the reaction on the second clamped node to
    (0, kappa_bar EI / dl, 0) (published sign).  ``released_layout=True`` copies the released code's layout: ls_bar
    counts from the second clamped node, one extra clamped edge lies behind it, and positions are reported from it
    (with n_edges = 232 at ls_bar = 13.68 this reproduces the published run to 5 digits); otherwise the rod
    has ls_bar of length from the first node and positions are reported from it (the continuum limit as dl -> 0).
    An independent check of the BVP: different discretisation, forces from DER gradients, outer Newton loop.
    """
    from ..physics.der_simulator import DiscreteElasticRod, RodParameters
    t0 = time.perf_counter()
    ks = 1e9 if ks_bar is None or not np.isfinite(ks_bar) else float(ks_bar)
    if n_edges is None:
        n_edges = int(np.clip(np.ceil(ls_bar / h), 20, 3000))
    dl = ls_bar / n_edges
    extra = dl if released_layout else 0.0
    seed = solve_optimal_configuration(ls_bar + extra, kappa_bar, ks, None)
    total = ls_bar + extra
    nn = n_edges + (1 if released_layout else 0)
    s = np.linspace(0.0, total, nn + 1)
    x = np.stack([np.interp(s, seed.s, seed.r[:, k]) for k in range(3)], axis=1)
    x[0] = 0.0
    x[1] = (dl, 0.0, 0.0)
    origin = np.array([extra, 0.0, 0.0])
    rod = DiscreteElasticRod(x, RodParameters.dimensionless(ks))
    rod.rest_lengths[:] = dl
    rod.voronoi[:] = dl
    for i in (0, 1, -1):
        rod.clamp_node(i)
    rod.clamp_theta(0)
    target = np.array([0.0, kappa_bar / dl, 0.0])
    tip = rod.node_dof(-1)

    def residual(q_tip):
        rod.state.q[tip] = q_tip
        rod.static_solve(tol=1e-10)
        return rod.reaction_forces()[rod.node_dof(1)] - target

    q = x[-1].copy()
    f = residual(q)
    for it in range(max_iter):
        if np.linalg.norm(f) * dl < tol:
            break
        base = rod.state
        J = np.zeros((3, 3))
        for k in range(3):
            dq = np.zeros(3)
            dq[k] = delta
            J[:, k] = (residual(q + dq) - f) / delta
            rod.state = base
        step = np.linalg.solve(J, f)
        alpha, f0 = 1.0, np.linalg.norm(f)
        while True:                                   # Alg. 3
            ft = residual(q - alpha * step)
            if np.linalg.norm(ft) < f0 or alpha < 1e-6:
                break
            rod.state = base
            alpha *= 0.5
        q, f = q - alpha * step, ft
    pos = q - origin
    R = np.column_stack([_edge_frame(rod, -1)]) @ _edge_frame(rod, 0).T
    return Grasp(ls_bar=float(ls_bar), ks_bar=float(ks), kappa_bar=float(kappa_bar), position=pos,
                 rotvec=Rotation.from_matrix(R).as_rotvec(), force_residual=float(np.linalg.norm(f)),
                 stable=None, time_s=time.perf_counter() - t0, clamp_force=-rod.reaction_forces()[rod.node_dof(0)]
                 - rod.reaction_forces()[rod.node_dof(1)], method='der', solution=seed)


def _edge_frame(rod, j):
    """Material frame [m1, m2, t] (columns) of edge j."""
    from ..physics.reference_frames import material_frames
    st = rod.state
    m1, m2 = material_frames(st.d1, st.d2, rod.theta)
    return np.column_stack([m1[j], m2[j], st.tangents[j]])


def clamp_force_at(q_target, ls_bar, ks_bar, guess):
    """F_ext at the connective node for a clamped rod with the gripper at q_target (forward problem)."""
    return forward_solve(q_target, ls_bar, ks_bar, guess).clamp_force


def constraints_satisfied(sol, tol=1e-9):
    """Paper Eq. 12: rod above the table and the table pushing (F_z >= 0)."""
    return bool(np.min(sol.r[1:, 2]) >= -tol and sol.clamp_force[2] >= -tol)


def _last_feasible_radius(solve_at, th, r0, sol0, step, direction, delta):
    """From the admissible grasp (r0, sol0) on the ray at angle ``th``, step along it in ``direction`` (+1 out,
    -1 in; each accepted step 1.5 times longer) until a solve fails, violates Eq. 12 or r reaches 0, then bisect
    down to ``delta``; returns the last admissible radius."""
    ok_r, ok_sol, bad_r = r0, sol0, None
    while bad_r is None:
        r_try = ok_r + direction * step
        if r_try <= 0:
            bad_r = 0.0
            break
        try:
            trial = solve_at(r_try, th, ok_sol)
        except BVPError:
            bad_r = r_try
            break
        if constraints_satisfied(trial):
            ok_sol, ok_r = trial, r_try
            step *= 1.5
        else:
            bad_r = r_try
    while abs(bad_r - ok_r) > delta:
        mid = 0.5 * (ok_r + bad_r)
        try:
            trial = solve_at(mid, th, ok_sol)
            admissible = constraints_satisfied(trial)
        except BVPError:
            admissible = False
        if admissible:
            ok_sol, ok_r = trial, mid
        else:
            bad_r = mid
    return ok_r


def discover_manifold_boundary(ls_bar, ks_bar, angles, delta=1e-3, seed=None):
    """Paper Alg. 1 for the planar problem: along rays from q_C at angle theta (from +x, in the x-z plane),
    bisect for the outer boundary (F_z -> 0, region I) and the inner boundary (table contact, region III) of the
    admissible grasp set M.  Returns an array (len(angles), 2, 2) of (outer, inner) boundary points (x, z); NaN
    where a ray misses M.  Rays are visited in order and each forward solve starts from the previous one.
    """
    L = float(ls_bar)
    if seed is None:
        seed = solve_optimal_configuration(L, 0.0, ks_bar)
    out = np.full((len(angles), 2, 2), np.nan)
    cur = seed

    def solve_at(rad, th, g):
        sol = forward_solve(np.array([rad * np.cos(th), 0.0, rad * np.sin(th)]), L, ks_bar, g)
        return sol

    for a, th in enumerate(angles):
        # move the seed onto the ray by a continuation in the angle of its gripper position
        p = cur.gripper_position
        rad0 = float(np.hypot(p[0], p[2]))
        th0 = float(np.arctan2(p[2], p[0]))
        ok = True
        for tk in np.linspace(th0, th, int(abs(th - th0) / 0.02) + 2)[1:]:
            try:
                cur = solve_at(rad0, tk, cur)
            except BVPError:
                ok = False
                break
        if not ok or not constraints_satisfied(cur):
            continue
        # outer boundary: increase r until F_z < 0 or the solve fails; inner: decrease r until table contact
        for side, (step, direction) in enumerate(((0.02 * L, 1.0), (0.05 * L, -1.0))):
            r = _last_feasible_radius(solve_at, th, rad0, cur, step, direction, delta)
            out[a, side] = (r * np.cos(th), r * np.sin(th))
    return out


# ------------------------------------------------------------------------------------------- stability (Fig. 5)
def elastic_stability(sol, h=None, eigen=False, gripper='position'):
    """Elastic stability of the suspended part at a grasp: the DER model of Eq. 7 (connective end clamped, gripper
    held by position) is re-equilibrated from the BVP solution by plain Newton and its Hessian on the free DOFs
    tested for positive definiteness (second variation).  The paper tests the same property by perturbation
    (Sec. 4.1.2, Fig. 5; :func:`perturbation_response`): a grasp at an indefinite equilibrium snaps.
    ``gripper='clamp'`` holds the last edge (position, direction, twist): a grasp whose gripper supplies a moment.
    """
    from ..physics.statics import clamped_suspended_rod, equilibrium_stability, newton_equilibrium
    L = sol.ls_bar
    tol = 1e-7 * max(1.0, GRAVITY_NUMBER * L)                 # relative to the weight of the rod
    hs = [h] if h is not None else [max(0.05, L / 400.0), 0.1, 0.05]
    for hk in dict.fromkeys(hk for hk in hs if hk is None or hk <= hs[0]):
        rod = clamped_suspended_rod(sol, h=hk, gripper=gripper)
        ok, rn = newton_equilibrium(rod, tol=tol, max_iter=25)
        if ok or rn < 10 * tol:
            break
    # a DER too coarse for Newton to re-equilibrate is refined before judging; a saddle still converges
    st = equilibrium_stability(rod, eigen=eigen)
    converged = bool(ok or rn < 10 * tol)
    if not converged:
        # an indefinite Hessian next to the BVP equilibrium is a saddle (Newton creeps there); otherwise unknown
        near = rn < 1e-2 * max(1.0, GRAVITY_NUMBER * L)
        st['stable'] = False if (near and not st['stable']) else None
    st['der_edges'] = rod.n_edges
    st['der_residual'] = rn
    st['der_converged'] = converged
    return st


def perturbation_response(sol, dy=0.12, steps=4):
    """Paper Sec. 4.1.2 / Fig. 4(d), 5: move the gripper sideways by dy (continuation in ``steps``) with the
    connective end clamped; returns the lateral clamp force F_y and the largest lateral displacement of the rod
    at each step.  A continuous, proportional response is the stable case; a failed or jumping continuation or an
    amplified displacement is the snap of Fig. 5 (b2).
    """
    q0 = sol.gripper_position
    try:
        cur = forward_solve(q0, sol.ls_bar, sol.ks_bar, sol)
    except BVPError:
        return {'converged': False, 'dy': [], 'force_y': [], 'max_lateral_displacement': []}
    ys0 = cur.r[:, 1].copy()
    dys, forces, disp = [], [], []
    for k in range(1, steps + 1):
        d = dy * k / steps
        try:
            cur = forward_solve(q0 + np.array([0.0, d, 0.0]), sol.ls_bar, sol.ks_bar, cur)
        except BVPError:
            return {'converged': False, 'dy': dys, 'force_y': forces, 'max_lateral_displacement': disp}
        dys.append(d)
        forces.append(float(cur.clamp_force[1]))
        disp.append(float(np.max(np.abs(cur.r[:, 1] - ys0))))
    return {'converged': True, 'dy': dys, 'force_y': forces, 'max_lateral_displacement': disp}


# ------------------------------------------------------------------------------------------ pattern continuation
def grasp_sequence(inputs, method='bvp', check_stability=False, connective_offset=0.0, progress=None):
    """Optimal grasps along a pattern: ``inputs`` rows (ls_bar, ks_bar, kappa_bar) (the released code's order),
    each solved from the previous one (the continuation the paper uses, Sec. 6.4.2).  Returns a list of Grasp.
    """
    out = []
    prev = None
    for row in inputs:
        ls, ks, kap = (float(v) for v in row)
        g = optimal_grasp(ls, kap, ks, method=method, guess=prev, check_stability=check_stability,
                          connective_offset=connective_offset)
        out.append(g)
        prev = g
        if progress is not None:
            progress(len(out))
    return out
