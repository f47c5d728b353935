"""Training dataset of optimal grasps: a sweep over (ls_bar, ks_bar, kappa_bar) (paper Sec. 4.3).

The sweep is a grid of *chains*: for each (ls_bar, ks_bar) one chain solves kappa_bar = 0, k1, k2, ... by
continuation (each solve starts from the previous one), as the released solver ramps the curvature.  kappa_bar >= 0
only: a pattern turning the other way is the y-mirror image (y, rotvec_x, rotvec_z change sign).

* parallel: chains are independent jobs on a local process pool, or on an existing distributed engine
  (``backend='dask'`` with a ``dask.distributed`` scheduler address, or ``backend='ray'``), when installed;
* resumable: every finished chain is written to ``work_dir/chain_XXXX.npz`` at once; a rerun skips those;
* compact: :func:`merge` packs all chains into one float32 ``.npz`` (a few hundred kB for 10^4 samples).

Columns of the merged file: ``inputs`` (N, 3) = (ls_bar, ks_bar, kappa_bar) in the released network's order;
``position`` (N, 3), ``rotvec`` (N, 3), ``clamp_force`` (N, 3) [k_b / L_gb^2], ``stable`` (N,), ``residual`` (N,),
``solve_time_s`` (N,), and ``ok`` (N,) (False where no solution was found; its outputs are NaN).
"""
from dataclasses import dataclass, asdict
import json
import os
import platform
import time

import numpy as np

from .optimal_grasp import optimal_grasp
from .suspended_rod import BVPError

FIELDS = ('position', 'rotvec', 'clamp_force')


@dataclass
class SweepSpec:
    """The grid.  Defaults: 42 ls x 12 ks x 21 kappa = 10584 samples (the paper used 6358)."""

    ls_min: float = 0.5
    ls_max: float = 100.0
    n_ls: int = 42
    ks_min: float = 200.0
    ks_max: float = 2.0e4
    n_ks: int = 12
    kappa_max: float = 4.0
    n_kappa: int = 21
    check_stability: bool = True

    def ls_values(self):
        # dense where the grasp changes fastest (short suspended parts), geometric above
        return np.unique(np.round(np.geomspace(self.ls_min, self.ls_max, self.n_ls), 6))

    def ks_values(self):
        return np.geomspace(self.ks_min, self.ks_max, self.n_ks)

    def kappa_values(self):
        # quadratic spacing: fine near 0 where the lateral offset is linear, coarse at tight curvatures
        return self.kappa_max * np.linspace(0.0, 1.0, self.n_kappa) ** 2

    def chains(self):
        return [(i, float(ls), float(ks)) for i, (ls, ks) in
                enumerate((ls, ks) for ls in self.ls_values() for ks in self.ks_values())]

    @property
    def n_samples(self):
        return len(self.ls_values()) * len(self.ks_values()) * len(self.kappa_values())


def solve_chain(ls_bar, ks_bar, kappas, check_stability=True):
    """Solve one chain by continuation in kappa_bar; returns a dict of arrays (NaN rows where it failed)."""
    n = len(kappas)
    out = {f: np.full((n, 3), np.nan) for f in FIELDS}
    out.update(stable=np.zeros(n, bool), residual=np.full(n, np.nan), solve_time_s=np.full(n, np.nan),
               ok=np.zeros(n, bool))
    out['inputs'] = np.column_stack([np.full(n, ls_bar), np.full(n, ks_bar), np.asarray(kappas, float)])
    prev = None
    for i, kap in enumerate(kappas):
        try:
            g = optimal_grasp(ls_bar, float(kap), ks_bar, guess=prev, check_stability=check_stability)
        except (BVPError, np.linalg.LinAlgError, ValueError, FloatingPointError):
            prev = None                       # restart cold at the next curvature
            continue
        out['position'][i] = g.position
        out['rotvec'][i] = g.rotvec
        out['clamp_force'][i] = g.clamp_force
        out['stable'][i] = bool(g.stable) if g.stable is not None else False
        out['residual'][i] = g.force_residual
        out['solve_time_s'][i] = g.time_s
        out['ok'][i] = True
        prev = g
    return out


def _chain_path(work_dir, index):
    return os.path.join(work_dir, f'chain_{index:05d}.npz')


def run_chain(args):
    """Job body (picklable): solve and save one chain unless it is already saved; returns (index, seconds)."""
    index, ls, ks, kappas, check_stability, work_dir = args
    path = _chain_path(work_dir, index)
    if os.path.exists(path):
        return index, 0.0
    t0 = time.perf_counter()
    res = solve_chain(ls, ks, kappas, check_stability)
    tmp = path + '.tmp.npz'
    np.savez(tmp, **res)
    os.replace(tmp, path)                     # atomic: a chain file is either complete or absent
    return index, time.perf_counter() - t0


def pending_jobs(spec, work_dir):
    kappas = spec.kappa_values()
    return [(i, ls, ks, kappas, spec.check_stability, work_dir) for i, ls, ks in spec.chains()
            if not os.path.exists(_chain_path(work_dir, i))]


def run_sweep(spec, work_dir, workers=None, backend='process', address=None, progress=None):
    """Run every pending chain; returns the list of (index, seconds) of the chains run now."""
    os.makedirs(work_dir, exist_ok=True)
    with open(os.path.join(work_dir, 'spec.json'), 'w') as f:
        json.dump(asdict(spec), f, indent=1)
    jobs = pending_jobs(spec, work_dir)
    done = []
    if not jobs:
        return done
    if backend == 'process':
        import multiprocessing as mp
        workers = workers or os.cpu_count() or 1
        if workers == 1:
            for j in jobs:
                done.append(run_chain(j))
                if progress:
                    progress(done[-1])
        else:
            ctx = mp.get_context('spawn')
            with ctx.Pool(workers) as pool:
                for r in pool.imap_unordered(run_chain, jobs, chunksize=1):
                    done.append(r)
                    if progress:
                        progress(r)
    elif backend == 'dask':
        try:
            from dask.distributed import Client, as_completed
        except ImportError as exc:
            raise RuntimeError('backend dask needs `pip install "dask[distributed]"`') from exc
        client = Client(address) if address else Client(n_workers=workers or os.cpu_count(), threads_per_worker=1)
        try:
            futures = client.map(run_chain, jobs, pure=False)
            for fut in as_completed(futures):
                done.append(fut.result())
                if progress:
                    progress(done[-1])
        finally:
            client.close()
    elif backend == 'ray':
        try:
            import ray
        except ImportError as exc:
            raise RuntimeError('backend ray needs `pip install ray`') from exc
        ray.init(address=address, ignore_reinit_error=True)
        remote = ray.remote(run_chain)
        refs = [remote.remote(j) for j in jobs]
        while refs:
            ready, refs = ray.wait(refs, num_returns=1)
            done.append(ray.get(ready[0]))
            if progress:
                progress(done[-1])
    else:
        raise ValueError(f'unknown backend {backend!r} (process, dask, ray)')
    return done


def merge(spec, work_dir, out_path):
    """Pack all finished chains into one compact npz; returns (n_samples, n_ok, n_chains_missing)."""
    parts, missing = [], 0
    for i, _, _ in spec.chains():
        p = _chain_path(work_dir, i)
        if not os.path.exists(p):
            missing += 1
            continue
        with np.load(p) as d:
            parts.append({k: d[k] for k in d.files})
    if not parts:
        raise RuntimeError('no finished chains to merge')
    data = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    packed = {k: (v.astype(np.float32) if v.dtype.kind == 'f' else v) for k, v in data.items()}
    packed['inputs'] = data['inputs'].astype(np.float32)
    np.savez_compressed(out_path, **packed)
    return len(data['ok']), int(np.sum(data['ok'])), missing


def machine_record():
    return {'platform': platform.platform(), 'python': platform.python_version(), 'cpu_count': os.cpu_count(),
            'processor': _cpu_model()}


def _cpu_model():
    try:
        with open('/proc/cpuinfo') as f:
            for line in f:
                if line.startswith('model name'):
                    return line.split(':', 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def load_dataset(path=None):
    """Load the shipped dataset (``rod_deploy/data/grasp_dataset.npz``) as a dict of arrays."""
    if path is None:
        path = os.path.join(os.path.dirname(os.path.dirname(__file__)), 'data', 'grasp_dataset.npz')
    with np.load(path) as d:
        return {k: d[k] for k in d.files}


def mirror(inputs, position, rotvec):
    """The y-mirror image: kappa -> -kappa, y -> -y, rotvec (x, z) -> -(x, z)."""
    i, p, r = np.array(inputs, float), np.array(position, float), np.array(rotvec, float)
    i[..., 2] *= -1
    p[..., 1] *= -1
    r[..., 0] *= -1
    r[..., 2] *= -1
    return i, p, r
