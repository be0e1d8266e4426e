"""Rasterise a world's *static* geometry (walls, static cylinders) into a :class:`GridMap`.

Movable obstacles are left out on purpose: they are what detection has to find.
"""
import math

import numpy as np

from tiago_nav.gridmap import FREE, OCCUPIED, GridMap


def rasterise_world(world, resolution=None):
    """Occupancy grid of ``world``'s static geometry over its ``bounds``.

    A cell is occupied when a wall or static cylinder overlaps the central half of the cell
    (a separating-axis test against the cell's inner square of half-size ``resolution / 4``),
    so walls thinner than a cell never vanish and a wall's occupied band is no more than one
    cell wider than the wall. Everything else inside the bounds is free.
    """
    res = float(resolution or world.resolution)
    xmin, ymin, xmax, ymax = world.bounds
    cols = int(math.ceil((xmax - xmin) / res - 1e-9))
    rows = int(math.ceil((ymax - ymin) / res - 1e-9))
    grid = GridMap(np.full((rows, cols), FREE, dtype=np.int8), res, (xmin, ymin))
    cx, cy = grid.cell_centres()
    h = res / 4.0
    occ = np.zeros((rows, cols), dtype=bool)
    for w in world.walls:
        a, b = w.length / 2.0, w.width / 2.0
        c, s = abs(math.cos(w.yaw)), abs(math.sin(w.yaw))
        # only look at the window around the box
        reach = a * c + b * s + h, a * s + b * c + h
        sl = _window(grid, w.x, w.y, reach[0], reach[1])
        if sl is None:
            continue
        dx, dy = cx[sl] - w.x, cy[sl] - w.y
        du = dx * math.cos(w.yaw) + dy * math.sin(w.yaw)
        dv = -dx * math.sin(w.yaw) + dy * math.cos(w.yaw)
        hit = ((np.abs(dx) <= reach[0]) & (np.abs(dy) <= reach[1])
               & (np.abs(du) <= a + h * (c + s)) & (np.abs(dv) <= b + h * (c + s)))
        occ[sl] |= hit
    for cyl in world.static_cylinders:
        r = cyl.radius + h * math.sqrt(2.0)
        sl = _window(grid, cyl.x, cyl.y, r, r)
        if sl is None:
            continue
        occ[sl] |= np.hypot(cx[sl] - cyl.x, cy[sl] - cyl.y) <= r
    grid.data[occ] = OCCUPIED
    return grid


def _window(grid, x, y, rx, ry):
    """Row/column slices of the cells within ``rx``, ``ry`` [m] of ``(x, y)``, or None."""
    (r0, c0), (r1, c1) = grid.world_to_cell([[x - rx, y - ry], [x + rx, y + ry]])
    r0, c0 = max(r0, 0), max(c0, 0)
    r1, c1 = min(r1 + 1, grid.height), min(c1 + 1, grid.width)
    if r0 >= r1 or c0 >= c1:
        return None
    return (slice(r0, r1), slice(c0, c1))
