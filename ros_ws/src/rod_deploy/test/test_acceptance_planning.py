"""What `rod-deploy plan` tells about a pattern it changes or refuses (found by the acceptance rehearsal,
``benchmarks/acceptance_rehearsal.py``): with the default friction-limited start, an error names a point of the
pattern as drawn, and the replaced start is reported (JSON summary, a note on stderr, the plot)."""
import re

import numpy as np
import pytest
from scipy.interpolate import splev, splprep

from rod_deploy.planning.rod_description import rod_description_from_dict
from rod_deploy.planning.trajectory import PlannerSettings, PlanningError, plan_trajectory

ROD = rod_description_from_dict({'length': 0.89, 'radius': 0.002, 'L_gb': 0.034})


def digit3():
    """A hand-drawn 3: curved from its start, a cusp in the middle (|kappa_bar| 42 for rod #3)."""
    pts = np.array([[-0.055, 0.13], [0.0, 0.16], [0.05, 0.135], [0.045, 0.095], [0.0, 0.08], [0.055, 0.055],
                    [0.06, 0.0], [0.0, -0.03], [-0.06, -0.005]])
    tck, _ = splprep(pts.T, s=0, k=3)
    return np.column_stack(splev(np.linspace(0, 1, 400), tck))


def test_a_too_sharp_pattern_is_refused_at_a_point_of_the_pattern_with_the_default_start():
    """The check ran on the replaced start only: the message named (0.0040, 0.0485) m, 3 cm off the drawn 3, with
    |kappa_bar| 4.3 instead of the cusp's 42."""
    pts = digit3()
    with pytest.raises(PlanningError, match='bends too sharply') as err:
        plan_trajectory(pts, ROD, PlannerSettings(method='nn'))
    x, y = map(float, re.search(r'at node \d+ \(([-\d.]+), ([-\d.]+)\) m', str(err.value)).groups())
    assert np.min(np.hypot(pts[:, 0] - x, pts[:, 1] - y)) < 0.002
    with pytest.raises(PlanningError) as tangent:
        plan_trajectory(pts, ROD, PlannerSettings(method='nn', start='tangent'))
    assert str(tangent.value) == str(err.value)
