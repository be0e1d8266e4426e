"""Planar (SE(2)) geometry helpers shared by every part of the package.

Poses are ``(x, y, yaw)`` in metres and radians; point sets are ``(N, 2)`` arrays in metres.
A pose ``p`` expressed in frame ``A`` maps points from the pose's own frame into ``A``.
"""
import math

import numpy as np


def wrap_angle(a):
    """Wrap an angle (or an array of angles) [rad] into [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi if np.ndim(a) else \
        (a + math.pi) % (2.0 * math.pi) - math.pi


def yaw_to_quaternion(yaw):
    """Quaternion ``(x, y, z, w)`` of a rotation by ``yaw`` [rad] about z."""
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def quaternion_to_yaw(x, y, z, w):
    """Yaw [rad] of a quaternion (rotation about z; roll and pitch are ignored)."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def compose(a, b):
    """Pose ``a ∘ b``: ``b`` (given in ``a``'s frame) expressed in ``a``'s parent frame."""
    ax, ay, ath = a
    bx, by, bth = b
    c, s = math.cos(ath), math.sin(ath)
    return (ax + c * bx - s * by, ay + s * bx + c * by, wrap_angle(ath + bth))


def inverse(a):
    """Inverse of pose ``a``: the parent frame's pose expressed in ``a``'s frame."""
    ax, ay, ath = a
    c, s = math.cos(ath), math.sin(ath)
    return (-c * ax - s * ay, s * ax - c * ay, wrap_angle(-ath))


def transform_points(pose, points):
    """Map ``(N, 2)`` points from the frame of ``pose`` into its parent frame."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    x, y, th = pose
    c, s = math.cos(th), math.sin(th)
    return np.column_stack((x + c * pts[:, 0] - s * pts[:, 1], y + s * pts[:, 0] + c * pts[:, 1]))


def oriented_box_corners(cx, cy, length, width, yaw):
    """The 4 corners (counter-clockwise, ``(4, 2)``) of a ``length`` × ``width`` box [m]
    centred at ``(cx, cy)`` whose length runs along ``yaw`` [rad]."""
    hl, hw = length / 2.0, width / 2.0
    local = np.array([[hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw]])
    return transform_points((cx, cy, yaw), local)
