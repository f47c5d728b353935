#!/usr/bin/env python3
"""Make the optimal-grasp training dataset (ros_ws/src/rod_deploy/rod_deploy/data/grasp_dataset.npz).

    python scripts/make_grasp_dataset.py                         # full sweep, all cores, resumable
    python scripts/make_grasp_dataset.py --workers 2 --work-dir out/grasp_sweep
    python scripts/make_grasp_dataset.py --backend dask --address tcp://scheduler:8786   # a Dask cluster
    python scripts/make_grasp_dataset.py --backend ray --address auto                    # a Ray cluster
    python scripts/make_grasp_dataset.py --merge-only            # pack what is finished so far

Every finished (ls_bar, ks_bar) chain is saved in the work directory at once; rerunning the command skips them,
so an interrupted sweep resumes where it stopped.  The record of the run (wall time, machine, counts) is written
beside the dataset as grasp_dataset_record.json.
"""
import argparse
from dataclasses import asdict
import datetime
import json
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, 'ros_ws', 'src', 'rod_deploy'))

from rod_deploy.planning.grasp_dataset import SweepSpec, machine_record, merge, run_sweep  # noqa: E402

DATA = os.path.join(ROOT, 'ros_ws', 'src', 'rod_deploy', 'rod_deploy', 'data')


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--work-dir', default=os.path.join(ROOT, 'out', 'grasp_sweep'))
    p.add_argument('--out', default=os.path.join(DATA, 'grasp_dataset.npz'))
    p.add_argument('--workers', type=int, default=None)
    p.add_argument('--backend', choices=('process', 'dask', 'ray'), default='process')
    p.add_argument('--address', default=None, help='scheduler address for dask / ray')
    p.add_argument('--merge-only', action='store_true')
    p.add_argument('--no-stability', action='store_true')
    for name, typ in (('ls_min', float), ('ls_max', float), ('n_ls', int), ('ks_min', float), ('ks_max', float),
                      ('n_ks', int), ('kappa_max', float), ('n_kappa', int)):
        p.add_argument('--' + name.replace('_', '-'), type=typ, default=getattr(SweepSpec, name))
    a = p.parse_args(argv)
    spec = SweepSpec(a.ls_min, a.ls_max, a.n_ls, a.ks_min, a.ks_max, a.n_ks, a.kappa_max, a.n_kappa,
                     not a.no_stability)
    record_path = os.path.splitext(a.out)[0] + '_record.json'
    record = {}
    if os.path.exists(record_path):
        with open(record_path) as f:
            record = json.load(f)
    runs = record.get('runs', [])
    if not a.merge_only:
        chains = spec.chains()
        t0 = time.perf_counter()
        started = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec='seconds')
        try:
            from tqdm import tqdm
            bar = tqdm(total=len(chains), desc='chains', unit='chain')
            bar.update(len(chains) - len([1 for i, _, _ in chains
                                          if not os.path.exists(os.path.join(a.work_dir, f'chain_{i:05d}.npz'))]))
            progress = lambda r: bar.update(1)  # noqa: E731
        except ImportError:
            bar, progress = None, None
        done = run_sweep(spec, a.work_dir, a.workers, a.backend, a.address, progress)
        if bar is not None:
            bar.close()
        runs.append({'started_utc': started, 'wall_time_s': round(time.perf_counter() - t0, 1),
                     'chains_run': len(done), 'chain_cpu_s': round(sum(s for _, s in done), 1),
                     'backend': a.backend, 'workers': a.workers or os.cpu_count(), 'machine': machine_record()})
    n, n_ok, missing = merge(spec, a.work_dir, a.out)
    record.update({'spec': asdict(spec), 'samples': n, 'solved': n_ok, 'chains_total': len(spec.chains()),
                   'chains_missing': missing, 'complete': missing == 0, 'runs': runs,
                   'total_wall_time_s': round(sum(r['wall_time_s'] for r in runs), 1),
                   'file': os.path.basename(a.out), 'file_bytes': os.path.getsize(a.out),
                   'command': 'python scripts/make_grasp_dataset.py ' + ' '.join(argv if argv is not None
                                                                                 else sys.argv[1:])})
    with open(record_path, 'w') as f:
        json.dump(record, f, indent=1)
    print(json.dumps({k: record[k] for k in ('samples', 'solved', 'chains_missing', 'total_wall_time_s')}))
    return 0


if __name__ == '__main__':
    sys.exit(main())
