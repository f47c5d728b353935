"""Static problems on discrete elastic rods: building rods from curves, equilibrium, stability.

* :func:`rod_from_curve` resamples a centreline (e.g. a BVP solution) into a DER with uniform edges;
* :func:`clamped_suspended_rod` is the suspended part of the paper's Eq. 7 in DER form: the connective end clamped
  (two nodes and the twist of the first edge, as the released code does), the gripper node held in position only;
* :func:`newton_equilibrium` is plain Newton (no energy line search), which converges to the nearby equilibrium
  whether it is a minimum or a saddle - what a stability check needs;
* :func:`equilibrium_stability`: an equilibrium is elastically stable when the Hessian of the potential energy on
  the free DOFs is positive definite (second variation), tested by a banded Cholesky factorisation; the smallest
  eigenvalue comes from shift-invert Lanczos.
"""
import numpy as np
from scipy.linalg import cholesky_banded, LinAlgError
from scipy.sparse import diags
from scipy.sparse.linalg import eigsh

from .der_simulator import BAND, DiscreteElasticRod, RodParameters


def rod_from_curve(points, n_edges, params, arc_length=None, rest_length=None):
    """DER with ``n_edges`` equal edges along the polyline ``points`` (M, 3).

    arc_length: the (undeformed) arc length of each point (default: cumulative polyline length);
    rest_length: total undeformed length (default arc_length[-1]).  The DER rest lengths are uniform.
    """
    p = np.asarray(points, float)
    if arc_length is None:
        arc_length = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))]
    L = float(arc_length[-1] if rest_length is None else rest_length)
    s = np.linspace(0.0, float(arc_length[-1]), n_edges + 1)
    x = np.stack([np.interp(s, arc_length, p[:, k]) for k in range(3)], axis=1)
    rod = DiscreteElasticRod(x, params)
    rod.rest_lengths[:] = L / n_edges
    rod.voronoi[:] = L / n_edges
    return rod


def clamped_suspended_rod(solution, n_edges=None, h=0.1, gripper='position'):
    """DER of a suspended-rod BVP solution (``planning.suspended_rod``): clamped at q_C, the gripper node held in
    position (``gripper='position'``) or the last edge clamped, position, direction and twist (``'clamp'``: a
    gripper that supplies a moment, the ``shear`` problem's gripper releases)."""
    if gripper not in ('position', 'clamp'):
        raise ValueError(f"gripper must be 'position' or 'clamp', got {gripper!r}")
    L = solution.ls_bar
    if n_edges is None:
        n_edges = int(np.clip(np.ceil(L / h), 30, 2000))
    # an inextensible rod is checked as a very stiff one (ks_bar 1e5: strains ~1e-4, Newton still well conditioned)
    params = RodParameters.dimensionless(min(solution.ks_bar, 1e5))
    rod = rod_from_curve(solution.r, n_edges, params, arc_length=solution.s)
    dl = L / n_edges
    rod.state.q[rod.node_dof(0)] = 0.0
    rod.state.q[rod.node_dof(1)] = (dl, 0.0, 0.0)
    rod.clamp_node(0)
    rod.clamp_node(1)
    rod.clamp_theta(0)
    rod.clamp_node(-1)
    if gripper == 'clamp':
        rod.clamp_node(-2)
        rod.clamp_theta(rod.n_edges - 1)
    rod._commit(rod.state.q, rod.state.u, 0.0)
    return rod


def newton_equilibrium(rod, tol=1e-10, max_iter=30):
    """Undamped Newton on the static equations from the current state; returns (converged, residual norm).

    Plain Newton (what finds a saddle as well as a minimum); the residual may rise for a few iterations before the
    quadratic phase, so it only stops early on divergence, and it keeps the best state.
    """
    best = (np.inf, rod.state)
    for _ in range(max_iter + 1):
        q = rod.state.q
        _, g, H = rod.elastic(q)
        _, fc, Hc = rod.contact(q)
        res = g - rod.gravity_force - fc
        res[rod.fixed] = 0.0
        rn = float(np.linalg.norm(res))
        if not np.isfinite(rn) or rn > 1e4 * best[0]:
            break
        if rn < best[0]:
            best = (rn, rod.state)
        if rn < tol:
            return True, rn
        if Hc is not None:
            H.ab += Hc.ab
        H.fix(rod.fixed)
        dq = H.solve(-res)
        dq[rod.fixed] = 0.0
        if not np.all(np.isfinite(dq)):
            break
        rod._commit(q + dq, rod.state.u, rod.state.time)
    rod.state = best[1]
    return best[0] < tol, best[0]


def _free_banded_upper(rod):
    """Upper band storage (for cholesky_banded) of the free-DOF Hessian."""
    _, _, H = rod.elastic(rod.state.q)
    _, _, Hc = rod.contact(rod.state.q)
    if Hc is not None:
        H.ab += Hc.ab
    A = H.to_dense()
    free = ~rod.fixed
    A = A[np.ix_(free, free)]
    A = 0.5 * (A + A.T)
    n = A.shape[0]
    ab = np.zeros((BAND + 1, n))
    for k in range(BAND + 1):
        ab[BAND - k, k:] = np.diagonal(A, k)
    return A, ab


def equilibrium_stability(rod, eigen=True):
    """Stability of the rod's current equilibrium: {'stable', 'min_eigenvalue' (closest to zero if stable)}."""
    A, ab = _free_banded_upper(rod)
    try:
        cholesky_banded(ab, lower=False, check_finite=False)
        pd = True
    except LinAlgError:
        pd = False
    out = {'stable': pd}
    if eigen and A.shape[0] <= 2500:
        out['min_eigenvalue'] = float(np.linalg.eigvalsh(A)[0])
    elif eigen:
        offsets = list(range(-BAND, BAND + 1))
        S = diags([np.diagonal(A, k) for k in offsets], offsets, format='csc')
        try:
            w = eigsh(S, k=1, sigma=-1e-6 if pd else None, which='LM' if pd else 'SA',
                      return_eigenvectors=False, tol=1e-8)
            out['min_eigenvalue'] = float(np.min(w))
        except Exception:                                   # pragma: no cover - diagnostics only
            out['min_eigenvalue'] = float(np.linalg.eigvalsh(A)[0]) if A.shape[0] < 3000 else float('nan')
    return out
