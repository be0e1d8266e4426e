"""The corridor motion-control law: drive a narrow corridor from the laser alone, stop at its end.

Frames and units: metres, radians. Scan points are handled in two frames:

* the robot frame (base_footprint: x forward, y left, REP 103), where walls are fitted;
* a fixed odometric frame (``odom``, REP 105), where the corridor's centre line, its end and
  the scan points are kept between scans, so the law can run at any rate from odometry.

Wall model. The corridor is two parallel lines: with ``theta`` the corridor's direction in the
robot frame and ``n = (-sin theta, cos theta)`` its left normal, the left wall is ``n.p = d_left``
(> 0) and the right wall ``n.p = d_right`` (< 0). From one scan, :func:`fit_walls` keeps, per
0.1 m slice along the corridor, the innermost point on each side of the current guess of the
centre line (the wall faces the robot sees), and fits both lines jointly by iteratively
re-weighted least squares with Tukey's biweight (robust to door frames, clutter and where a
wall turns away). Errors of the robot with respect to the centre line:

* lateral offset ``e_y = -(d_left + d_right) / 2`` (positive when the robot is left of it),
* heading error ``e_theta = -theta`` (positive when the robot points left of the corridor).

Control law (:func:`control_law`), with gains expressed per metre travelled so convergence is
the same at any speed::

    sin(e_theta_ref) = -clip(k_y * e_y / k_theta, -sin(theta_max), sin(theta_max))
    omega = -max(v, v_turn) * k_theta * (sin(e_theta) - sin(e_theta_ref))

which for small errors is ``omega = -v (k_y e_y + k_theta e_theta)``: along the path
``e_y'' + k_theta e_y' + k_y e_y = 0`` (natural frequency ``sqrt(k_y)`` per metre, damping
``k_theta / (2 sqrt(k_y))``); the clip bounds the angle at which the robot rejoins the centre
line. ``v`` is ``max_speed`` scaled by ``1 - (e_theta / slow_heading)^2`` and by
``max(0.3, 1 - (e_y / (width/2 - robot_radius))^2)`` (the lateral offset relative to the free
play; both quadratic, so small errors barely slow it and large ones, which need room and time
to turn within the angular acceleration limit, do), capped so that the wall the robot heads
for is at least ``wall_time`` away (``v |sin e_theta| <= clearance / wall_time``), scaled
further so that ``|omega|`` stays within its limit (keeping the path's curvature), and capped
so that the robot can brake (``decel``) before the stop point and before anything in its swept
footprint ahead (front safety check).

Before the corridor (the robot up to ~1.5 m in front of its entrance, facing it),
:func:`find_corridor` finds the widest-reaching free strip ahead and fits the walls beyond the
entrance; the same law then steers onto the centre line extended out of the corridor, so it
aims at the opening and takes over seamlessly once walls are on both sides.

End of the corridor (:func:`wall_end`): along each wall line, slices where that side has any
point within ``end_band`` of the line; the end is where, after the wall was seen, a side has no
wall for ``end_gap`` metres (a wall turning away at an angle leaves the band within a few
centimetres; a slight bend does not). The end point is kept in the odom frame; the robot stops
``exit_margin`` past it, facing along the corridor, or earlier where something beyond the end
lies straight ahead (:func:`stop_distance`): at a bend the outer wall crosses the corridor's
extension, so the stop point is ``end_clearance`` before the robot's disc would touch it. The
law does not drive into the next leg: it stops before the bend (centred, with the outer wall
``end_clearance`` ahead), turns in place toward the longest free way (:func:`next_leg`, the
next leg's direction; a disc turns without sweeping anything), and the mission drives the rest
with move_base.

Scans are read by REP 117 (:mod:`tiago_nav.scan`, :meth:`CorridorFollower.update_laser`): walls
are fitted from hits only; a too-close beam (-inf) is an obstacle at ``range_min`` along it for
the front safety check (blocked); NaN and out-of-limits beams say nothing. A scan with too few
informative beams (:func:`scan_usability`) is "blocked", never "free space".
"""
import math
from dataclasses import dataclass
from typing import Tuple

import numpy as np

from tiago_nav.geometry import compose, inverse, transform_points, wrap_angle
from tiago_nav.goal import ABORTED, PREEMPTED, SUCCEEDED  # noqa: F401 (the corridor goal's statuses)
from tiago_nav.params import param, validate
from tiago_nav.robot import ROBOT_RADIUS
from tiago_nav.scan import (TOO_CLOSE, FrozenScanCheck, classify, informative_fraction, scan_to_points,
                            usable_ranges)


@dataclass(frozen=True)
class CorridorParams:
    """Settings of the law (parameters of ``corridor_controller``; defaults: config/corridor.yaml).
    Lengths [m], angles [rad], speeds [m/s, rad/s], accelerations [m/s^2]."""
    # the robot and the law
    robot_radius: float = param(ROBOT_RADIUS, '[m] base footprint radius', gt=0)
    max_speed: float = param(1.0, '[m/s] forward speed when the goal\'s max_speed is 0', gt=0,
                             dynamic=(0.05, 2.0))
    speed_limit: float = param(1.0, '[m/s] the base\'s limit: goal speeds are clamped to it', gt=0,
                               dynamic=(0.05, 2.0))
    min_speed: float = param(0.1, '[m/s] slowest cruise while correcting large errors', ge=0)
    max_angular: float = param(1.5, '[rad/s] turn rate limit', gt=0, dynamic=(0.1, 4.0))
    decel: float = param(0.95, '[m/s^2] braking for the stop point and the front safety check', gt=0)
    k_lateral: float = param(9.0, '[1/m^2] k_y, lateral gain per metre travelled', gt=0)
    k_heading: float = param(5.0, '[1/m] k_theta, heading gain per metre travelled', gt=0)
    max_approach: float = param(0.5, '[rad] theta_max: steepest angle to rejoin the centre line', gt=0)
    v_turn: float = param(0.25, '[m/s] steering acts as if at least this fast', ge=0)
    slow_heading: float = param(0.5, '[rad] v = 0 at this heading error (quadratic), floored at '
                                     'min_speed', gt=0)
    wall_time: float = param(0.5, '[s] heading for a wall: slow so that it is at least this far away',
                             gt=0)
    # finding and fitting the walls
    look_ahead: float = param(3.0, '[m] the corridor must start within this distance, else the goal '
                                   'aborts', gt=0)
    fit_behind: float = param(0.3, '[m] wall fit window along the corridor, behind the robot', ge=0)
    fit_ahead: float = param(2.0, '[m] ... and ahead of it', gt=0)
    max_width: float = param(2.0, '[m] wider passages are not corridors', gt=0)
    min_width_margin: float = param(0.03, '[m] a corridor is at least 2 (robot_radius + this) wide',
                                    ge=0)
    slice_length: float = param(0.1, '[m] slices along the corridor (wall faces, end detection)', gt=0)
    tukey_scale: float = param(0.06, '[m] wall fit: a residual beyond this has no weight', gt=0)
    face_band: float = param(0.04, '[m] a slice\'s wall face: points this close to its innermost',
                             ge=0)
    min_wall_points: int = param(8, '[points] per side, for a wall fit', ge=2)
    min_wall_length: float = param(0.4, '[m] inliers\' extent along the corridor, per side', gt=0)
    # the end, the stop and the front safety check
    end_band: float = param(0.25, '[m] a slice "has a wall" with a point this close to the line', gt=0)
    end_gap: float = param(0.5, '[m] one side without wall for this long = end of the corridor', gt=0)
    exit_margin: float = param(0.35, '[m] stop the base centre this far past the end', ge=0)
    end_clearance: float = param(0.25, '[m] past the end, stop this far before anything straight '
                                       'ahead (the outer wall of a bend)', ge=0, dynamic=(0.0, 1.0))
    bend_turn: bool = param(True, 'stopped short by a wall ahead (a bend): turn in place toward '
                                  'the longest free way before the goal succeeds')
    bend_search: float = param(math.radians(100.0), '[rad] ... searched within +- this of the '
                                                    'corridor\'s direction', gt=0)
    turn_tolerance: float = param(0.05, '[rad] ... until the heading is within this of it', gt=0)
    stop_margin: float = param(0.08, '[m] front safety: stop this far before touching anything '
                                     'ahead', ge=0, dynamic=(0.0, 0.5))
    max_jump: float = param(0.2, '[m] a wall fit this far from the tracked centre line is rejected',
                            gt=0)
    max_turn: float = param(0.35, '[rad] ... or turned this much from it', gt=0)
    search_half_angle: float = param(math.radians(60.0), '[rad] the corridor is searched within '
                                                         '+- this of straight ahead', gt=0)
    min_informative: float = param(0.5, '[fraction] a scan whose informative beams (REP 117 hit, '
                                        'no return, too close) are fewer, over the whole fan or '
                                        'within search_half_angle ahead, is unusable: blocked',
                                   ge=0, le=1)

    def __post_init__(self):
        validate(self)

    @property
    def min_width(self):
        return 2.0 * (self.robot_radius + self.min_width_margin)


@dataclass
class Walls:
    """Two parallel wall lines in the robot frame (see the module docstring)."""
    theta: float                  # corridor direction in the robot frame [rad]
    d_left: float                 # n.p of the left wall [m] (> 0 when the robot is inside)
    d_right: float                # n.p of the right wall [m] (< 0 when the robot is inside)
    n_left: int = 0               # inliers per side
    n_right: int = 0
    extent_left: Tuple[float, float] = (0.0, 0.0)    # inliers' span along the corridor [m]
    extent_right: Tuple[float, float] = (0.0, 0.0)
    rms: float = 0.0              # inliers' residual RMS [m]

    @property
    def width(self):
        return self.d_left - self.d_right

    @property
    def lateral_offset(self):
        """Robot's signed distance from the centre line, positive to the left [m]."""
        return -0.5 * (self.d_left + self.d_right)

    @property
    def heading_error(self):
        """Robot heading minus corridor direction [rad]."""
        return wrap_angle(-self.theta)


def _frame(points, theta):
    """(u, w): coordinates of robot-frame points along direction ``theta`` and its left normal."""
    c, s = math.cos(theta), math.sin(theta)
    return points[:, 0] * c + points[:, 1] * s, -points[:, 0] * s + points[:, 1] * c


def free_strip_directions(points, half_width, half_angle=math.radians(60.0), step=math.radians(2.0),
                          horizon=25.0):
    """Free length [m] of straight strips of ``half_width`` [m] leaving the robot (robot frame
    points) in directions ``-half_angle..half_angle``. Returns ``(angles, lengths)``."""
    angles = np.arange(-half_angle, half_angle + 1e-9, step)
    pts = np.asarray(points, float).reshape(-1, 2)
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    u = pts[None, :, 0] * c + pts[None, :, 1] * s
    w = -pts[None, :, 0] * s + pts[None, :, 1] * c
    blocked = (np.abs(w) < half_width) & (u > 0)
    lengths = np.where(blocked, u, horizon).min(axis=1) if pts.size else np.full(angles.size, horizon)
    return angles, lengths


def fit_walls(points, theta, centre, params, window=None, iterations=3):
    """Robust joint fit of two parallel walls to robot-frame ``points`` [m].

    ``theta`` [rad] and ``centre`` [m] (the centre line's ``n.p``) are the initial guess; the
    fit uses points within ``window = (u_min, u_max)`` along the corridor (default
    ``(-fit_behind, fit_ahead)``) and within ``max_width / 2`` of the centre line.
    Returns :class:`Walls` or ``None`` when a side has fewer than ``min_wall_points`` inliers
    or spans less than ``min_wall_length``, or the width is not a corridor's.
    """
    p = params
    pts = np.asarray(points, float).reshape(-1, 2)
    if window is None:
        window = (-p.fit_behind, p.fit_ahead)
    result = None
    for _ in range(iterations):
        u, w = _frame(pts, theta)
        rel = w - centre
        sel = (u >= window[0]) & (u <= window[1]) & (np.abs(rel) <= 0.5 * p.max_width)
        if not np.any(sel):
            return None
        us, rs = u[sel], rel[sel]
        nb = int(math.ceil((window[1] - window[0]) / p.slice_length)) + 1
        b = np.clip(((us - window[0]) / p.slice_length).astype(int), 0, nb - 1)
        side_pts = []
        for sign in (1, -1):
            m = sign * rs > 0
            if not np.any(m):
                return None
            key = np.full(nb, np.inf)
            np.minimum.at(key, b[m], sign * rs[m])
            # the wall face of each slice on this side: points within face_band of the
            # innermost one (all of them, so that range noise does not bias the fit inwards)
            idx = np.flatnonzero(m)
            inner = idx[sign * rs[idx] <= key[b[idx]] + p.face_band]
            side_pts.append((us[inner], rs[inner]))
        (ul, rl), (ur, rr) = side_pts
        if ul.size < p.min_wall_points or ur.size < p.min_wall_points:
            return None
        # model: rel = a_side + delta * u  (small rotation delta of the guess), IRLS with Tukey
        U = np.concatenate((ul, ur))
        R = np.concatenate((rl, rr))
        A = np.zeros((U.size, 3))
        A[:ul.size, 0] = 1.0
        A[ul.size:, 1] = 1.0
        A[:, 2] = U
        wts = np.ones(U.size)
        # start from the medians: robust to a wall that turns away
        x = np.array([np.median(rl), np.median(rr), 0.0])
        for _ in range(6):
            res = R - A @ x
            wts = np.where(np.abs(res) < p.tukey_scale, (1 - (res / p.tukey_scale) ** 2) ** 2, 0.0)
            if (wts[:ul.size] > 0).sum() < 2 or (wts[ul.size:] > 0).sum() < 2:
                return None
            sw = np.sqrt(wts)
            x, *_ = np.linalg.lstsq(A * sw[:, None], R * sw, rcond=None)
        res = R - A @ x
        inl = np.abs(res) < 0.5 * p.tukey_scale
        inl_l, inl_r = inl[:ul.size], inl[ul.size:]
        a_l, a_r, delta = x
        # back to a line in the robot frame: rotate the guess by atan(delta)
        d_ang = math.atan(delta)
        cos_d = math.cos(d_ang)
        theta = wrap_angle(theta + d_ang)
        d_left = (centre + a_l) * cos_d
        d_right = (centre + a_r) * cos_d
        centre = 0.5 * (d_left + d_right)
        result = Walls(theta, d_left, d_right, int(inl_l.sum()), int(inl_r.sum()),
                       (float(ul[inl_l].min()), float(ul[inl_l].max())) if inl_l.any() else (0.0, 0.0),
                       (float(ur[inl_r].min()), float(ur[inl_r].max())) if inl_r.any() else (0.0, 0.0),
                       float(np.sqrt(np.mean(res[inl] ** 2))) if inl.any() else 0.0)
    r = result
    if (r.n_left < p.min_wall_points or r.n_right < p.min_wall_points
            or r.extent_left[1] - r.extent_left[0] < p.min_wall_length
            or r.extent_right[1] - r.extent_right[0] < p.min_wall_length
            or not (p.min_width <= r.width <= p.max_width)):
        return None
    return r


def find_corridor(points, params):
    """A corridor ahead of the robot, from robot-frame scan ``points`` alone (no prior).

    Picks the direction of the free strip (robot width plus margin) that reaches farthest,
    then fits the walls along it within ``look_ahead``. Returns :class:`Walls` or ``None``.
    """
    p = params
    pts = np.asarray(points, float).reshape(-1, 2)
    if pts.shape[0] < 2 * p.min_wall_points:
        return None
    half = p.robot_radius + p.min_width_margin
    angles, lengths = free_strip_directions(pts, half, p.search_half_angle)
    best = lengths.max()
    if best < p.min_wall_length:
        return None
    # runs of neighbouring directions whose strips reach past the look-ahead (or are the
    # longest): try them from the one nearest straight ahead (the robot faces the entrance)
    good = lengths >= min(best - 0.05, p.look_ahead)
    runs, start = [], None
    for i, g in enumerate(np.append(good, False)):
        if g and start is None:
            start = i
        elif not g and start is not None:
            runs.append(angles[start:i])
            start = None
    runs.sort(key=lambda r: abs(float(np.median(r))))
    for run in runs:
        theta = float(run[np.argmin(np.abs(run - np.median(run)))])
        walls = fit_walls(pts, theta, 0.0, p, window=(-p.fit_behind, p.look_ahead), iterations=4)
        if walls is None:
            continue
        # the walls must start within the look-ahead, the robot roughly facing along them
        if min(walls.extent_left[0], walls.extent_right[0]) > p.look_ahead:
            continue
        if abs(walls.heading_error) > p.search_half_angle + 0.1:
            continue
        return walls
    return None


def corridor_toward(points, target, params, max_angle=math.radians(60.0)):
    """A corridor ahead of the robot that leads toward ``target``, or ``None``.

    ``points``: robot-frame (base_footprint) scan points [m]; ``target``: ``(x, y)`` [m] in the
    same frame (pose B). The corridor (:func:`find_corridor`) must run within ``max_angle``
    [rad] of the bearing to the target, and the target must lie beyond the walls the robot sees
    (farther along the corridor than their far end): a target beside the entrance, or inside
    the visible stretch of the corridor, is reached without the law. Used by the mission proxy
    to decide whether the corridor law applies. A non-finite target raises ``ValueError``.
    """
    tx, ty = float(target[0]), float(target[1])
    if not (math.isfinite(tx) and math.isfinite(ty)):
        raise ValueError('corridor_toward: target (%r, %r) is not a finite point' % (tx, ty))
    walls = find_corridor(points, params)
    if walls is None:
        return None
    if abs(wrap_angle(math.atan2(ty, tx) - walls.theta)) > max_angle:
        return None
    along = tx * math.cos(walls.theta) + ty * math.sin(walls.theta)
    if along <= max(walls.extent_left[1], walls.extent_right[1]):
        return None
    return walls


def wall_end(points, walls, params, horizon=None):
    """Distance [m] along the corridor (from the robot) where a wall ends, or ``None``.

    For each side, slices of ``slice_length`` from the robot to ``horizon`` (default
    ``look_ahead``) hold a wall when a point lies within ``end_band`` of that side's line. After
    the first slice with a wall, a run of ``end_gap`` without one (inside the horizon) is an end.
    Returns the nearest end of the two sides.
    """
    p = params
    horizon = p.look_ahead if horizon is None else horizon
    pts = np.asarray(points, float).reshape(-1, 2)
    u, w = _frame(pts, walls.theta)
    nb = int(horizon / p.slice_length)
    need = int(math.ceil(p.end_gap / p.slice_length))
    ends = []
    for d in (walls.d_left, walls.d_right):
        m = (np.abs(w - d) <= p.end_band) & (u >= 0.0) & (u < nb * p.slice_length)
        has = np.zeros(nb, bool)
        has[(u[m] / p.slice_length).astype(int)] = True
        seen = np.flatnonzero(has)
        if seen.size == 0:
            continue
        run = 0
        for i in range(seen[0], nb):
            if has[i]:
                run = 0
                continue
            run += 1
            if run >= need:
                ends.append((i - run + 1) * p.slice_length)
                break
    return min(ends) if ends else None


def stop_distance(points, walls, end_u, params):
    """Where [m along the corridor from the robot] the law stops once a wall end is seen at
    ``end_u`` [m]: ``end_u + exit_margin``, or earlier so that the robot's disc, centred on the
    centre line, stays ``end_clearance`` short of every robot-frame point beyond the end within
    its width (e.g. the outer wall of a bend, which crosses the corridor's extension). Points
    before the end are not considered: an obstacle inside the corridor is the front safety
    check's (``blocked``)."""
    p = params
    stop = end_u + p.exit_margin
    pts = np.asarray(points, float).reshape(-1, 2)
    if pts.size == 0:
        return stop
    u, w = _frame(pts, walls.theta)
    rel = w - 0.5 * (walls.d_left + walls.d_right)
    r = p.robot_radius
    m = (u >= end_u) & (np.abs(rel) < r)
    if np.any(m):
        touch = u[m] - np.sqrt(r * r - rel[m] ** 2)
        stop = min(stop, float(touch.min()) - p.end_clearance)
    return stop


def next_leg(points, params):
    """The direction [rad, robot frame] of the longest free strip (robot width plus margin)
    leaving the robot within ``+-bend_search``: the middle of the run of directions within 5 cm
    of the longest. ``None`` without points."""
    p = params
    pts = np.asarray(points, float).reshape(-1, 2)
    if pts.shape[0] == 0:
        return None
    angles, lengths = free_strip_directions(pts, p.robot_radius + p.min_width_margin, p.bend_search)
    best = int(np.argmax(lengths))
    good = lengths >= lengths[best] - 0.05
    lo, hi = best, best
    while lo > 0 and good[lo - 1]:
        lo -= 1
    while hi < len(good) - 1 and good[hi + 1]:
        hi += 1
    return float(0.5 * (angles[lo] + angles[hi]))


def front_free_distance(points, radius, horizon=25.0):
    """How far [m] the robot (a disc of ``radius``) can drive straight ahead before touching
    one of the robot-frame ``points``."""
    pts = np.asarray(points, float).reshape(-1, 2)
    m = (pts[:, 0] > 0) & (np.abs(pts[:, 1]) < radius)
    if not np.any(m):
        return horizon
    d = pts[m, 0] - np.sqrt(radius ** 2 - pts[m, 1] ** 2)
    return float(max(0.0, min(horizon, d.min())))


def control_law(e_y, e_theta, width, params, max_speed=None):
    """The steering law of the module docstring. Returns ``(v, omega)`` [m/s, rad/s] before the
    braking caps (``v >= 0``, ``|omega| <= max_angular``)."""
    p = params
    vmax = p.max_speed if max_speed is None else max_speed
    vmax = min(vmax, p.speed_limit)
    slack = max(0.5 * width - p.robot_radius, 0.05)
    # quadratic: small errors barely slow the robot, large ones do
    s_head = max(0.0, 1.0 - (e_theta / p.slow_heading) ** 2)
    s_lat = max(0.3, 1.0 - (e_y / slack) ** 2)
    v = vmax * s_head * s_lat
    # and slow enough that the wall the robot heads for is >= wall_time away, sideways
    sin_e = abs(math.sin(e_theta))
    if sin_e > 1e-6:
        ahead = slack - e_y if e_theta > 0 else slack + e_y
        v = min(v, max(ahead, 0.0) / (p.wall_time * sin_e))
    v = max(p.min_speed, v)
    v = min(v, vmax)
    lim = math.sin(p.max_approach)
    s_ref = -max(-lim, min(lim, p.k_lateral * e_y / p.k_heading))
    omega = -max(v, p.v_turn) * p.k_heading * (math.sin(e_theta) - s_ref)
    if abs(omega) > p.max_angular:
        v *= p.max_angular / abs(omega)
        omega = math.copysign(p.max_angular, omega)
    return v, omega


def scan_usability(scan, params):
    """Why the :class:`tiago_nav.scan.Scan` is too broken to judge the scene from, or ``''`` when it is usable.

    Informative beams (:func:`tiago_nav.scan.informative_fraction`: a hit, no return or too
    close; NaN and out-of-limits readings are not) must be at least ``min_informative`` of the
    whole fan and of the beams within ``search_half_angle`` of straight ahead; an empty scan
    has none."""
    r = np.asarray(scan.ranges, float)
    ahead = np.abs(scan.angle_min + scan.angle_increment * np.arange(r.size)) \
        <= params.search_half_angle
    worst = min(informative_fraction(r, scan.range_min, scan.range_max),
                informative_fraction(r[ahead], scan.range_min, scan.range_max))
    if worst >= params.min_informative and r.size:
        return ''
    return ('blocked: the laser scan is unusable (%.0f%% of its beams informative, need %.0f%%)'
            % (100 * worst, 100 * params.min_informative))


@dataclass
class Command:
    """What :meth:`CorridorFollower.command` decides."""
    v: float = 0.0
    omega: float = 0.0
    state: str = 'searching'        # searching | driving | done | blocked | failed
    reason: str = ''
    lateral_offset: float = float('nan')
    heading_error: float = float('nan')
    left_distance: float = float('nan')
    right_distance: float = float('nan')
    front_free: float = float('nan')


class CorridorFollower:
    """Keeps the corridor's centre line and end in the odom frame and applies the law.

    Feed it scans with :meth:`update_scan` (points in the odom frame and the robot's odom pose
    at scan time) and ask :meth:`command` for velocities with the robot's current odom pose.
    """

    def __init__(self, params=CorridorParams(), max_speed=None, max_distance=None, lost_scans=15):
        self.p = params
        self.goal_speed = max_speed
        self.max_speed = min(max_speed or params.max_speed, params.speed_limit)
        self.max_distance = max_distance if max_distance else None
        self.lost_scans = lost_scans
        self.line = None            # (x, y, theta) of the centre line in odom: point + direction
        self.width = None
        self.end = None             # (x, y) odom point on the centre line where a wall ends
        self.stop = None            # (x, y) odom point on the centre line where the law stops
        self.stop_short = False     # ... short of end + exit_margin: something lies beyond the end
        self.turn_to = None         # odom yaw [rad] to turn to there (bend_turn), once decided
        self.points = np.zeros((0, 2))     # last scan's hits, odom frame
        self.too_close = np.zeros((0, 2))  # its too-close beams at range_min, odom frame
        self.unusable = ''                 # why the last scan said nothing, if it did not
        self.frozen = FrozenScanCheck()
        self.scans = 0
        self.misses = 0
        self.failure = ''
        self.walls = None
        self.travelled = 0.0
        self._last_pose = None

    def reconfigure(self, params):
        """New :class:`CorridorParams` from the next scan and command on (the node calls it
        between two control cycles): the speed (the goal's max_speed, or ``max_speed``, capped
        at ``speed_limit``), turn rate and clearances. The tracked corridor is kept."""
        self.p = params
        self.max_speed = min(self.goal_speed or params.max_speed, params.speed_limit)

    # --- perception -----------------------------------------------------------------------
    def update_laser(self, scan, laser_pose, pose_odom):
        """One :class:`tiago_nav.scan.Scan`, taken with the laser at ``laser_pose`` and the base at
        ``pose_odom`` (both in odom), read by REP 117 (:mod:`tiago_nav.scan`) after
        :func:`tiago_nav.scan.usable_ranges` (no self-hits, no veils): the walls are fitted from
        its hits only; a too-close beam (-inf) is an obstacle at ``range_min`` along
        it for the front safety check; no-return and invalid beams give no point.

        A scan with too few informative beams (:func:`scan_usability`), or a repeat of the last
        one taken while the laser moved (:class:`tiago_nav.scan.FrozenScanCheck`), says nothing: the walls
        are not updated and :meth:`command` answers ``blocked`` until a usable scan arrives.
        Returns the fitted :class:`Walls` (robot frame) or ``None``."""
        self.unusable = scan_usability(scan, self.p)
        if not self.unusable and self.frozen(scan.ranges, laser_pose):
            self.unusable = 'blocked: the laser repeats its last scan while the robot moves (a stuck driver?)'
        if self.unusable:
            return None
        ranges = usable_ranges(scan.ranges, scan.angle_min, scan.angle_increment, scan.range_min,
                               scan.range_max, compose(inverse(pose_odom), laser_pose))
        pts, _ = scan_to_points(ranges, scan.angle_min, scan.angle_increment,
                                scan.range_min, scan.range_max)
        close = np.flatnonzero(classify(scan.ranges, scan.range_min, scan.range_max) == TOO_CLOSE)
        a = scan.angle_min + scan.angle_increment * close
        too_close = scan.range_min * np.column_stack((np.cos(a), np.sin(a)))
        return self.update_scan(transform_points(laser_pose, pts), pose_odom,
                                transform_points(laser_pose, too_close))

    def update_scan(self, points_odom, pose_odom, too_close_odom=()):
        """One scan: ``points_odom`` (N, 2) in odom [m] (its hits), ``pose_odom`` the base pose
        at scan time, ``too_close_odom`` (K, 2) obstacles that only the front safety check uses.
        Returns the fitted :class:`Walls` (robot frame) or ``None``."""
        p = self.p
        self.points = np.asarray(points_odom, float).reshape(-1, 2)
        self.too_close = np.asarray(too_close_odom, float).reshape(-1, 2)
        self.scans += 1
        local = transform_points(inverse(pose_odom), self.points)
        if self.line is None:
            walls = find_corridor(local, p)
            if walls is None:
                self.misses += 1
                if self.misses >= 3:
                    self.failure = 'no corridor ahead within %.1f m' % p.look_ahead
                return None
        else:
            theta0, c0 = self._line_in_robot(pose_odom)
            walls = fit_walls(local, theta0, c0, p)
            if walls is not None and (abs(wrap_angle(walls.theta - theta0)) > p.max_turn
                                      or abs(0.5 * (walls.d_left + walls.d_right) - c0) > p.max_jump):
                walls = None
            if walls is None:
                self.misses += 1
                if self.end is None and self.misses >= self.lost_scans:
                    self.failure = 'lost the corridor walls for %d scans' % self.misses
                return None
        self.misses = 0
        self.walls = walls
        self.width = walls.width
        x, y, yaw = pose_odom
        th = wrap_angle(yaw + walls.theta)
        c = 0.5 * (walls.d_left + walls.d_right)
        self.line = (x - c * math.sin(th), y + c * math.cos(th), th)
        end_u = wall_end(local, walls, p)
        if end_u is not None:
            # the end's odom point on the centre line, ahead of the robot by end_u, and the stop
            px, py = self._project(pose_odom)
            self.end = (px + end_u * math.cos(th), py + end_u * math.sin(th))
            stop_u = stop_distance(local, walls, end_u, p)
            self.stop_short = stop_u < end_u + p.exit_margin - 1e-9
            self.stop = (px + stop_u * math.cos(th), py + stop_u * math.sin(th))
        return walls

    def _line_in_robot(self, pose):
        """The tracked centre line as ``(theta, n.p)`` in the robot frame at ``pose``."""
        lx, ly, lth = self.line
        theta = wrap_angle(lth - pose[2])
        # n.p of the line's point expressed in the robot frame
        q = transform_points(inverse(pose), [[lx, ly]])[0]
        return theta, -q[0] * math.sin(theta) + q[1] * math.cos(theta)

    def _project(self, pose):
        lx, ly, lth = self.line
        c, s = math.cos(lth), math.sin(lth)
        t = (pose[0] - lx) * c + (pose[1] - ly) * s
        return lx + t * c, ly + t * s

    def errors(self, pose):
        """``(e_y, e_theta)`` of the odom ``pose`` with respect to the tracked centre line."""
        lx, ly, lth = self.line
        e_y = -(pose[0] - lx) * math.sin(lth) + (pose[1] - ly) * math.cos(lth)
        return e_y, wrap_angle(pose[2] - lth)

    def remaining(self, pose):
        """Distance [m] along the corridor to the stop point, or ``None`` before the end is seen."""
        if self.stop is None:
            return None
        lth = self.line[2]
        return (self.stop[0] - pose[0]) * math.cos(lth) + (self.stop[1] - pose[1]) * math.sin(lth)

    # --- control --------------------------------------------------------------------------
    def moved_to(self, pose_odom):
        """The base is now at ``pose_odom``: adds the way from its last pose to ``travelled``."""
        if self._last_pose is not None:
            self.travelled += math.hypot(pose_odom[0] - self._last_pose[0],
                                         pose_odom[1] - self._last_pose[1])
        self._last_pose = pose_odom

    def command(self, pose_odom):
        """Velocities for the robot at ``pose_odom`` (its current odom pose)."""
        p = self.p
        self.moved_to(pose_odom)
        if self.failure:
            return Command(state='failed', reason=self.failure)
        if self.unusable:
            return Command(state='blocked', reason=self.unusable)
        if self.line is None:
            return Command(state='searching', reason='looking for a corridor ahead')
        e_y, e_th = self.errors(pose_odom)
        half = 0.5 * self.width
        cmd = Command(lateral_offset=e_y, heading_error=e_th, left_distance=half - e_y,
                      right_distance=half + e_y)
        rem = self.remaining(pose_odom)
        if self.turn_to is not None or (rem is not None and rem <= 0.02):
            # at the stop point (and, once turning there, until the turn ends: the stop point
            # moves with later scans, the robot does not)
            if self.stop_short and p.bend_turn:
                if self.turn_to is None:
                    local_pts = transform_points(inverse(pose_odom), self.points)
                    a = next_leg(local_pts, p)
                    self.turn_to = wrap_angle(pose_odom[2] + a) if a is not None else pose_odom[2]
                err = wrap_angle(self.turn_to - pose_odom[2])
                if abs(err) > p.turn_tolerance:
                    w = max(0.3, min(p.max_angular, 2.0 * abs(err)))
                    cmd.v, cmd.omega, cmd.state = 0.0, math.copysign(w, err), 'driving'
                    return cmd
            cmd.state, cmd.reason = 'done', 'reached the end of the corridor'
            if self.stop_short:
                cmd.reason += (' (stopped %.2f m before a wall ahead past its end: it bends or '
                               'ends there%s)' % (p.end_clearance, '' if self.turn_to is None else
                                                  '; turned %.0f deg toward the longest free way'
                                                  % math.degrees(wrap_angle(self.turn_to - self.line[2]))))
            return cmd
        if self.max_distance is not None and self.travelled >= self.max_distance - 0.01:
            cmd.state = 'done'
            cmd.reason = 'travelled max_distance %.2f m before the corridor end' % self.max_distance
            return cmd
        local = transform_points(inverse(pose_odom), np.vstack((self.points, self.too_close)))
        free = front_free_distance(local, p.robot_radius)
        cmd.front_free = free
        if free < p.stop_margin:
            cmd.state, cmd.reason = 'blocked', 'blocked ahead: obstacle %.2f m in front' % free
            return cmd
        v, w = control_law(e_y, e_th, self.width, p, self.max_speed)
        caps = [free - p.stop_margin]
        if rem is not None:
            caps.append(rem)
        if self.max_distance is not None:
            caps.append(self.max_distance - self.travelled)
        vcap = math.sqrt(2.0 * p.decel * max(0.0, min(caps)))
        if v > vcap:
            # keep the curvature while braking, but let it still turn when nearly stopped
            w = w * vcap / v if vcap > 0.05 else w
            v = vcap
        cmd.v, cmd.omega, cmd.state = v, w, 'driving'
        return cmd


class GoalJudge:
    """How a corridor goal ends, from the follower's :class:`Command` at each control tick:
    ``done`` -> SUCCEEDED, ``failed`` -> ABORTED, ``blocked`` for longer than
    ``blocked_timeout`` [s] -> ABORTED, each with the command's reason."""

    def __init__(self, blocked_timeout):
        self.blocked_timeout = float(blocked_timeout)
        self.blocked_since = None

    def judge(self, cmd, now):
        """``cmd`` decided at time ``now`` [s]: None while the goal goes on, else
        ``(SUCCEEDED or ABORTED, reason)``."""
        if cmd.state == 'done':
            return SUCCEEDED, cmd.reason
        if cmd.state == 'failed':
            return ABORTED, cmd.reason
        if cmd.state != 'blocked':
            self.blocked_since = None
            return None
        if self.blocked_since is None:
            self.blocked_since = now
        if now - self.blocked_since > self.blocked_timeout:
            return ABORTED, cmd.reason
        return None
