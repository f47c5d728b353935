"""Discrete elastic rod simulator: implicit Euler with Newton's method (paper Eq. 6; Bergou et al. 2010).

* elastic forces and Hessians from ``der_energy`` (stretching, bending, twisting), reference frames by time-parallel
  transport (``reference_frames``);
* gravity, lumped masses (Voronoi share of each edge's mass to its nodes, rotational inertia of the edges);
* boundary conditions: any DOF can be clamped or given a prescribed motion (a function of time);
* contact with a rigid table z = 0: a stiff one-sided penalty on node height (the node is a sphere of the rod
  radius) with regularised Coulomb friction, both implicit (their Jacobians enter Newton);
* the Newton system is banded (bandwidth 10 in the DOF order of the paper's Eq. 1) and solved with LAPACK's banded LU;
  the elastic, contact and friction terms are assembled into its band storage by numba kernels (``der_energy``,
  ``_contact``), the reference frames transported by one (``reference_frames.transported_frames``).

Units are the caller's: SI, or the dimensionless units of the planning code (EI = 1, L_gb = 1, rho A g = 1/2).
"""
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.linalg import LinAlgError
from scipy.linalg.lapack import dgbsv

from . import der_energy as de
from .der_energy import BAND
from .reference_frames import edge_tangents, initial_reference_frames, reference_twist, transported_frames


@dataclass
class RodParameters:
    """Material and environment of a rod (isotropic, circular cross-section, straight at rest unless
    ``natural_curvature`` is given)."""

    EI: float                    # bending stiffness k_b [N m^2]
    EA: float                    # stretching stiffness k_s [N]
    GJ: float                    # twisting stiffness k_t [N m^2]
    rho_A: float                 # mass per length [kg/m]
    radius: float = 0.0          # contact radius h [m]
    gravity: tuple = (0.0, 0.0, -9.81)
    damping: float = 0.0         # viscous damping per length [N s/m^2] (numerical, for relaxation)
    table: bool = False          # rigid table at z = 0
    friction: float = 0.0        # Coulomb coefficient mu with the table
    contact_stiffness: float = None   # penalty stiffness per node [N/m]; default from the node weight
    #: regularisation of Coulomb friction [the caller's velocity unit]; the deployments set theirs from
    #: ``deployment.simulate.DEFAULT_FRICTION_VELOCITY_M_S`` (1e-6 m/s)
    friction_velocity: float = 1e-4
    natural_curvature: tuple = (0.0, 0.0)   # rest material curvature (kappa1, kappa2) [1/m], uniform along the rod

    @classmethod
    def dimensionless(cls, ks_bar, poisson=0.5, **kw):
        """EI = 1, EA = ks_bar, GJ = EI / (1 + nu), rho A = 1/2, g = 1 (lengths in L_gb, time in sqrt(L_gb / g))."""
        kw.setdefault('gravity', (0.0, 0.0, -1.0))
        return cls(EI=1.0, EA=float(ks_bar), GJ=1.0 / (1.0 + poisson), rho_A=0.5, **kw)


def rest_curvatures(natural_curvature, voronoi_lengths):
    """Discrete rest curvatures (N-1, 2) of a rod whose material curvature at rest is ``natural_curvature``
    (kappa1, kappa2) [1/m]: 2 tan(phi / 2) with the turning angle phi = kappa l_i (the discrete curvature of a
    polygon inscribed in the rest circle), None for a straight rod."""
    k = np.asarray(natural_curvature, float)
    if not np.any(k):
        return None
    phi = np.linalg.norm(k) * np.asarray(voronoi_lengths, float)
    return (2.0 * np.tan(0.5 * phi) / np.linalg.norm(k))[:, None] * k[None, :]


@njit(cache=True)
def _fix_band(ab, idx):
    """Replace rows and columns idx of a band-stored matrix by the identity."""
    n = ab.shape[1]
    for i in idx:
        for k in range(2 * BAND + 1):
            ab[k, i] = 0.0                                 # column i
            j = i - (k - BAND)                             # row i: entry (i, j) lives at ab[BAND + i - j, j]
            if 0 <= j < n:
                ab[k, j] = 0.0
        ab[BAND, i] = 1.0


@njit(cache=True)
def _contact(q, q_old, dt, radius, kc, mu, eps, friction, hessian, force, ab):
    """Table contact of every node (penalty on z < radius) and regularised Coulomb friction at the velocity
    (x - x_old) / dt: energy returned, force added to ``force``, stiffness -dF/dq added to ``ab`` (band storage)."""
    energy = 0.0
    for i in range(len(q) // 4 + 1):
        o = 4 * i
        pen = radius - q[o + 2]
        if not pen > 0:
            continue
        fn = kc * pen
        energy += 0.5 * kc * pen * pen
        force[o + 2] += fn
        if hessian:
            ab[BAND, o + 2] += kc
        if friction:
            v0, v1 = (q[o] - q_old[o]) / dt, (q[o + 1] - q_old[o + 1]) / dt
            sv = np.sqrt(v0 * v0 + v1 * v1 + eps * eps)
            phi = (v0 / sv, v1 / sv)
            force[o] += -mu * fn * phi[0]
            force[o + 1] += -mu * fn * phi[1]
            if hessian:
                v = (v0, v1)
                for a in range(2):
                    for b in range(2):
                        Dphi = (1.0 if a == b else 0.0) / sv - v[a] * v[b] / sv ** 3
                        ab[BAND + a - b, o + b] += mu * fn * Dphi / dt
                    ab[BAND + a - 2, o + 2] += -mu * kc * phi[a]
    return energy


class _Banded:
    """A (4N+3)-square matrix of half-bandwidth BAND in LAPACK band storage: entry (i, j) at ab[BAND + i - j, j]."""

    def __init__(self, n):
        self.n = n
        self.ab = np.zeros((2 * BAND + 1, n))

    def add_diagonal(self, dofs, values):
        np.add.at(self.ab, (BAND, dofs), values)

    def fix(self, fixed):
        """Replace fixed rows and columns by the identity."""
        _fix_band(self.ab, np.flatnonzero(fixed))

    def to_dense(self):
        A = np.zeros((self.n, self.n))
        for k in range(-BAND, BAND + 1):
            i = np.arange(max(0, k), min(self.n, self.n + k))
            A[i, i - k] = self.ab[BAND + k, i - k]
        return A

    def solve(self, rhs):
        """LAPACK's banded LU (gbsv, as scipy's solve_banded calls it; the matrix is kept)."""
        lu = np.zeros((3 * BAND + 1, self.n))
        lu[BAND:] = self.ab
        _, _, x, info = dgbsv(BAND, BAND, lu, rhs, overwrite_ab=True)
        if info > 0:
            raise LinAlgError('singular matrix')
        if info < 0:
            raise ValueError(f'illegal value in {-info}-th argument of internal gbsv')
        return x


class NewtonNotConverged(ArithmeticError):
    """An implicit-Euler step whose Newton iteration did not reach the tolerance; the rod's state is unchanged (the
    caller may retry with smaller steps, e.g. ``deployment.simulate``'s step halving)."""

    def __init__(self, time, dt, iterations, residual, tolerance):
        super().__init__(f'Newton did not converge in the step to t = {time:.6g} s (dt {dt:.3g} s): residual '
                         f'{residual:.3g} after {iterations} iterations, tolerance {tolerance:.3g}')
        self.time, self.dt, self.iterations, self.residual, self.tolerance = time, dt, iterations, residual, tolerance


@dataclass
class RodState:
    q: np.ndarray
    u: np.ndarray
    d1: np.ndarray
    d2: np.ndarray
    tangents: np.ndarray
    ref_twist: np.ndarray
    time: float = 0.0


class DiscreteElasticRod:
    """A DER rod with N edges: node positions x (N+1, 3), twist angles theta (N)."""

    def __init__(self, nodes, params: RodParameters, theta=None, d1_first=None):
        x = np.asarray(nodes, float)
        if x.ndim != 2 or x.shape[1] != 3 or len(x) < 3:
            raise ValueError('nodes must be an (N+1, 3) array with N >= 2')
        self.params = params
        self.n_edges = len(x) - 1
        self.ndof = 4 * self.n_edges + 3
        _, self.rest_lengths = edge_tangents(x)
        self.voronoi = 0.5 * (self.rest_lengths[1:] + self.rest_lengths[:-1])
        q = np.zeros(self.ndof)
        q[de.node_dofs(len(x))] = x
        if theta is not None:
            q[4 * np.arange(self.n_edges) + 3] = theta
        d1, d2 = initial_reference_frames(x, d1_first)
        t, _ = edge_tangents(x)
        self.state = RodState(q, np.zeros(self.ndof), d1, d2, t, reference_twist(d1, t))
        # lumped mass: half of each edge's mass to each end node; rotational inertia rho I l = rho A h^2/2 l
        m = np.zeros(self.ndof)
        node_m = np.zeros(len(x))
        node_m[:-1] += 0.5 * params.rho_A * self.rest_lengths
        node_m[1:] += 0.5 * params.rho_A * self.rest_lengths
        m[de.node_dofs(len(x))] = node_m[:, None]
        r = params.radius if params.radius > 0 else 1e-3 * np.mean(self.rest_lengths)
        m[4 * np.arange(self.n_edges) + 3] = 0.5 * params.rho_A * r ** 2 * self.rest_lengths
        self.mass = m
        self.node_mass = node_m
        self.fixed = np.zeros(self.ndof, bool)
        self._prescribed = {}          # dof index array -> callable(t) giving values
        self.kappa_rest = rest_curvatures(params.natural_curvature, self.voronoi)
        self._ks = np.full(self.n_edges, float(params.EA))      # per element, as the compiled kernel takes them
        self._kappa_rest = (np.zeros((self.n_edges - 1, 2)) if self.kappa_rest is None
                            else np.ascontiguousarray(self.kappa_rest, float))
        self._no_band = np.zeros((1, 1))
        g = np.asarray(params.gravity, float)
        self.gravity_force = np.zeros(self.ndof)
        self.gravity_force[de.node_dofs(len(x))] = node_m[:, None] * g[None, :]
        kc = params.contact_stiffness
        if kc is None:
            kc = 1e4 * np.max(node_m) * max(np.linalg.norm(g), 1e-12) / max(r, 1e-12)
        self.contact_stiffness = kc
        self.contact_radius = params.radius

    # ----------------------------------------------------------------------------------------- configuration
    @property
    def nodes(self):
        return de.positions(self.state.q)

    @property
    def theta(self):
        return de.thetas(self.state.q)

    def node_dof(self, i):
        i = i % (self.n_edges + 1)
        return 4 * i + np.arange(3)

    def theta_dof(self, j):
        return 4 * (j % self.n_edges) + 3

    def clamp_node(self, i):
        self.fixed[self.node_dof(i)] = True

    def clamp_theta(self, j):
        self.fixed[self.theta_dof(j)] = True

    def prescribe(self, dofs, func):
        """Prescribed motion: DOFs ``dofs`` follow ``func(t)`` (array of the same length)."""
        dofs = np.atleast_1d(np.asarray(dofs))
        self.fixed[dofs] = True
        self._prescribed[tuple(dofs.tolist())] = func

    def set_positions(self, dofs, values):
        self.state.q[np.atleast_1d(dofs)] = values

    # --------------------------------------------------------------------------------------- forces, Hessian
    def _frames(self, q):
        s = self.state
        return transported_frames(q, s.d1, s.tangents, s.ref_twist)

    def elastic(self, q, hessian=True):
        """Elastic energy, gradient and (banded) Hessian at q (frames transported from the current state)."""
        d1, d2, _, rt = self._frames(q)
        H = _Banded(self.ndof) if hessian else None
        g = np.zeros(self.ndof)
        p = self.params          # rest and Voronoi lengths may be set after construction (statics, optimal_grasp)
        E = de.elastic_banded(q, d1, d2, rt, self.rest_lengths, self._ks, p.EI / self.voronoi, p.GJ / self.voronoi,
                              self._kappa_rest, hessian, g, H.ab if hessian else self._no_band)
        return E, g, H

    def contact(self, q, q_old=None, dt=None, hessian=True, H=None):
        """Table contact (penalty) and friction: potential energy, force and banded stiffness contributions (added
        into ``H`` when given, which is then returned)."""
        if not self.params.table:
            return 0.0, np.zeros(self.ndof), None
        force = np.zeros(self.ndof)
        if hessian and H is None:
            H = _Banded(self.ndof)
        mu = self.params.friction
        friction = mu > 0 and q_old is not None
        energy = _contact(q, q if q_old is None else q_old, 1.0 if dt is None else dt, self.contact_radius,
                          self.contact_stiffness, mu, self.params.friction_velocity, friction, hessian, force,
                          H.ab if hessian else self._no_band)
        return energy, force, (H if hessian else None)

    def reaction_forces(self, q=None):
        """Forces the supports exert on the fixed DOFs in static equilibrium: grad E - external force."""
        q = self.state.q if q is None else q
        _, g, _ = self.elastic(q, hessian=False)
        _, fc, _ = self.contact(q, hessian=False)
        r = g - self.gravity_force - fc
        out = np.zeros(self.ndof)
        out[self.fixed] = r[self.fixed]
        return out

    # ---------------------------------------------------------------------------------------------- solvers
    def _apply_prescribed(self, q, t):
        for dofs, func in self._prescribed.items():
            q[list(dofs)] = func(t)

    def _commit(self, q, u, t):
        d1, d2, tan, rt = self._frames(q)
        self.state = RodState(q, u, d1, d2, tan, rt, t)

    def step(self, dt, tol=1e-10, max_iter=40):
        """One implicit-Euler step (Eq. 6a-b) by Newton with a backtracking line search on the residual norm.

        Converged: the residual force norm below ``tol`` x the largest node weight x the number of DOFs, or a full
        Newton step below 1e-14. Returns the number of Newton iterations; a step that does not converge within
        ``max_iter`` iterations is not taken: ``NewtonNotConverged`` is raised and the state left as it was (it used
        to be accepted silently: the snap of the hanging rod #1 in the old rest-length set-up ended steps at dt 0.01
        and 0.02 s 3-10 node weights away from equilibrium).
        """
        s = self.state
        q0, u0 = s.q, s.u
        t1 = s.time + dt
        q = q0 + dt * u0
        held = self.fixed & ~self._prescribed_mask()
        q[held] = q0[held]
        self._apply_prescribed(q, t1)
        M = self.mass
        damp = self.mass / max(self.params.rho_A, 1e-300) * self.params.damping
        fscale = max(np.max(np.abs(self.gravity_force)), 1e-12)

        def residual(qq, with_h):
            _, g, H = self.elastic(qq, with_h)
            _, fc, _ = self.contact(qq, q0, dt, with_h, H)
            r = M / dt * ((qq - q0) / dt - u0) + damp * (qq - q0) / dt + g - self.gravity_force - fc
            r[self.fixed] = 0.0
            if with_h:
                H.ab[BAND] += M / dt ** 2 + damp / dt
                H.fix(self.fixed)
            return r, H

        res, H = residual(q, True)
        rn = np.linalg.norm(res)
        tol_abs = tol * fscale * self.ndof
        converged = False
        for it in range(1, max_iter + 1):
            dq = H.solve(-res)
            alpha = 1.0
            while True:
                qt = q + alpha * dq
                # the full Newton step is accepted nearly always: its Hessian comes with the residual (one
                # evaluation per iteration instead of a residual and then the Hessian at the same point)
                rt, Ht = residual(qt, alpha == 1.0)
                rtn = np.linalg.norm(rt)
                if rtn < (1 - 1e-4 * alpha) * rn or alpha < 1e-6:
                    break
                alpha *= 0.5
            q = qt
            res, rn = rt, rtn
            if rn < tol_abs or (alpha == 1.0 and np.max(np.abs(dq)) < 1e-14):
                converged = True
                break
            H = Ht if Ht is not None else residual(q, True)[1]
        if not converged:
            raise NewtonNotConverged(t1, dt, it, rn, tol_abs)
        u = (q - q0) / dt
        self._commit(q, u, t1)
        return it

    def _prescribed_mask(self):
        mask = np.zeros(self.ndof, bool)
        for dofs in self._prescribed:
            mask[list(dofs)] = True
        return mask

    def total_potential(self, q):
        E, _, _ = self.elastic(q, hessian=False)
        Ec, _, _ = self.contact(q, hessian=False)
        return E + Ec - np.dot(self.gravity_force, q)

    def static_solve(self, tol=1e-10, max_iter=100, shift=0.0):
        """Static equilibrium by Newton's method with a backtracking line search on the potential energy.

        Neutral modes (e.g. a loop that can roll on a frictionless table) are handled by a Levenberg shift
        ``lam * mass`` added to the Hessian, raised when a step must be cut and lowered when a full step is
        accepted (``shift`` is its initial value; 0 starts with pure Newton).  The reference frames are
        re-transported to each accepted iterate, so the Hessian stays the exact one.  Returns the final norm of
        the free-DOF residual force.
        """
        q = self.state.q.copy()
        self._apply_prescribed(q, self.state.time)
        self._commit(q, np.zeros(self.ndof), self.state.time)
        lam = float(shift)
        free_idx = np.flatnonzero(~self.fixed)
        for it in range(max_iter):
            q = self.state.q
            E0 = self.total_potential(q)
            _, g, H = self.elastic(q)
            _, fc, Hc = self.contact(q)
            res = g - self.gravity_force - fc
            res[self.fixed] = 0.0
            rn = np.linalg.norm(res)
            if rn < tol:
                return rn
            if Hc is not None:
                H.ab += Hc.ab
            if lam > 0:
                H.add_diagonal(free_idx, lam * self.mass[free_idx])
            H.fix(self.fixed)
            dq = H.solve(-res)
            dq[self.fixed] = 0.0
            if not np.all(np.isfinite(dq)) or np.dot(dq, res) > 0:   # indefinite: move to a shifted step
                lam = max(10 * lam, 1e-6 * np.max(np.abs(res)) / max(np.max(self.mass), 1e-300) + 1e-8)
                continue
            alpha = 1.0
            while alpha > 1e-8:
                qt = q + alpha * dq
                if self.total_potential(qt) <= E0 + 1e-4 * alpha * np.dot(dq, res) or rn < 1e-7:
                    break
                alpha *= 0.5
            if shift > 0 or lam > 0:
                lam = lam / 10 if alpha == 1.0 else max(lam * 10, 1e-8)
            self._commit(qt, np.zeros(self.ndof), self.state.time)
        q = self.state.q
        _, g, _ = self.elastic(q, hessian=False)
        _, fc, _ = self.contact(q, hessian=False)
        res = g - self.gravity_force - fc
        res[self.fixed] = 0.0
        return np.linalg.norm(res)

    def hessian_dense(self, free_only=True):
        """Dense stiffness matrix (elastic + contact) at the current state, restricted to free DOFs."""
        _, _, H = self.elastic(self.state.q)
        _, _, Hc = self.contact(self.state.q)
        if Hc is not None:
            H.ab += Hc.ab
        A = H.to_dense()
        if free_only:
            free = ~self.fixed
            A = A[np.ix_(free, free)]
        return A

    def energies(self):
        q = self.state.q
        Ee, _, _ = self.elastic(q, hessian=False)
        Ec, _, _ = self.contact(q, hessian=False)
        kinetic = 0.5 * np.sum(self.mass * self.state.u ** 2)
        return {'elastic': Ee, 'contact': Ec, 'gravity': -np.dot(self.gravity_force, q), 'kinetic': kinetic}
