"""Ghosts in move_base's published costmap: marks of what is no longer there, after the laser
has seen the place free (issue: people leave marks that never clear).

The navigation node publishes its costmap (``/move_base/global_costmap/costmap``, costmap_2d's
values, inflated: every cell within the robot's radius of a mark is 99 or 100). The laser's
marks are recovered from it by erosion: a cell whose whole disc of ``robot_radius`` minus
1.5 cells is so (an isolated mark keeps itself and its neighbours; where lethal discs merge,
at a wall's corner or between two legs, the cells between them survive too). The same is done
to the costmap the things that are there at the costmap's stamp would make alone: the static
map's occupied cells, the world file's movable obstacles (their outlines, ``distance``) and the
walkers' legs of the nearest ``/sim/objects`` at or before it, with the keep-out the navigation
holds round a person (:func:`tiago_nav.nav.people.person_keep_out`: what it marks round a walker
who is there is no ghost). A recovered mark farther than
``EXPLAINED`` from every mark of that costmap is a *phantom*. A phantom cell is *seen free*
from the first scan after it became one that saw its place free
(:func:`seen_free`, the laser placed at the robot's true pose). A
region of phantoms (8-connected) is a *ghost* once every one of its cells has been seen free
(the marks it comes from lie somewhere in it, but not every cell of it is one), for as long as
it stays. Its age at a costmap is that costmap's stamp minus the latest of those scans.
Costmaps come at ``costmap_publish_frequency`` (1 Hz): a ghost is seen at the first costmap
after it appears, so the ages are lower bounds, within a second of the truth.

Frames and units: the map frame, metres, seconds (ROS time).
"""
import bisect
import math

import numpy as np
from scipy import ndimage

from tiago_nav.geometry import compose
from tiago_nav.gridmap import distance_to_mask
from tiago_nav.nav.costmap import MapScan

EXPLAINED = 0.1     # [m] a mark this near a mark of what is there is that thing's (a hit lies
                    # within half a cell of its mark, and a few centimetres off the surface
                    # where the localisation places the scan)
LETHAL_VALUE = 99   # costmap_2d's values of a cell within the robot's radius of a mark: 99
                    # (inscribed, on the radius) and 100 (lethal, inside it)


def seen_free(scan, xy, resolution, raytrace_range):
    """Boolean per ``(N, 2)`` cell centre [m, map frame]: did ``scan`` (a
    :class:`~tiago_nav.nav.costmap.MapScan`) see the cell free where move_base would clear it?
    Every beam near the centre reached beyond it
    (:meth:`~tiago_nav.nav.costmap.MapScan.seen_beyond` with a one-cell margin), and the centre
    lies half a cell (``resolution`` [m]) or more inside ``raytrace_range`` [m]: the costmap
    clears a cell only where a beam's reach, capped at that range, passes its centre by half
    a cell, so a cell on the range's edge is never cleared from there, seen free or not."""
    d = np.hypot(xy[:, 0] - scan.laser_pose[0], xy[:, 1] - scan.laser_pose[1])
    return scan.seen_beyond(xy, resolution) & (d + 0.5 * resolution < raytrace_range)


def _disc(r):
    """A boolean disc of radius ``r`` [cells] (a structuring element)."""
    k = int(math.floor(r))
    yy, xx = np.mgrid[-k:k + 1, -k:k + 1]
    return xx * xx + yy * yy <= r * r


class GhostWatch:
    """Feed it costmaps (:meth:`costmap`), scans (:meth:`scan`), true poses (:meth:`pose`) and
    walkers (:meth:`walkers`) as they come, each stream in stamp order; :attr:`records` holds
    one ``[stamp, oldest ghost age [s] (0 without ghosts), ghost cells, phantom cells]`` per
    costmap. Costmaps and scans are looked at in stamp order (a scan before a costmap of the
    same stamp) once the true poses and the walkers have come up to their stamp (the streams
    arrive out of step under load), and the rest at :meth:`flush`.

    ``grid``: ``/map`` as a :class:`~tiago_nav.gridmap.GridMap`; ``movables``: the world
    file's movable obstacles (objects with ``distance(x, y)``); ``robot_radius`` [m];
    ``laser_offset`` [m]: the laser ahead of the base centre; ``raytrace_range`` [m]:
    move_base's; ``keep_out`` [m]: how far round a person's points its costmap marks a
    person (0: not at all)."""

    def __init__(self, grid, movables, robot_radius, laser_offset, raytrace_range, keep_out=0.0):
        static = grid.occupied()
        self.grid = grid
        self.res = float(grid.resolution)
        self.robot_radius = float(robot_radius)
        self.laser_offset = float(laser_offset)
        self.raytrace_range = float(raytrace_range)
        self.keep_out = float(keep_out)
        r = max(robot_radius - 1.5 * self.res, 0.0) / self.res
        self.disc = _disc(r)
        self.near = _disc(EXPLAINED / self.res)
        # every cell's centre [m], row by row
        self.xy = grid.cell_to_world(np.argwhere(np.ones(static.shape, dtype=bool)))
        gap = np.full(len(self.xy), np.inf)
        for m in movables:
            gap = np.minimum(gap, m.distance(self.xy[:, 0], self.xy[:, 1]))
        # what the obstacles occupy, as the laser's marks would (a cell a surface crosses)
        self.fixed = static | (gap <= 0.5 * math.sqrt(2.0) * self.res).reshape(static.shape)
        self.phantoms = np.zeros((0, 2), dtype=int)     # (row, col) of the last costmap's
        self.seen_free = {}                             # phantom cell -> stamp [s] of its scan
        self.legs, self.leg_stamps = [], []             # [((K, 2) leg centres, radius)], [s]
        self.truth, self.truth_stamps = [], []          # [(x, y, yaw)], [s]
        self.events = []                                # [(stamp, 0 scan / 1 costmap, data)]
        self.records = []

    def walkers(self, stamp, legs, leg_radius):
        """The walkers' ``(K, 2)`` leg centres [m] with ``leg_radius`` [m] at ``stamp``."""
        self.legs.append((np.asarray(legs, dtype=float).reshape(-1, 2), float(leg_radius)))
        self.leg_stamps.append(float(stamp))
        self._advance()

    def pose(self, stamp, pose):
        """The robot's true ``(x, y, yaw)`` at ``stamp``."""
        self.truth.append(tuple(pose))
        self.truth_stamps.append(float(stamp))
        self._advance()

    def costmap(self, stamp, values):
        """A published costmap: ``(rows, cols)`` int8 ``values`` at ``stamp`` [s]."""
        self.events.append((float(stamp), 1, np.asarray(values)))
        self._advance()

    def scan(self, stamp, ranges, angle_min, angle_increment, range_min, range_max):
        """A laser scan at ``stamp`` [s]."""
        self.events.append((float(stamp), 0, (ranges, angle_min, angle_increment, range_min,
                                              range_max)))
        self._advance()

    def _advance(self, until=None):
        """Look at the events up to where both the true poses and the walkers have come (or
        up to ``until`` [s])."""
        if until is None:
            if not self.truth_stamps or not self.leg_stamps:
                return
            until = min(self.truth_stamps[-1], self.leg_stamps[-1])
        if not self.events or self.events[0][0] > until:
            return
        self.events.sort(key=lambda e: e[:2])
        while self.events and self.events[0][0] <= until:
            stamp, kind, data = self.events.pop(0)
            if kind:
                self._costmap(stamp, data)
            else:
                self._scan(stamp, *data)

    def flush(self, until=math.inf):
        """Look at every event stamped up to ``until`` [s] (the end of the mission)."""
        self._advance(until)

    @staticmethod
    def _at(stamps, log, stamp):
        """The entry of ``log`` of the newest of ``stamps`` at or before ``stamp`` (None
        before the first)."""
        i = bisect.bisect_right(stamps, stamp + 1e-9)
        return log[i - 1] if i else None

    def _marks(self, lethal):
        """The marks an inflated lethal ``(rows, cols)`` bool grid comes from (erosion)."""
        return ndimage.binary_erosion(lethal, structure=self.disc, border_value=1)

    def _costmap(self, stamp, values):
        marks = self._marks(np.asarray(values) >= LETHAL_VALUE)
        there = self.fixed.copy()
        walkers = self._at(self.leg_stamps, self.legs, stamp)
        if walkers is not None and len(walkers[0]):
            d = np.full(len(self.xy), np.inf)
            for lx, ly in walkers[0]:
                d = np.minimum(d, np.hypot(self.xy[:, 0] - lx, self.xy[:, 1] - ly))
            # a leg's hits, in cells whose centres lie within half a diagonal of them, and the
            # keep-out round those centres
            near = walkers[1] + 0.5 * math.sqrt(2.0) * self.res + self.keep_out
            there |= (d <= near).reshape(there.shape)
        lethal = distance_to_mask(there, self.res) <= self.robot_radius
        explained = ndimage.binary_dilation(self._marks(lethal), structure=self.near)
        phantom = marks & ~explained
        rc = np.argwhere(phantom)
        self.phantoms = rc
        keep = set(map(tuple, rc))
        self.seen_free = {c: t for c, t in self.seen_free.items() if c in keep}
        # a phantom is a ghost once every cell of its region has been seen free: the marks it
        # comes from lie somewhere in it, but erosion also keeps up to 1.5 cells round a mark
        # and the cells between marks less than a robot's width apart, which a scan can see
        # free while the mark beside them stays (a walker's trail seen through a door: its
        # cells between the two legs' lines "ghosts" for 4.9 s, the marks never seen free)
        ages, cells = [], 0
        labels, n = ndimage.label(phantom, structure=np.ones((3, 3), dtype=bool))
        if n and self.seen_free:
            seen = np.full(phantom.shape, -np.inf)
            idx = tuple(np.array(list(self.seen_free)).T)
            seen[idx] = list(self.seen_free.values())
            regions = np.arange(1, n + 1)
            whole = np.asarray(ndimage.minimum(seen, labels, regions)) > -np.inf   # all seen
            latest = np.asarray(ndimage.maximum(seen, labels, regions))[whole]
            ages = [stamp - t for t in latest]
            cells = int(np.asarray(ndimage.sum(phantom, labels, regions))[whole].sum())
        self.records.append([round(float(stamp), 4), round(float(max(ages, default=0.0)), 4),
                             cells, len(rc)])

    def _scan(self, stamp, ranges, angle_min, angle_increment, range_min, range_max):
        """A laser scan at ``stamp`` [s], placed at the robot's true pose then: the phantoms
        it sees free become ghosts."""
        if not len(self.phantoms):
            return
        truth = self._at(self.truth_stamps, self.truth, stamp)
        if truth is None:
            return
        laser = compose(truth, (self.laser_offset, 0.0, 0.0))
        scan = MapScan(laser, np.asarray(ranges, dtype=float), angle_min, angle_increment,
                       range_min, range_max, stamp)
        todo = [i for i, c in enumerate(map(tuple, self.phantoms)) if c not in self.seen_free]
        if not todo:
            return
        rc = self.phantoms[todo]
        xy = self.grid.cell_to_world(rc)
        free = seen_free(scan, xy, self.res, self.raytrace_range)
        for c in map(tuple, rc[free]):
            self.seen_free[c] = float(stamp)
