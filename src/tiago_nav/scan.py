"""Laser scans as plain arrays: one validity rule (REP 117) and one scan → points conversion,
used by the costmap, the collision checks, the corridor law and detection.

REP 117 values of a ``sensor_msgs/LaserScan`` range ``r`` with limits ``[range_min, range_max]``:

* a finite ``r`` within the limits is a **hit** (something at ``r``);
* ``+inf`` is **no return**: nothing within ``range_max`` along the beam (free space, may clear);
* ``-inf`` is **too close**: something nearer than ``range_min`` (never clears; for a safety
  check the beam is blocked);
* ``NaN`` and a finite value outside the limits are **invalid**: the measurement says nothing
  and is used for nothing.

Angles are in the laser's frame (``base_laser_link``), radians; ranges and points in metres.
"""
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from tiago_nav.geometry import wrap_angle
from tiago_nav.robot import LASER_OFFSET, ROBOT_RADIUS

HIT, NO_RETURN, TOO_CLOSE, INVALID = 0, 1, 2, 3


@dataclass(frozen=True)
class Scan:
    """One laser scan as plain values: the fields of sensor_msgs/LaserScan that the corridor law
    and detection use."""
    ranges: Sequence[float]   # [m] REP 117 values, one per beam
    angle_min: float          # [rad] first beam, in the laser frame
    angle_increment: float    # [rad] between beams
    range_min: float          # [m]
    range_max: float          # [m]
    stamp: Any                # the scan's time: ROS time [s], or the time type the consumer's
    #                           transform lookups take (the detection node passes rospy.Time)
    frame_id: str             # the laser's frame


def beam_angles(angle_min, angle_increment, n):
    """Beam angles [rad] of a scan with ``n`` beams, in the laser frame."""
    return angle_min + angle_increment * np.arange(n)


def classify(ranges, range_min, range_max):
    """Per beam, one of :data:`HIT`, :data:`NO_RETURN`, :data:`TOO_CLOSE`, :data:`INVALID`
    (the module's REP 117 rule). Returns an int8 array."""
    r = np.asarray(ranges, dtype=float)
    out = np.full(r.shape, INVALID, dtype=np.int8)
    with np.errstate(invalid='ignore'):
        out[np.isfinite(r) & (r >= range_min) & (r <= range_max)] = HIT
    out[r == np.inf] = NO_RETURN
    out[r == -np.inf] = TOO_CLOSE
    return out


def hits(ranges, range_min, range_max):
    """Boolean mask of the beams that measured something within the limits (:data:`HIT` of
    :func:`classify`)."""
    r = np.asarray(ranges, dtype=float)
    with np.errstate(invalid='ignore'):
        return np.isfinite(r) & (r >= range_min) & (r <= range_max)


def informative_fraction(ranges, range_min, range_max):
    """Fraction of the beams that say something (a hit, no return or too close); 0 for an
    empty scan. A scan far below 1 is too broken to judge the scene from."""
    c = classify(ranges, range_min, range_max)
    return float(np.mean(c != INVALID)) if c.size else 0.0


def median_ranges(scans, range_min, range_max):
    """Per beam, the median of the hits of several scans of one sensor at one pose (the
    first of ``scans`` is the reference scan: a list of ``(n,)`` range arrays [m], one beam
    geometry): where more than half of the scans hit (REP 117, within ``[range_min,
    range_max]``), the median of those hits; elsewhere the reference scan's own value (no
    return, too close or invalid keep their meaning). A mixed pixel or a dropout in one scan
    is outvoted; the range noise of the median of K scans is about ``sqrt(pi / 2K)`` of one
    scan's. Returns an ``(n,)`` float array."""
    r = np.asarray(scans, dtype=float)
    ok = (classify(r, range_min, range_max) == HIT)
    out = np.array(r[0], dtype=float)
    majority = 2 * ok.sum(axis=0) > len(r)
    if np.any(majority):
        masked = np.where(ok[:, majority], r[:, majority], np.nan)
        out[majority] = np.nanmedian(masked, axis=0)
    return out


def scan_to_points(ranges, angle_min, angle_increment, range_min=0.0, range_max=np.inf):
    """The hits of a scan as points in the laser frame.

    Returns ``(points, index)``: the ``(M, 2)`` points [m] of the :data:`HIT` beams and the beam
    index of each point (no return, too close and invalid beams have no point).
    """
    r = np.asarray(ranges, dtype=float)
    idx = np.flatnonzero(hits(r, range_min, range_max))
    ang = angle_min + angle_increment * idx
    rv = r[idx]
    return np.column_stack((rv * np.cos(ang), rv * np.sin(ang))), idx


BODY_MARGIN = 0.05   # [m] beyond the footprint, still the robot: 5 sigma of 0.01 m range noise


def body_returns(ranges, angles, laser_pose=(LASER_OFFSET, 0.0, 0.0), radius=ROBOT_RADIUS,
                 margin=BODY_MARGIN):
    """Mask of the beams whose return lies on or inside the robot's own body: ignore them.

    The body is the footprint, a circle of ``radius`` + ``margin`` about base_footprint's origin
    (the margin covers the range noise of a return from the body's shell). Only finite ranges
    are judged (NaN and +-inf are False: :func:`classify` decides what they mean). A real
    obstacle this close is already touching the robot.

    Args:
        ranges: ``(n,)`` ranges [m] of a scan.
        angles: ``(n,)`` beam angles [rad] in the laser frame (:func:`beam_angles`).
        laser_pose: ``(x, y, yaw)`` of the laser frame in base_footprint [m, rad].
        radius: [m] the footprint's radius.
        margin: [m] added to ``radius``.

    Returns:
        ``(n,)`` bool array, True for the beams to ignore.
    """
    r = np.asarray(ranges, dtype=float)
    a = np.asarray(angles, dtype=float) + laser_pose[2]
    finite = np.isfinite(r)
    rf = np.where(finite, r, 0.0)
    x = laser_pose[0] + rf * np.cos(a)
    y = laser_pose[1] + rf * np.sin(a)
    return finite & (np.hypot(x, y) <= radius + margin)


SHADOW_ANGLE = np.radians(10.0)  # [rad] laser_filters ScanShadowsFilter's usual min_angle
SHADOW_MIN_JUMP = 0.05           # [m] a veil's depth step: 3.5 sigma of two 0.01 m noisy ranges
SHADOW_RANGE_STD = 0.01          # [m] range noise (1 sigma) the straightness test of a chain allows


def usable_ranges(ranges, angle_min, angle_increment, range_min, range_max,
                  laser_pose=(LASER_OFFSET, 0.0, 0.0), radius=ROBOT_RADIUS, margin=BODY_MARGIN,
                  shadow_angle=SHADOW_ANGLE, shadow_min_jump=SHADOW_MIN_JUMP,
                  range_std=SHADOW_RANGE_STD):
    """The ranges a consumer may use: a copy of the scan's ranges [m] with the beams it must
    not use set to NaN (REP 117 *invalid*: they mark nothing and clear nothing, and are never
    read as free space). Every consumer of a scan (costmap, detection, corridor law,
    localisation) calls this first, then :func:`scan_to_points` / :func:`classify` as before.

    Dropped:

    * the robot's own body: :func:`body_returns` (by geometry, about base_footprint), for the
      beams pointing backwards from the laser (in base_footprint): the laser sits at the front
      of the base and sees its body only behind it (TIAGo's self-hits are the fan's ends). A
      return ahead of the laser is never taken for the body, however close: an obstacle
      ``margin`` from the front bumper must still stop the robot. A hit beside a body return
      (behind the laser) and within ``shadow_min_jump`` of it goes too: the veil rule below
      would keep it as a near surface, but it is the body's mixed pixel or noise, and can lie
      just past the margin (a wall that close is touching the body anyway);
    * veils (mixed pixels), by the rule of ROS laser_filters' ``ScanShadowsFilter``: two
      neighbouring hits form a *grazing step* when the segment between their points makes an
      angle below ``shadow_angle`` with the beam (the pair lies almost along the beam) and
      their ranges differ by more than ``shadow_min_jump`` (range noise alone never makes
      one). The farther point of a grazing step is a veil point and dropped, unless the step
      continues a grazing step in the same direction (a wall seen at grazing incidence is a
      chain of such steps and keeps its points but the first). At a depth edge the near point
      is the occluding edge, a real surface, and its other neighbour lies on the same surface;
      the mixed pixel beyond it is dropped, and so is a cylinder's last point before its
      tangent. A mixed pixel within ``shadow_min_jump`` of the near surface is kept (it is
      close to a real surface); the far surface's first point behind it is dropped instead.
      A point inside a chain (a grazing step going away on each side) is kept only if it lies
      on the straight line through its two neighbours and on the lines through the two points
      on each side of it (where both are hits next to it), each within 3 ``range_std`` of
      range noise (a wall is straight; a mixed pixel that follows a grazing step on a
      cylinder's flank, between the cylinder and the wall behind it, is not; nor is one past
      the end of a wall seen at grazing incidence, even where it falls on the line through its
      neighbours, which then lie on two surfaces, or on the wall's line, which runs along the
      beams there; the wall's last two points before such a step go too).
      An invalid beam (NaN: a dropout, common at a cylinder's tangent) says nothing: the beams
      either side of it (up to ``MAX_SKIP`` beams apart) are neighbours.

    No return (+inf) and too close (-inf) are kept: they still mean what REP 117 says.

    Args:
        ranges: ``(n,)`` ranges [m] of a scan.
        angle_min, angle_increment: [rad] the scan's first beam and step, laser frame.
        range_min, range_max: [m] the scan's limits.
        laser_pose: ``(x, y, yaw)`` of the laser frame in base_footprint [m, rad] (from tf).
        radius, margin: [m] the body, as :func:`body_returns` takes them.
        shadow_angle: [rad] a neighbour's segment closer than this to the beam is a veil.
        shadow_min_jump: [m] and only if their ranges differ by more than this.
        range_std: [m] range noise (1 sigma) of the straightness test inside a chain.

    Returns:
        ``(n,)`` float array.
    """
    r = np.array(ranges, dtype=float)
    n = r.size
    if n == 0:
        return r
    geo = _geometry(angle_min, angle_increment, n, laser_pose[2])
    hit = hits(r, range_min, range_max)
    # the body lies behind the laser (mounted at the front of the base): a return ahead of it is
    # an obstacle however close, and must stop the robot
    drop = np.zeros(n, dtype=bool)
    near = np.flatnonzero(hit & geo.behind)
    if near.size:       # (body_returns, on the hits behind the laser)
        rn = r[near]
        drop[near] = np.hypot(laser_pose[0] + rn * geo.cos_base[near],
                              laser_pose[1] + rn * geo.sin_base[near]) <= radius + margin
    # a beam with no valid measurement (NaN, e.g. a dropout at a cylinder's tangent) says
    # nothing: the beams either side of it (up to MAX_SKIP beams apart) are neighbours
    idx = np.flatnonzero(~np.isnan(r))
    if idx.size > 1:
        adjacent = np.diff(idx) <= MAX_SKIP
        body = drop[idx]
        rv, hv = r[idx], hit[idx]
        drop[idx] |= _veils(rv, geo.angles[idx], geo.cos[idx], geo.sin[idx], hv,
                            adjacent, shadow_angle, shadow_min_jump, range_std)
        if body.any():
            # a hit behind the laser beside a body return and within shadow_min_jump of it
            # makes no grazing step, so the veil rule takes it for the near surface: it is the
            # body's mixed pixel (or noise), and may lie just past the margin
            behind = hv & geo.behind[idx]
            close = adjacent & (np.abs(np.diff(rv)) <= shadow_min_jump)
            drop[idx[1:][close & body[:-1] & behind[1:]]] = True
            drop[idx[:-1][close & body[1:] & behind[:-1]]] = True
    r[drop] = np.nan
    return r


MAX_SKIP = 3    # [beams] neighbours across up to two invalid beams


class _Geometry:
    """A scan's beam angles [rad] in the laser frame, their cosines and sines, and in
    base_footprint's heading (laser yaw added): what :func:`usable_ranges` needs of a beam
    geometry, computed once per geometry (every scan of a laser has the same)."""

    def __init__(self, angle_min, angle_increment, n, yaw):
        self.angles = beam_angles(angle_min, angle_increment, n)
        self.cos, self.sin = np.cos(self.angles), np.sin(self.angles)
        base = self.angles + yaw
        self.cos_base, self.sin_base = np.cos(base), np.sin(base)
        self.behind = self.cos_base <= 0.0


_GEOMETRIES = {}


def _geometry(angle_min, angle_increment, n, yaw):
    key = (float(angle_min), float(angle_increment), int(n), float(yaw))
    geo = _GEOMETRIES.get(key)
    if geo is None:
        if len(_GEOMETRIES) >= 8:
            _GEOMETRIES.clear()
        geo = _GEOMETRIES[key] = _Geometry(angle_min, angle_increment, n, yaw)
    return geo


def _veils(r, angles, c, s, hit, adjacent, shadow_angle, shadow_min_jump, range_std):
    """The veil rule of :func:`usable_ranges` over a sequence of beams (ranges ``r`` [m],
    directions ``angles`` [rad] with their cosines ``c`` and sines ``s``, ``hit`` mask,
    ``adjacent[k]``: beams k and k+1 count as neighbours, True: all); returns the mask of the
    points to drop."""
    n = r.size
    rh = np.where(hit, r, 0.0)
    r0, r1, c0, s0 = rh[:-1], rh[1:], c[:-1], s[:-1]
    dx, dy = r1 * c[1:] - r0 * c0, r1 * s[1:] - r0 * s0
    along = np.abs(dx * c0 + dy * s0)
    across = np.abs(dx * s0 - dy * c0)
    step = (adjacent & hit[:-1] & hit[1:] & (across < np.tan(shadow_angle) * along)
            & (np.abs(r1 - r0) > shadow_min_jump))
    out = np.concatenate(([False], step & (r1 > r0), [False]))  # step k -> k+1 goes away
    back = np.concatenate(([False], step & (r0 > r1), [False]))  # step k+1 -> k goes away
    # beam k: reached going away from k-1 (out[k]) not continuing out[k-1], or from k+1
    # (back[k+1]) not continuing back[k+2]
    drop = out[:n] & ~np.concatenate((out[:1], out[:n - 1]))
    drop |= back[1:] & ~np.concatenate((back[2:], back[n:]))
    # inside a chain, a wall's points lie on a line: three points at angles a0, a1, a2 of a line
    # satisfy sin(a2 - a1) / r0 + sin(a1 - a0) / r2 = sin(a2 - a0) / r1. A point must lie on the
    # line through its two neighbours and on the lines through the two points on each side of
    # it. A mixed pixel between the end of a wall seen at grazing incidence and what lies behind
    # it can fall on the line through its neighbours, which then lie on two surfaces, or on the
    # near surface's own line (at short range the test allows centimetres along the beam, and
    # the wall's line runs along the beams), but not on both surfaces' lines.
    inside = (out[:n] & out[1:]) | (back[:n] & back[1:])
    m = np.flatnonzero(inside[1:n - 1]) + 1
    if m.size:
        def on_line(k):
            """Whether the points k - 1, k, k + 1 (index arrays) lie on a line, within 3 sigma
            of range noise; False where one of them is not a hit."""
            i0, i1, i2 = (np.where(hit[j], 1.0 / np.where(hit[j], r[j], 1.0), 0.0)
                          for j in (k - 1, k, k + 1))
            s21, s10 = np.sin(angles[k + 1] - angles[k]), np.sin(angles[k] - angles[k - 1])
            s20 = np.sin(angles[k + 1] - angles[k - 1])
            resid = i0 * s21 + i2 * s10 - i1 * s20
            sigma = range_std * np.sqrt((i0 ** 2 * s21) ** 2 + (i2 ** 2 * s10) ** 2
                                        + (i1 ** 2 * s20) ** 2)
            return hit[k - 1] & hit[k] & hit[k + 1] & (np.abs(resid) <= 3.0 * np.abs(sigma))

        def neighbours(k):
            """Whether beams k and k + 1 (an index array) count as neighbours."""
            return np.broadcast_to(adjacent, (n - 1,))[k]

        def beside(k, exists):
            """on_line(k), or True where there is no such line: ``exists`` False (k - 1 or
            k + 1 is past the scan's end), k - 1 or k + 1 not a hit or not k's neighbour."""
            ok = np.ones(k.size, dtype=bool)
            j = k[exists]
            present = hit[j - 1] & hit[j + 1] & neighbours(j - 1) & neighbours(j)
            ok[exists] = ~present | on_line(j)
            return ok

        drop[m] |= ~(on_line(m) & beside(m - 1, m >= 2) & beside(m + 1, m <= n - 3))
    return drop


def same_ranges(a, b):
    """True if two range arrays of one shape are equal element by element, NaN equal to NaN
    (what ``np.array_equal(a, b, equal_nan=True)`` says, which needs numpy >= 1.19; Noetic's
    is 1.17)."""
    nan = np.isnan(a)
    return bool(np.array_equal(nan, np.isnan(b)) and np.array_equal(a[~nan], b[~nan]))


class FrozenScanCheck:
    """Tells a stuck laser driver from a live laser: a driver that hangs may go on sending its
    last ranges with new stamps. Real ranges are noisy (the TiM571's 20 mm, 1 mm steps), so two
    scans whose every range is bit-identical while the laser moved are one scan sent again.

    Call it with each scan's ranges and the laser's pose ``(x, y, yaw)`` [m, rad] in a fixed
    frame (map or odom) at the scan's stamp; it returns True for a repeat taken after the laser
    moved at least ``min_motion`` [m] or turned ``min_turn`` [rad] since the first copy. A
    standing robot's repeats are not flagged (nothing is gained by driving on them), nor are
    scans with fewer than ``min_hits`` finite ranges (only measured ranges carry noise: open
    floor with no return in range looks the same from everywhere). A laser simulated without
    any noise in a scene that looks the same as the robot moves would be taken for a stuck one.
    """

    def __init__(self, min_motion=0.02, min_turn=np.radians(1.0), min_hits=10):
        self.min_motion, self.min_turn, self.min_hits = min_motion, min_turn, min_hits
        self.ranges = None
        self.pose = None

    def __call__(self, ranges, laser_pose):
        r = np.asarray(ranges, dtype=float)
        if self.ranges is not None and r.shape == self.ranges.shape \
                and same_ranges(r, self.ranges) \
                and np.isfinite(r).sum() >= self.min_hits:
            dx, dy = laser_pose[0] - self.pose[0], laser_pose[1] - self.pose[1]
            turn = abs(wrap_angle(laser_pose[2] - self.pose[2]))
            return bool(np.hypot(dx, dy) >= self.min_motion or turn >= self.min_turn)
        self.ranges, self.pose = r.copy(), tuple(laser_pose)
        return False
