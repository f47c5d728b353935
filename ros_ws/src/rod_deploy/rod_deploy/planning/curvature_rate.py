"""How fast the planned curvature may change along the pattern: the laid rod cannot take a sudden change of moment.

Why the gripper jumped (issue #10, ``benchmarks/grasp_jump.py``): the optimal grasp is a smooth function of the
node's curvature, with no change of branch (the network agrees with the numeric solver there to 0.02 L_gb), but a
steep one - at ls_bar = 25 the gripper's lateral offset moves by 5-6 L_gb per unit of kappa_bar, 17-20 cm for rod
#3. A pattern whose curvature changes by about one unit of kappa_bar within one 5 mm node (the 10 cm hook's straight
stem running into its 1.6 cm curl, the digit 2's lower corner) therefore moves the gripper 11-17 cm per node, along a
straight chord up to 4.8 cm off the path of the optimal grasps in between.

The jump is not what drags the laid rod: the same trajectories deploy to 0.29-0.37 cm on a table with friction 2-5
instead of 1.2-9.4 cm at 0.5, and 1 mm nodes (the gripper on the optimal grasps all along, steps of 2.7 cm) leave the
digit 2 as it was (1.86 cm against 1.81). The optimal grasp at a node imposes the pattern's bending moment EI kappa
there; the rod laid just before it holds its own, and the difference is taken by friction over a length of laid rod
that grows with the jump (a sudden kappa_bar of 2.5 after a 30 cm straight lead drags the last 11 cm of the lead into
a loop at friction 0.5). The planner therefore asks the grasp solver for a curvature that changes at most ``max_rate``
per L_gb of pattern: :func:`limit_curvature_rate` spreads a faster change over the neighbouring nodes, conservatively
(the integral of kappa, the pattern's turning, is kept, so the heading after the change is the pattern's) and only
where the limit is exceeded (a curvature that changes slower is untouched). The contact point and the tangent stay on
the pattern; the grasp moves at most about 1 cm per node in the pattern's frame (the rate times dq/dkappa_bar), the
gripper a few centimetres in the table's (it also orbits the contact point as the tangent turns). Measured at friction
0.5 (rod #3, e_mean): digit 2 1.81 -> 0.60 cm, tight wave 1.20 -> 0.79, letter A 0.84 -> 0.42; the limit's default
scales with sqrt(friction) (:func:`default_max_rate`). A ramp may not bend the friction-limited start more than
friction holds there (the planner caps it, ``trajectory.plan_trajectory``).
"""
from __future__ import annotations

import numpy as np
from scipy import sparse

#: the limit on |d kappa_bar / d(s / L_gb)| of the planned curvature at table friction 0.5 (benchmarks/grasp_jump.py:
#: rod #3, 1 -> 0.5 -> 0.35 -> 0.25 -> 0.125 per L_gb; 0.35 the largest gain with none of the paper's 7 worse)
DEFAULT_MAX_RATE = 0.35
#: the friction DEFAULT_MAX_RATE was measured at
DEFAULT_RATE_FRICTION = 0.5


def default_max_rate(friction):
    """The default limit at table friction ``friction``: DEFAULT_MAX_RATE sqrt(friction / 0.5). Friction over a
    stretch l of laid rod holds a change of kappa_bar of about mu (l / L_gb)^2 / 8 (achievable_start.py's bound), so
    a change d kappa_bar needs a ramp of L_gb sqrt(8 d kappa_bar / mu): its slope scales with sqrt(mu). Measured at
    0.5 (the paper's medium) and, for the hook, at 5 (benchmarks/grasp_jump.py)."""
    return DEFAULT_MAX_RATE * float(np.sqrt(friction / DEFAULT_RATE_FRICTION))


def limit_curvature_rate(kappa_bar, step_bar, max_rate, max_iterations=20000):
    """kappa_bar (m,) with |kappa_bar[i+1] - kappa_bar[i]| <= max_rate * step_bar at every node pair.

    Conservative diffusion on the violating node pairs only: each pair that changes by more than the limit passes a
    share of its excess to the other node; the sum of kappa_bar (the total turning) is unchanged and a curvature that
    changes within the limit everywhere is returned unchanged. ``step_bar``: the node spacing over L_gb."""
    k = np.array(kappa_bar, float, copy=True)
    if not np.isfinite(max_rate):
        return k
    if not (max_rate > 0 and step_bar > 0):
        raise ValueError(f'max_rate and step_bar must be positive, got {max_rate}, {step_bar}')
    limit = max_rate * step_bar
    tol = 1e-2 * limit
    for _ in range(max_iterations):
        d = np.diff(k)
        excess = np.sign(d) * np.maximum(np.abs(d) - limit, 0.0)
        if np.abs(excess).max(initial=0.0) <= tol:
            return k
        # 1/3 of the excess each way: a node between two violating pairs still moves less than either asks
        k[:-1] += excess / 3.0
        k[1:] -= excess / 3.0
    raise RuntimeError('the curvature rate limit did not converge')   # pragma: no cover (a bounded diffusion)


#: knot spacing of the closest rate-limited curve's curvature [L_gb] (piecewise linear between knots)
CLOSEST_KNOT_SPACING_BAR = 0.25
#: weight of d kappa_bar / d(s / L_gb) against the distance from the pattern [L_gb] in the closest curve's fit
#: (a little, so that the fit does not wiggle within the limit)
CLOSEST_RATE_WEIGHT = 0.1


def closest_rate_limited_curve(pattern, kappa0, theta0, gravito_bending_length_m, max_rate, cap_bar,
                                free_start_point=False):
    """The curve closest to ``pattern`` (least squares on the nodes at equal arc length, Eq. 17's pairing; the free
    end at the pattern's first point) whose curvature changes at most ``max_rate`` per L_gb and stays within
    ``cap_bar`` (m,) [kappa_bar] at each node (the friction-limited start): a ProcessedPattern on the same nodes whose
    points, tangents and curvature belong to one curve.

    Why: the rod lays the curvature its grasps ask for, not the contact points (a rounded zig-zag on rod #3 lay
    1.2 cm from the curve of its asked curvature, 4.3 cm from the pattern). :func:`limit_curvature_rate` spreads a
    bend symmetrically, which keeps the turning but rounds a corner wider: the curve comes out shorter around it and
    every later node lags along the pattern. Here the unknowns are the curvature at knots every
    CLOSEST_KNOT_SPACING_BAR L_gb (piecewise linear, so the rate is the slope between knots) and the first heading,
    started from ``kappa0`` (m,) [1/m] and ``theta0`` [rad] (the spread curvature and the start heading); the limits
    are penalties, then enforced exactly (``limit_curvature_rate``, a clip) and the curve integrated once more.

    ``free_start_point``: the curve's first point (the free end) is an unknown too (two more, appended after the
    knots: its offset from the pattern's first point in L_gb), instead of the pattern's first point. Near a free end
    the friction-limited start holds the curvature to kappa_max(s) ~ s^2, so a curved start (letter C) must begin
    nearly straight; from the pattern's first point that straight start leaves the pattern by up to 8 mm (rod #3),
    while a free end placed a few millimetres inside the bend lets the same bounded curve straddle the pattern
    (``benchmarks/start_floor.py``: letter C, rod #3, mu 0.5, the best e_mean under the planner's bounds 0.144 ->
    0.072 cm)."""
    from .achievable_start import _cumtrapz, integrate_curvature
    from .closest_curve_kernel import column_support, fit_normal_equations
    from .trajectory import ProcessedPattern

    Lgb = gravito_bending_length_m
    s, target = pattern.s, pattern.xy
    n = len(s)
    n_knots = max(int(np.ceil(s[-1] / (CLOSEST_KNOT_SPACING_BAR * Lgb))), 1) + 1
    s_knots = np.linspace(0.0, s[-1], n_knots)
    h_bar = (s_knots[1] - s_knots[0]) / Lgb
    hat = np.clip(1.0 - np.abs(s[:, None] - s_knots[None, :]) / (s_knots[1] - s_knots[0]), 0.0, None)   # (n, k)
    cap_knots = np.interp(s_knots, s, cap_bar)
    ds = np.diff(s)
    dtheta = np.column_stack([np.ones(n), _cumtrapz(hat, ds) / Lgb])                  # d theta / d(theta0, c)
    w_pen = 10.0 * np.sqrt(n)

    # the fit rows' J^T J and J^T r by a recurrence (closest_curve_kernel); the smoothing rows are linear in the
    # knots: their share is formed directly (D^T D is tridiagonal) rather than by stacking their rows. Both limits,
    # the cap on each knot and the rate between neighbours, are linear in the knots too: handed to the solver as
    # limits |D x| <= c (penalty rows it steps onto exactly; as residuals here, each change of which rows are active
    # broke the Gauss-Newton model: 145 Jacobians on the letter C, 15 now). No BLAS call in the loop: OpenBLAS's
    # threads, woken by a product above its size threshold, spin on the second core after it (the CPU time doubled
    # at load 2.5)
    first, settled = column_support(dtheta)
    half_ds = 0.5 * ds / Lgb
    knots = slice(1, 1 + n_knots)                       # the knots' place in the unknowns (theta0 first)
    rate_weight2 = CLOSEST_RATE_WEIGHT ** 2
    n_free = 2 if free_start_point else 0               # the start point's offset [L_gb], after the knots
    n_x = 1 + n_knots + n_free
    cap_rows = sparse.eye(n_knots, n_x, k=1, format='csr')                          # x[knots]
    rate_rows = (sparse.eye(n_knots - 1, n_x, k=2) - sparse.eye(n_knots - 1, n_x, k=1)).tocsr() / h_bar
    limits = (sparse.vstack([cap_rows, rate_rows], format='csr'),
              np.concatenate([cap_knots, np.full(n_knots - 1, max_rate)]), w_pen)
    diagonal, upper = np.arange(n_knots), np.arange(n_knots - 1)
    main_smoothing = np.zeros(n_knots)
    main_smoothing[:-1] += rate_weight2 / h_bar ** 2
    main_smoothing[1:] += rate_weight2 / h_bar ** 2
    off_smoothing = rate_weight2 / h_bar ** 2
    last = {}                                           # the heading of the last curve integrated (x, theta)

    def origin(x):
        return target[0] + Lgb * x[1 + n_knots:] if free_start_point else target[0]

    def curve(x):
        # the piecewise linear curvature between the knots (the hat functions' sum)
        xy, theta = integrate_curvature(s, theta0 + x[0], np.interp(s, s_knots, x[knots]) / Lgb, origin(x))
        last['x'], last['theta'] = x.copy(), theta
        return xy, theta

    def residuals(x):
        xy, _ = curve(x)
        rate = np.diff(x[knots]) / h_bar
        return np.concatenate([((xy - target) / Lgb).ravel(), CLOSEST_RATE_WEIGHT * rate])

    def normal_equations(x, r):
        theta = last['theta'] if np.array_equal(last.get('x'), x) else curve(x)[1]
        r_fit = r[:2 * n].reshape(n, 2)
        A, g = fit_normal_equations(theta, dtheta, first, settled, half_ds, r_fit)
        if free_start_point:
            # the start point's offset [L_gb] moves every node's fit residual by itself (d r / d offset = I); its
            # cross terms with (theta0, knots) are the fit Jacobian's columns summed over the nodes (formed densely:
            # an option, not the default path)
            f = dtheta.T[:, None, :] * np.stack([-np.sin(theta), np.cos(theta)])[None]
            cross = np.cumsum(half_ds * (f[:, :, 1:] + f[:, :, :-1]), axis=2).sum(axis=2).T     # (2, k + 1)
            A = np.block([[A, cross.T], [cross, n * np.eye(2)]])
            g = np.concatenate([g, r_fit.sum(axis=0)])
        rate = np.diff(x[knots]) / h_bar
        # the smoothing rows: rate_weight2 D^T D, D the knots' differences over h_bar (tridiagonal)
        Ac = A[knots, knots]                                                  # a view: updates A
        Ac[diagonal, diagonal] += main_smoothing
        Ac[upper, upper + 1] -= off_smoothing
        Ac[upper + 1, upper] -= off_smoothing
        v = rate_weight2 * rate
        g[knots] += (np.r_[0.0, v] - np.r_[v, 0.0]) / h_bar                 # D^T v
        return A, g

    x0 = np.concatenate([[0.0], np.interp(s_knots, s, np.asarray(kappa0, float) * Lgb), np.zeros(n_free)])
    # ftol 1e-13: on a flat minimum (a cursive e, an outward spiral) 1e-10 left the plan up to 1e-5 m, 1e-5 rad from
    # the minimum's (benchmarks/results/planning_equivalence.md), for 2 % more Jacobians over its 64 fits
    x = levenberg_marquardt(residuals, normal_equations, x0, limits=limits, ftol=1e-13)
    kappa_bar = np.clip(np.interp(s, s_knots, x[knots]), -cap_bar, cap_bar)
    kappa_bar = np.clip(limit_curvature_rate(kappa_bar, float(np.mean(ds)) / Lgb, max_rate), -cap_bar, cap_bar)
    xy, theta = integrate_curvature(s, theta0 + x[0], kappa_bar / Lgb, origin(x))
    return ProcessedPattern(s=s.copy(), xy=xy, tangent=np.column_stack([np.cos(theta), np.sin(theta)]),
                            kappa=kappa_bar / Lgb)


#: exact active-set iterations on a step before levenberg_marquardt only adds limit rows (see its step_to)
EXACT_SET_ITERATIONS = 8


def levenberg_marquardt(residuals, normal_equations, x0, limits=None, ftol=1e-10, xtol=1e-10, max_iterations=1000):
    """argmin |residuals(x)|^2 + |w max(|D x| - c, 0)|^2 from ``x0``: Levenberg-Marquardt on the normal equations
    (Cholesky of J^T J plus Marquardt's damping, scaled by the largest diagonal seen so far; compiled, single-threaded:
    ``closest_curve_kernel.cholesky_solve``). ``normal_equations(x,
    r)`` returns (J^T J, J^T r) at x, r = residuals(x) (the last residuals evaluated were at x when the step was
    taken, so a caller may reuse what it computed there). ``limits``: None or (D, c, w), D an (m, p) matrix (dense or
    scipy.sparse), c (m,) >= 0 (inf: none), w >= 0: limits |D_i x| <= c_i kept as penalty rows of weight w (a bound
    |x_i| <= b_i is a row of the identity). They are piecewise linear in x, so each step minimises the Gauss-Newton
    model with them exactly (an active-set iteration on the step): a step that would cross a limit stops at it,
    where the model linearised at x overshoots it and is rejected (the closest curve's start, capped knot after
    knot, took 71 Jacobians on the 200-node spiral that way, 9 now; its rate limit as residual rows, 145 on the
    letter C, 15 now). For the closest curve's few hundred residuals and about a hundred unknowns a step costs a
    fraction of one of scipy's ``least_squares`` (trf), whose SVD of J per step took 90 % of the planning time
    (benchmarks/planning_speed.py), and it runs to the minimum (trf with 100 evaluations stopped short of it). Stops
    when the Gauss-Newton model at x (undamped) promises less than ``ftol`` of the cost, checked after a step that
    gained less than that (a heavily damped step gains little far from the minimum too: stopping there left the cost
    2e-6 above the minimum on some plans), or when a step changes x by less than ``xtol`` (relative), or after
    ``max_iterations`` Jacobians."""
    from .closest_curve_kernel import cholesky_solve

    x = np.array(x0, float, copy=True)
    p = len(x)
    if limits is None:
        D, c, w = sparse.coo_matrix((0, p)), np.zeros(0), 0.0
    else:
        D, c, w = limits
        D = sparse.coo_matrix(D)
        c = np.asarray(c, float)
        if D.shape != (len(c), p) or np.any(c < 0) or not w >= 0:
            raise ValueError(f'limits: (D, c, w) with D of shape (m, {p}), c (m,) >= 0 and w >= 0, got D '
                             f'{D.shape}, c {c.shape}, w {w}')
    # D's nonzeros, and each row's products of pairs of them (D_i^T D_i), summed by bincount: no BLAS call (see
    # closest_rate_limited_curve) and no sparse-matrix overhead in the step's loop
    rows, cols, vals = D.row, D.col, D.data
    m = len(c)
    pair_i, pair_j = np.nonzero(rows[:, None] == rows[None, :])
    pair_row, pair_at, pair_v = rows[pair_i], cols[pair_i] * p + cols[pair_j], vals[pair_i] * vals[pair_j]
    c_finite = np.where(np.isfinite(c), c, 0.0)
    w2 = float(w) ** 2

    def D_at(v):
        return np.bincount(rows, weights=vals * v[cols], minlength=m)

    def DT_at(u):
        return np.bincount(cols, weights=vals * u[rows], minlength=p)

    def DT_diag_D(a):
        return np.bincount(pair_at, weights=a[pair_row] * pair_v, minlength=p * p).reshape(p, p)

    def over(x):
        return np.maximum(np.abs(D_at(x)) - c, 0.0)

    def objective(x):
        r = residuals(x)
        o = over(x)
        return r, float(r @ r) + w2 * float(o @ o)

    def step_to(x, A, g, damping):
        """The step s minimising |r + J s|^2 + s^T diag(damping) s + the limit rows at x + s: the rows active at x + s
        found by iterating on them; coupled rows (the rate between neighbours) can make that iteration cycle, so after
        EXACT_SET_ITERATIONS rows are only added (a model above the true one where an added row is not violated:
        a shorter step, which the caller accepts only if it lowers the cost)."""
        Dx = D_at(x)
        active, sign = np.abs(Dx) > c, np.sign(Dx)
        H0 = A + np.diag(damping)
        for iteration in range(EXACT_SET_ITERATIONS + m + 1):
            a = w2 * active
            H = H0 + DT_diag_D(a) if active.any() else H0
            solution, ok = cholesky_solve(H, g + DT_at(a * (Dx - sign * c_finite)))
            if not ok:
                raise np.linalg.LinAlgError('the damped normal equations are not positive definite')
            step = -solution
            Dy = Dx + D_at(step)
            now = np.abs(Dy) > c
            if iteration < EXACT_SET_ITERATIONS:
                if np.array_equal(now, active) and np.array_equal(np.sign(Dy)[now], sign[now]):
                    break
                active, sign = now, np.sign(Dy)
            else:
                added = now & ~active
                if not added.any():
                    break
                active, sign = active | now, np.where(added, np.sign(Dy), sign)
        return step

    def gauss_newton_gain(x, r, cost, A, g, safe):
        """The decrease of the cost that the model at x promises for its own (barely damped) step."""
        try:
            step = step_to(x, A, g, 1e-12 * safe)
        except np.linalg.LinAlgError:
            return np.inf
        o = over(x + step)
        model = float(r @ r) + 2.0 * float(g @ step) + float(np.einsum('i,ij,j->', step, A, step)) + w2 * float(o @ o)
        return cost - model

    r, cost = objective(x)
    lam = 1e-3
    scale = np.zeros(len(x))
    small_gain = False
    for _ in range(max_iterations):
        A, g = normal_equations(x, r)
        scale = np.maximum(scale, np.diag(A) + w2 * np.bincount(cols, weights=vals ** 2 * (np.abs(D_at(x)) > c)[rows],
                                                               minlength=p))     # active limit rows
        safe = np.where(scale > 0, scale, 1.0)
        if small_gain and gauss_newton_gain(x, r, cost, A, g, safe) <= ftol * cost:
            break
        while lam < 1e16:
            try:
                step = step_to(x, A, g, lam * safe)
            except np.linalg.LinAlgError:
                lam *= 4.0
                continue
            x_new = x + step
            r_new, cost_new = objective(x_new)
            if cost_new < cost:
                break
            lam *= 4.0
        else:
            return x
        small_gain = cost - cost_new <= ftol * cost
        small_step = np.linalg.norm(step) <= xtol * (xtol + np.linalg.norm(x))
        x, r, cost = x_new, r_new, cost_new
        lam = max(lam / 3.0, 1e-12)
        if small_step:
            break
    return x
