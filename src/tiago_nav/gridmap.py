"""An occupancy grid as a numpy array, laid out as nav_msgs/OccupancyGrid.

``data[row, col]`` with ``row`` along +y and ``col`` along +x; cell ``(0, 0)``'s lower-left
corner is at ``origin`` ``(x, y)`` [m] in the map frame (no rotation). Values: 100 occupied,
0 free, -1 unknown.
"""
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

OCCUPIED = 100
FREE = 0
UNKNOWN = -1


def distance_to_mask(mask, resolution):
    """Euclidean distance [m] from every cell centre to the nearest ``True`` cell centre of the
    boolean ``(rows, cols)`` ``mask`` (scipy's exact distance transform); ``inf`` everywhere when
    the mask is empty."""
    if not mask.any():
        return np.full(mask.shape, np.inf)
    return ndimage.distance_transform_edt(~mask) * resolution


@dataclass
class GridMap:
    data: np.ndarray        # (rows, cols) int8
    resolution: float       # [m] per cell
    origin: tuple           # (x, y) [m] of cell (0, 0)'s lower-left corner
    _distance: np.ndarray = field(default=None, init=False, repr=False, compare=False)

    @property
    def shape(self):
        return self.data.shape

    @property
    def width(self):
        """Number of columns (cells along x)."""
        return self.data.shape[1]

    @property
    def height(self):
        """Number of rows (cells along y)."""
        return self.data.shape[0]

    @property
    def bounds(self):
        """``(xmin, ymin, xmax, ymax)`` [m] of the grid's extent."""
        x0, y0 = self.origin
        return (x0, y0, x0 + self.width * self.resolution, y0 + self.height * self.resolution)

    def world_to_cell(self, xy):
        """``(N, 2)`` points [m] → ``(N, 2)`` integer ``(row, col)`` indices (maybe out of range)."""
        p = np.asarray(xy, dtype=float).reshape(-1, 2)
        col = np.floor((p[:, 0] - self.origin[0]) / self.resolution).astype(int)
        row = np.floor((p[:, 1] - self.origin[1]) / self.resolution).astype(int)
        return np.column_stack((row, col))

    def cell_to_world(self, rc):
        """``(N, 2)`` ``(row, col)`` indices → ``(N, 2)`` cell-centre points [m]."""
        c = np.asarray(rc, dtype=float).reshape(-1, 2)
        return np.column_stack((self.origin[0] + (c[:, 1] + 0.5) * self.resolution,
                                self.origin[1] + (c[:, 0] + 0.5) * self.resolution))

    def in_bounds(self, rc):
        """Boolean mask: which ``(row, col)`` indices lie inside the grid."""
        c = np.asarray(rc).reshape(-1, 2)
        return (c[:, 0] >= 0) & (c[:, 0] < self.height) & (c[:, 1] >= 0) & (c[:, 1] < self.width)

    def contains(self, xy):
        """Boolean mask: which ``(N, 2)`` points [m] lie inside the grid's extent."""
        return self.in_bounds(self.world_to_cell(xy))

    def occupied(self):
        """Boolean ``(rows, cols)`` mask of occupied cells."""
        return self.data >= 50

    def distance_field(self):
        """``(rows, cols)`` distance [m] from each cell centre to the nearest occupied cell
        centre (:func:`distance_to_mask`), computed once per grid and cached: do not change
        ``data`` afterwards."""
        if self._distance is None:
            self._distance = distance_to_mask(self.occupied(), self.resolution)
        return self._distance

    def cell_centres(self):
        """Two ``(rows, cols)`` arrays: the x and y [m] of every cell centre."""
        xs = self.origin[0] + (np.arange(self.width) + 0.5) * self.resolution
        ys = self.origin[1] + (np.arange(self.height) + 0.5) * self.resolution
        return np.meshgrid(xs, ys)
