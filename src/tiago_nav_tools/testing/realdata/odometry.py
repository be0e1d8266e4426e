"""Odometry synthesised from a reference trajectory, and the kidnap splice (pure numpy).

The corrected logs hold no raw odometry, so the benchmarks make one from the reference's steps,
as a wheel encoder would err: each step ``inverse(p[k-1]) ∘ p[k]`` (in the robot's frame) has its
translation scaled by ``1 + N(0, scale_sigma)`` and its rotation perturbed by ``N(0, 1) ×
(turn_fraction × |turn| + per_metre × distance)``, and the noisy steps are composed from
``(0, 0, 0)`` (odom's origin is the robot's start, REP 105), so the drift accumulates. Defaults:
2 % scale, 2 % of the turn plus 0.5° per metre driven.
"""
import math

import numpy as np

from tiago_nav_tools.testing.realdata.carmen import wrap

SCALE_SIGMA = 0.02
TURN_FRACTION = 0.02
PER_METRE = math.radians(0.5)


def relative(a, b):
    """``(N, 3)`` poses of ``b[i]`` in the frame of ``a[i]`` (``inverse(a) ∘ b``)."""
    a, b = np.atleast_2d(a), np.atleast_2d(b)
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    return np.column_stack((c * dx + s * dy, -s * dx + c * dy, wrap(b[:, 2] - a[:, 2])))


def compose(a, b):
    """``(N, 3)`` poses ``a[i] ∘ b[i]`` (``b`` given in ``a``'s frame); ``a`` or ``b`` may be one pose."""
    a, b = np.atleast_2d(a).astype(float), np.atleast_2d(b).astype(float)
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    return np.column_stack((a[:, 0] + c * b[:, 0] - s * b[:, 1],
                            a[:, 1] + s * b[:, 0] + c * b[:, 1], wrap(a[:, 2] + b[:, 2])))


def integrate(steps):
    """``(N + 1, 3)`` poses from ``(0, 0, 0)`` composing the ``(N, 3)`` relative ``steps`` in turn."""
    out = np.zeros((len(steps) + 1, 3))
    for k, step in enumerate(steps):
        out[k + 1] = compose(out[k], step)[0]
    return out


def noisy_steps(steps, rng, scale_sigma=SCALE_SIGMA, turn_fraction=TURN_FRACTION,
                per_metre=PER_METRE):
    """The ``(N, 3)`` relative ``steps`` [m, m, rad] as the odometry reports them: translation
    × ``1 + N(0, scale_sigma)``, rotation + ``N(0, 1) × (turn_fraction × |turn| + per_metre
    [rad/m] × distance)``; ``rng`` a numpy Generator."""
    steps = np.asarray(steps, dtype=float).reshape(-1, 3)
    n = len(steps)
    scale = 1.0 + scale_sigma * rng.standard_normal(n)
    dist = np.hypot(steps[:, 0], steps[:, 1])
    turn_sigma = turn_fraction * np.abs(steps[:, 2]) + per_metre * dist
    out = steps.copy()
    out[:, :2] *= scale[:, None]
    out[:, 2] = wrap(steps[:, 2] + turn_sigma * rng.standard_normal(n))
    return out


def synthesise(poses, seed, scale_sigma=SCALE_SIGMA, turn_fraction=TURN_FRACTION,
               per_metre=PER_METRE, still=()):
    """``(N, 3)`` odometry poses [m, m, rad] in odom for the ``(N, 3)`` reference ``poses``,
    ``[0] = (0, 0, 0)``, from the reference's steps made noisy (:func:`noisy_steps`, a numpy
    Generator seeded with ``seed``). ``still``: indices ``k`` whose step into ``k`` the odometry
    does not see (a kidnap: it reports no motion there)."""
    poses = np.asarray(poses, dtype=float)
    steps = relative(poses[:-1], poses[1:])
    noisy = noisy_steps(steps, np.random.default_rng(seed), scale_sigma, turn_fraction, per_metre)
    for k in still:
        noisy[k - 1] = 0.0
    return integrate(noisy)


def dead_reckoning(start, odom):
    """``(N, 3)`` map poses the odometry alone gives from ``start`` (the pose at ``odom[0]``)."""
    odom = np.asarray(odom, dtype=float)
    return compose(np.asarray(start, dtype=float), relative(odom[:1], odom))


def kidnap_index(poses, at, distance=3.0):
    """The first index ``j > at`` whose reference position lies at least ``distance`` [m] from
    scan ``at``'s (ValueError if none): dropping the scans between ``at`` and ``j`` carries the
    robot ``distance`` away in one step."""
    poses = np.asarray(poses, dtype=float)
    d = np.hypot(*(poses[at + 1:, :2] - poses[at, :2]).T)
    far = np.nonzero(d >= distance)[0]
    if not len(far):
        raise ValueError('no scan after %d lies %g m from it' % (at, distance))
    return at + 1 + int(far[0])


def offset_pose(pose, distance, yaw_deg):
    """``pose`` moved ``distance`` [m] to its left (perpendicular to its heading) and turned by
    ``yaw_deg`` [deg]: a start that far off."""
    x, y, th = pose
    return (x - distance * math.sin(th), y + distance * math.cos(th),
            float(wrap(th + math.radians(yaw_deg))))
