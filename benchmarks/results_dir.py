"""Where a benchmark writes its results: ``out/benchmarks/`` by default, so that a run never overwrites the
committed figures the README quotes; ``--commit-results`` writes into ``benchmarks/results/`` instead."""
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
COMMITTED = ROOT / 'benchmarks' / 'results'
SCRATCH = ROOT / 'out' / 'benchmarks'


def add_results_argument(parser):
    parser.add_argument('--commit-results', action='store_true',
                        help='write into benchmarks/results/ (the committed results the README quotes) instead of '
                             'out/benchmarks/')


def results_path(args, name: str) -> Path:
    """Path of the results file ``name`` for this run (its folder created)."""
    folder = COMMITTED if getattr(args, 'commit_results', False) else SCRATCH
    folder.mkdir(parents=True, exist_ok=True)
    return folder / name
