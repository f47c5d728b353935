"""Short strands riding on a rod: a texture blob or bump beside a rod (a grey rod on a textured table, whose
mask takes in the table's specks along its edge) leaves a skeleton branch that runs a few widths along the
rod, inside its mask, before it turns off; left unpaired at its junction it becomes an object of its own,
an extra rod. Units: pixels."""
from __future__ import annotations

import numpy as np

from rod_deploy.perception.crossing_order import median0
from rod_deploy.perception.nearest import nearest_distances


def drop_riding_strands(objects: list, half_width_at, max_length_factor: float = 24.0,
                        min_inside_fraction: float = 0.5) -> list:
    """Drop every object no longer than ``max_length_factor`` h (12 widths) that lies with at least
    ``min_inside_fraction`` of its points within h + 1 px of a longer object's path, h the longer object's
    half-width (``half_width_at(points)``, the mask's distance to background, median along it). The strands
    this drops (development scenes) run 6-17 h long, on the rod in their middle and off it at both ends,
    into texture specks on either side.

    A rod lying alongside another lies about a width (2 h) off its path, not within h + 1; a rod crossing
    another lies within it over about 2 (h + 1) / sin(angle): half of a rod 24 h long only at crossings
    shallower than about 11 degrees (h = 6 px), so a rod shorter than 12 widths crossing a longer one that
    shallowly is dropped too. (:func:`~.traversal.drop_shadow_strands` drops strands of any length at least
    80 % inside.)"""
    if len(objects) < 2:
        return objects
    if not (max_length_factor > 0 and 0 < min_inside_fraction <= 1):
        raise ValueError(f'need max_length_factor > 0 and 0 < min_inside_fraction <= 1, got '
                         f'{max_length_factor}, {min_inside_fraction}')
    lengths = [o.length_px() for o in objects]
    order = sorted(range(len(objects)), key=lambda i: -lengths[i])
    half_widths = {}
    drop = set()
    for rank, i in enumerate(order):
        for j in order[:rank]:
            if j in drop:
                continue
            if j not in half_widths:
                pts = objects[j].points
                half_widths[j] = float(median0(half_width_at(pts[::max(1, len(pts) // 60)])))
            h = half_widths[j]
            if lengths[i] > max_length_factor * h or lengths[i] >= lengths[j]:
                continue
            d = nearest_distances(objects[j].points, objects[i].points, h + 1.0)
            if np.mean(np.isfinite(d)) >= min_inside_fraction:
                drop.add(i)
                break
    return [o for k, o in enumerate(objects) if k not in drop]
