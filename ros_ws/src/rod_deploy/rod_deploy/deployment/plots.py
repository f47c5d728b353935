"""Plots of a planned trajectory and of a simulated deployment (matplotlib, Agg)."""
from __future__ import annotations

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def plot_plan(path, plan, pattern_xy=None, predicted_xy=None, predicted_e_mean_cm=None):
    """Top view (pattern, gripper path) and side view (gripper height along the pattern). A refined plan
    (``rod-deploy plan --refine``): ``plan`` is the template's, drawn with the pattern ``pattern_xy`` and the
    simulator's predicted deployment ``predicted_xy``."""
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.6))
    P, g = plan.pattern.xy, plan.position
    if pattern_xy is not None:
        Q = np.asarray(pattern_xy, float)
        a.plot(Q[:, 0], Q[:, 1], '-', color='tab:green', lw=4, alpha=0.4, label='pattern')
    if predicted_xy is not None:
        D = np.asarray(predicted_xy, float)
        a.plot(D[:, 0], D[:, 1], '--', color='tab:blue', lw=1.2,
               label='predicted deployment (our DER)' + (f', e_mean {predicted_e_mean_cm:.3f} cm'
                                                         if predicted_e_mean_cm is not None else ''))
    k = plan.first_grasp_index
    replaced_m, dev_m = plan.start_replacement()
    asked_m = plan.asked_deviation()[0]
    if replaced_m > 0 or asked_m > 1e-3:   # the planned curve is not the pattern: draw both
        G = plan.pattern_as_given.xy
        a.plot(G[:, 0], G[:, 1], '-', color='0.55', lw=4, alpha=0.5, label='pattern (smoothed, resampled)')
        what = f'the first {100 * replaced_m:.0f} cm replaced (up to {1000 * dev_m:.0f} mm off), ' if replaced_m else ''
        C = plan.asked_xy if plan.asked_xy is not None else P     # the curve the grasps ask for
        a.plot(C[:, 0], C[:, 1], 'k-', lw=1.5, label=f'planned curve: {what}up to {100 * asked_m:.1f} cm off')
    else:
        a.plot(P[:, 0], P[:, 1], 'k-', lw=2, label='pattern (smoothed, resampled)' if pattern_xy is None else
               'template planned for (refined)')
    a.plot(g[:k + 1, 0], g[:k + 1, 1], ':', color='tab:gray', label='lead-in from the hanging pose')
    a.plot(g[k:, 0], g[k:, 1], '-', color='tab:red', lw=1.2, label=f'gripper ({plan.method})')
    a.plot(P[0, 0], P[0, 1], 'o', color='k', ms=5, label='start (free end)')
    a.set_aspect('equal', adjustable='datalim')
    a.set_xlabel('x [m]')
    a.set_ylabel('y [m]')
    a.legend(fontsize=8)
    a.grid(alpha=0.3)
    a.set_title('top view (table frame)', fontsize=9)
    b.plot(plan.t, g[:, 2], color='tab:red')
    b.axvline(plan.t[k], color='0.6', ls=':', lw=1)
    b.set_xlabel('time [s]')
    b.set_ylabel('gripper height [m]')
    b.grid(alpha=0.3)
    b.set_title(f'{len(plan.t)} poses, {plan.t[-1]:.0f} s at the planned speed', fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_deployment(path, result, pattern_xy=None, title=''):
    """Prescribed (if known) vs deployed shape on the table, with the gripper path projected on the table."""
    fig, ax = plt.subplots(figsize=(7, 6))
    if pattern_xy is not None:
        ax.plot(pattern_xy[:, 0], pattern_xy[:, 1], 'k-', lw=3, alpha=0.35, label='prescribed')
    d = result.deployed_xy
    ax.plot(d[:, 0], d[:, 1], '-', color='tab:blue', lw=1.5, label='deployed (simulated)', zorder=3)
    ax.plot(d[0, 0], d[0, 1], 'o', color='tab:blue', ms=5, zorder=3)
    gp = result.gripper_path
    ax.plot(gp[:, 0], gp[:, 1], '--', color='tab:red', lw=0.8, label='gripper path (top view)')
    n = result.nodes
    ax.plot(n[:, 0], n[:, 1], '-', color='tab:green', lw=0.8, alpha=0.7, label='whole rod at the end (top view)')
    if pattern_xy is not None and len(d) > 1:
        from .metrics import eq17_error
        e = eq17_error(pattern_xy, d)
        ax.set_title(f'{title}\nEq. 17: e_mean {e["e_mean_cm"]:.3f} cm, sigma {e["sigma_cm"]:.3f} cm, '
                     f'coverage {e["coverage"]:.2f}; friction {result.friction:g}', fontsize=9)
    else:
        ax.set_title(f'{title}\nfriction {result.friction:g} (prescribed pattern not drawn: give it with --pattern)',
                     fontsize=9)
    _table_axes(ax)
    _save(fig, path)


def plot_correction(path, pattern_xy, diagnosis, replan, report):
    """The closed loop: prescribed vs deployed (observed, declared model, fitted model) and after the correction."""
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 5.2))
    for ax in (a, b):
        ax.plot(pattern_xy[:, 0], pattern_xy[:, 1], 'k-', lw=3, alpha=0.3, label='prescribed')
    o, n, f = diagnosis.observed_xy, diagnosis.nominal_xy, diagnosis.fitted_xy
    a.plot(o[:, 0], o[:, 1], '-', color='tab:blue', lw=1.6, label='deployed (observed)')
    a.plot(n[:, 0], n[:, 1], '--', color='tab:gray', lw=1.0, label='simulated, declared rod')
    if diagnosis.effects_added:
        a.plot(f[:, 0], f[:, 1], ':', color='tab:orange', lw=1.4, label='simulated, fitted rod')
    added = ', '.join(f'{e["key"]} = {e["parameters"][e["key"]]:.3g}' for e in diagnosis.effects_added) or 'none'
    a.set_title(f'before: e_mean {report["error_before"]["e_mean_cm"]:.3f} cm; residual vs declared model '
                f'{report["error_before"]["residual_rms_mm"]:.2f} mm RMS\neffects added: {added}', fontsize=9)
    if replan is not None and replan.predicted_xy is not None:
        p = replan.predicted_xy
        b.plot(p[:, 0], p[:, 1], '-', color='tab:green', lw=1.6, label='corrected plan, fitted rod (predicted)')
        b.set_title(f'after: e_mean {report["error_after"]["e_mean_cm"]:.3f} cm (predicted; '
                    f'{"replanned" if replan.replanned else "original plan kept"})', fontsize=9)
    else:
        b.set_title('after: not simulated (--replan --simulate)', fontsize=9)
    for ax in (a, b):
        _table_axes(ax)
    _save(fig, path)


def _table_axes(ax):
    """Table-frame axes in metres, equal scale, grid and legend."""
    ax.set_aspect('equal', adjustable='datalim')
    ax.set_xlabel('x [m]')
    ax.set_ylabel('y [m]')
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)


def _save(fig, path):
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
