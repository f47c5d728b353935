"""Optimal grasp (paper Sec. 3.2.3, 4.1-4.2): acceptance numbers, limits, cross-checks, stability, Alg. 1."""
from pathlib import Path

import numpy as np
import pytest

from rod_deploy.planning.optimal_grasp import (RELEASED_CONNECTIVE_OFFSET, discover_manifold_boundary,
                                               elastic_stability, grasp_sequence, optimal_grasp,
                                               optimal_grasp_der, perturbation_response)
from rod_deploy.planning.suspended_rod import default_mesh, solve_suspended_rod

REF = Path(__file__).resolve().parents[4].parent / 'shared' / 'reference' / 'rod_deployment' / 'numeric_solver_runs'
PUBLISHED = np.array([2.507738742, 0.0, 12.24094075])      # released C++ solver, (13.68, 2087, 0)


def test_published_point_in_the_released_convention():
    g = optimal_grasp(13.68, 0.0, 2087, connective_offset=RELEASED_CONNECTIVE_OFFSET)
    assert g.position == pytest.approx(PUBLISHED, rel=1e-3, abs=1e-9)
    assert g.stable is True


def test_published_point_continuum_differs_only_by_the_clamp_edge():
    g = optimal_grasp(13.68, 0.0, 2087)
    assert g.position == pytest.approx([2.56628, 0.0, 12.18237], abs=2e-5)
    assert np.linalg.norm(g.position - PUBLISHED) / np.linalg.norm(PUBLISHED) < 0.01
    d = RELEASED_CONNECTIVE_OFFSET                        # x - dl and ls + dl: the released node numbering
    assert g.position[0] - d == pytest.approx(PUBLISHED[0], abs=1e-3)
    assert g.rotvec == pytest.approx([0.0, -np.pi / 2, 0.0], abs=1e-7)
    assert g.force_residual < 1e-8
    assert g.clamp_force[2] > 0                           # Eq. 12: the table pushes


def test_heavy_elastica_straight_line_limit():
    for ls in (30.0, 60.0):
        g = optimal_grasp(ls, 0.0, np.inf, check_stability=False)
        assert g.position[0] == pytest.approx(2.5662, abs=2e-4)
        assert ls - g.position[2] == pytest.approx(1.5153, abs=2e-4)


def test_extensibility_adds_the_stretch_of_a_hanging_rod():
    ls, ks = 60.0, 1000.0
    z_inext = optimal_grasp(ls, 0.0, np.inf, check_stability=False).position[2]
    z = optimal_grasp(ls, 0.0, ks, check_stability=False).position[2]
    # tension G s + n_z(0) along the (vertical) hanging part: extra length (G ls^2 / 2 - F_z ls) / ks
    Fz = optimal_grasp(ls, 0.0, ks, check_stability=False).clamp_force[2]
    assert z - z_inext == pytest.approx((0.5 * ls ** 2 / 2 - Fz * ls) / ks, rel=0.01)


def test_lateral_offset_is_linear_in_kappa():
    kappas = np.array([0.01, 0.05, 0.1, 0.2])
    prev, slopes = None, []
    for k in kappas:
        prev = optimal_grasp(13.7, k, 2087, guess=prev, check_stability=False)
        slopes.append(prev.position[1] / k)
    slopes = np.array(slopes)
    assert np.all(slopes < 0)                              # released sign: kappa > 0 -> gripper at y < 0
    assert np.ptp(slopes) / abs(slopes.mean()) < 0.005
    assert slopes[0] == pytest.approx(-4.08, rel=0.02)     # released table: -4.08; released run: -4.04


def test_mirror_symmetry():
    a = optimal_grasp(9.0, 0.7, 900, check_stability=False)
    b = optimal_grasp(9.0, -0.7, 900, check_stability=False)
    assert b.position == pytest.approx(a.position * [1, -1, 1], abs=1e-9)
    assert b.rotvec == pytest.approx(a.rotvec * [-1, 1, -1], abs=1e-9)


def test_mesh_convergence():
    sol = solve_suspended_rod('optimal', 13.68, 2087.0, -0.5)
    fine = solve_suspended_rod('optimal', 13.68, 2087.0, -0.5, guess=sol, s=default_mesh(13.68, h_max=0.03))
    assert np.max(np.abs(sol.gripper_position - fine.gripper_position)) < 2e-6


@pytest.mark.skipif(not REF.exists(), reason='reference runs not present')
def test_agreement_with_the_released_numeric_solver_run():
    from scipy.spatial.transform import Rotation
    d = np.loadtxt(REF / 'ls13.68_ks2087_kappa0to0.2_simDER.txt')
    prev = prev_c = None
    for row in d[::4]:
        k = row[6]
        prev = optimal_grasp(13.68, k, 2087, guess=prev, check_stability=False,
                             connective_offset=RELEASED_CONNECTIVE_OFFSET)
        prev_c = optimal_grasp(13.68, k, 2087, guess=prev_c, check_stability=False)
        ref_rv = Rotation.from_matrix(row[7:16].reshape(3, 3)).as_rotvec()
        assert prev.position[[0, 2]] == pytest.approx(row[[0, 2]], rel=2e-3)
        assert prev.position[1] == pytest.approx(row[1], rel=0.03, abs=1e-9)       # released dl error in y
        assert prev_c.position == pytest.approx(row[:3], rel=0.03, abs=1e-9)
        assert prev.rotvec == pytest.approx(ref_rv, abs=0.005)


def test_der_solver_reproduces_the_released_run_exactly():
    # the released method (DER, two-node clamp, reaction target (0, kappa EI/dl, 0)) with its 232 edges
    g = optimal_grasp_der(13.68, 0.05, 2087, n_edges=232, released_layout=True)
    assert g.position == pytest.approx([2.505051551, -0.2021585899, 12.23934234], abs=5e-5)


@pytest.mark.parametrize('ls,kappa,ks', [(4.3, 0.9, 700.0), (6.5, 2.5, 6000.0)])
def test_held_out_points_against_independent_der_solution(ls, kappa, ks):
    g = optimal_grasp(ls, kappa, ks, check_stability=False)
    # the released method on a DER (discrete reaction target) converges at first order in dl: Richardson
    h = 0.05
    d1 = optimal_grasp_der(ls, kappa, ks, h=h)
    d2 = optimal_grasp_der(ls, kappa, ks, h=h / 2)
    extrapolated = 2 * d2.position - d1.position
    scale = np.abs(g.position).max()
    assert np.max(np.abs(d2.position - g.position)) < np.max(np.abs(d1.position - g.position))
    assert np.max(np.abs(extrapolated - g.position)) < 3e-3 * scale
    assert g.rotvec == pytest.approx(2 * d2.rotvec - d1.rotvec, abs=3e-3)


def test_alg2_and_bvp_agree():
    for args in [(13.68, 0.3, 2087.0), (6.2, 1.1, 400.0)]:
        a = optimal_grasp(*args, check_stability=False)
        b = optimal_grasp(*args, method='alg2', check_stability=False)
        assert b.position == pytest.approx(a.position, abs=1e-7)
        assert b.force_residual < 1e-8


def _looped_guess(ls):
    s = default_mesh(ls)
    th = np.pi / 2 * (1 - np.exp(-(s / 1.0) ** 3)) + np.exp(-((s - 1.0) / 1.0) ** 2)
    Y = np.zeros((len(s), 12))
    Y[:, 3], Y[:, 5], Y[:, 7] = np.cos(th), np.sin(th), -np.gradient(th, s)
    Y[1:, 0:3] = np.cumsum(0.5 * (Y[1:, 3:6] + Y[:-1, 3:6]) * np.diff(s)[:, None], axis=0)
    Y[:, 11] = -3.0
    return s, Y


def test_stability_selects_the_gentle_branch():
    """Fig. 4-5: of the roots of Eq. 14 for ls = 17.68, the gentle one is stable, a looped one snaps."""
    ls = 17.68
    main = optimal_grasp(ls, 0.0, 2087)
    assert main.stable is True
    s, Y = _looped_guess(ls)
    other = solve_suspended_rod('optimal', ls, 2087.0, 0.0, guess=Y, s=s)
    assert np.linalg.norm(other.gripper_position - main.position) > 1.0
    assert other.clamp_force[2] > main.clamp_force[2]
    assert elastic_stability(other)['stable'] is False
    resp = perturbation_response(main.solution)
    assert resp['converged'] and max(resp['max_lateral_displacement']) <= 0.12 + 1e-6


def test_manifold_boundary_contains_the_optimum():
    ls, ks = 8.0, 1000.0
    g = optimal_grasp(ls, 0.0, ks, check_stability=False)
    th = float(np.arctan2(g.position[2], g.position[0]))
    b = discover_manifold_boundary(ls, ks, [th], delta=1e-3)
    r_opt = np.hypot(g.position[0], g.position[2])
    r_out, r_in = np.linalg.norm(b[0, 0]), np.linalg.norm(b[0, 1])
    assert r_in < r_opt < r_out <= ls * 1.01                  # region II between contact and pulling


def test_continuation_along_a_pattern_is_cheap():
    rows = [(20.0 - 0.1 * i, 1156.0, 0.3 * np.sin(0.2 * i)) for i in range(20)]
    out = grasp_sequence(rows)
    assert all(g.force_residual < 1e-8 for g in out)
    assert np.median([g.time_s for g in out]) < 0.2


# ------------------------------------------------------------------------------------------------------- dataset
def test_sweep_is_resumable_and_merges(tmp_path):
    import os
    from rod_deploy.planning.grasp_dataset import SweepSpec, load_dataset, merge, mirror, run_sweep
    spec = SweepSpec(ls_min=1.0, ls_max=6.0, n_ls=2, ks_min=500.0, ks_max=5000.0, n_ks=2, kappa_max=1.0,
                     n_kappa=3, check_stability=False)
    work = str(tmp_path / 'work')
    assert len(run_sweep(spec, work, workers=1)) == 4
    os.remove(os.path.join(work, 'chain_00002.npz'))
    rerun = run_sweep(spec, work, workers=1)
    assert [i for i, _ in rerun] == [2]                         # only the missing chain runs again
    n, ok, missing = merge(spec, work, str(tmp_path / 'ds.npz'))
    assert (n, ok, missing) == (12, 12, 0)
    d = load_dataset(str(tmp_path / 'ds.npz'))
    g = optimal_grasp(*d['inputs'][5][[0, 2, 1]].astype(float), check_stability=False)
    assert d['position'][5] == pytest.approx(g.position, abs=1e-4)
    i, p, r = mirror(d['inputs'][5], d['position'][5], d['rotvec'][5])
    gm = optimal_grasp(float(i[0]), float(i[2]), float(i[1]), check_stability=False)
    assert p == pytest.approx(gm.position, abs=1e-4) and r == pytest.approx(gm.rotvec, abs=1e-4)


DATASET = Path(__file__).resolve().parents[1] / 'rod_deploy' / 'data' / 'grasp_dataset.npz'


@pytest.mark.skipif(not DATASET.exists(), reason='dataset not generated yet')
def test_shipped_dataset_is_wide_and_consistent():
    import json
    from rod_deploy.planning.grasp_dataset import load_dataset
    d = load_dataset()
    record = json.loads((DATASET.parent / 'grasp_dataset_record.json').read_text())
    assert DATASET.stat().st_size < 5e6
    ok = d['ok']
    assert ok.sum() >= 6358 or not record['complete']
    inp = d['inputs'][ok]
    if record['complete']:
        assert inp[:, 0].max() >= 99 and inp[:, 1].max() >= 1e4 and inp[:, 2].max() >= 4.0 - 1e-6
    rng = np.random.default_rng(1)
    for i in rng.choice(np.flatnonzero(ok), 3, replace=False):
        ls, ks, kap = (float(v) for v in d['inputs'][i])
        g = optimal_grasp(ls, kap, ks, check_stability=False)
        assert d['position'][i] == pytest.approx(g.position, abs=2e-3 * max(1.0, np.abs(g.position).max()))
