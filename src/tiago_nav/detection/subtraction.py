"""Map subtraction: remove scan points that lie on the static map.

:class:`MapDistance` uses the map's Euclidean distance transform
(:meth:`tiago_nav.gridmap.GridMap.distance_field`, computed once per map), so the distance from any point to the nearest occupied cell is one array
look-up: O(N) for N scan points, against O(N·M) for comparing every scan point with every one of
the M occupied cells (:func:`brute_force_distance`, kept as the reference).
"""
import numpy as np
from scipy.spatial.distance import cdist


class MapDistance:
    """Distance [m] from map-frame points to the nearest occupied cell centre of a GridMap."""

    def __init__(self, grid):
        self.grid = grid
        self.field = grid.distance_field()

    def __call__(self, points):
        """Distances [m] for ``(N, 2)`` points in the map frame; ``inf`` outside the map.

        The value is the distance from the centre of the point's cell to the nearest occupied
        cell centre (error at most half a cell diagonal, 0.035 m at 0.05 m cells).
        """
        rc = self.grid.world_to_cell(points)
        inside = self.grid.in_bounds(rc)
        out = np.full(len(rc), np.inf)
        out[inside] = self.field[rc[inside, 0], rc[inside, 1]]
        return out


def subtract(points, distance, threshold):
    """Boolean mask of the ``(N, 2)`` map-frame ``points`` farther than ``threshold`` [m] from
    the static map (the points that are not explained by the map)."""
    return distance(points) > threshold


def brute_force_distance(points, grid):
    """Reference: distance [m] from each point to the nearest occupied cell centre, comparing
    every point with every occupied cell (O(N·M)); ``inf`` when the map has no occupied cell."""
    occ = grid.cell_to_world(np.argwhere(grid.occupied()))
    if len(occ) == 0:
        return np.full(len(points), np.inf)
    return cdist(np.asarray(points, dtype=float).reshape(-1, 2), occ).min(axis=1)
