"""Where on the map does a scan fit? Correlative scan matching over a region of the map (all
of its free space for a global relocalisation), by branch and bound on a multi-resolution
max-pooled likelihood grid, without ROS.

Frames: poses are ``(x, y, yaw)`` [m, m, rad] of base_footprint in ``map``; scan points
``(N, 2)`` [m] in base_footprint.

The likelihood of a map cell is ``exp(-d² / 2σ²)`` with ``d`` the distance [m] from its centre
to the nearest occupied cell's centre and ``σ`` (:data:`SIGMA`) covering the translation and
heading steps of the finest level (a point 12 m out moves 0.1 m per half degree), stored as
``uint8``. A candidate pose's score is the mean likelihood of its scan points' cells (0..1).

Level ``k`` of the pyramid holds, at each cell, the maximum of the finest grid over the
``2^k × 2^k`` cells starting there (Olson's multi-resolution correlative matching, as in
Cartographer's fast correlative scan matcher): a candidate translation on level ``k``'s lattice
(every ``2^k`` cells) scored on it bounds the score of every translation of its block at the
same heading. The search scores every block of the region at every heading step on the top
level, then descends best first: the top level's blocks in batches of decreasing bound
(:data:`BATCH`), each batch level by level, where a greedy descent from the level's best blocks
raises ``B``, the best score reached at the finest level so far, every block whose bound is
below ``ratio · B`` is pruned (none of its poses can reach it) and the others are split in
four. Once a batch's best bound is below ``ratio · B`` the search ends. At the finest level the
poses within ``ratio`` of the best are returned, one per ``separation`` (non-maximum
suppression). Memory:
``levels + 1`` ``uint8`` grids of the map's size; time: the top level's blocks × headings ×
points, plus what survives the bound.
"""
import math

import numpy as np
from scipy import ndimage

from tiago_nav.gridmap import distance_to_mask

# [m] standard deviation of the likelihood of a point at distance d from the nearest occupied
# cell: the finest lattice is 2 cells (0.1 m at 0.05 m) and the heading step 1 deg, so a true
# pose is up to 0.05 m + 12 m · 0.5 deg ≈ 0.15 m from the nearest candidate at the range limit
SIGMA = 0.1
# the finest lattice [cells] and the top level's block [cells] (2^levels)
FINEST_LEVEL = 1
LEVELS = 5
# [rad] heading step: a point at 12 m (the registration's range limit) moves 0.21 m per step,
# half of it at most to the nearest step, within 1 σ... 2 σ of the likelihood
YAW_STEP = math.radians(1.0)
# the bound is kept for at most this many blocks per level (the best by bound): bounds memory
# and time when a map is full of look-alike places
MAX_BLOCKS = 100000
# the top level's blocks are descended this many at a time, the best bounds first
BATCH = 4096
# a greedy descent (into the best child at each level) from this many of a level's best
# blocks gives a score reached at the finest level: the bound's first reference
GREEDY_TRIES = 8
# candidates scored at once
CHUNK = 4096
# scored heading by heading from this many candidates per heading on average
PER_HEADING = 64


class LikelihoodPyramid:
    """The max-pooled likelihood grids of a :class:`tiago_nav.gridmap.GridMap` (read only).

    Args:
        grid: the static map (100 occupied, 0 free, -1 unknown).
        levels: top level (its blocks are ``2^levels`` cells wide).
        sigma: [m] see :data:`SIGMA`.
    """

    def __init__(self, grid, levels=LEVELS, sigma=SIGMA):
        self.grid = grid
        self.levels = int(levels)
        occ = np.asarray(grid.data) >= 50
        d = distance_to_mask(occ, grid.resolution)
        like = np.zeros(occ.shape, dtype=np.uint8)
        fin = np.isfinite(d)
        like[fin] = np.round(255.0 * np.exp(-0.5 * (d[fin] / sigma) ** 2)).astype(np.uint8)
        del d
        # zeros before the near edges (a block whose corner lies below them still covers
        # cells of the map: its pooled value must see them) and one row and column of zeros
        # beyond the far edges: a point off the map (its index clipped onto them) scores 0
        self.rows, self.cols = occ.shape
        self.pad = p = 2 ** self.levels
        self.pyramid = [np.pad(like, ((p, 1), (p, 1)))]
        free = np.pad(np.asarray(grid.data) == 0, ((p, 1), (p, 1)))
        self.free = [free]
        for k in range(1, self.levels + 1):
            h = 2 ** (k - 1)
            self.pyramid.append(_pool(self.pyramid[-1], h))
            self.free.append(_pool(self.free[-1], h))

    def cell(self, xy):
        """``(N, 2)`` points [m] in map → ``(N, 2)`` int ``(row, col)`` of their cells."""
        g = self.grid
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        return np.column_stack((np.floor((xy[:, 1] - g.origin[1]) / g.resolution),
                                np.floor((xy[:, 0] - g.origin[0]) / g.resolution))).astype(int)

    def centre(self, rc):
        """``(N, 2)`` int ``(row, col)`` → ``(N, 2)`` their centres ``(x, y)`` [m] in map."""
        g = self.grid
        rc = np.asarray(rc, dtype=float).reshape(-1, 2)
        return np.column_stack((g.origin[0] + (rc[:, 1] + 0.5) * g.resolution,
                                g.origin[1] + (rc[:, 0] + 0.5) * g.resolution))

    def scores(self, level, rows, cols, offsets):
        """Mean likelihood (0..1) of the points at ``offsets`` (int cells relative to the
        robot's cell: ``(P, 2)``, one heading for every robot, or ``(M, P, 2)``, each robot's
        own) for robots at cells ``rows``, ``cols`` (``(M,)``), on ``level``: ``(M,)``."""
        g = self.pyramid[level]
        p = self.pad
        off = offsets if offsets.ndim == 3 else offsets[None]
        r = rows[:, None] + off[:, :, 0]
        c = cols[:, None] + off[:, :, 1]
        # beyond the padding: the far zero row / column
        r = np.where((r < -p) | (r >= self.rows), self.rows, r) + p
        c = np.where((c < -p) | (c >= self.cols), self.cols, c) + p
        return g[r, c].sum(axis=1, dtype=np.int64) / (255.0 * max(off.shape[1], 1))

    def is_free(self, level, rows, cols):
        """Whether the block of ``level`` at cells ``rows``, ``cols`` (in the map) holds a
        free cell (level 0: the cell is free)."""
        return self.free[level][rows + self.pad, cols + self.pad]


def _pool(a, h):
    """``out[i, j] = max(a[i:i+2h:h, j:j+2h:h])``: the max over the 2 × 2 blocks ``h`` apart,
    zero (False) beyond the edges."""
    out = a.copy()
    out[:-h, :] = np.maximum(out[:-h, :], a[h:, :])
    out[:, :-h] = np.maximum(out[:, :-h], out[:, h:].copy())
    return out


def heading_offsets(pyr, points, yaws):
    """Cell offsets ``(Y, P, 2)`` int ``(row, col)`` of the ``points`` [m, base_footprint]
    rotated by each of ``yaws`` [rad], relative to the robot's cell (rounded: the robot stands
    at its cell's centre)."""
    c, s = np.cos(yaws)[:, None], np.sin(yaws)[:, None]
    x = c * points[None, :, 0] - s * points[None, :, 1]
    y = s * points[None, :, 0] + c * points[None, :, 1]
    res = pyr.grid.resolution
    return np.stack((np.round(y / res), np.round(x / res)), axis=-1).astype(int)


def search(pyr, points, centre=None, radius=None, yaw=None, yaw_window=None, ratio=0.9,
           separation=(0.5, math.radians(20.0)), keep=8, finest=FINEST_LEVEL, yaw_step=YAW_STEP):
    """The poses where ``points`` fit the map best within a region, by branch and bound.

    Args:
        pyr: the map's :class:`LikelihoodPyramid`.
        points: ``(N, 2)`` scan points [m] in base_footprint (a few hundred at most).
        centre: ``(x, y)`` [m] in map of a disc of ``radius`` [m] to search; None: the whole
            map's free space.
        yaw, yaw_window: [rad] headings within ``yaw_window`` of ``yaw``; None: every heading.
        ratio: poses (and blocks) scoring below this fraction of the best are pruned.
        separation: ``(metres, radians)``: two poses closer than both are the same hypothesis.
        keep: at most this many poses returned.
        finest: the finest level searched (its lattice is ``2^finest`` cells).
        yaw_step: [rad] heading step.

    Returns:
        ``(poses (K, 3), scores (K,))``, the best first: robot poses in map at the finest
        lattice's cells (``K = 0`` when the region holds no free cell).
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if yaw is None or yaw_window is None or yaw_window >= math.pi:
        yaws = np.arange(-math.pi, math.pi, yaw_step)
    else:
        n = int(math.ceil(yaw_window / yaw_step))
        yaws = yaw + yaw_step * np.arange(-n, n + 1)
    offsets = heading_offsets(pyr, pts, yaws)
    top = pyr.levels
    b = 2 ** top
    # the region's blocks on the top lattice: those holding a free cell (and, for a disc,
    # reaching into it)
    if centre is None:
        r0, r1, c0, c1 = 0, pyr.rows, 0, pyr.cols
    else:
        lo = pyr.cell([(centre[0] - radius, centre[1] - radius)])[0]
        hi = pyr.cell([(centre[0] + radius, centre[1] + radius)])[0]
        r0, c0 = max(lo[0], 0), max(lo[1], 0)
        r1, c1 = min(hi[0] + 1, pyr.rows), min(hi[1] + 1, pyr.cols)
    if r1 <= r0 or c1 <= c0:
        return np.zeros((0, 3)), np.zeros(0)
    rr, cc = np.meshgrid(np.arange(r0, r1, b), np.arange(c0, c1, b), indexing='ij')
    rr, cc = rr.ravel(), cc.ravel()
    ok = pyr.is_free(top, rr, cc)
    rr, cc = rr[ok], cc[ok]
    if not len(rr):
        return np.zeros((0, 3)), np.zeros(0)
    # candidates: (row, col, heading index), bounds on the top level
    cand = np.column_stack((np.repeat(rr, len(yaws)), np.repeat(cc, len(yaws)),
                            np.tile(np.arange(len(yaws)), len(rr))))
    bound = _score_all(pyr, top, cand, offsets)
    # best first: the top level's blocks in batches of decreasing bound, each descended to
    # the finest level; once a batch's best bound is below ratio · (the best score reached),
    # no later block can hold a pose worth returning
    order = np.argsort(-bound, kind='stable')
    best = 0.0
    finest_c, finest_b = [], []
    for start in range(0, len(order), BATCH):
        idx = order[start:start + BATCH]
        if bound[idx[0]] < ratio * best - 1e-12:
            break
        c, s = _descend(pyr, cand[idx], bound[idx], offsets, top, finest, ratio, best)
        if len(s):
            best = max(best, float(s.max()))
            finest_c.append(c)
            finest_b.append(s)
    if not finest_c:
        return np.zeros((0, 3)), np.zeros(0)
    cand, bound = np.concatenate(finest_c), np.concatenate(finest_b)
    # the finest level: a robot stands on a free cell (its block's own, not the pooled one)
    on_free = pyr.is_free(0, cand[:, 0], cand[:, 1])
    cand, bound = cand[on_free], bound[on_free]
    if not len(cand):
        return np.zeros((0, 3)), np.zeros(0)
    order = np.argsort(-bound)
    cand, bound = cand[order], bound[order]
    xy = pyr.centre(cand[:, :2])
    poses = np.column_stack((xy, yaws[cand[:, 2]]))
    out = []
    for k in range(len(poses)):
        if bound[k] < ratio * bound[0] or len(out) >= keep:
            break
        if all(not _same(poses[k], poses[j], separation) for j in out):
            out.append(k)
    return poses[out], bound[out]


def _same(a, b, separation):
    d = math.hypot(a[0] - b[0], a[1] - b[1])
    t = abs((a[2] - b[2] + math.pi) % (2 * math.pi) - math.pi)
    return d < separation[0] and t < separation[1]


def _score_all(pyr, level, cand, offsets):
    """Scores of candidates ``(M, 3)`` (row, col, heading index) on ``level``: heading by
    heading when there are many per heading (one offset table each), else a chunk of
    :data:`CHUNK` candidates at a time, each with its heading's offsets (memory: a chunk's
    candidates × points)."""
    out = np.zeros(len(cand))
    if not len(cand):
        return out
    if len(cand) >= PER_HEADING * len(offsets):
        order = np.argsort(cand[:, 2], kind='stable')
        yi = cand[order, 2]
        starts = np.flatnonzero(np.r_[True, yi[1:] != yi[:-1]])
        ends = np.r_[starts[1:], len(yi)]
        for s, e in zip(starts, ends):
            idx = order[s:e]
            out[idx] = pyr.scores(level, cand[idx, 0], cand[idx, 1], offsets[yi[s]])
        return out
    for s in range(0, len(cand), CHUNK):
        c = cand[s:s + CHUNK]
        out[s:s + CHUNK] = pyr.scores(level, c[:, 0], c[:, 1], offsets[c[:, 2]])
    return out


def _descend(pyr, cand, bound, offsets, level, finest, ratio, best):
    """Branch and bound from blocks ``cand`` (``(M, 3)`` row, col, heading index) of ``level``
    with their bounds ``bound`` down to the ``finest`` level: at each level the blocks below
    ``ratio`` times the best score known (``best``, raised by a greedy descent from the level's
    best blocks) are pruned and the others split in four. Returns the finest level's
    candidates and scores that were not pruned."""
    while level > finest:
        if len(bound):
            best = max(best, _greedy(pyr, cand, bound, offsets, level, finest, GREEDY_TRIES))
        keep_mask = bound >= ratio * best - 1e-12
        cand, bound = cand[keep_mask], bound[keep_mask]
        if len(cand) > MAX_BLOCKS:
            k = np.argsort(-bound)[:MAX_BLOCKS]
            cand, bound = cand[k], bound[k]
        level -= 1
        h = 2 ** level
        cand = np.concatenate([cand + np.array([dr, dc, 0]) for dr in (0, h) for dc in (0, h)])
        cand = cand[(cand[:, 0] < pyr.rows) & (cand[:, 1] < pyr.cols)]
        cand = cand[pyr.is_free(level, cand[:, 0], cand[:, 1])]
        bound = _score_all(pyr, level, cand, offsets)
    return cand, bound


def _greedy(pyr, cand, bound, offsets, top, finest, tries):
    """A score reached at the finest level (a lower bound on the best): from each of the
    ``tries`` best blocks ``cand`` of level ``top``, descend into the best child at each level."""
    best = 0.0
    for k in np.argsort(-bound)[:tries]:
        c = cand[k:k + 1]
        for level in range(top - 1, finest - 1, -1):
            h = 2 ** level
            kids = np.concatenate([c + np.array([dr, dc, 0]) for dr in (0, h) for dc in (0, h)])
            kids = kids[(kids[:, 0] < pyr.rows) & (kids[:, 1] < pyr.cols)]
            kids = kids[pyr.is_free(level, kids[:, 0], kids[:, 1])]
            if not len(kids):
                c = None
                break
            s = _score_all(pyr, level, kids, offsets)
            c = kids[int(np.argmax(s))][None, :]
            sc = float(s.max())
        if c is not None and pyr.is_free(0, c[:, 0], c[:, 1])[0]:
            best = max(best, sc)
    return best
