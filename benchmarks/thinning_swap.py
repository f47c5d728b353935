"""Run a perception benchmark with the pipeline's thinning swapped for scikit-image's ``skeletonize`` (the
skeleton the pipeline used before ``rod_deploy.perception.thinning``), to measure what the thinning changes.

    python benchmarks/thinning_swap.py skimage|ours benchmarks/perception_crossings.py [its arguments ...]

``ours`` runs the script unchanged (for a like-for-like pair of runs). Only the thinning inside
``skeleton_of`` is replaced (same bounding-box crop); everything else is this checkout's code. The script
writes its results where it always does (``out/benchmarks`` unless ``--commit-results``): do not combine
``skimage`` with ``--commit-results``.
"""
from __future__ import annotations

import runpy
import sys
from pathlib import Path


def main():
    if len(sys.argv) < 3 or sys.argv[1] not in ('skimage', 'ours') or not Path(sys.argv[2]).is_file():
        sys.exit('thinning_swap: error: usage: thinning_swap.py skimage|ours <benchmark script> [arguments ...]')
    variant, script = sys.argv[1], sys.argv[2]
    if variant == 'skimage' and '--commit-results' in sys.argv[3:]:
        sys.exit('thinning_swap: error: a run with the swapped thinning must not overwrite the committed results')
    sys.argv = [script] + sys.argv[3:]
    if variant == 'skimage':
        from skimage.morphology import skeletonize

        import rod_deploy.perception.skeleton_graph as skeleton_graph
        skeleton_graph.zhang_suen_thinning = skeletonize
    sys.path.insert(0, str(Path(script).resolve().parent))
    runpy.run_path(script, run_name='__main__')


if __name__ == '__main__':
    main()
