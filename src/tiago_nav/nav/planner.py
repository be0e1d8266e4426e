"""Global planner: Dijkstra (scipy.sparse.csgraph, compiled) on the 8-connected costmap graph.

Edge weight = step length [m] * (1 + ``cost_weight`` * cost / 252) of the cell entered, so the
path keeps to the middle of free space where there is room, yet takes a narrow corridor when it
must. Lethal/inscribed cells are not entered. The grid path is then shortened by a
line-of-sight pass that never raises the cost it crosses (:func:`shortcut`).
"""
from functools import lru_cache

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from tiago_nav.nav.costmap import INSCRIBED, MAX_NON_LETHAL

_NEIGHBOURS = [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]


class PlanError(Exception):
    """No plan: ``reason`` is a sentence for the action's status text."""


def _shifted(rows, cols, dr, dc):
    """The slices ``(rows_from, cols_from, rows_to, cols_to)`` pairing every cell of a
    ``rows x cols`` grid with its neighbour ``(dr, dc)`` away, where that neighbour exists."""
    r0, r1 = max(0, -dr), rows - max(0, dr)
    c0, c1 = max(0, -dc), cols - max(0, dc)
    return slice(r0, r1), slice(c0, c1), slice(r0 + dr, r1 + dr), slice(c0 + dc, c1 + dc)


@lru_cache(maxsize=4)
def _csr_layout(rows, cols):
    """For the 8-neighbour edges of a ``rows x cols`` grid listed direction by direction (as
    :func:`build_graph` lists them, :data:`_NEIGHBOURS` order, each a row-major block): the
    permutation into CSR order (by source cell, then target cell) and the edges' source and
    target cells in that order. Computed once per grid shape: a plan then only decides which
    edges exist and what they weigh."""
    idx = np.arange(rows * cols, dtype=np.int32).reshape(rows, cols)
    src, dst = [], []
    for dr, dc in _NEIGHBOURS:
        rs, cs, rd, cd = _shifted(rows, cols, dr, dc)
        src.append(idx[rs, cs].ravel())
        dst.append(idx[rd, cd].ravel())
    src, dst = np.concatenate(src), np.concatenate(dst)
    order = np.lexsort((dst, src))
    return order, src[order], dst[order]


def build_graph(cost, cost_weight, passable=None):
    """CSR adjacency matrix over the ``rows*cols`` cells (weights in cells): an edge into every
    passable neighbour of a passable cell, no corner cutting between two blocked cells."""
    rows, cols = cost.shape
    if passable is None:
        passable = cost < INSCRIBED
    w_cell = 1.0 + cost_weight * cost.astype(float) / MAX_NON_LETHAL
    allowed, weight = [], []
    for dr, dc in _NEIGHBOURS:
        rs, cs, rd, cd = _shifted(rows, cols, dr, dc)
        a = passable[rs, cs] & passable[rd, cd]
        if dr and dc:   # no corner cutting between two blocked cells
            a &= passable[rd, cs] | passable[rs, cd]
        allowed.append(a.ravel())
        weight.append((np.hypot(dr, dc) * w_cell[rd, cd]).ravel())
    order, src, dst = _csr_layout(rows, cols)
    keep = np.concatenate(allowed)[order]
    n = rows * cols
    indptr = np.zeros(n + 1, dtype=np.int32)
    np.cumsum(np.bincount(src[keep], minlength=n), out=indptr[1:])
    return csr_matrix((np.concatenate(weight)[order][keep], dst[keep], indptr), shape=(n, n))


def grid_path(cost, start_rc, goal_rc, cost_weight=3.0, passable=None):
    """Cheapest 8-connected cell path ``(K, 2)`` of ``(row, col)`` from start to goal, or
    :class:`PlanError`. The start cell may be lethal (the robot may already be close to
    something): it is allowed to leave it."""
    rows, cols = cost.shape
    if passable is None:
        passable = cost < INSCRIBED
    passable = passable.copy()
    passable[start_rc[0], start_rc[1]] = True
    g = build_graph(cost, cost_weight, passable)
    s = int(start_rc[0] * cols + start_rc[1])
    t = int(goal_rc[0] * cols + goal_rc[1])
    dist, pred = dijkstra(g, directed=True, indices=s, return_predecessors=True)
    if not np.isfinite(dist[t]):
        raise PlanError('no path to the goal')
    return _walk_back(pred, s, t, cols)


def _walk_back(pred, s, t, cols):
    """The cells ``(K, 2)`` from node ``s`` to node ``t`` along Dijkstra's predecessors."""
    path = [t]
    while path[-1] != s:
        path.append(int(pred[path[-1]]))
    path.reverse()
    p = np.array(path)
    return np.column_stack((p // cols, p % cols))


def path_to_nearest(cost, start_rc, targets, cost_weight=3.0):
    """Cheapest 8-connected cell path ``(K, 2)`` from ``start_rc`` to the cheapest to reach of
    the cells where the boolean grid ``targets`` is True (the start may be lethal, as in
    :func:`grid_path`), or :class:`PlanError` when none is reachable."""
    rows, cols = cost.shape
    passable = cost < INSCRIBED
    passable[start_rc[0], start_rc[1]] = True
    g = build_graph(cost, cost_weight, passable)
    s = int(start_rc[0] * cols + start_rc[1])
    dist, pred = dijkstra(g, directed=True, indices=s, return_predecessors=True)
    dist = np.where(targets.ravel(), dist, np.inf)
    t = int(np.argmin(dist))
    if not np.isfinite(dist[t]):
        raise PlanError('no reachable place')
    return _walk_back(pred, s, t, cols)


def line_cells(a, b):
    """Integer cells ``(K, 2)`` sampled densely on the segment between cells ``a`` and ``b``."""
    n = int(max(abs(b[0] - a[0]), abs(b[1] - a[1])) * 2) + 1
    t = np.linspace(0.0, 1.0, n + 1)
    return np.round(np.outer(1 - t, a) + np.outer(t, b)).astype(int)


def shortcut(cells, cost, tolerance=0):
    """Greedy line-of-sight shortening of a cell path: from each kept cell jump to the farthest
    later cell whose straight segment crosses no cell costlier than ``tolerance`` above the
    costliest cell of the skipped stretch. Returns the kept cells."""
    cells = np.asarray(cells)
    if len(cells) <= 2:
        return cells
    c = cost[cells[:, 0], cells[:, 1]].astype(int)
    out = [0]
    i = 0
    while i < len(cells) - 1:
        best = i + 1
        j = len(cells) - 1     # scan back from the far end with a shrinking stride
        while j > i + 1:
            seg = line_cells(cells[i], cells[j])
            allowed = max(c[i:j + 1].max(), 0) + tolerance
            if cost[seg[:, 0], seg[:, 1]].max() <= allowed:
                best = j
                break
            j -= max(1, (j - i) // 8)
        out.append(best)
        i = best
    return cells[out]


def path_length(points):
    p = np.asarray(points, dtype=float)
    return float(np.sum(np.hypot(*np.diff(p, axis=0).T))) if len(p) > 1 else 0.0


def densify(points, step):
    """Resample a polyline ``(K, 2)`` [m] at ``step`` [m] (keeps both ends)."""
    p = np.asarray(points, dtype=float)
    if len(p) < 2:
        return p.copy()
    seg = np.hypot(*np.diff(p, axis=0).T)
    s = np.concatenate(([0.0], np.cumsum(seg)))
    n = max(2, int(np.ceil(s[-1] / step)) + 1)
    q = np.linspace(0.0, s[-1], n)
    return np.column_stack((np.interp(q, s, p[:, 0]), np.interp(q, s, p[:, 1])))


def plan(costmap, start_xy, goal_xy, cost_weight=3.0, step=0.05, shortcut_tolerance=8):
    """Plan on a :class:`~tiago_nav.nav.costmap.Costmap` from ``start_xy`` to ``goal_xy``
    (map frame [m]); ``shortcut_tolerance``: cost a straightened stretch may add (0-252).
    Returns ``(K, 2)`` points every ``step`` m, starting at the start and
    ending exactly at the goal. Raises :class:`PlanError` with the reason."""
    grid = costmap.grid
    rc = grid.world_to_cell([start_xy, goal_xy])
    if not grid.in_bounds(rc[1:])[0]:
        raise PlanError('goal (%.2f, %.2f) is outside the map' % tuple(goal_xy))
    if not grid.in_bounds(rc[:1])[0]:
        raise PlanError('robot (%.2f, %.2f) is outside the map' % tuple(start_xy))
    if costmap.cost[rc[1, 0], rc[1, 1]] >= INSCRIBED:
        raise PlanError(costmap.blocked_reason(goal_xy))
    cells = grid_path(costmap.cost, rc[0], rc[1], cost_weight)
    cells = shortcut(cells, costmap.cost, tolerance=shortcut_tolerance)
    pts = grid.cell_to_world(cells)
    pts[0] = start_xy
    pts[-1] = goal_xy
    return densify(pts, step)
