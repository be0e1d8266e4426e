"""What moved: laser hits on space a recent scan saw free, which the navigation keeps a
person's distance from.

A wall, a box or a cylinder stands where it stood: no beam of an earlier scan ever passed
through the place one of its points is seen at now. A person walks into space the laser saw
free a moment before. So a hit counts as *moved* when, in one of the scans kept from the last
``memory`` seconds, every beam passing within ``margin`` of its place reached more than
:attr:`MovedMarks.beyond` beyond it (:meth:`tiago_nav.nav.costmap.MapScan.seen_beyond`; only
where its beams lie at most :attr:`MovedMarks.max_gap` apart), and at least
:attr:`MovedMarks.min_points` such hits lie together (a leg is several beams wide; a lone hit
in free space is a mixed pixel), and the hit lies farther than :attr:`MovedMarks.beside` from
every laser mark of earlier scans that is no person's (what stands still, its hits moved off
its marks by the pose error). A person who then stops keeps the label: a cell a moved hit fell
in stays a person's for ``memory`` seconds after it was last hit (:meth:`MovedMarks.hold`; the
navigator holds a person's laser marks for as long as they stay marked), and a hit in such a
cell is a person's too. A person who moved while out of view, or onto floor no kept scan saw
free, is looked for where they could have walked since their last hit (up to
:attr:`MovedMarks.max_reach`): hits there are a person's for that scan
(:meth:`MovedMarks._within_reach`). Hits near the static map (within ``map_margin``) are the
map's and never a person's.

Frames and units: the ``map`` frame, metres, seconds (the scans' stamps).
"""
import math
from collections import deque

import numpy as np
from scipy.spatial import cKDTree

from tiago_nav.nav.costmap import bearings, seen_past


def person_keep_out(clearance, safety_margin, resolution):
    """[m] How far round a person's points the navigation's plan keeps the robot's footprint
    (its people layer, :meth:`tiago_nav.nav.costmap.Costmap.set_people`) to keep ``clearance``
    [m] between the base and the person: as far as the collision check keeps it (the clearance
    and its ``safety_margin`` [m]) and half a cell's diagonal (``resolution`` [m]) more, as a
    cell's centre stands for anywhere in it; or the plan would take a way the check refuses to
    drive. 0 without a clearance (people are obstacles like any other)."""
    if clearance <= 0:
        return 0.0
    return clearance + safety_margin + resolution / math.sqrt(2.0)


class MovedMarks:
    """Per scan (:meth:`update`), which of its obstacle points are a person's.

    ``grid``: the static :class:`~tiago_nav.gridmap.GridMap`; ``memory`` [s]: how long a scan
    stays a witness of free space, and a cell a person's after its last hit; ``keep_every``
    [s]: one scan kept per this long (the witnesses); ``margin`` [m]: a witness's beams this
    near a point (across) must reach :attr:`beyond` beyond it; ``map_margin`` [m]: points this
    near the static map are the map's.

    The scans are placed with the localisation's pose, whose error moves the hits of what
    stands still between one scan and another: a localisation off by 5 cm and 1.4 deg (as
    through ROS in the course world) by up to 15 cm at 4 m. So :attr:`beyond` and
    :attr:`beside` are wider than that: with 0.1 m and no look at the marks, a cylinder's hits,
    and an unmapped wall's, were taken for a person's. ``margin`` stays 0.1 m: 0.2 m across
    left walkers near walls and doors unlabelled (through ROS in office_walkers the base passed
    them at 0.19 m instead of 0.34 m)."""

    min_points = 3          # moved points that make a person's leg (a leg is 3 beams or more)
    cluster_radius = 0.1    # [m] ... within this of each other (a calf is 0.1-0.15 m across)
    walk_speed = 1.5        # [m/s] a person walks at most this fast (1.4 m/s is brisk) ...
    max_reach = 1.0         # [m] ... and is looked for at most this far from where last seen
    beyond = 0.2            # [m] a witness's beams must reach this far beyond a hit (the pose
                            # error: see above) ...
    beside = 0.2            # [m] ... and a hit this near a mark of earlier scans that is no
                            # person's is that thing's
    max_gap = 0.02          # [m] a witness vouches for free space only where its beams lie at
                            # most this far apart (a chair's leg 2.4 cm across hid between
                            # beams 4 cm apart)

    def __init__(self, grid, memory=10.0, keep_every=1.0, margin=0.1, map_margin=0.15):
        self.grid = grid
        self.memory = float(memory)
        self.keep_every = float(keep_every)
        self.margin = float(margin)
        self.map_margin = float(map_margin)
        self.until = np.full(grid.shape, -np.inf)     # [s] a cell is a person's until then
        self.latest = -np.inf                         # [s] the latest of them
        self.witnesses = deque()
        self._stack = None                            # the witnesses' beams as arrays (seen_free)
        self._marks_then = deque(maxlen=2)            # the marks when the last two were kept

    def update(self, scan, marks=None):
        """``(M,)`` bool over ``scan.obstacles[0]`` (a
        :class:`~tiago_nav.nav.costmap.MapScan`): True for a person's point. ``marks``: the
        laser's marks before this scan (a boolean grid like ``grid``, the costmap's obstacle
        layer), if any: a hit within :attr:`beside` of one that is no person's has not moved
        (:meth:`_beside_marks`). The scan then becomes a witness when the newest one is
        ``keep_every`` older. With ``marks``, nothing has moved before two witnesses have
        been kept with theirs (:meth:`_beside_marks` has nothing to go on)."""
        t = scan.stamp
        while self.witnesses and self.witnesses[0].stamp < t - self.memory:
            self.witnesses.popleft()
        pts = scan.obstacles[0]
        person = np.zeros(len(pts), dtype=bool)
        if len(pts):
            g = self.grid
            rc = g.world_to_cell(pts)
            inb = g.in_bounds(rc)
            idx = np.flatnonzero(inb)
            idx = idx[g.distance_field()[rc[idx, 0], rc[idx, 1]] > self.map_margin]
            if len(idx):
                if marks is not None and len(self._marks_then) < 2:
                    # no marks of what stands still yet (the first two witnesses after the
                    # start or a clear): a hit on a static thing's side that an earlier beam
                    # passed close by cannot be told from a person's
                    moved = np.zeros(len(idx), dtype=bool)
                else:
                    moved = self.seen_free(pts[idx], t)
                if marks is not None and moved.any():
                    moved[moved] = ~self._beside_marks(pts[idx][moved], marks, t)
                moved[moved] = self._together(pts[idx][moved])
                cells = rc[idx]
                held = self.until[cells[:, 0], cells[:, 1]] >= t
                person[idx] = moved | held
                self.hold(cells[moved | held], t + self.memory)
                rest = ~(moved | held)
                if rest.any() and self.any_held(t):
                    person[idx[rest]] = self._within_reach(pts[idx[rest]], t)
        if not self.witnesses or t - self.witnesses[-1].stamp >= self.keep_every:
            self.witnesses.append(scan)
            if marks is not None:
                self._marks_then.append(marks.copy())
        return person

    def clear(self):
        """Forget the witnesses, the marks kept with them and every person's cells (the
        costmap's ``clear_costmaps``: its marks of what stands still are gone, so the free space
        seen before cannot be told from a person's place until new witnesses come)."""
        self.until[:] = -np.inf
        self.latest = -np.inf
        self.witnesses.clear()
        self._stack = None
        self._marks_then.clear()

    def seen_free(self, xy, t):
        """Boolean per ``(N, 2)`` map point: did a witness older than ``t`` [s] see free space
        there (:meth:`~tiago_nav.nav.costmap.MapScan.seen_beyond` with :attr:`margin`,
        :attr:`max_gap` and :attr:`beyond`)? All witnesses at once
        (:func:`~tiago_nav.nav.costmap.seen_past`): their beams are stacked once per change of
        witnesses."""
        ws = [w for w in self.witnesses if w.stamp < t and len(w.ranges)]
        if not ws or not len(xy):
            return np.zeros(len(xy), dtype=bool)
        key = tuple(map(id, ws))                      # alive while the stack holds ws
        if self._stack is None or self._stack[0] != key:
            n = np.array([len(w.ranges) for w in ws])
            width = n.max() + 1
            reach = np.full((len(ws), width), -np.inf)
            valid = np.zeros((len(ws), width), dtype=int)
            for k, w in enumerate(ws):
                reach[k, :n[k] + 1] = w.reach_ends
                valid[k, :n[k] + 1] = w.valid_ends
            pose = np.array([w.laser_pose for w in ws], dtype=float)
            beams = np.array([(w.angle_min, w.angle_increment or 1.0) for w in ws])
            offset = (np.arange(len(ws)) * width)[:, None]
            self._stack = (key, ws, reach.ravel(), valid.ravel(), offset, n[:, None],
                           (pose[:, :1], pose[:, 1:2], pose[:, 2:]), beams[:, :1], beams[:, 1:])
        _, _, reach, valid, offset, n, pose, a0, inc = self._stack
        d, rel = bearings(xy, pose, a0, inc)
        return seen_past(reach, valid, offset, n, d, rel, np.abs(inc), self.margin,
                         self.max_gap, self.beyond).any(axis=0)

    def held(self, cells, t):
        """Boolean per ``(N, 2)`` grid cell ``(row, col)``: a person's at time ``t`` [s]."""
        cells = np.asarray(cells, dtype=int).reshape(-1, 2)
        if self.latest < t:
            return np.zeros(len(cells), dtype=bool)
        return self.until[cells[:, 0], cells[:, 1]] >= t

    def any_held(self, t):
        """Is any cell a person's at time ``t`` [s]?"""
        return self.latest >= t

    def _within_reach(self, xy, t):
        """Boolean per ``(N, 2)`` map point at time ``t`` [s]: could a person whose hits held a
        cell have walked there since (:attr:`walk_speed` times the time since the cell's last
        hit, up to :attr:`max_reach`), with :attr:`min_points` such points together? A person
        who moved while out of the laser's view, or onto floor no kept scan saw, stays one
        where they are seen next. These points are a person's for this scan only (their cells
        are not held: a person's label must not creep along whatever stands near them)."""
        cells = np.argwhere(self.until >= t)
        if not len(cells) or not len(xy):
            return np.zeros(len(xy), dtype=bool)
        age = t - (self.until[cells[:, 0], cells[:, 1]] - self.memory)
        reach = np.minimum(self.walk_speed * age, self.max_reach) + self.grid.resolution
        centres = self.grid.cell_to_world(cells)
        tree = cKDTree(centres)
        out = np.zeros(len(xy), dtype=bool)
        for i, near in enumerate(tree.query_ball_point(xy, float(reach.max()))):
            if near:
                out[i] = bool(np.any(np.hypot(*(centres[near] - xy[i]).T) <= reach[near]))
        out[out] = self._together(xy[out])
        return out

    def _beside_marks(self, xy, marks, t):
        """Boolean per ``(N, 2)`` map point at time ``t`` [s]: is a cell of ``marks`` (a
        boolean grid) that is no person's, and was marked already when the witness before the
        newest was kept (``keep_every`` to twice that ago), within :attr:`beside` of it? What
        stands still was marked there by earlier scans, and the pose error moves its hits off
        those marks by less than that. A walker's trail is marked only for as long as the leg
        hides it: a walker seen from the start, not yet a person, is not kept one by the marks
        it leaves behind."""
        if len(self._marks_then) < 2:
            return np.zeros(len(xy), dtype=bool)
        g = self.grid
        box = g.window(xy.min(axis=0) - self.beside, xy.max(axis=0) + self.beside)
        if box is None:
            return np.zeros(len(xy), dtype=bool)
        r0, r1, c0, c1 = box
        w = np.s_[r0:r1, c0:c1]
        cells = np.argwhere(marks[w] & self._marks_then[0][w] & (self.until[w] < t)) + (r0, c0)
        if not len(cells):
            return np.zeros(len(xy), dtype=bool)
        d, _ = cKDTree(g.cell_to_world(cells)).query(xy, distance_upper_bound=self.beside)
        return np.isfinite(d)

    def _together(self, xy):
        """Boolean per moved point: are at least :attr:`min_points` moved points (itself
        included) within :attr:`cluster_radius` of it? A leg is several beams wide; a lone
        point in free space is a mixed pixel or a stray return, not a person."""
        if len(xy) < self.min_points:
            return np.zeros(len(xy), dtype=bool)
        counts = cKDTree(xy).query_ball_point(xy, self.cluster_radius, return_length=True)
        return counts >= self.min_points

    def hold(self, cells, until, grow=True):
        """The ``(N, 2)`` grid cells are a person's until ``until`` [s] at least, and with
        ``grow`` their 8 neighbours too (a standing leg's hits wander by a cell; a refresh of
        cells already held does not grow, or a person's label would creep along whatever
        stands next to them)."""
        cells = np.asarray(cells, dtype=int).reshape(-1, 2)
        if not len(cells):
            return
        self.latest = max(self.latest, until)
        h, w = self.until.shape
        steps = (-1, 0, 1) if grow else (0,)
        for dr in steps:
            for dc in steps:
                r = np.clip(cells[:, 0] + dr, 0, h - 1)
                c = np.clip(cells[:, 1] + dc, 0, w - 1)
                self.until[r, c] = np.maximum(self.until[r, c], until)
