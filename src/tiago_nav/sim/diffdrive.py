"""Kinematics of a differential-drive base with velocity and acceleration limits.

Velocities are in base_footprint (``v`` forward [m/s], ``w`` counter-clockwise [rad/s]);
poses ``(x, y, yaw)`` are in the frame the base is integrated in (odom or map).
"""
import math
from dataclasses import dataclass

from tiago_nav.geometry import wrap_angle
from tiago_nav.params import param, validate


@dataclass(frozen=True)
class BaseLimits:
    """TIAGo-like limits: speeds [m/s, rad/s] and accelerations [m/s², rad/s²]."""
    max_linear_velocity: float = param(1.0, '[m/s] base speed limit', gt=0)
    max_angular_velocity: float = param(1.5, '[rad/s] base turn rate limit', gt=0)
    max_linear_acceleration: float = param(1.0, '[m/s^2] base acceleration limit', gt=0)
    max_angular_acceleration: float = param(2.0, '[rad/s^2] base angular acceleration limit', gt=0)

    def __post_init__(self):
        validate(self)


def clamp(value, limit):
    """``value`` clamped into ``[-limit, limit]``."""
    return max(-limit, min(limit, value))


def limit_velocity(v, w, v_prev, w_prev, dt, limits):
    """The command ``(v, w)`` the base can follow within ``dt`` [s]: clamped to the speed
    limits, then to what the acceleration limits allow from ``(v_prev, w_prev)``."""
    v = clamp(v, limits.max_linear_velocity)
    w = clamp(w, limits.max_angular_velocity)
    dv = limits.max_linear_acceleration * dt
    dw = limits.max_angular_acceleration * dt
    return (v_prev + clamp(v - v_prev, dv), w_prev + clamp(w - w_prev, dw))


def integrate(pose, v, w, dt):
    """Exact unicycle motion: the pose after ``dt`` [s] at constant ``(v, w)``."""
    x, y, th = pose
    if abs(w) < 1e-9:
        return (x + v * dt * math.cos(th), y + v * dt * math.sin(th), th)
    th2 = th + w * dt
    r = v / w
    return (x + r * (math.sin(th2) - math.sin(th)), y - r * (math.cos(th2) - math.cos(th)),
            wrap_angle(th2))


class DiffDrive:
    """A base that follows velocity commands within :class:`BaseLimits`."""

    def __init__(self, pose=(0.0, 0.0, 0.0), limits=BaseLimits()):
        self.pose = tuple(float(p) for p in pose)
        self.limits = limits
        self.v = 0.0
        self.w = 0.0

    def step(self, v_cmd, w_cmd, dt):
        """Advance ``dt`` [s] towards the command; returns the new pose (also ``self.pose``)."""
        v, w = limit_velocity(v_cmd, w_cmd, self.v, self.w, dt, self.limits)
        # trapezoid rule on the speeds keeps the integrated distance right under acceleration
        self.pose = integrate(self.pose, 0.5 * (v + self.v), 0.5 * (w + self.w), dt)
        self.v, self.w = v, w
        return self.pose

    def stop(self):
        """Zero the speeds at once (what a bumper does)."""
        self.v = self.w = 0.0
