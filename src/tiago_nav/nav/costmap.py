"""A 2-D costmap in the map frame: the static map plus a rolling obstacle layer from the laser,
inflated by the robot radius with an exponential cost gradient (as costmap_2d does).

Frames and units: everything is in the ``map`` frame, metres and radians. The grid layout is
:class:`tiago_nav.gridmap.GridMap`'s (``[row=y, col=x]``).

Costs: ``LETHAL`` (254) where the robot centre would overlap an obstacle (within
``robot_radius`` of an occupied cell), ``INSCRIBED`` (253) on the boundary, then
``252 * exp(-cost_scaling_factor * (d - robot_radius))`` out to ``inflation_radius``, 0 beyond.

Laser beams follow REP 117 (:func:`tiago_nav.scan.classify`): a hit marks its cell and clears
the cells before it, ``+inf`` (no return) clears up to ``raytrace_range``, ``-inf`` (too close)
marks the cell at ``range_min`` and clears nothing, and an invalid beam (NaN, a finite value
outside the laser's limits) changes nothing.
"""
import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

from tiago_nav.geometry import compose, inverse, transform_points, wrap_angle
from tiago_nav.gridmap import distance_to_mask
from tiago_nav.robot import ROBOT_RADIUS
from tiago_nav.scan import (HIT, INVALID, NO_RETURN, TOO_CLOSE, beam_angles, classify, scan_to_points,
                            usable_ranges)

LETHAL = 254
INSCRIBED = 253
MAX_NON_LETHAL = 252


def occupancy_values(cost):
    """``(rows, cols)`` uint8 costs → int8 occupancy values as ROS's costmap_2d publishes them
    (nav_msgs/OccupancyGrid): 0 free, ``LETHAL`` 100, ``INSCRIBED`` 99, the inflation's 1-252
    spread over 1-98, 255 (no information) -1."""
    cost = np.asarray(cost, dtype=np.int32)
    out = (1 + (97 * (cost - 1)) // 251).astype(np.int8)
    out[cost == 0] = 0
    out[cost == INSCRIBED] = 99
    out[cost == LETHAL] = 100
    out[cost == 255] = -1
    return out


@dataclass(frozen=True)
class MapScan:
    """One laser scan placed in the map: the laser's pose ``(x, y, yaw)`` in ``map`` at the
    scan's stamp, the ranges [m] and the LaserScan's angle and range limits (laser frame, rad
    and m), the stamp [s, ROS time] and the laser's pose ``(x, y, yaw)`` in the base frame.
    The ranges are stored as :func:`tiago_nav.scan.usable_ranges` leaves them."""
    laser_pose: tuple
    ranges: np.ndarray
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    stamp: float = 0.0
    laser_in_base: tuple = None

    DIP = 0.05      # [m] see _reach

    def __post_init__(self):
        """Keep only the beams the costmap may use (:func:`tiago_nav.scan.usable_ranges`): the
        robot's own body (when ``laser_in_base``, the laser's pose in the base frame from tf, is
        given; without it no body is filtered) and veils (mixed pixels) become invalid."""
        kw = (dict(radius=0.0, margin=0.0) if self.laser_in_base is None
              else dict(laser_pose=tuple(self.laser_in_base)))
        object.__setattr__(self, 'ranges', usable_ranges(
            self.ranges, self.angle_min, self.angle_increment, self.range_min, self.range_max, **kw))

    @cached_property
    def kinds(self):
        """Per beam, :data:`~tiago_nav.scan.HIT`, ``NO_RETURN``, ``TOO_CLOSE`` or ``INVALID``."""
        return classify(self.ranges, self.range_min, self.range_max)

    def angles(self):
        """Beam directions [rad] in ``map``."""
        return self.laser_pose[2] + beam_angles(self.angle_min, self.angle_increment, len(self.ranges))

    def informative(self):
        """False for an empty scan or one whose every beam is invalid: it says nothing, so the
        space ahead must be taken as blocked."""
        return bool(np.any(self.kinds != INVALID))

    @cached_property
    def obstacles(self):
        """``(points (M, 2) in map, range [m] of each)``: the hits, plus a point at
        ``range_min`` along every too-close beam (something is there, nearer than the laser can
        measure)."""
        pts, idx = scan_to_points(self.ranges, self.angle_min, self.angle_increment,
                                  self.range_min, self.range_max)
        close = np.flatnonzero(self.kinds == TOO_CLOSE)
        a = self.angle_min + self.angle_increment * close
        pts = np.vstack((pts, self.range_min * np.column_stack((np.cos(a), np.sin(a)))))
        r = np.concatenate((np.asarray(self.ranges, dtype=float)[idx],
                            np.full(len(close), float(self.range_min))))
        return transform_points(self.laser_pose, pts), r

    def invalid_beam_at(self, xy):
        """Boolean per ``(N, 2)`` map point: does the point lie in the direction of an invalid
        beam (the laser cannot vouch for it being free)? Points outside the fan: False."""
        if len(self.ranges) == 0 or len(xy) == 0:
            return np.zeros(len(xy), dtype=bool)
        inc = self.angle_increment or 1.0
        _, rel = bearings(xy, self.laser_pose, self.angle_min, inc)
        i = np.round(rel / abs(inc)).astype(int)
        inside = (i >= 0) & (i < len(self.ranges))
        out = np.zeros(len(xy), dtype=bool)
        out[inside] = self.kinds[i[inside]] == INVALID
        return out

    @cached_property
    def _reach(self):
        """Per beam, how far [m] it saw free space: its hit's range, ``range_max`` for no
        return, -inf for a too-close beam or a hit that dips below both neighbours (below),
        +inf for an invalid one (it says nothing, so it vetoes nothing)."""
        reach = np.full(len(self.ranges), np.inf)
        hit = self.kinds == HIT
        reach[hit] = np.asarray(self.ranges, dtype=float)[hit]
        reach[self.kinds == NO_RETURN] = self.range_max
        reach[self.kinds == TOO_CLOSE] = -np.inf
        # a hit shorter than both its neighbours by more than DIP grazed something thin: a
        # mixed pixel's range lies anywhere between the thin thing and what is behind it, so
        # the beam vouches for nothing beyond the laser
        if len(reach) >= 3:
            side = np.minimum(reach[:-2], reach[2:])
            dip = np.zeros(len(reach), dtype=bool)
            with np.errstate(invalid='ignore'):        # inf - inf beside invalid beams
                dip[1:-1] = hit[1:-1] & (side - reach[1:-1] > self.DIP)
            reach[dip] = -np.inf
        return reach

    def seen_beyond(self, xy, margin, max_gap=None, beyond=None):
        """Boolean per ``(N, 2)`` map point: did this scan see free space there, i.e. did every
        valid beam passing within ``margin`` [m] of the point reach more than ``beyond`` [m]
        (``margin`` when None) beyond it, were at least half of those beams valid, and all of
        those within half the margin of its bearing (three at least)? (A beam grazing an edge, or one that misses a point
        by less than the pose's and the ranges' errors, proves nothing; an invalid beam, e.g. a
        mixed pixel at a leg's edge, says nothing either way, and a thin object whose only
        beam was invalid was not seen through.) With ``max_gap`` [m], also only where
        neighbouring beams lie at most that far apart at the point (anything narrower may have
        hidden between them). Points whose beams leave the fan: False."""
        n = len(self.ranges)
        if n == 0 or len(xy) == 0:
            return np.zeros(len(xy), dtype=bool)
        d, rel = bearings(xy, self.laser_pose, self.angle_min, self.angle_increment or 1.0)
        return seen_past(self.reach_ends, self.valid_ends, 0, n, d, rel,
                         abs(self.angle_increment) or 1.0, margin, max_gap, beyond)

    @cached_property
    def reach_ends(self):
        """:attr:`_reach` with a sentinel after the last beam (-inf: reduceat's last bound,
        and no beam reaches past a point outside the fan)."""
        return np.append(self._reach, -np.inf)

    @cached_property
    def valid_ends(self):
        """Per beam 1 where it is not invalid, then a 0 sentinel (as :attr:`reach_ends`)."""
        return np.append(self.kinds != INVALID, False).astype(int)


def bearings(xy, laser_pose, angle_min, angle_increment):
    """``(distance [m], angle [rad] from the first beam counted in the scan's direction of
    rotation, in [0, 2 pi))`` of ``(N, 2)`` map points from a laser at ``laser_pose`` ``(x, y,
    yaw)`` in ``map``. The pose's values and the angles may also be ``(W, 1)`` arrays, one row
    per scan: then both are ``(W, N)``."""
    x, y, yaw = laser_pose
    dx, dy = xy[:, 0] - x, xy[:, 1] - y
    rel = np.mod((np.arctan2(dy, dx) - yaw - angle_min) * np.sign(angle_increment), 2 * np.pi)
    return np.hypot(dx, dy), rel


def seen_past(reach, valid, offset, n, d, rel, inc, margin, max_gap=None, beyond=None):
    """:meth:`MapScan.seen_beyond` over pairs of a scan and a point, several scans at once:
    ``reach`` and ``valid``, flat, hold each scan's :attr:`MapScan.reach_ends` and
    :attr:`MapScan.valid_ends` from index ``offset`` on; per pair (arrays of one shape, or
    scalars) the scan's ``offset``, number of beams ``n`` and beam spacing ``inc`` [rad], and
    the point's distance ``d`` [m] and angle ``rel`` [rad] from :func:`bearings`. ``beyond``
    [m]: how far beyond the point the beams within ``margin`` of it must reach (``margin``
    when None). Boolean per pair."""
    beyond = margin if beyond is None else beyond
    d, rel = np.asarray(d, dtype=float), np.asarray(rel, dtype=float)
    shape = d.shape
    offset, n, inc = (np.broadcast_to(v, shape).ravel() for v in (offset, n, inc))
    d, rel = d.ravel(), rel.ravel()
    out = np.zeros(d.size, dtype=bool)
    # first the beam nearest the point's bearing, which every window below holds: where it
    # stopped within the margin beyond the point (most points: the thing the point lies on
    # stood there then too), nothing else needs looking at
    ok = reach[offset + np.minimum(np.round(rel / inc).astype(int), n)] > d + beyond
    if max_gap is not None:
        ok &= d * inc <= max_gap
    cand = np.flatnonzero(ok)
    if len(cand):
        offset, n, inc, d, rel = offset[cand], n[cand], inc[cand], d[cand], rel[cand]
        half = np.arctan2(margin, np.maximum(d, 1e-9))
        lo = np.floor((rel - half) / inc).astype(int)
        hi = np.ceil((rel + half) / inc).astype(int) + 1
        inside = np.flatnonzero((lo >= 0) & (hi <= n))
        if len(inside):
            offset, n, inc, d, rel, half, lo, hi = (v[inside] for v in (offset, n, inc, d, rel,
                                                                         half, lo, hi))
            bounds = np.column_stack((offset + lo, offset + hi)).ravel()
            least = np.minimum.reduceat(reach, bounds)[::2]
            said = np.add.reduceat(valid, bounds)[::2]
            # the beams within half the margin of the point's bearing (three at least) must all
            # have said something: a thin object whose one beam came back invalid (a mixed
            # pixel), or an edge beside beams the robot's body hid, was not seen through
            core = np.maximum(half / 2, 1.5 * inc)
            c_lo = np.maximum(np.floor((rel - core) / inc).astype(int), 0)
            c_hi = np.minimum(np.ceil((rel + core) / inc).astype(int) + 1, n)
            core_said = np.add.reduceat(valid, np.column_stack((offset + c_lo,
                                                                offset + c_hi)).ravel())[::2]
            out[cand[inside]] = (least > d + beyond) & (2 * said >= hi - lo) \
                & (core_said == c_hi - c_lo)
    return out.reshape(shape)


def inflate(occupied, resolution, robot_radius, inflation_radius, cost_scaling_factor):
    """Boolean ``(rows, cols)`` obstacles → ``(cost uint8, distance float [m])``.

    ``distance`` is each cell centre's Euclidean distance to the nearest occupied cell centre
    (:func:`tiago_nav.gridmap.distance_to_mask`), ``cost`` as in the module docstring."""
    dist = distance_to_mask(occupied, resolution)
    return cost_of_distance(dist, robot_radius, inflation_radius, cost_scaling_factor), dist


def cost_of_distance(dist, robot_radius, inflation_radius, cost_scaling_factor):
    """uint8 costs (module docstring) of an array of distances [m] to the nearest obstacle."""
    cost = np.zeros(dist.shape, dtype=np.uint8)
    band = (dist >= robot_radius) & (dist <= inflation_radius)
    cost[band] = np.minimum(
        MAX_NON_LETHAL,
        np.round(MAX_NON_LETHAL * np.exp(-cost_scaling_factor * (dist[band] - robot_radius)))).astype(np.uint8)
    cost[dist < robot_radius] = LETHAL
    return cost


class Costmap:
    """Static layer + obstacle layer, inflated when ``cost``/``distance`` are read after an
    :meth:`update` (one EDT). :meth:`cost_at` a few points does not inflate: it measures their
    distance to the static layer (its distance field, computed once) and to the obstacle layer
    (a KD-tree of its cells), which gives the same costs.

    ``obstacle_range`` [m]: laser returns farther than this are not marked;
    ``raytrace_range`` [m]: beams clear the obstacle layer up to this range (or their hit).
    """

    def __init__(self, grid, robot_radius=ROBOT_RADIUS, inflation_radius=0.8, cost_scaling_factor=4.0,
                 obstacle_range=4.0, raytrace_range=5.0):
        if robot_radius <= 0 or inflation_radius < robot_radius:
            raise ValueError('need 0 < robot_radius <= inflation_radius, got %r, %r'
                             % (robot_radius, inflation_radius))
        self.grid = grid
        self.robot_radius = float(robot_radius)
        self.inflation_radius = float(inflation_radius)
        self.cost_scaling_factor = float(cost_scaling_factor)
        self.obstacle_range = float(obstacle_range)
        self.raytrace_range = float(raytrace_range)
        self.static = grid.occupied()
        self.obstacles = np.zeros(grid.shape, dtype=bool)
        self.people = np.zeros(grid.shape, dtype=bool)   # a person's keep-out (set_people)
        self.people_set = False                          # ... has any cell
        self.update()

    @property
    def resolution(self):
        return self.grid.resolution

    def set_inflation(self, inflation_radius):
        """A new ``inflation_radius`` [m] (>= ``robot_radius``): costs read from now on use it."""
        if not self.robot_radius <= inflation_radius:
            raise ValueError('need robot_radius <= inflation_radius, got %r, %r'
                             % (self.robot_radius, inflation_radius))
        self.inflation_radius = float(inflation_radius)
        self.update()

    def clear_obstacles(self):
        """Forget everything the laser marked (``clear_costmaps``), people included."""
        self.obstacles[:] = False
        self.people[:] = False
        self.people_set = False
        self.update()

    def set_people(self, xy, clearance):
        """The people layer: the cells whose centres lie within ``clearance`` [m] of any of
        the ``(N, 2)`` map points ``xy`` (a person's points, :mod:`tiago_nav.nav.people`),
        replacing the previous ones. They count as occupied, so the robot's centre is kept
        ``robot_radius + clearance`` from a person. Does not re-inflate: call :meth:`update`."""
        self.people[:] = False
        self.people_set = len(xy) > 0
        if len(xy) == 0:
            return
        g = self.grid
        k = int(math.ceil(clearance / g.resolution))
        dr, dc = np.mgrid[-k:k + 1, -k:k + 1]
        disk = np.hypot(dr, dc) * g.resolution <= clearance
        off = np.column_stack((dr[disk], dc[disk]))
        rc = np.unique(g.world_to_cell(xy), axis=0)
        cells = (rc[:, None, :] + off[None, :, :]).reshape(-1, 2)
        cells = cells[g.in_bounds(cells)]
        self.people[cells[:, 0], cells[:, 1]] = True

    def forget_marks_beyond(self, xy, distance):
        """Forget the laser's marks whose cell centres lie farther than ``distance`` [m] from
        the point ``xy`` [m, map] (move_base's ``conservative_reset`` around the robot); returns
        how many were forgotten."""
        return self._forget_marks(xy, distance, beyond=True)

    def _forget_marks(self, xy, distance, beyond):
        """Forget the marks whose cell centres lie farther than ``distance`` [m] from ``xy``
        (``beyond``) or within it (then only the cells near ``xy`` are looked at); the count."""
        if beyond:
            rc = np.argwhere(self.obstacles)
        else:
            w = self._window(xy, distance)
            if w is None:
                return 0
            r0, r1, c0, c1 = w
            rc = np.argwhere(self.obstacles[r0:r1, c0:c1]) + (r0, c0)
        if len(rc) == 0:
            return 0
        pts = self.grid.cell_to_world(rc)
        d = np.hypot(pts[:, 0] - xy[0], pts[:, 1] - xy[1])
        gone = rc[d > distance] if beyond else rc[d <= distance]
        if len(gone):
            self.obstacles[gone[:, 0], gone[:, 1]] = False
            self.update()
        return len(gone)

    def add_scan(self, scan):
        """Mark and clear the obstacle layer with one :class:`MapScan` (REP 117, see the module
        docstring): hit and no-return beams clear the marked cells they cross, up to half a cell
        short of the hit (or up to ``raytrace_range``), then hits within ``obstacle_range``
        and too-close beams are marked. Does not re-inflate: call :meth:`update`."""
        self._clear(scan)
        pts, ranges = scan.obstacles
        self._set(pts[ranges <= self.obstacle_range], True)
        if scan.laser_in_base is not None:
            # the robot's footprint (costmap_2d's footprint_clearing_enabled): nothing the laser
            # reports there can be an obstacle, or the robot would be touching it; a mark left
            # there (a noisy self-hit, a mixed pixel at the body) stays behind when the robot
            # leaves and later rejects goals near that place. Cleared: the cells whose centres
            # lie within robot_radius plus half a cell. (The controller stops on the scan's own
            # points, not on these cells.)
            base = compose(scan.laser_pose, inverse(scan.laser_in_base))
            self._forget_marks(base[:2], self.robot_radius + 0.5 * self.resolution, beyond=False)

    def _clear(self, scan):
        """Clear the marked cells within ``raytrace_range`` of the laser that a clearing beam
        crosses (passes within the cell's half-diagonal of its centre) with the cell's centre at
        least half a cell short of the beam's reach (the cell of the hit itself is marked again
        right after). Only marked cells can change, so only they are tested: O(marked cells +
        beams) instead of sampling every beam every half cell, which it matches: on 200 random
        scenes it kept 5 of the 42,482 cells the sampling cleared, and cleared 2 % more."""
        n = len(scan.ranges)
        if n == 0 or not self.obstacles.any():
            return
        kinds = scan.kinds
        reach = np.where(kinds == HIT, np.minimum(np.asarray(scan.ranges, dtype=float),
                                                  self.raytrace_range), self.raytrace_range)
        reach[(kinds != HIT) & (kinds != NO_RETURN)] = -np.inf
        reach = np.append(reach, -np.inf)              # a sentinel for reduceat's last bound
        g, res = self.grid, self.resolution
        x, y, yaw = scan.laser_pose
        rng = self.raytrace_range
        w = self._window((x, y), rng)
        if w is None:
            return
        r0, r1, c0, c1 = w
        rc = np.argwhere(self.obstacles[r0:r1, c0:c1]) + (r0, c0)
        if len(rc) == 0:
            return
        centres = g.cell_to_world(rc)
        dx, dy = centres[:, 0] - x, centres[:, 1] - y
        d = np.hypot(dx, dy)
        inc = abs(scan.angle_increment) or 1.0
        sign = -1.0 if scan.angle_increment < 0 else 1.0
        # each cell's bearing as a (fractional) beam index, and the beams within its half-width
        mid = scan.angle_min + scan.angle_increment * (n - 1) / 2
        rel = wrap_angle(np.arctan2(dy, dx) - yaw - mid) * sign + inc * (n - 1) / 2
        half = np.arcsin(np.minimum(1.0, math.sqrt(0.5) * res / np.maximum(d, 1e-9)))
        i_lo = np.maximum(np.ceil((rel - half) / inc), 0).astype(int)
        i_hi = np.minimum(np.floor((rel + half) / inc), n - 1).astype(int)
        hit = (i_lo <= i_hi) & (d <= rng)
        if not hit.any():
            return
        bounds = np.column_stack((i_lo[hit], i_hi[hit] + 1)).ravel()
        longest = np.maximum.reduceat(reach, bounds)[::2]      # the longest reach among them
        cleared = np.flatnonzero(hit)[longest > d[hit] + 0.5 * res]
        self.obstacles[rc[cleared, 0], rc[cleared, 1]] = False

    def _set(self, xy, value):
        rc = self.grid.world_to_cell(xy)
        inb = self.grid.in_bounds(rc)
        self.obstacles[rc[inb, 0], rc[inb, 1]] = value

    def update(self):
        """Both layers changed: ``cost`` and ``distance`` are recomputed from them when next
        read. (One inflation is a full-grid EDT, the costliest part of taking in a scan; scans
        that arrive between two reads, e.g. while no goal is active, then cost none.)"""
        self._inflated = None
        self._marked = None         # KD-tree of the obstacle layer's cells, for cost_at

    def _inflation(self):
        if self._inflated is None:
            self._inflated = inflate(self.static | self.obstacles | self.people, self.resolution,
                                     self.robot_radius, self.inflation_radius,
                                     self.cost_scaling_factor)
        return self._inflated

    @property
    def cost(self):
        """``(rows, cols)`` uint8 costs of both layers (module docstring)."""
        return self._inflation()[0]

    @property
    def distance(self):
        """``(rows, cols)`` [m] distance of each cell centre to the nearest occupied cell."""
        return self._inflation()[1]

    def occupied_near(self, xy, radius):
        """Centres ``(M, 2)`` [m] of the occupied cells (static or laser-marked) within
        ``radius`` [m] of the point ``xy``."""
        return self._near(xy, radius, self.static, self.obstacles)

    def _window(self, xy, radius):
        """``(r0, r1, c0, c1)``: the grid's rows and columns within ``radius`` [m] of ``xy`` in
        each axis (a square, clipped to the grid), or None when it misses the grid."""
        return self.grid.window((xy[0] - radius, xy[1] - radius), (xy[0] + radius, xy[1] + radius))

    def _near(self, xy, radius, *layers):
        """Centres ``(M, 2)`` [m] of the cells set in any of ``layers`` (boolean grids) within
        ``radius`` [m] of the point ``xy``."""
        g = self.grid
        w = self._window(xy, radius)
        if w is None:
            return np.zeros((0, 2))
        r0, r1, c0, c1 = w
        window = np.zeros((r1 - r0, c1 - c0), dtype=bool)
        for layer in layers:
            window |= layer[r0:r1, c0:c1]
        pts = g.cell_to_world(np.argwhere(window) + (r0, c0))
        return pts[np.hypot(pts[:, 0] - xy[0], pts[:, 1] - xy[1]) <= radius]

    def blocker(self, xy):
        """What makes the point ``xy`` [m, map] too close for the robot: ``(centre, layer,
        distance)`` of the occupied cell nearest to the centre of ``xy``'s cell (costs are
        those of cell centres) within ``robot_radius`` [m]; ``layer`` is ``'map'`` for the
        static map, ``'laser'`` for a cell the laser marked (the map's when both are as near),
        ``'person'`` for a cell of a person's keep-out (:meth:`set_people`). None when there
        is none."""
        centre = self.grid.cell_to_world(self.grid.world_to_cell([xy[:2]]))[0]
        best = None
        for layer, occupied in (('map', self.static), ('laser', self.obstacles),
                                ('person', self.people)):
            pts = self._near(centre, self.robot_radius + 1e-9, occupied)
            if len(pts):
                d = np.hypot(pts[:, 0] - centre[0], pts[:, 1] - centre[1])
                i = int(np.argmin(d))
                if best is None or d[i] < best[2]:
                    best = ((float(pts[i, 0]), float(pts[i, 1])), layer, float(d[i]))
        return best

    def blocked_reason(self, xy):
        """The sentence :class:`PlanError` gives for a goal ``xy`` [m, map] whose cost is at
        least ``INSCRIBED``: which layer's cell is within the robot's radius, and where (a mark
        of the laser can be forgotten with ``clear_costmaps``; a wall of the map cannot)."""
        what = 'goal (%.2f, %.2f) is inside an obstacle (after inflation)' % tuple(xy[:2])
        b = self.blocker(xy)
        if b is None:
            return what
        (x, y), layer, d = b
        if layer == 'map':
            return '%s: %.2f m from the map\'s obstacle at (%.2f, %.2f)' % (what, d, x, y)
        if layer == 'person':
            return ('%s: %.2f m from the keep-out at (%.2f, %.2f) of a person (something the '
                    'laser saw move)' % (what, d, x, y))
        return ('%s: %.2f m from an obstacle the laser marked at (%.2f, %.2f) (clear_costmaps '
                'forgets the laser\'s marks)' % (what, d, x, y))

    def cost_at(self, xy):
        """Costs at ``(N, 2)`` map points; ``LETHAL`` outside the grid. Read from ``cost`` when
        it is up to date, else from the distances of the points' cells to the nearest static
        and marked cell centres: the same numbers as the EDT's, without inflating the whole grid
        (a control cycle checks the plan ahead, about 50 points, after every scan)."""
        rc = self.grid.world_to_cell(xy)
        inb = self.grid.in_bounds(rc)
        out = np.full(len(rc), LETHAL, dtype=np.uint8)
        cells = rc[inb]
        if self._inflated is not None:
            out[inb] = self.cost[cells[:, 0], cells[:, 1]]
            return out
        if self._marked is None:
            marked = np.argwhere(self.obstacles | self.people)
            self._marked = cKDTree(marked) if len(marked) else False
        dist = self.grid.distance_field()[cells[:, 0], cells[:, 1]]
        if self._marked is not False and len(cells):
            near, _ = self._marked.query(cells)
            dist = np.minimum(dist, near * self.resolution)
        out[inb] = cost_of_distance(dist, self.robot_radius, self.inflation_radius,
                                    self.cost_scaling_factor)
        return out
