"""Centre estimates of one cluster of points (map frame, metres).

A laser sees less than half of a cylinder, so the centroid of its points lies between the true
centre and the sensor (by about ``r·(1 - 2/π)`` for a half circle): :func:`circle_fit` fits the
circle itself, geometric least squares (scipy.optimize) started from an algebraic fit.
"""
import numpy as np
from scipy.optimize import least_squares


def algebraic_circle(points):
    """Kåsa's algebraic circle fit: ``(cx, cy, r)`` minimising ``Σ (|p-c|² - r²)²``."""
    p = np.asarray(points, dtype=float)
    A = np.column_stack((2 * p[:, 0], 2 * p[:, 1], np.ones(len(p))))
    b = (p ** 2).sum(axis=1)
    (cx, cy, c), *_ = np.linalg.lstsq(A, b, rcond=None)
    return cx, cy, float(np.sqrt(max(c + cx * cx + cy * cy, 0.0)))


def circle_fit(points, radius=0.0, sensor=None):
    """Geometric least-squares circle ``(cx, cy, r, rms)`` through ``(N, 2)`` points (N ≥ 3).

    ``radius`` > 0 fixes the radius and fits the centre only. ``sensor`` (the laser's position in
    the same frame) breaks the tie of a fixed-radius fit: the centre lies beyond the points, away
    from the sensor. ``rms`` is the root-mean-square of the radial residuals [m].
    """
    p = np.asarray(points, dtype=float)
    cx, cy, r0 = algebraic_circle(p)
    if radius > 0:
        if sensor is not None:
            # start on the far side of the arc: its middle point pushed back by the radius
            mid = p.mean(axis=0)
            away = mid - np.asarray(sensor, dtype=float)
            away /= max(np.linalg.norm(away), 1e-9)
            cx, cy = mid + away * radius * 0.8
        sol = least_squares(lambda c: np.hypot(p[:, 0] - c[0], p[:, 1] - c[1]) - radius,
                            (cx, cy), method='lm')
        cx, cy = sol.x
        r = radius
    else:
        sol = least_squares(lambda c: np.hypot(p[:, 0] - c[0], p[:, 1] - c[1]) - c[2],
                            (cx, cy, r0), method='lm')
        cx, cy, r = sol.x
    rms = float(np.sqrt(np.mean((np.hypot(p[:, 0] - cx, p[:, 1] - cy) - abs(r)) ** 2)))
    return float(cx), float(cy), float(abs(r)), rms


def centroid(points):
    """The cluster's centroid ``(cx, cy)`` (biased toward the sensor; the classic estimate)."""
    c = np.asarray(points, dtype=float).mean(axis=0)
    return float(c[0]), float(c[1])
