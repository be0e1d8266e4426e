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


ROWS_AT_ONCE = 256      # rows of distances computed at once from the feature transform


def distance_to_mask(mask, resolution, dtype=np.float64):
    """Euclidean distance [m] from every cell centre to the nearest ``True`` cell centre of the
    boolean ``(rows, cols)`` ``mask`` (scipy's exact distance transform), as ``dtype``; ``inf``
    everywhere when the mask is empty.

    The distances are computed from scipy's feature transform (each cell's nearest ``True``
    cell) a band of rows at a time, as scipy computes them (the same values): its own
    distances take about 40 bytes a cell of temporaries, this 8 (the feature transform)."""
    if not mask.any():
        return np.full(mask.shape, np.inf, dtype=dtype)
    ft = ndimage.distance_transform_edt(~mask, return_distances=False, return_indices=True)
    out = np.empty(mask.shape, dtype=dtype)
    cols = np.arange(mask.shape[1])
    for r0 in range(0, mask.shape[0], ROWS_AT_ONCE):
        r1 = min(r0 + ROWS_AT_ONCE, mask.shape[0])
        dr = (ft[0, r0:r1] - np.arange(r0, r1)[:, None]).astype(np.float64)
        dc = (ft[1, r0:r1] - cols[None, :]).astype(np.float64)
        out[r0:r1] = np.sqrt(dr * dr + dc * dc) * resolution
    return out


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

    def window(self, lo, hi):
        """``(r0, r1, c0, c1)``: the rows and columns of the cells between the map points
        ``lo`` and ``hi`` [m] (the box's corners, ``hi`` included), clipped to the grid, or
        None when the box misses it."""
        a = self.world_to_cell([lo])[0]
        b = self.world_to_cell([hi])[0] + 1
        r0, c0 = max(a[0], 0), max(a[1], 0)
        r1, c1 = min(b[0], self.height), min(b[1], self.width)
        return None if r1 <= r0 or c1 <= c0 else (r0, r1, c0, c1)

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


SCAN_MAP_DEPTH = 0.5     # [cells] a surface's mean depth inside its occupied cells: map from scans
RASTER_MAP_DEPTH = 0.25  # ... and in a map rasterised from geometry (the simulator's)


class DistanceField:
    """The signed distance [m] from points in the map frame to the boundary between a grid's
    occupied and free cells, and its gradient, for registering scans to the map: positive in
    free space, negative inside occupied cells, interpolated bilinearly between cell centres;
    points outside the grid get the border's value.

    At each cell centre the value is the exact Euclidean distance (:func:`distance_to_mask`) to
    the nearest centre of the other kind less half a cell: each side of a boundary reads half a
    cell at the cells next to it, so the field crosses 0 on the boundary with slope 1 (exactly
    so for axis-aligned walls; within a few millimetres along other surfaces at 0.05 m cells).
    The field is then shifted by where a surface lies on average inside that boundary,
    ``surface_depth`` cells, so that a surface point reads 0 on average; it depends on how the
    map was made:

    - ``0.5`` (:data:`SCAN_MAP_DEPTH`), a map built from laser scans (gmapping, cartographer,
      slam_toolbox, a map built from a log's scans at their poses): a cell is occupied when a
      hit falls in it, so a surface lies anywhere within its occupied cells, half a cell inside
      the boundary on average;
    - ``0.25`` (:data:`RASTER_MAP_DEPTH`), a map rasterised from geometry (the simulator's
      ``map.pgm``, :func:`tiago_nav.sim.raster.rasterise_world`): a cell is occupied when an
      obstacle covers its central half, so a straight surface lies from a quarter cell outside
      the boundary to three quarters inside, a quarter cell inside on average.

    Registering a scan on a field shifted by the wrong depth moves the pose by the difference
    (a quarter cell, 1.25 cm at 0.05 m) away from the surfaces in view: with a laser that faces
    forward, backwards along the direction of travel.

    Memory: 12 bytes per cell (value and gradient as float32), whatever the map's size, plus
    the transient work of building it (the distance transforms, one at a time): a 100 m ×
    100 m map at 0.05 m keeps 48 MB.
    """

    def __init__(self, grid, surface_depth=RASTER_MAP_DEPTH):
        self.grid = grid
        self.surface_depth = float(surface_depth)
        res = grid.resolution
        occ = grid.occupied()
        d = distance_to_mask(occ, res, np.float32)
        d -= np.float32(res / 2.0)
        if occ.any():
            inside = distance_to_mask(~occ, res, np.float32)
            inside -= np.float32(res / 2.0)
            np.negative(inside, out=inside)
            d[occ] = inside[occ]
            del inside
        d += np.float32(res * self.surface_depth)
        d[~np.isfinite(d)] = 0.0
        rows, cols = d.shape
        # value and gradient side by side, so that one gather reads all three at a corner
        self._v = np.empty((rows, cols, 3), dtype=np.float32)
        self._v[:, :, 0] = d
        del d
        for k, g in ((1, 1), (2, 0)):       # d/dx along columns, d/dy along rows
            if self._v.shape[g] > 1:
                self._v[:, :, k] = np.gradient(self._v[:, :, 0], res, axis=g)
            else:
                self._v[:, :, k] = 0.0
        self._flat = self._v.reshape(-1, 3)

    @property
    def values(self):
        """``(rows, cols)`` float32 view of the field [m] at the cell centres."""
        return self._v[:, :, 0]

    @property
    def gradient(self):
        """``(gx, gy)``: two ``(rows, cols)`` float32 views of the field's gradient at the cell
        centres (central differences), along x and along y."""
        return self._v[:, :, 1], self._v[:, :, 2]

    @property
    def nbytes(self):
        """Bytes the field keeps."""
        return self._v.nbytes

    def __call__(self, pts):
        """``(distance, dx, dy)`` at the ``(N, 2)`` points [m] in map: three ``(N,)`` float64
        arrays (signed distance [m] to the nearest mapped surface and its gradient)."""
        pts = np.asarray(pts, dtype=float)
        return self.at(pts[:, 0], pts[:, 1])

    def at(self, x, y):
        """:meth:`__call__` at the points of coordinates ``x``, ``y`` (``(N,)`` arrays [m] in
        map)."""
        g = self.grid
        rows, cols = g.data.shape
        # continuous (column, row) of the points, cell centres at integers, clamped to the
        # grid (the border's value beyond it)
        # (np.minimum / np.maximum: np.clip costs tens of microseconds a call on older numpy)
        fc = np.minimum(np.maximum((np.asarray(x, dtype=float) - g.origin[0]) / g.resolution
                                   - 0.5, 0.0), cols - 1)
        fr = np.minimum(np.maximum((np.asarray(y, dtype=float) - g.origin[1]) / g.resolution
                                   - 0.5, 0.0), rows - 1)
        c0 = np.minimum(fc.astype(np.intp), max(cols - 2, 0))
        r0 = np.minimum(fr.astype(np.intp), max(rows - 2, 0))
        tc = (fc - c0)[:, None]
        tr = (fr - r0)[:, None]
        i = r0 * cols + c0
        dc = 1 if cols > 1 else 0
        dr = cols if rows > 1 else 0
        f = self._flat
        lo = f[i] * (1.0 - tc) + f[i + dc] * tc
        hi = f[i + dr] * (1.0 - tc) + f[i + dr + dc] * tc
        v = lo * (1.0 - tr) + hi * tr
        return v[:, 0], v[:, 1], v[:, 2]
