"""A whole deployment in our discrete elastic rod simulator (``rod_deploy.physics.der_simulator``).

Set-up (CONTRACTS.md section 4): the rod hangs straight and at rest, its free end (node 0) on the table at the start
point and the held end (the last node) at the trajectory's hanging pose. The gripper holds the last edge: the last
two nodes follow the trajectory (positions interpolated linearly in time, orientation by slerp; the last edge along
d3 = -z_gripper) and so does the last edge's material frame (d1 = x_gripper), i.e. position, direction and twist.
The free end is held in place during the lead-in - the straight line on which the gripper leaves the hanging pose
(the planner's lead-in, or the straight line to the first pose of a trajectory that starts elsewhere) - and released
after it (``hold_free_end='always'`` keeps it pinned, as the paper does for a rope on a pattern whose start is curved:
a free end carries no moment, so it cannot stay curved; a pin does not carry one either: the experiment option
``clamp_start_xy`` holds the first nodes on given points, position and direction, a start that carries a moment).
The rod's rest length is its own length L (CONTRACTS.md section 4: the rod's length is its material length); the
first static solve stretches it by its weight up to the hanging pose, L + h + rho g L^2 / (2 E). (Until this round
the rest length was the stretched hanging length, 0.57 % (5.0 mm) too long for rod #3 and 2.4 % for rod #1: the hanging rod
then stood on its free end, its lower half compressed, an unstable straight equilibrium whose buckling direction at
the start of the lead-in was decided by the time step.) A perfect rod deployed by a mirror-symmetric trajectory stays
symmetric in the simulation, and the symmetric path can be an unstable one: a straight line planned by the numeric
planner (grasps exactly in the vertical plane) was laid 4.5 cm off on rods #2 and #3, its free end sliding back by
centimetres after the lead-in, while a 1 um random offset of the hanging rod's nodes laid it within 0.001-0.023 cm
(and within 0.03 cm the network's grasps, 0.3 mm off that plane, had laid it). The hanging rod therefore starts
with such an imperfection (``imperfection_m``, seeded: runs stay reproducible), as any buckling analysis does; a real
rod has far larger ones. The rest of the rod is free, under gravity, on a rigid table with regularised Coulomb friction, with a
small viscous damping (quasi-static deployment). Self-contact is ignored.

The trajectory is replayed with the gripper at ``max_gripper_speed_m_s`` (default 0.01 m/s, the planner's speed:
quasi-static; at 0.05 m/s the hanging rod already drags its free end along a straight line) in implicit-Euler steps
of ``dt_s``, then held still for ``settle_s``. Friction is Coulomb's law regularised below
``friction_velocity_m_s`` (mu N v / sqrt(v^2 + v_f^2)): under a steady tangential load r mu N, r < 1, a node creeps at
v_f r / sqrt(1 - r^2) instead of sticking, so slow replays creep more. The default, ``DEFAULT_FRICTION_VELOCITY_M_S``
= 1e-6 m/s (1e-4 until issue #10's measurement, ``benchmarks/friction_regularisation.py``): e_mean converges as v_f
goes to zero (rod #3's letter U 0.371, 0.135, 0.080 cm at 1e-4, 1e-5, 1e-6 m/s; the letter A 1.021, 0.862, 0.843)
with no halved step and the same CPU time; the straight rod under half the friction limit creeps 5.8 um in 10 s
(0.58 mm at 1e-4). At the end the deployed
shape is read off the table (``deployed_shape``): the nodes lying on it, in rod order from the free end, up to where
the rod rises towards the gripper; a node counts as lying while its centreline is at most
``LAID_HEIGHT_TOLERANCE_M`` = 0.3 mm above the table's contact height (the PyElastica replay reads its rods the same
way). With no tolerance (until issue #10's rod #1 round) the readout stopped at the first node lifted by any amount:
the rod leaves the table at the last planned contact point, and the node there, or the one beyond, is a few
nanometres to micrometres above or below the contact height, so the deployed curve ended up to one edge (5 mm)
early by chance, and Eq. 17, which resamples a shorter deployed curve over its own length, spread that shortfall
along the whole curve (rod #1's circle: 0.24 cm with the end node lifted by 19 um, 0.04 cm with it counted). The
tolerance alone counted the rod rising within 0.3 mm of the table beyond the lift-off point too (about 1 cm for the
paper's rods, 0.5-1.5 cm past the pattern's end), which a reader of the CSV would take for laid rod: an Eq. 17 that
resamples each curve over its own length scored rod #3's line 0.50 cm instead of 0.03. The shape therefore ends at
the touch-down point, between nodes: beyond it the rod rises as z - h = c (s - s_td)^3 (the heavy elastica's
boundary layer: curvature zero and a shear jump at the touch-down point), so the cube roots of the first two lifted
nodes' heights (above ``TOUCHING_HEIGHT_M``) extrapolate linearly to s_td, kept between the last node pressed into
the table as far as a laid one and the first lifted node (``touchdown_cut``): up to one edge past the pattern's end
where a node beyond the touch-down point still carries its weight, never a cut before a node that does. Eq. 17's
numbers do not move where the deployed curve stays longer than the pattern (``eq17_error`` compares the deployed
curve's first pattern length): the paper's 7 on rods #1-#3, nn plans, medium friction, to the 3rd decimal
(``benchmarks/results/deployment_table_r11_rods123_medium.md``); a rod that touches down short of the pattern's
end now shows it (rod #3's loop crossing itself at friction 1.0: 0.045 -> 0.269 cm, ``readout_touchdown.md`` and
the tables of the eleventh round).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from rod_deploy.deployment.metrics import arc_length
from rod_deploy.physics.der_simulator import DiscreteElasticRod, NewtonNotConverged, RodParameters
from rod_deploy.physics.reference_frames import parallel_transport, signed_angle
from rod_deploy.planning.rod_description import RodDescription

G = 9.81
DEFAULT_DENSITY = 1180.0          # kg/m^3 (vinyl polysiloxane, the paper's rods), when the rod file gives none
FRICTION_LEVELS = {'low': 0.2, 'medium': 0.5, 'high': 1.0}
#: regularisation velocity of Coulomb friction [m/s], the deployments' default (the only place it is set; see above)
DEFAULT_FRICTION_VELOCITY_M_S = 1e-6
#: a node counts as laid (``deployed_shape``) while its centreline is at most this above the table's contact height
LAID_HEIGHT_TOLERANCE_M = 3e-4
#: a node touches the table (``touchdown_cut``) while its centreline is at most this above the contact height: the
#: laid nodes sink 0.1-2 um into our penalty contact (PyElastica's: within its 1 um band), and the heavy elastica
#: rises only about 0.1 um in the first mm past the touch-down point
TOUCHING_HEIGHT_M = 2e-6
#: the rod's natural curvature (> 0 turning left once laid) as the material curvature kappa2: the gripper holds
#: d1 = x_gripper, which the planner's frames turn vertical on the table, so an in-plane bend is a kappa2 = -kb . d1
NATURAL_CURVATURE_SIGN = -1.0


class DeploymentError(ValueError):
    """A trajectory that cannot be simulated (clear message, no partial result)."""


@dataclass
class SimulationSettings:
    edge_length_m: float = 0.005     # rod discretisation
    dt_s: float = 0.02               # implicit Euler step (simulated time)
    max_gripper_speed_m_s: float = 0.01   # replay speed (quasi-static; 0.05 m/s already drags the free end)
    damping_per_s: float = 2.0       # viscous damping gamma [1/s]: force -gamma m v on every node
    settle_s: float = 1.0            # simulated time at the end with the gripper still
    friction: float | None = None    # Coulomb coefficient; None: the rod file's, else 'medium'
    start_xy: tuple | None = None    # free end's start point; None: below the trajectory's first (hanging) pose
    contact_tolerance_m: float = LAID_HEIGHT_TOLERANCE_M   # the deployed shape: nodes with z <= radius + this
    hold_twist: bool = True          # the gripper also holds the last edge's twist (d1 = x_gripper)
    friction_velocity_m_s: float = DEFAULT_FRICTION_VELOCITY_M_S   # regularisation of Coulomb friction (creep scale)
    hold_free_end: str = 'lead-in'   # 'lead-in' (CONTRACTS.md) or 'always' (the paper pins it for the rope's C)
    #: experiment: (k, 2) points [m], one edge apart, where the first k nodes lie and stay all along (k >= 2: a
    #: clamped start, position and direction, that carries a bending moment, unlike a pinned or free end); None: off
    clamp_start_xy: tuple | None = None
    #: a step whose Newton iteration does not converge is never accepted: it is retried as two half steps, down to
    #: dt_s / 2**max_step_halvings, then the simulation fails with a DeploymentError
    max_step_halvings: int = 6
    #: standard deviation [m] of horizontal offsets (seeded by ``imperfection_seed``) of the hanging rod's free
    #: interior nodes at the start: without them a mirror-symmetric deployment follows an unstable symmetric
    #: equilibrium (see the module docstring); 0: the perfect rod
    imperfection_m: float = 1e-6
    imperfection_seed: int = 20261126


@dataclass
class DeploymentResult:
    deployed_xy: np.ndarray          # (k, 2) nodes on the table from the free end [m]
    nodes: np.ndarray                # (N+1, 3) final configuration [m]
    gripper_path: np.ndarray         # (m, 3) the held node's prescribed positions [m]
    start_xy: np.ndarray
    lead_in_rows: int
    steps: int
    newton_iterations: int
    wall_time_s: float
    friction: float
    settings: SimulationSettings = field(repr=False, default=None)
    max_newton_iterations: int = 0   # in any accepted step
    halved_steps: int = 0            # steps of dt_s whose Newton did not converge and were retried as half steps
    smallest_step_s: float = 0.0     # the smallest (sub)step taken


def deployed_shape(nodes, radius_m, tolerance_m=LAID_HEIGHT_TOLERANCE_M):
    """The deployed shape (k, 2) [m]: the rod's nodes (N+1, 3) lying on the table, i.e. with the centreline at most
    ``tolerance_m`` above the contact height ``radius_m``, in rod order from the free end (node 0) up to where the rod
    rises towards the gripper, ended at the touch-down point (``touchdown_cut``); empty when the free end itself is
    above the tolerance."""
    nodes = np.asarray(nodes, float)
    on_table = nodes[:, 2] <= radius_m + tolerance_m
    k_end = int(np.argmin(on_table)) if not np.all(on_table) else len(nodes)
    if k_end == 0 or k_end == len(nodes):
        return nodes[:k_end, :2].copy()
    return touchdown_cut(nodes, radius_m, k_end)


def touchdown_cut(nodes, radius_m, k_end):
    """The laid nodes (x, y) before ``k_end`` (the first node above the laid tolerance) up to the touch-down point
    s_td, the last one interpolated: c the last node before ``k_end`` within ``TOUCHING_HEIGHT_M`` of the contact
    height, j = c + 1, c + 2 the first two beyond it (rising), h_j their heights above the contact height; the rod
    rises as h = a (s - s_td)^3 there, so s_td = s_j1 - cbrt(h_j1) (s_j2 - s_j1) / (cbrt(h_j2) - cbrt(h_j1)), kept in
    [s_p, s_j1], p the last node pressed into the table at least as far as the laid rod's median node. Without two
    rising nodes beyond c (the rod ends there) s_td = s_c; with no touching node before ``k_end`` the nodes before
    it, as the tolerance reads them."""
    h = nodes[:, 2] - radius_m
    touching = np.flatnonzero(h[:k_end] <= TOUCHING_HEIGHT_M)
    if len(touching) == 0:
        return nodes[:k_end, :2].copy()
    c = int(touching[-1])
    s = arc_length(nodes)
    s_td = s[c]
    if c + 2 < len(nodes) and TOUCHING_HEIGHT_M < h[c + 1] < h[c + 2]:
        r1, r2 = np.cbrt(h[c + 1]), np.cbrt(h[c + 2])
        s_td = s[c + 1] - r1 * (s[c + 2] - s[c + 1]) / (r2 - r1)
        # not before the last node pressed into the table at least as far as the laid rod's median node (carrying
        # its weight or more, e.g. a share of the touch-down's point force: on the table whatever the fit says).
        # Edges of 0.15-0.3 L_gb resolve the boundary layer poorly: on rod #1 (L_gb 1.8 cm, 5 mm edges) the fit put
        # the end 2.6 mm before such a node, and Eq. 17 spread that shortfall (a loop 0.034 -> 0.108 cm)
        # (never empty: at least one touching node, all at or before c, lies at or below their median)
        pressed = np.flatnonzero(h[:c + 1] <= float(np.median(h[touching])))
        s_td = min(max(s_td, s[int(pressed[-1])]), s[c + 1])
    i = int(np.searchsorted(s, s_td, side='right')) - 1       # s[i] <= s_td < s[i + 1]
    if s_td - s[i] < 1e-9:
        return nodes[:i + 1, :2].copy()
    f = (s_td - s[i]) / (s[i + 1] - s[i])
    end = nodes[i, :2] + f * (nodes[i + 1, :2] - nodes[i, :2])
    return np.vstack([nodes[:i + 1, :2], end])


def is_hanging_pose(position, quaternion, rod: RodDescription, tol_m=0.01, tol_rad=0.05):
    z_g = Rotation.from_quat(quaternion).as_matrix()[:, 2]
    return (abs(position[2] - rod.hanging_height_m) < tol_m and
            math.acos(min(1.0, max(-1.0, -z_g[2]))) < tol_rad)


def lead_in_rows(position, tol_m=1e-4):
    """Rows on the straight line leaving the first pose: the lead-in (at least the first row)."""
    if len(position) < 2:
        return 1
    d = position[1] - position[0]
    n = np.linalg.norm(d)
    if n < 1e-12:
        return 1
    d /= n
    last = 1
    for k in range(2, len(position)):
        v = position[k] - position[0]
        along = float(np.dot(v, d))
        if along < np.dot(position[last] - position[0], d) - 1e-12 or np.linalg.norm(v - along * d) > tol_m:
            break
        last = k
    return last + 1


def material_parameters(rod: RodDescription, friction: float, damping_per_s: float,
                        friction_velocity=DEFAULT_FRICTION_VELOCITY_M_S):
    """SI rod parameters with the rod's L_gb: E from L_gb = (E h^2 / (8 rho g))^(1/3) and the density."""
    rho = rod.density_kg_m3 or DEFAULT_DENSITY
    h = rod.radius_m
    E = rod.youngs_modulus_pa or 8.0 * rho * G * rod.gravito_bending_length_m ** 3 / h ** 2
    if rod.youngs_modulus_pa and rod.density_kg_m3:      # keep the rod's own pair; its L_gb follows from them
        E = rod.youngs_modulus_pa
    A = math.pi * h ** 2
    EI = E * math.pi * h ** 4 / 4.0
    nu = 0.5
    return RodParameters(EI=EI, EA=E * A, GJ=EI / (1.0 + nu), rho_A=rho * A, radius=h, gravity=(0.0, 0.0, -G),
                         damping=rho * A * damping_per_s, table=True, friction=friction,
                         friction_velocity=friction_velocity,
                         natural_curvature=(0.0, NATURAL_CURVATURE_SIGN * rod.natural_curvature_per_m))


@dataclass
class ReplaySchedule:
    """The trajectory as a simulator replays it: from the hanging pose, at the speed cap."""
    t: np.ndarray            # (n,) replay times [s], t[0] = 0
    position: np.ndarray     # (n, 3) held node [m]
    quaternion: np.ndarray   # (n, 4) gripper orientation, scalar-last, one hemisphere
    start_xy: np.ndarray     # the free end's start point on the table [m]
    lead_in_rows: int        # rows on the straight line leaving the hanging pose
    t_release: float         # replay time at which the free end is released [s]

    def gripper(self, time_s):
        """(position (3,), rotation matrix (3, 3)) of the gripper at replay time ``time_s`` (clamped)."""
        tt = min(max(time_s, self.t[0]), self.t[-1])
        if tt != self._last[0]:       # a step asks twice for the same time (positions, then the twist)
            p = np.array([np.interp(tt, self.t, self.position[:, k]) for k in range(3)])
            R = self._slerp([tt]).as_matrix()[0]
            p.flags.writeable = R.flags.writeable = False
            self._last = (tt, p, R)
        return self._last[1], self._last[2]

    def __post_init__(self):
        self._slerp = Slerp(self.t, Rotation.from_quat(self.quaternion))
        self._last = (None, None, None)


def replay_schedule(t, position, quaternion, rod: RodDescription, start_xy=None,
                    max_gripper_speed_m_s=0.01, n_lead_in: int | None = None) -> ReplaySchedule:
    """Where the free end starts, the hanging pose prepended when the trajectory starts elsewhere (the straight
    lead-in of CONTRACTS.md section 4), the lead-in rows and the replay times at the gripper speed cap.

    ``n_lead_in``: rows of the lead-in when known (e.g. a measured trajectory, whose straight lead-in line is only
    straight to the arm's tracking error); default: found by ``lead_in_rows``."""
    t = np.asarray(t, float)
    n_given = len(t)
    position = np.asarray(position, float)
    quaternion = np.asarray(quaternion, float)
    # -- where the rod starts: hanging from the first pose, or below the hanging pose above start_xy
    if start_xy is not None:
        start = np.asarray(start_xy, float)
        hang_p = np.array([start[0], start[1], rod.hanging_height_m])
        z_first = Rotation.from_quat(quaternion[0]).as_matrix()
        x0 = z_first[:, 0].copy()
        x0[2] = 0.0
        x0 = x0 / np.linalg.norm(x0) if np.linalg.norm(x0) > 1e-6 else np.array([1.0, 0.0, 0.0])
        hang_R = np.column_stack([x0, np.cross([0.0, 0.0, -1.0], x0), [0.0, 0.0, -1.0]])
        if not is_hanging_pose(position[0], quaternion[0], rod) or np.linalg.norm(position[0] - hang_p) > 1e-3:
            position = np.vstack([hang_p, position])
            quaternion = np.vstack([Rotation.from_matrix(hang_R).as_quat(), quaternion])
            gap = np.linalg.norm(position[1] - position[0])
            t = np.concatenate([[t[0] - max(gap / 0.01, 1.0)], t])
    else:
        if not is_hanging_pose(position[0], quaternion[0], rod):
            z_g = Rotation.from_quat(quaternion[0]).as_matrix()[:, 2]
            raise DeploymentError(
                f'the trajectory does not start at a hanging pose (gripper {rod.hanging_height_m:.4f} m above the table, '
                f'+z_gripper down): first pose at z = {position[0, 2]:.4f} m with +z_gripper = '
                f'{np.round(z_g, 3).tolist()}; give the pattern\'s first point (--start X Y or --pattern) so that '
                f'the simulation can lead in from the hanging pose above it')
        start = position[0, :2].copy()
    n_lead = lead_in_rows(position) if n_lead_in is None else int(n_lead_in) + (len(position) - n_given)
    t = t - t[0]
    # -- replay speed: the gripper never faster than max_gripper_speed_m_s
    seg = np.linalg.norm(np.diff(position, axis=0), axis=1)
    dts = np.diff(t)
    peak = float(np.max(seg / np.maximum(dts, 1e-12))) if len(seg) else 0.0
    ts = t * (peak / max_gripper_speed_m_s) if peak > 0 else t    # replayed at the speed cap
    return ReplaySchedule(t=ts, position=position, quaternion=quaternion, start_xy=start, lead_in_rows=n_lead,
                          t_release=float(ts[n_lead - 1]))


def held_edge_twist(rod_model: DiscreteElasticRod, R_gripper, previous_theta: float) -> float:
    """Twist angle of the last edge that turns its material d1 onto x_gripper, the edge along d3 = -z_gripper
    (reference frame parallel-transported from the rod's current one), on the branch nearest ``previous_theta``."""
    last = rod_model.n_edges - 1
    d3 = -R_gripper[:, 2]
    st = rod_model.state
    d1_ref = parallel_transport(st.d1[last][None], st.tangents[last][None], d3[None])[0]
    d1_ref -= d3 * np.dot(d1_ref, d3)
    d1_ref /= np.linalg.norm(d1_ref)
    target = float(signed_angle(d1_ref, R_gripper[:, 0], d3))
    return target + 2 * np.pi * round((previous_theta - target) / (2 * np.pi))


def _check_clamp(clamp_xy, edge_m, n_edges):
    """Number of clamped nodes; the points must be (k, 2), 2 <= k < n_edges, one edge length apart."""
    if clamp_xy.ndim != 2 or clamp_xy.shape[1] != 2 or not 2 <= len(clamp_xy) < n_edges \
            or not np.all(np.isfinite(clamp_xy)):
        raise DeploymentError(f'clamp_start_xy must be 2 to {n_edges - 1} finite (x, y) points, got shape '
                              f'{clamp_xy.shape}')
    gaps = np.linalg.norm(np.diff(clamp_xy, axis=0), axis=1)
    if np.max(np.abs(gaps - edge_m)) > 0.02 * edge_m:
        raise DeploymentError(f'clamp_start_xy points must be one edge ({edge_m * 1000:.3f} mm) apart, got gaps of '
                              f'{gaps.min() * 1000:.3f}-{gaps.max() * 1000:.3f} mm')
    return len(clamp_xy)


def simulate_deployment(t, position, quaternion, rod: RodDescription, settings: SimulationSettings | None = None,
                        progress=None, n_lead_in: int | None = None) -> DeploymentResult:
    """Simulate the deployment of ``rod`` by a gripper following the trajectory (t, position, quaternion).
    ``n_lead_in``: rows of the lead-in when known (see :func:`replay_schedule`)."""
    settings = settings or SimulationSettings()
    if settings.hold_free_end not in ('lead-in', 'always'):
        raise DeploymentError(f"hold_free_end must be 'lead-in' or 'always', got {settings.hold_free_end!r}")
    t = np.asarray(t, float)
    position = np.asarray(position, float)
    quaternion = np.asarray(quaternion, float)
    friction = settings.friction if settings.friction is not None else (
        rod.friction if rod.friction is not None else FRICTION_LEVELS['medium'])
    t_wall = time.perf_counter()
    L, h = rod.length_m, rod.radius_m
    clamp_xy = None if settings.clamp_start_xy is None else np.asarray(settings.clamp_start_xy, float)
    start_xy = settings.start_xy if clamp_xy is None else clamp_xy[0]
    sched = replay_schedule(t, position, quaternion, rod, start_xy, settings.max_gripper_speed_m_s, n_lead_in)
    ts, position, start, n_lead, t_release, gripper = (sched.t, sched.position, sched.start_xy, sched.lead_in_rows,
                                                        sched.t_release, sched.gripper)

    # -- the rod, hanging straight from the first pose
    n_edges = max(int(round(L / settings.edge_length_m)), 4)
    s = np.linspace(0.0, L, n_edges + 1)
    p0, R0 = gripper(0.0)
    free = np.array([start[0], start[1], h])
    nodes = np.repeat(free[None], n_edges + 1, axis=0)
    n_clamp = 0
    if clamp_xy is not None:
        n_clamp = _check_clamp(clamp_xy, L / n_edges, n_edges)
        nodes[:n_clamp] = np.column_stack([clamp_xy, np.full(n_clamp, h)])
    # the rod at its own length L (edges of rest length L / N), straight from the free end (or the last clamped node)
    # towards the hanging pose; the first static solve brings the held nodes up to it, stretching the rod by its weight
    k = max(n_clamp - 1, 0)
    u = (p0 - nodes[k]) / np.linalg.norm(p0 - nodes[k])
    nodes[k:] = nodes[k][None] + (s[k:] - s[k])[:, None] * u[None]
    if settings.imperfection_m > 0:           # the free interior nodes; the free end, clamp and held edge stay put
        rng = np.random.default_rng(settings.imperfection_seed)
        nodes[k + 1:n_edges - 1, :2] += settings.imperfection_m * rng.standard_normal((n_edges - 2 - k, 2))
    params = material_parameters(rod, friction, settings.damping_per_s, settings.friction_velocity_m_s)
    d1_top = R0[:, 0]
    rod_model = DiscreteElasticRod(nodes, params, d1_first=d1_top)
    dl = L / n_edges
    last = n_edges - 1
    top_dofs = np.concatenate([rod_model.node_dof(n_edges), rod_model.node_dof(n_edges - 1)])
    theta_dof = rod_model.theta_dof(last)
    state = {'theta': 0.0}
    # initial twist of the last edge so that its material d1 = x_gripper
    t_last = rod_model.state.tangents[last]
    state['theta'] = float(signed_angle(rod_model.state.d1[last], R0[:, 0], t_last))
    rod_model.set_positions(theta_dof, state['theta'])

    def top_positions(time_s):
        p, R = gripper(time_s)
        return np.concatenate([p, p + dl * R[:, 2]])           # node N, node N-1 = N - dl d3 = N + dl z_g

    def top_theta(time_s):
        state['theta'] = held_edge_twist(rod_model, gripper(time_s)[1], state['theta'])
        return np.array([state['theta']])

    rod_model.prescribe(top_dofs, top_positions)
    if settings.hold_twist:
        rod_model.prescribe(np.array([theta_dof]), top_theta)
    free_end = rod_model.node_dof(0)
    hold = {'on': True}
    rod_model.prescribe(free_end, lambda _t: np.array([start[0], start[1], h]))
    for i in range(1, n_clamp):
        rod_model.clamp_node(i)
    # settle the hanging rod (it starts straight and at rest: a few steps suffice)
    rod_model.static_solve(tol=1e-8, max_iter=50)
    total = ts[-1] + settings.settle_s
    steps = int(math.ceil(total / settings.dt_s))
    stats = {'iterations': 0, 'max_iterations': 0, 'halved': 0, 'smallest': settings.dt_s}

    def advance(dt, halvings):
        """One step of dt; a step whose Newton does not converge is retried as two half steps (the state is left
        unchanged by the failed attempt), never accepted."""
        try:
            it = rod_model.step(dt)
        except NewtonNotConverged as e:
            if halvings >= settings.max_step_halvings:
                raise DeploymentError(f'the rod simulation did not converge at t = {e.time:.4f} s, even with steps of '
                                      f'{dt:.3g} s (dt_s / 2^{halvings}): {e}') from None
            if halvings == 0:
                stats['halved'] += 1
            advance(0.5 * dt, halvings + 1)
            advance(0.5 * dt, halvings + 1)
            return
        stats['iterations'] += it
        stats['max_iterations'] = max(stats['max_iterations'], it)
        stats['smallest'] = min(stats['smallest'], dt)

    path = []
    for k in range(steps):
        now = (k + 1) * settings.dt_s
        if hold['on'] and now > t_release and settings.hold_free_end != 'always' and n_clamp == 0:
            hold['on'] = False
            del rod_model._prescribed[tuple(free_end.tolist())]
            rod_model.fixed[free_end] = False
        try:
            advance(settings.dt_s, 0)
        except DeploymentError:
            raise
        except (np.linalg.LinAlgError, ValueError, FloatingPointError) as e:
            raise DeploymentError(f'the rod simulation failed at t = {now:.3f} s: {e}') from None
        if not np.all(np.isfinite(rod_model.state.q)):
            raise DeploymentError(f'the rod simulation diverged at t = {now:.3f} s')
        path.append(rod_model.nodes[-1].copy())
        if progress is not None:
            progress(k + 1, steps)
    final = rod_model.nodes
    return DeploymentResult(deployed_xy=deployed_shape(final, h, settings.contact_tolerance_m), nodes=final,
                            gripper_path=np.array(path), start_xy=start,
                            lead_in_rows=n_lead, steps=steps, newton_iterations=stats['iterations'],
                            wall_time_s=time.perf_counter() - t_wall, friction=friction, settings=settings,
                            max_newton_iterations=stats['max_iterations'], halved_steps=stats['halved'],
                            smallest_step_s=stats['smallest'])
