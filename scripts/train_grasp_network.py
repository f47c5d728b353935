"""Train the neural controller on the optimal-grasp dataset (paper Sec. 4.3); writes the shipped weights.

    python scripts/train_grasp_network.py [--epochs 3000] [--width 128] [--depth 3] [--seed 0]
                                          [--out ros_ws/src/rod_deploy/rod_deploy/data/grasp_network.npz]

Seeded and deterministic on the CPU (torch==2.13.0, 2 threads). Inputs and outputs are described in
``rod_deploy/planning/neural_controller.py``. 10 % of the dataset's grid points are held out (never trained on)
and reported; the weights, the standardisation, the trained range and a record of the run (data, hyper-parameters,
errors, time) go into one small .npz; a loss plot goes next to it as ``grasp_network_loss.png`` unless
``--no-plot``. Full-batch Adam with a cosine learning-rate decay, then L-BFGS polishing; MSE on standardised
outputs.
"""
from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'ros_ws' / 'src' / 'rod_deploy'))
from rod_deploy.planning.neural_controller import features, targets  # noqa: E402

DATASET = ROOT / 'ros_ws' / 'src' / 'rod_deploy' / 'rod_deploy' / 'data' / 'grasp_dataset.npz'
OUT = ROOT / 'ros_ws' / 'src' / 'rod_deploy' / 'rod_deploy' / 'data' / 'grasp_network.npz'


class GraspMLP(torch.nn.Module):
    def __init__(self, width=128, depth=3):
        super().__init__()
        layers, n_in = [], 3
        for _ in range(depth):
            layers += [torch.nn.Linear(n_in, width), torch.nn.SiLU()]
            n_in = width
        layers.append(torch.nn.Linear(n_in, 6))
        self.net = torch.nn.Sequential(*layers)

    def forward(self, x):
        return self.net(x)


def load_dataset(path=DATASET):
    d = np.load(path)
    keep = d['ok'] & d['stable']
    x = d['inputs'][keep].astype(float)
    return x, d['position'][keep].astype(float), d['rotvec'][keep].astype(float), int((~keep).sum())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--epochs', type=int, default=3000)
    ap.add_argument('--lbfgs-steps', type=int, default=300)
    ap.add_argument('--width', type=int, default=128)
    ap.add_argument('--depth', type=int, default=3)
    ap.add_argument('--lr', type=float, default=3e-3)
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--holdout', type=float, default=0.1)
    ap.add_argument('--out', default=str(OUT))
    ap.add_argument('--no-plot', action='store_true')
    args = ap.parse_args(argv)
    t0 = time.monotonic()
    torch.manual_seed(args.seed)
    torch.set_num_threads(2)
    rng = np.random.default_rng(args.seed)
    inputs, position, rotvec, dropped = load_dataset()
    X = features(inputs[:, 0], inputs[:, 1], inputs[:, 2])
    Y = targets(inputs[:, 0], position, rotvec)
    held = rng.random(len(X)) < args.holdout
    xm, xs = X[~held].mean(0), X[~held].std(0)
    ym, ys = Y[~held].mean(0), Y[~held].std(0)
    Xt = torch.tensor((X - xm) / xs, dtype=torch.float64)
    Yt = torch.tensor((Y - ym) / ys, dtype=torch.float64)
    train, test = torch.tensor(~held), torch.tensor(held)
    model = GraspMLP(args.width, args.depth).double()
    opt = torch.optim.Adam(model.parameters(), lr=args.lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, args.epochs, eta_min=args.lr * 1e-3)
    history = []

    def losses():
        with torch.no_grad():
            err = model(Xt) - Yt
            return float((err[train] ** 2).mean()), float((err[test] ** 2).mean())

    for epoch in tqdm(range(args.epochs), desc='Adam', unit='epoch', mininterval=1.0):
        opt.zero_grad()
        loss = ((model(Xt[train]) - Yt[train]) ** 2).mean()
        loss.backward()
        opt.step()
        sched.step()
        if epoch % 25 == 0 or epoch == args.epochs - 1:
            history.append((epoch, *losses()))
    lbfgs = torch.optim.LBFGS(model.parameters(), lr=1.0, max_iter=20, history_size=50,
                              line_search_fn='strong_wolfe')

    def closure():
        lbfgs.zero_grad()
        loss = ((model(Xt[train]) - Yt[train]) ** 2).mean()
        loss.backward()
        return loss

    for step in tqdm(range(args.lbfgs_steps // 20), desc='L-BFGS', unit='x20'):
        lbfgs.step(closure)
        history.append((args.epochs + 20 * (step + 1), *losses()))
    with torch.no_grad():
        pred = model(Xt).numpy() * ys + ym
    err = np.abs(pred - Y)
    pos_err = np.linalg.norm(pred[:, :3] - Y[:, :3], axis=1)      # |d(ls - z)| = |dz|
    record = {
        'dataset': DATASET.name, 'samples': int(len(X)), 'dropped_unstable_or_unsolved': dropped,
        'held_out': int(held.sum()), 'seed': args.seed, 'width': args.width, 'depth': args.depth,
        'activation': 'SiLU', 'epochs': args.epochs, 'lbfgs_steps': args.lbfgs_steps, 'lr': args.lr,
        'train_mse_standardised': history[-1][1], 'held_out_mse_standardised': history[-1][2],
        'held_out_position_error_Lgb': {'mean': float(pos_err[held].mean()), 'max': float(pos_err[held].max())},
        'held_out_rotvec_error_rad': {'mean': float(err[held, 3:].mean()), 'max': float(err[held, 3:].max())},
        'train_time_s': round(time.monotonic() - t0, 1), 'torch': torch.__version__,
        'machine': f'{platform.machine()}, {torch.get_num_threads()} threads',
    }
    trained_range = {'ls_bar': [float(inputs[:, 0].min()), float(inputs[:, 0].max())],
                      'ks_bar': [float(inputs[:, 1].min()), float(inputs[:, 1].max())],
                      'abs_kappa_bar': [0.0, float(inputs[:, 2].max())]}
    linears = [m for m in model.net if isinstance(m, torch.nn.Linear)]
    arrays = {f'w{i}': l.weight.detach().numpy().astype(np.float32) for i, l in enumerate(linears)}
    arrays.update({f'b{i}': l.bias.detach().numpy().astype(np.float32) for i, l in enumerate(linears)})
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out, n_layers=len(linears), input_mean=xm, input_std=xs, output_mean=ym, output_std=ys,
                        trained_range=json.dumps(trained_range), record=json.dumps(record), **arrays)
    print(json.dumps(record, indent=1))
    print(f'weights: {out} ({out.stat().st_size / 1024:.0f} KiB)')
    if not args.no_plot:
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
        h = np.array(history)
        fig, ax = plt.subplots(figsize=(6, 4))
        ax.semilogy(h[:, 0], h[:, 1], label='training grid points')
        ax.semilogy(h[:, 0], h[:, 2], label=f'held-out grid points ({int(held.sum())})')
        ax.axvline(args.epochs, color='0.5', ls=':', lw=1)
        ax.text(args.epochs, h[:, 1].max(), ' L-BFGS', fontsize=8, va='top')
        ax.set_xlabel('epoch (Adam), then L-BFGS iterations')
        ax.set_ylabel('MSE of the standardised outputs')
        ax.set_title('Grasp network training', fontsize=10)
        ax.grid(True, which='both', alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(out.with_name('grasp_network_loss.png'), dpi=110)
        plt.close(fig)
    return 0


if __name__ == '__main__':
    sys.exit(main())
