"""visualization_msgs/MarkerArray builders shared by the nodes (RViz and Foxglove display them)."""
from __future__ import annotations

import numpy as np
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

COLOURS = {'black': (0.1, 0.1, 0.1, 0.9), 'red': (0.85, 0.15, 0.1, 1.0), 'orange': (1.0, 0.55, 0.0, 1.0),
           'blue': (0.1, 0.35, 0.9, 1.0), 'green': (0.1, 0.7, 0.2, 0.8), 'grey': (0.5, 0.5, 0.5, 0.6),
           'purple': (0.55, 0.2, 0.75, 1.0)}


def line_strip(ns: str, marker_id: int, points, colour: str, width_m: float, frame_id: str, stamp=None) -> Marker:
    """A LINE_STRIP through ``points`` ((n, 2) at z = 0 or (n, 3), metres) in ``frame_id``."""
    pts = np.asarray(points, float)
    if pts.ndim == 2 and pts.shape[1] == 2:
        pts = np.column_stack([pts, np.zeros(len(pts))])
    m = Marker(ns=ns, id=int(marker_id), type=Marker.LINE_STRIP, action=Marker.ADD)
    m.header.frame_id = frame_id
    if stamp is not None:
        m.header.stamp = stamp
    m.pose.orientation.w = 1.0
    m.scale.x = float(width_m)
    m.color = ColorRGBA(r=COLOURS[colour][0], g=COLOURS[colour][1], b=COLOURS[colour][2], a=COLOURS[colour][3])
    m.points = [Point(x=float(x), y=float(y), z=float(z)) for x, y, z in pts]
    return m


def marker_array(markers) -> MarkerArray:
    """The markers after a DELETEALL, so that a latched array replaces what a display showed before."""
    clear = Marker(action=Marker.DELETEALL)
    return MarkerArray(markers=[clear, *markers])
