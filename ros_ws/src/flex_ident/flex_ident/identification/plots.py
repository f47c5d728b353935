"""Plots of an identification run (matplotlib, Agg): the paper's Fig. 4 and Fig. 5, and the residual over time.

* ``cost_vs_iteration.png``: cost per optimizer iteration, log scale (paper Fig. 4);
* ``end_effector_path.png``: measured end-effector path against the simulated path at every iteration, in three
  projections of the base frame (paper Fig. 5);
* ``residual_over_time.png``: end-effector error over time (log scale) and per-joint RMS angle error, before and
  after;
* warm-start stages (fits on the first seconds) appear in the cost plot with every iteration, shaded by window.
"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from .cost import end_effector_positions  # noqa: E402


def write_plots(out_dir, problem, result, initial, evaluations: dict, warm_start_stages=()) -> list[Path]:
    out = Path(out_dir)
    paths = [out / 'cost_vs_iteration.png', out / 'end_effector_path.png', out / 'residual_over_time.png']
    names = problem.free

    # Fig. 4: cost vs iteration, every evaluation; warm-start stages on their own (shorter) windows
    stages = list(warm_start_stages)
    fig, ax = plt.subplots(figsize=(7, 4.2))
    its = [h['iteration'] for h in result.history]
    costs = [h['cost'] for h in result.history]
    it0 = 0
    greys = plt.get_cmap('Greys')
    for k, stage in enumerate(stages):
        hist = stage.get('cost_history') or [stage['cost']]
        x = np.arange(it0, it0 + len(hist))
        ax.axvspan(it0 - 0.4, x[-1] + 0.4, color=greys(0.12 + 0.1 * k), zorder=0)
        ax.semilogy(x, hist, 's-', ms=4, color=greys(0.5 + 0.15 * k), label=f'warm start: first {stage["window_s"]:g} s')
        ax.text(0.5 * (it0 + x[-1]), max(hist), f'first\n{stage["window_s"]:g} s', ha='center', va='bottom',
                fontsize=7)
        it0 = x[-1]
    if stages:
        ax.semilogy(its[:1], costs[:1], 'o', color='tab:blue')
        ax.semilogy(its[1:], costs[1:], 'o-', color='tab:blue', label='whole recording')
        ax.set_xlabel('iteration (shaded: warm start on the first seconds; its costs are on those windows)')
    else:
        ax.semilogy(its, costs, 'o-', color='tab:blue', label='whole recording')
        ax.set_xlabel('iteration')
    ax.set_ylabel('cost J [m$^2$]' if problem.cost.kind == 'end_effector' else 'cost J [rad$^2$]')
    final = ', '.join(f'{n} = {v:.4g}' for n, v in zip(names, result.params))
    ax.set_title(f'Cost per iteration ({its[-1]} iterations)\n{final}', fontsize=9)
    ax.legend(fontsize=7, loc='upper right')
    ax.grid(True, which='both', alpha=0.3)
    fig.tight_layout()
    fig.savefig(paths[0], dpi=120)
    plt.close(fig)

    # Fig. 5: end-effector paths
    t = problem.data.t_s
    y_meas = problem.cost.y_meas
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.3), constrained_layout=True)
    planes = [(0, 1, 'x', 'y'), (0, 2, 'x', 'z'), (1, 2, 'y', 'z')]
    its_sorted = sorted(evaluations)
    cmap = plt.get_cmap('viridis')
    paths_sim = {}
    for i in its_sorted:
        ev = evaluations[i]
        if ev is not None and ev.traj is not None:
            paths_sim[i], _ = end_effector_positions(problem.model, ev.traj.q)
    for ax, (a, b, la, lb) in zip(axes, planes):
        for j, i in enumerate(its_sorted):
            if i not in paths_sim:
                continue
            frac = j / max(1, len(its_sorted) - 1)
            label = 'initial guess' if i == 0 else ('final' if i == its_sorted[-1] else None)
            ax.plot(paths_sim[i][:, a], paths_sim[i][:, b], color=cmap(frac), lw=1.0 if 0 < i < its_sorted[-1] else 1.6,
                    alpha=0.8, label=label)
        ax.plot(y_meas[:, a], y_meas[:, b], 'k--', lw=1.2, label='measured')
        ax.set_xlabel(f'{la} [m]')
        ax.set_ylabel(f'{lb} [m]')
        ax.set_aspect('equal', adjustable='datalim')
        ax.xaxis.set_major_locator(MaxNLocator(4))
        ax.yaxis.set_major_locator(MaxNLocator(5))
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8, loc='best')
    if len(its_sorted) > 1:
        sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(its_sorted[0], its_sorted[-1]))
        fig.colorbar(sm, ax=axes, shrink=0.8, pad=0.01, label='iteration')
    fig.suptitle('End-effector path: measured vs simulated at each iteration (colour: iteration)', fontsize=10)
    fig.savefig(paths[1], dpi=120, bbox_inches='tight')
    plt.close(fig)

    # residual over time: end-effector error (log scale: mm before, sub-mm after) and per-joint RMS before/after
    final_ev = result.evaluation
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2), gridspec_kw={'width_ratios': [2.2, 1]})
    idx = problem.model.measured_coords
    joint_rms = {}
    for ev, label, color in ((initial, 'initial guess', 'tab:gray'), (final_ev, 'identified', 'tab:red')):
        if ev is None or ev.traj is None:
            continue
        y, _ = end_effector_positions(problem.model, ev.traj.q)
        err_mm = 1000 * np.linalg.norm(y - y_meas, axis=1)
        axes[0].semilogy(t, np.maximum(err_mm, 1e-4), color=color, lw=1,
                         label=f'{label} (RMS {np.sqrt(np.mean(err_mm ** 2)):.3g} mm)')
        joint_rms[label] = 1000 * np.sqrt(np.mean((ev.traj.q[:, idx] - problem.data.theta) ** 2, axis=0))
        floor = 0.3 * np.percentile(err_mm, 5)
    if np.isfinite(floor) and floor > 0:
        axes[0].set_ylim(bottom=floor)                 # the exact start (zero error) is not a data point to show
    axes[0].set_ylabel('end-effector error [mm] (log)')
    axes[0].set_xlabel('time [s]')
    axes[0].legend(fontsize=8)
    axes[0].grid(True, which='both', alpha=0.3)
    joint_names = [problem.model.coord_names[i] for i in idx]
    xj = np.arange(len(joint_names))
    for k, (label, color) in enumerate((('initial guess', 'tab:gray'), ('identified', 'tab:red'))):
        if label in joint_rms:
            axes[1].bar(xj + (k - 0.5) * 0.4, np.maximum(joint_rms[label], 1e-4), 0.4, color=color, label=label)
    axes[1].set_yscale('log')
    axes[1].set_xticks(xj, joint_names, rotation=45, ha='right', fontsize=7)
    axes[1].set_ylabel('joint angle RMS error [mrad] (log)')
    axes[1].legend(fontsize=7)
    axes[1].grid(True, axis='y', which='both', alpha=0.3)
    fig.suptitle('Residual (simulated - measured) before and after identification', fontsize=10)
    fig.tight_layout()
    fig.savefig(paths[2], dpi=110)
    plt.close(fig)
    return paths
