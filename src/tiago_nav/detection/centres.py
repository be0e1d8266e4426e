"""Centre estimates of one cluster of points (map frame, metres).

A laser sees less than half of a cylinder, so the centroid of its points lies between the true
centre and the sensor (by about ``r·(1 - 2/π)`` for a half circle): :func:`circle_fit` fits the
circle itself, geometric least squares (scipy.optimize) started from an algebraic fit.
"""
import math

import numpy as np
from scipy.optimize import leastsq


def algebraic_circle(points):
    """Kåsa's algebraic circle fit: ``(cx, cy, r)`` minimising ``Σ (|p-c|² - r²)²``."""
    p = np.asarray(points, dtype=float)
    A = np.column_stack((2 * p[:, 0], 2 * p[:, 1], np.ones(len(p))))
    b = (p ** 2).sum(axis=1)
    (cx, cy, c), *_ = np.linalg.lstsq(A, b, rcond=None)
    return cx, cy, float(np.sqrt(max(c + cx * cx + cy * cy, 0.0)))


TOL = 1e-8             # relative tolerances of the fit (least_squares' defaults)
PASSING_WEIGHT = 3.0   # a passing beam counts as a point three times as precise


def circle_fit(points, radius=0.0, sensor=None, passing=None, margin=0.0, radius_prior=None,
               noise=0.01):
    """Geometric least-squares circle ``(cx, cy, r, rms)`` through ``(N, 2)`` points (N ≥ 3).

    ``radius`` > 0 fixes the radius and fits the centre only. ``sensor`` (the laser's position in
    the same frame) breaks the tie of a fixed-radius fit: the centre lies beyond the points, away
    from the sensor. ``passing`` (``(K, 2)`` unit directions from ``sensor``, needs ``sensor``):
    beams beside the cluster that were measured to go past it; a circle they would have hit is
    penalised when it reaches more than ``margin`` [m] into them (a beam's width: one missing
    return at the edge of an obstacle must not pull the fit), which keeps a short, noisy arc
    from growing a too-large circle. Levenberg-Marquardt (MINPACK's lmder, through
    scipy.optimize.leastsq: the same solver as ``least_squares(method='lm')`` at half the cost
    per call, most of which is call overhead on a few dozen points) with the analytic Jacobian,
    started from the algebraic fit.
    ``radius_prior`` ``(r0, std)`` [m] (free radius only): what else is known of the radius,
    one more residual ``(r - r0) * noise / std`` (``noise`` [m]: the points' assumed std), so
    the radius is the compromise of the arc's and the prior's, each by its precision.
    ``rms`` is the root-mean-square of the radial residuals [m].
    """
    p = np.asarray(points, dtype=float)
    px, py = p[:, 0], p[:, 1]
    m = len(p)
    k = 0
    if passing is not None and len(passing) and sensor is not None:
        sx, sy = float(sensor[0]), float(sensor[1])
        rays = np.asarray(passing, dtype=float).reshape(-1, 2)
        ux, uy = rays[:, 0].copy(), rays[:, 1].copy()
        k = len(rays)
    fixed = radius > 0
    w = PASSING_WEIGHT
    q = 0 if fixed or radius_prior is None else 1
    if q:
        r_prior, w_prior = float(radius_prior[0]), noise / max(float(radius_prior[1]), 1e-9)

    # fun and jac are written out in scalar-per-array numpy (no stacking helpers): with a few
    # dozen points, the call overhead of each numpy operation is most of a fit's cost
    def fun(x):
        r = radius if fixed else x[2]
        dx, dy = px - x[0], py - x[1]
        out = np.empty(m + k + q)
        out[:m] = np.sqrt(dx * dx + dy * dy) - r
        if q:
            out[m + k] = w_prior * (r - r_prior)
        if k:
            # how far the circle reaches into each passing ray beyond margin (0 where the ray
            # passes outside it, or the circle lies behind the sensor)
            ex, ey = x[0] - sx, x[1] - sy
            reach = r - np.abs(ux * ey - uy * ex) - margin
            out[m:m + k] = w * np.where((ux * ex + uy * ey > 0) & (reach > 0), reach, 0.0)
        return out

    def jac(x):
        r = radius if fixed else x[2]
        dx, dy = px - x[0], py - x[1]
        n = np.maximum(np.sqrt(dx * dx + dy * dy), 1e-12)
        J = np.zeros((m + k + q, 2 if fixed else 3))
        J[:m, 0] = -dx / n
        J[:m, 1] = -dy / n
        if not fixed:
            J[:m, 2] = -1.0
        if k:
            ex, ey = x[0] - sx, x[1] - sy
            cross = ux * ey - uy * ex
            active = (ux * ex + uy * ey > 0) & (r - np.abs(cross) - margin > 0)
            sg = np.sign(cross) * active * w
            # d(r - |cross|)/dc = -sign(cross) * (-u_y, u_x); d/dr = 1
            J[m:m + k, 0] = sg * uy
            J[m:m + k, 1] = -sg * ux
            if not fixed:
                J[m:m + k, 2] = active * w
        if q:
            J[m + k, 2] = w_prior
        return J

    cx, cy, r0 = algebraic_circle(p)
    if fixed:
        if sensor is not None:
            # start on the far side of the arc: its middle point pushed back by the radius
            mid = p.mean(axis=0)
            away = mid - np.asarray(sensor, dtype=float)
            away /= max(np.linalg.norm(away), 1e-9)
            cx, cy = mid + away * radius * 0.8
        x, _ = leastsq(fun, (cx, cy), Dfun=jac, xtol=TOL, ftol=TOL)
        (cx, cy), r = x, radius
    else:
        x, _ = leastsq(fun, (cx, cy, r0), Dfun=jac, xtol=TOL, ftol=TOL)
        cx, cy, r = x
    rms = float(np.sqrt(np.mean((np.hypot(p[:, 0] - cx, p[:, 1] - cy) - abs(r)) ** 2)))
    return float(cx), float(cy), float(abs(r)), rms


def radius_std(points, cx, cy, r, noise_floor=0.005):
    """Standard error [m] of the fitted radius of the circle ``(cx, cy, r)`` through ``(N, 2)``
    points, from the fit's Jacobian and its residuals (at least ``noise_floor`` [m] per point).
    Large on a short arc, where the radius and the centre's range trade off: the circle is then
    ill-conditioned. ``inf`` when the problem is singular."""
    p = np.asarray(points, dtype=float)
    d = p - (cx, cy)
    n = np.hypot(d[:, 0], d[:, 1])
    if len(p) < 4 or np.any(n < 1e-9):
        return math.inf
    u = d / n[:, None]                       # the Jacobian is [-u, -1]: JᵀJ = [[A, b], [bᵀ, N]]
    sigma = max(float(np.sqrt(np.mean((n - r) ** 2))), noise_floor)
    a11, a12, a22 = float(u[:, 0] @ u[:, 0]), float(u[:, 0] @ u[:, 1]), float(u[:, 1] @ u[:, 1])
    b1, b2 = float(u[:, 0].sum()), float(u[:, 1].sum())
    det = a11 * a22 - a12 * a12
    if det <= 1e-12:
        return math.inf
    # (JᵀJ)⁻¹ at (r, r) is the inverse of the Schur complement N - bᵀA⁻¹b
    schur = len(p) - (a22 * b1 * b1 - 2 * a12 * b1 * b2 + a11 * b2 * b2) / det
    if schur <= 1e-12:
        return math.inf
    return sigma / math.sqrt(schur)


MIN_SIGMA = 0.001     # [m] least point noise assumed by circle_covariance (1 mm, the range
                      # resolution): a noise-free arc still has finite precision
MAX_RHO = 0.9         # residual autocorrelation used at most (an inflation of 19)


def correlation_inflation(residuals):
    """How much correlated residuals widen a least-squares covariance: ``(1 + ρ) / (1 - ρ)``,
    ``ρ`` the lag-1 autocorrelation of ``residuals`` [m] (in scan order, neighbouring beams),
    clipped to ``[0, MAX_RHO]``. Residuals that run in long same-signed stretches (a mixed
    pixel's neighbours, a borrowed radius that does not fit, the median of scans at rest) carry
    fewer independent points than their number: for an AR(1) sequence the mean of ``N`` of them
    has the variance of ``N (1 - ρ) / (1 + ρ)`` independent ones. 1 for independent residuals
    (their estimated ``ρ`` is about ``-1/N``, clipped to 0) and for fewer than 3."""
    r = np.asarray(residuals, dtype=float)
    r = r - r.mean() if len(r) else r
    den = float(r @ r)
    if len(r) < 3 or den <= 0:
        return 1.0
    rho = min(max(float(r[1:] @ r[:-1]) / den, 0.0), MAX_RHO)
    return (1.0 + rho) / (1.0 - rho)


def circle_covariance(points, cx, cy, r, fixed=False, radius_prior=None):
    """Covariance ``(3, 3)`` of the circle ``(cx, cy, r)`` [m², map frame] fitted to ``(N, 2)``
    points, from the fit's Jacobian and its residuals: ``k s² (JᵀJ)⁻¹``, one row of ``J`` per
    point (``[-u, -1]``, ``u`` the unit vector from the centre to the point), ``s²`` the points'
    residual variance ``Σ res² / (N - p)`` (``p`` fitted parameters; at least
    :data:`MIN_SIGMA`²), ``k`` :func:`correlation_inflation` of the residuals in the points'
    order (the points must be in scan order): correlated residuals count as fewer points. ``radius_prior`` ``(r0, std)`` [m]: the radius was also pulled toward
    ``r0`` with that std (:func:`circle_fit`), which adds ``1/std²`` to its information.
    ``fixed``: the radius was given exactly (its row and column are 0).

    The passing beams of :func:`circle_fit` are bounds, not measurements: they add nothing
    here, so a circle they hold in place is reported as no surer than its points make it.
    A short arc leaves the radius and the centre's range trading off: their variances are then
    large; ``inf`` where the problem is singular (no more points than parameters, a
    degenerate arc)."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    d = p - (cx, cy)
    n = np.hypot(d[:, 0], d[:, 1])
    npar = 2 if fixed else 3
    inf = np.full((3, 3), np.inf)
    if len(p) <= npar or np.any(n < 1e-9):
        return inf
    u = d / n[:, None]
    J = np.column_stack((-u, -np.ones(len(p))))
    dof = len(p) - npar
    s2 = max(float(np.sum((n - r) ** 2)) / dof, MIN_SIGMA ** 2) * correlation_inflation(n - r)
    info = J.T @ J / s2
    if fixed:
        info = info[:2, :2]
    elif radius_prior is not None:
        info[2, 2] += 1.0 / max(float(radius_prior[1]), 1e-9) ** 2
    try:
        if np.linalg.cond(info) > 1e12:
            return inf
        cov = np.linalg.inv(info)
    except np.linalg.LinAlgError:
        return inf
    if fixed:
        out = np.zeros((3, 3))
        out[:2, :2] = cov
        return out
    return cov


def centroid(points):
    """The cluster's centroid ``(cx, cy)`` (biased toward the sensor; the classic estimate)."""
    c = np.asarray(points, dtype=float).mean(axis=0)
    return float(c[0]), float(c[1])
