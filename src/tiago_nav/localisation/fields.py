"""One :class:`tiago_nav.gridmap.DistanceField` per map, kept across the localisation node's
resets, and the map's grid frame (a map whose origin is rotated is worked on in its grid's own
frame). No ROS here."""
import math

import numpy as np

from tiago_nav.geometry import compose, inverse
from tiago_nav.gridmap import DistanceField
from tiago_nav.localisation.global_search import LikelihoodPyramid

_FIELD = []     # [(map key, DistanceField)]: the last map's field


def distance_field(grid, surface_depth):
    """``grid``'s :class:`tiago_nav.gridmap.DistanceField` (``surface_depth`` [cells]), built
    once per map: a reset builds the node's state again for the same map, and the field (read
    only, 12 bytes per cell) is the same."""
    key = (grid.data.tobytes(), grid.resolution, tuple(grid.origin), surface_depth)
    if not _FIELD or _FIELD[0][0] != key:
        _FIELD[:] = [(key, DistanceField(grid, surface_depth))]
    return _FIELD[0][1]


def to_grid(frame, pose):
    """``pose`` ``(x, y, yaw)`` in map → in the grid's frame ``frame`` (its pose in map,
    :func:`tiago_nav.ros.conversions.gridmap_in_grid_frame`)."""
    return pose if frame == (0.0, 0.0, 0.0) else compose(inverse(frame), pose)


def from_grid(frame, pose):
    """``pose`` ``(x, y, yaw)`` in the grid's frame ``frame`` → in map."""
    return pose if frame == (0.0, 0.0, 0.0) else compose(frame, pose)


def turn_covariance(cov, yaw):
    """A 3 × 3 ``(x, y, yaw)`` covariance of a pose turned by ``yaw`` [rad] (``T C Tᵀ``, ``T =
    diag(R(yaw), 1)``): from the grid's frame to map."""
    if yaw == 0.0:
        return cov
    c, s = math.cos(yaw), math.sin(yaw)
    t = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return t @ np.asarray(cov, dtype=float) @ t.T


_PYRAMID = []   # [(map key, LikelihoodPyramid)]: the last map's


def likelihood_pyramid(grid):
    """``grid``'s :class:`tiago_nav.localisation.global_search.LikelihoodPyramid` (the global
    search's), built once per map as :func:`distance_field`."""
    key = (grid.data.tobytes(), grid.resolution, tuple(grid.origin))
    if not _PYRAMID or _PYRAMID[0][0] != key:
        _PYRAMID[:] = [(key, LikelihoodPyramid(grid))]
    return _PYRAMID[0][1]
