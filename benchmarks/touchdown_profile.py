"""Where a bend's error arises, per 4 cm of the pattern (issue #10): the laid rod at touch-down against the planned
curve, its motion after touch-down, and the final error against the pattern, each split into the inward (towards
the side the pattern turns to) and tangential components, mm; our DER, nodes kept every 0.5 s.

    PYTHONPATH=ros_ws/src/rod_deploy .venv/bin/python benchmarks/touchdown_profile.py ROD FRICTION PATTERNS DRAG

DRAG 1: the planner's default (drag compensation on), 0: off. Prints the table; development patterns only.
Touch-down: the first 0.5 s snapshot from which the node stays within 0.5 mm of the table (error_profile.py).
"""
import sys
sys.path.insert(0, str(__import__('pathlib').Path(__file__).resolve().parent))
import numpy as np
from deployment_table import RODS, all_patterns
from replay_probe import run_der
from error_profile import profile
from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, plan_trajectory
from rod_deploy.deployment.metrics import eq17_error
rodn, mu, names = int(sys.argv[1]), float(sys.argv[2]), sys.argv[3]
drag = sys.argv[4] == '1'
rod = rod_description_from_dict(RODS[rodn])
for name in names.split(','):
    P = all_patterns(name)[name]
    plan = plan_trajectory(P, rod, PlannerSettings(friction=mu, drag_compensation=drag))
    f = f'/tmp/touchdown_profile_{name}_{mu}_{int(drag)}.npz'
    import os
    if not os.path.exists(f):
        times, nodes, dep, *_ = run_der((plan.t, plan.position, plan.quaternion, None), rod, mu, {}, 0.5)
        np.savez(f, times=times, nodes=nodes, pattern=P, deployed=dep, e_mean_cm=eq17_error(P, dep)['e_mean_cm'])
    pr = profile(f, rod.radius_m, rod.gravito_bending_length_m)
    s = pr['s']; Ps = pr['Ps']; fin = pr['final'][:len(s), :2]
    nodes = np.load(f)['nodes']
    g = plan.drawn_pattern
    tg = np.column_stack([np.interp(s, g.s, g.tangent[:, k]) for k in range(2)]); tg /= np.linalg.norm(tg, axis=1, keepdims=True)
    kap = np.interp(s, g.s, g.kappa)
    inward = np.sign(kap)[:, None] * np.column_stack([-tg[:, 1], tg[:, 0]])
    # touch-down positions
    on = nodes[:, :len(s), 2] <= rod.radius_m + 5e-4
    stays = np.flip(np.cumprod(np.flip(on, axis=0), axis=0), axis=0).astype(bool)
    first = np.argmax(stays, axis=0)
    touch = nodes[first, np.arange(len(s)), :2]
    # the planned curve (the grasp's contact point) at s
    pc = plan.pattern
    pcs = np.column_stack([np.interp(s, pc.s, pc.xy[:, k]) for k in range(2)])
    print(f'== {name} mu {mu} drag {drag}: e_mean {float(np.load(f)["e_mean_cm"]):.3f}  (mm; inward + ; tang along pattern)')
    for a in np.arange(0, s[-1], 0.04):
        k = (s >= a) & (s < a + 0.04)
        dt = touch[k] - pcs[k]; dm = fin[k] - touch[k]; de = fin[k] - Ps[k]
        f_in = lambda d: 1e3 * np.mean(np.sum(d * inward[k], axis=1))
        f_t = lambda d: 1e3 * np.mean(np.sum(d * tg[k], axis=1))
        print(f' s {100*a:3.0f}-{100*(a+.04):3.0f}: |kb| {np.abs(kap[k]).max()*rod.gravito_bending_length_m:.2f} touch-vs-planned in {f_in(dt):+5.1f} t {f_t(dt):+5.1f} | moved in {f_in(dm):+5.1f} t {f_t(dm):+5.1f} | final-vs-pattern in {f_in(de):+5.1f} t {f_t(de):+5.1f} |{1e3*np.linalg.norm(de,axis=1).mean():5.1f}')
