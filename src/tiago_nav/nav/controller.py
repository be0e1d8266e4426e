"""Local controller: regulated pure pursuit along the global plan, with the base's velocity and
acceleration limits, speed regulated by curvature, distance to the goal and clearance, a
forward-collision check of every command against the laser points, and a final in-place turn
to the goal yaw.

Frames: poses and points in ``map``; ``(x, y, yaw)`` [m, m, rad]; speeds [m/s, rad/s].
"""
import math
from dataclasses import dataclass

import numpy as np

from tiago_nav.geometry import wrap_angle
from tiago_nav.params import ParamError, param, validate
from tiago_nav.robot import ROBOT_RADIUS


@dataclass(frozen=True)
class ControllerConfig:
    """The local controller's limits and gains (parameters of the ``move_base`` node)."""
    robot_radius: float = param(ROBOT_RADIUS, '[m] base footprint radius (tiago_nav.robot)', gt=0)
    max_vel_x: float = param(1.0, '[m/s] forward speed limit', gt=0, dynamic=(0.05, 2.0))
    min_vel_x: float = param(0.05, '[m/s] slowest forward cruise', ge=0)
    max_vel_theta: float = param(1.5, '[rad/s] turn rate limit', gt=0, dynamic=(0.1, 4.0))
    acc_lim_x: float = param(1.0, '[m/s^2] forward acceleration limit', gt=0,
                             dynamic=(0.1, 5.0))
    acc_lim_theta: float = param(2.0, '[rad/s^2] angular acceleration limit', gt=0,
                                 dynamic=(0.1, 10.0))
    decel_x: float = param(0.9, '[m/s^2] braking used for the goal approach and the collision '
                           'check (a bit under the limit)', gt=0)
    lookahead_min: float = param(0.35, '[m] shortest pure-pursuit lookahead', gt=0)
    lookahead_time: float = param(0.7, '[s] lookahead = lookahead_min + lookahead_time * speed', ge=0)
    lookahead_max: float = param(1.2, '[m] longest lookahead', gt=0)
    rotate_in_place_angle: float = param(1.3, '[rad] heading error above which the base turns '
                                         'on the spot (open space)', gt=0)
    slow_clearance: float = param(0.15, '[m] slow down when the gap to the nearest laser point '
                                  'is below this', ge=0)
    slow_clearance_speed: float = param(0.35, '[m/s] speed at zero gap', gt=0)
    safety_margin: float = param(0.04, '[m] extra radius of the forward-collision check', ge=0)
    tight_clearance: float = param(0.25, '[m] gap below which the base tracks the plan closely '
                                   '(short lookahead)', ge=0)
    tight_rotate_angle: float = param(0.5, '[rad] ... and turns on the spot above this heading '
                                      'error', gt=0)
    heading_gain: float = param(2.5, '[1/s] in-place turning gain', gt=0)
    xy_goal_tolerance: float = param(0.15, '[m] goal reached within this distance', gt=0,
                                     dynamic=(0.01, 1.0))
    yaw_goal_tolerance: float = param(0.1, '[rad] ... and within this heading error', gt=0,
                                      dynamic=(0.01, math.pi))

    def __post_init__(self):
        validate(self)
        if self.min_vel_x > self.max_vel_x:
            raise ParamError('must not exceed max_vel_x (%g m/s)' % self.max_vel_x, 'min_vel_x')
        if self.lookahead_max < self.lookahead_min:
            raise ParamError('must be >= lookahead_min (%g m)' % self.lookahead_min,
                             'lookahead_max')


def _ramp(target, current, limit, dt):
    return current + max(-limit * dt, min(limit * dt, target - current))


def arc_poses(pose, v, w, horizon, dt):
    """Poses ``(K, 3)`` of the unicycle from ``pose`` under constant ``(v, w)``."""
    n = max(1, int(math.ceil(horizon / dt)))
    t = np.arange(1, n + 1) * dt
    x, y, th = pose
    if abs(w) < 1e-6:
        return np.column_stack((x + v * t * math.cos(th), y + v * t * math.sin(th), np.full(n, th)))
    ths = th + w * t
    return np.column_stack((x + v / w * (np.sin(ths) - math.sin(th)),
                            y - v / w * (np.cos(ths) - math.cos(th)), ths))


def gaps(positions, points, radius, margins=None):
    """``(K,)`` gap [m] between a circle of ``radius`` at each of ``positions (K, 2)`` and the
    nearest of ``points (M, 2)``, each point's distance less its own ``margins`` ``(M,)`` [m]
    (None: 0); ``inf`` without points."""
    if len(points) == 0:
        return np.full(len(positions), math.inf)
    d = np.hypot(positions[:, None, 0] - points[None, :, 0], positions[:, None, 1] - points[None, :, 1])
    if margins is not None:
        d = d - margins[None, :]
    return d.min(axis=1) - radius


def min_gap(positions, points, radius, margins=None):
    """Smallest gap [m] between circles of ``radius`` at ``positions (K, 2)`` and ``points (M, 2)``,
    each point's distance less its own ``margins`` ``(M,)`` [m] (None: 0)."""
    if len(points) == 0 or len(positions) == 0:
        return math.inf
    return float(gaps(positions, points, radius, margins).min())


class Controller:
    """Stateful: remembers the last command (for the acceleration ramp) and the path progress."""

    def __init__(self, config=ControllerConfig()):
        self.c = config
        self.reset()

    def configure(self, config):
        """New limits and tolerances from the next :meth:`command` on. The path and the last
        command are kept: a lower ``max_vel_x`` is reached at ``acc_lim_x``, as the base
        would brake anyway."""
        self.c = config

    def reset(self, path=None):
        self.v = 0.0
        self.w = 0.0
        self.set_path(path)

    def set_path(self, path):
        self.path = None if path is None else np.asarray(path, dtype=float)
        self.index = 0

    # ------------------------------------------------------------------------------------
    def _progress(self, xy):
        p = self.path
        lo = self.index
        hi = min(len(p), lo + 60)
        d = np.hypot(p[lo:hi, 0] - xy[0], p[lo:hi, 1] - xy[1])
        self.index = lo + int(np.argmin(d))
        return float(d.min())

    def _lookahead(self, xy, dist):
        p = self.path[self.index:]
        d = np.hypot(p[:, 0] - xy[0], p[:, 1] - xy[1])
        beyond = np.nonzero(d >= dist)[0]
        return p[beyond[0]] if len(beyond) else p[-1]

    def safe(self, pose, v, w, points, dt, blind=False, margins=None):
        """True when ``(v, w)`` held for ``dt`` and then braked at ``decel_x`` keeps the footprint
        (plus ``safety_margin``, plus each point's own ``margins``) clear of ``points``, or,
        where the base already stands within that (a person stepped near, a margin came with
        a person seen), brings it no nearer: it may drive out, not further in.
        ``blind`` (the laser saw nothing it could vouch for): no forward motion is safe."""
        if v <= 1e-3:
            return True   # a round base turning on the spot or stopping cannot hit anything new
        if blind:
            return False
        horizon = dt + v / self.c.decel_x + 0.1
        poses = arc_poses(pose, v, w, horizon, 0.05)
        if not len(points):
            return True
        keep = np.hypot(points[:, 0] - pose[0], points[:, 1] - pose[1]) \
            < v * horizon + self.c.robot_radius + 0.3
        g = gaps(np.vstack((pose[:2], poses[:, :2])), points[keep],
                 self.c.robot_radius + self.c.safety_margin,
                 None if margins is None else margins[keep])      # here, then along the arc
        return bool(g[1:].min() > 0.0 or g[1:].min() >= g[0])

    def command(self, pose, goal, points, dt, blind=False, margins=None):
        """One control step. ``points``: obstacle points ``(M, 2)`` in map (laser hits and
        what the collision check must assume), each nearer than it is by its ``margins``
        ``(M,)`` [m] at most (None: 0; a remembered map cell's centre, by half its diagonal);
        ``blind``: the newest scan had no informative beam, so only turning on the spot is
        allowed. Returns ``(v, w, phase)`` with phase ``'follow'``, ``'rotate'``, ``'arrived'``
        or ``'blocked'``."""
        c = self.c
        x, y, yaw = pose
        dg = math.hypot(goal[0] - x, goal[1] - y)
        if self.path is None or dg <= c.xy_goal_tolerance:
            err = wrap_angle(goal[2] - yaw)
            if dg <= c.xy_goal_tolerance and abs(err) <= c.yaw_goal_tolerance and abs(self.w) < 0.3:
                self.v, self.w = 0.0, 0.0
                return 0.0, 0.0, 'arrived'
            w_t = math.copysign(min(c.max_vel_theta, c.heading_gain * abs(err),
                                    math.sqrt(2 * c.acc_lim_theta * 0.8 * abs(err))), err)
            self.v = _ramp(0.0, self.v, c.acc_lim_x, dt)
            self.w = _ramp(w_t, self.w, c.acc_lim_theta, dt)
            return self.v, self.w, 'rotate'

        self._progress((x, y))
        gap = math.inf
        if len(points):
            keep = np.hypot(points[:, 0] - x, points[:, 1] - y) < c.robot_radius + 0.8
            gap = min_gap(np.array([[x, y]]), points[keep], c.robot_radius,
                          None if margins is None else margins[keep])
        tight = gap < c.tight_clearance
        L = min(c.lookahead_max, max(c.lookahead_min, c.lookahead_min + c.lookahead_time * self.v))
        if tight:
            L = c.lookahead_min
        L = min(L, max(dg, 0.05))
        tx, ty = self._lookahead((x, y), L)
        alpha = wrap_angle(math.atan2(ty - y, tx - x) - yaw)
        turn_limit = c.tight_rotate_angle if tight else c.rotate_in_place_angle
        if abs(alpha) > turn_limit and self.v < 0.3:
            return self.turn(alpha, dt, 'rotate')
        Ld = max(math.hypot(tx - x, ty - y), 1e-3)
        k = 2.0 * math.sin(alpha) / Ld                          # curvature [1/m]
        v_t = c.max_vel_x
        v_t = min(v_t, c.max_vel_theta / max(abs(k), 1e-6))
        v_t = min(v_t, max(0.0, c.max_vel_x * (1.0 - 0.5 * max(0.0, abs(alpha) - 0.3) / c.rotate_in_place_angle)))
        v_t = min(v_t, math.sqrt(2 * c.decel_x * max(dg - 0.5 * c.xy_goal_tolerance, 0.0)) + 0.02)
        if gap < c.slow_clearance:
            v_t = min(v_t, c.slow_clearance_speed + (c.max_vel_x - c.slow_clearance_speed)
                      * max(gap, 0.0) / c.slow_clearance)
        v_t = max(v_t, c.min_vel_x)
        v = _ramp(v_t, self.v, c.acc_lim_x, dt)
        w_t = max(-c.max_vel_theta, min(c.max_vel_theta, k * max(v, c.min_vel_x)))
        w = _ramp(w_t, self.w, c.acc_lim_theta, dt)
        if not self.safe(pose, v, w, points, dt, blind, margins):
            # slower, then on the spot towards the plan (a round base cannot hit anything
            # turning); slower only as far as the base can brake within the cycle: the check
            # assumes the base runs at the speed it is given, and self.v is the speed it runs at
            floor = self.v - c.acc_lim_x * dt
            for vs in sorted({min(max(s, floor), v) for s in (0.5 * v, 0.25 * v, 0.1, 0.05)},
                             reverse=True):
                if vs > 0.02 and self.safe(pose, vs, w, points, dt, blind, margins):
                    self.v, self.w = vs, w
                    return vs, w, 'follow'
            return self.turn(alpha, dt, 'blocked')
        self.v, self.w = v, w
        return v, w, 'follow'

    def turn(self, alpha, dt, phase):
        """Brake and turn on the spot towards heading error ``alpha`` [rad]."""
        c = self.c
        w_t = math.copysign(min(c.max_vel_theta, c.heading_gain * abs(alpha),
                                math.sqrt(2 * c.acc_lim_theta * 0.8 * abs(alpha))), alpha)
        self.v = _ramp(0.0, self.v, c.acc_lim_x, dt)
        self.v = 0.0 if self.v < 0.05 else self.v
        self.w = _ramp(w_t, self.w, c.acc_lim_theta, dt)
        return self.v, self.w, phase
