"""Plots of an identification run (matplotlib, Agg): the paper's Fig. 4 and Fig. 5, and the residual over time.

* ``cost_vs_iteration.png``: cost per optimizer iteration, log scale (paper Fig. 4);
* ``end_effector_path.png``: measured end-effector path against the simulated path at every iteration, in three
  projections of the base frame (paper Fig. 5);
* ``residual_over_time.png``: end-effector error and per-joint angle error over time, before and after.
"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .cost import end_effector_positions  # noqa: E402


def write_plots(out_dir, problem, result, initial, evaluations: dict) -> list[Path]:
    out = Path(out_dir)
    paths = [out / 'cost_vs_iteration.png', out / 'end_effector_path.png', out / 'residual_over_time.png']
    names = problem.free

    # Fig. 4: cost vs iteration
    fig, ax = plt.subplots(figsize=(6, 4))
    its = [h['iteration'] for h in result.history]
    costs = [h['cost'] for h in result.history]
    ax.semilogy(its, costs, 'o-', color='tab:blue')
    if len(its) > 1 and its[1] - its[0] > 1:      # warm start on short windows between the first two points
        ax.axvspan(its[0], its[1], color='0.9', zorder=0)
        ax.text(0.5 * (its[0] + its[1]), costs[0], 'warm start on\nshort windows', ha='center', va='top', fontsize=8)
    ax.set_xlabel('iteration (whole recording; shaded: iterations on its first seconds)')
    ax.set_ylabel('cost J [m$^2$]' if problem.cost.kind == 'end_effector' else 'cost J [rad$^2$]')
    final = ', '.join(f'{n} = {v:.4g}' for n, v in zip(names, result.params))
    ax.set_title(f'Cost per iteration ({its[-1]} iterations)\n{final}', fontsize=9)
    ax.grid(True, which='both', alpha=0.3)
    fig.tight_layout()
    fig.savefig(paths[0], dpi=120)
    plt.close(fig)

    # Fig. 5: end-effector paths
    t = problem.data.t_s
    y_meas = problem.cost.y_meas
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.3))
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
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8, loc='best')
    fig.suptitle('End-effector path: measured vs simulated at each iteration (colour: iteration)', fontsize=10)
    fig.tight_layout()
    fig.savefig(paths[1], dpi=120)
    plt.close(fig)

    # residual over time
    final_ev = result.evaluation
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for ev, label, color in ((initial, 'initial guess', 'tab:gray'), (final_ev, 'identified', 'tab:red')):
        if ev is None or ev.traj is None:
            continue
        y, _ = end_effector_positions(problem.model, ev.traj.q)
        axes[0].plot(t, 1000 * np.linalg.norm(y - y_meas, axis=1), color=color, label=label, lw=1)
    axes[0].set_ylabel('end-effector error [mm]')
    axes[0].legend(fontsize=8)
    axes[0].grid(True, alpha=0.3)
    idx = problem.model.measured_coords
    err = final_ev.traj.q[:, idx] - problem.data.theta
    for j in range(err.shape[1]):
        axes[1].plot(t, 1000 * err[:, j], lw=0.8, label=problem.model.coord_names[idx[j]])
    axes[1].set_ylabel('joint angle error after [mrad]')
    axes[1].set_xlabel('time [s]')
    axes[1].legend(fontsize=7, ncol=4)
    axes[1].grid(True, alpha=0.3)
    fig.suptitle('Residual over time (simulated - measured)', fontsize=10)
    fig.tight_layout()
    fig.savefig(paths[2], dpi=110)
    plt.close(fig)
    return paths
