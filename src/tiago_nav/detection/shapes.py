"""Shapes other than circles: boxes (rectangles), furniture legs and people's legs.

Everything here works on points in one plane frame (the map's for the service, the laser's for
map-free data), in scan order, with the sensor's position in that frame; lengths in metres,
angles in radians. No ROS, no map: :mod:`tiago_nav.detection.pipeline` calls it on the points the
map does not explain, and the real-data benchmark on whole scans.

The constants are the physics of what is measured, not fits to any recording:

* a person's leg at a laser's height (0.1-0.4 m above the floor) is a calf or an ankle in a
  trouser leg: 5-25 cm across, :data:`PERSON_LEG_RADIUS` 0.025-0.125 m (an ankle 6-7 cm, a
  calf 8-20 cm, a wide trouser leg up to 25 cm); its points span at least 5 cm even without
  the beam spacing (the least radius its arc allows: far away a beam spacing widens a table's
  leg of 1-2.5 cm radius as much); a person's two legs stand
  up to a stride apart: centre to centre at most :data:`PERSON_LEG_SPACING` 0.6 m (a walker's
  legs swing 0.2 m ahead and behind and stand 0.1 m either side of its line: 0.45 m); two
  legs side by side within the points' join distance are one run up to
  :data:`PERSON_PAIR_WIDTH` 0.5 m wide (two calves and the gap between them) with a notch
  between two fronts (:func:`split_pair`);
* a table's or chair's leg is a tube or a bar of at most :data:`FURNITURE_LEG_RADIUS` 0.04 m;
  a chair's legs are 0.3-0.6 m apart, a table's 0.4-2.0 m (:data:`FURNITURE_SIDE`), at the
  corners of a rectangle (right angles within :data:`RIGHT_ANGLE_TOL`: the legs' centres are
  known to 1-2 cm);
* a box's face is straight: a rectangle (two perpendicular faces) fits its points to within the
  range noise, a circle does not.
"""
import math
from dataclasses import dataclass, field

import numpy as np

from tiago_nav.detection.centres import circle_fit, correlation_inflation

PERSON_LEG_RADIUS = (0.025, 0.125)  # [m] an ankle or a calf, bare or in a trouser leg
PERSON_PAIR_WIDTH = 0.5            # [m] two legs side by side seen as one run: at most this wide
MIN_PERSON_LEG_POINTS = 3          # a person's leg: seen by this many beams or more
PERSON_LEG_SPACING = 0.6           # [m] two legs of one person: centres at most this apart
FURNITURE_LEG_RADIUS = 0.04        # [m] a table's or chair's leg is at most this thick
FURNITURE_SIDE = (0.25, 2.2)       # [m] distance between neighbouring legs of one piece
RIGHT_ANGLE_TOL = math.radians(4.0)   # legs at the corners of a rectangle: 90 deg within this
                                      # (leg centres within 1-2 cm over sides of 0.25 m or more)
SIDE_TOL = 0.06                    # [m] opposite sides of a leg rectangle agree within this
MIN_FACE_POINTS = 4                # a face of a box: at least this many points ...
MIN_FACE_LENGTH = 0.08             # [m] ... spanning at least this
MAX_DEPTH = 1.0                    # [m] a box seen on one face: its depth is within (0, this]
LEG_MAX_WIDTH = 0.25               # [m] a cluster narrower than this may be one leg
FREE_MARGIN = 0.15                 # [m] a beam this far behind a point went past it
NEARER = 0.05                      # [m] a beam beside a run this much nearer hit what hides it
FACE_INCIDENCE = math.radians(10.0)   # a box's face seen at this angle to the beams or more
MIN_GRAZE = math.sin(math.radians(5.0))  # the spacing of hits along a face is taken at this
                                   # angle between beam and face at least
INSIDE_HITS = 2                    # lone hits inside a leg rectangle that rule it out: one may
                                   # be a mixed pixel (a beam grazing a thin leg in front returns
                                   # a range anywhere behind it, in the median of the scans at
                                   # rest too), two are other legs


@dataclass
class Shape:
    """One object that is not a circle: ``shape`` ``'rectangle'``, ``'legs'`` or ``'unknown'``;
    ``center`` ``(x, y)`` [m]; ``covariance`` ``(2, 2)`` of the centre [m²] (the fit's: where the
    points put it relative to the sensor); ``extent`` ``(length, width)`` [m] along
    ``orientation`` [rad] and across it (NaN: not observed); ``orientation_std`` [rad],
    ``extent_std`` [m]; ``center_fixed``: False when the points bound the centre without fixing
    it (a box seen on one face, part of a leg group), the covariance then spans what is
    possible; ``note``: what was seen; ``legs``: ``(K, 2)`` leg centres [m] of a ``legs`` object;
    ``points``: the points it was fitted to."""
    shape: str
    center: tuple
    covariance: np.ndarray
    extent: tuple = (math.nan, math.nan)
    orientation: float = math.nan
    orientation_std: float = math.nan
    extent_std: tuple = (math.nan, math.nan)
    center_fixed: bool = True
    note: str = ''
    legs: np.ndarray = field(default=None, repr=False)
    points: np.ndarray = field(default=None, repr=False)
    leg_radius: float = math.nan
    kind: str = ''              # a legs object's: 'person' or 'furniture'
    used: list = field(default_factory=list)   # indices of describe()'s extra legs in it
    index: np.ndarray = field(default=None, repr=False)   # a rectangle's points in describe()


# --- segments ------------------------------------------------------------------------------
def segments(points, beams, sensor, increment, gap=0.08, ranges=None, incidence=0.0,
             noise=0.01):
    """Split ``(N, 2)`` points in scan order (beam indices ``beams``) into runs of neighbours:
    consecutive points belong together when within ``gap`` [m] or three beam spacings at their
    range (``increment`` [rad]), plus one spacing per beam between them that has no hit
    (``ranges``: the scan's, NaN or inf where it says nothing; None: every beam between them
    counts). ``incidence`` [rad] > 0: also join points a surface seen at that angle to the
    beams or more would put apart (an oblique face), ``noise`` [m] the range noise. Returns a
    list of index arrays."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(p) == 0:
        return []
    b = np.asarray(beams, dtype=int)
    rng = np.hypot(p[:, 0] - sensor[0], p[:, 1] - sensor[1])
    step = np.hypot(*np.diff(p, axis=0).T)
    if ranges is None:
        skipped = np.maximum(np.diff(b) - 1, 0)
    else:
        none = np.concatenate(([0], np.cumsum(~np.isfinite(np.asarray(ranges, dtype=float)))))
        skipped = none[b[1:]] - none[np.minimum(b[:-1] + 1, b[1:])]
    allow = np.maximum(gap, (3.0 + skipped) * np.maximum(rng[1:], rng[:-1]) * increment)
    if incidence:
        # the adaptive breakpoint: a surface seen at ``incidence`` [rad] to the beam puts
        # neighbouring beams' points r sin(dphi) / sin(incidence - dphi) apart, plus the noise
        dphi = (1.0 + skipped) * increment
        allow = np.maximum(allow, np.minimum(rng[1:], rng[:-1]) * np.sin(dphi)
                           / np.sin(incidence - dphi) + 3.0 * noise)
    cut = np.flatnonzero(step > allow) + 1
    return [np.arange(a, e) for a, e in zip(np.concatenate(([0], cut)),
                                            np.concatenate((cut, [len(p)])))]


# --- rectangles (L-shape fit) -----------------------------------------------------------------
def _l_cost(p, theta, sensor):
    """The L-shape criterion at orientation ``theta``: each point's squared distance to the
    nearer of the two edges facing the sensor (each edge at the mean of the points nearer it).
    Returns ``(cost, a, b, on_a)``: edges ``c1 = a`` and ``c2 = b`` in the axes
    ``e1 = (cos, sin)``, ``e2 = (-sin, cos)``, and the mask of points on edge ``a``."""
    c, s = math.cos(theta), math.sin(theta)
    c1 = p[:, 0] * c + p[:, 1] * s
    c2 = -p[:, 0] * s + p[:, 1] * c
    s1 = sensor[0] * c + sensor[1] * s
    s2 = -sensor[0] * s + sensor[1] * c
    a = c1.min() if s1 < c1.mean() else c1.max()       # the edges that face the sensor
    b = c2.min() if s2 < c2.mean() else c2.max()
    on_a = np.abs(c1 - a) < np.abs(c2 - b)
    for _ in range(2):                                  # edges at their points' means
        if np.any(on_a):
            a = float(c1[on_a].mean())
        if np.any(~on_a):
            b = float(c2[~on_a].mean())
        on_a = np.abs(c1 - a) < np.abs(c2 - b)
    d = np.where(on_a, c1 - a, c2 - b)
    return float(d @ d), a, b, on_a


def _l_costs(p, thetas, sensor):
    """:func:`_l_cost`'s cost at each of the orientations ``thetas`` [rad] at once."""
    c, s = np.cos(thetas), np.sin(thetas)
    c1 = np.outer(p[:, 0], c) + np.outer(p[:, 1], s)
    c2 = np.outer(p[:, 1], c) - np.outer(p[:, 0], s)
    s1 = sensor[0] * c + sensor[1] * s
    s2 = sensor[1] * c - sensor[0] * s
    a = np.where(s1 < c1.mean(axis=0), c1.min(axis=0), c1.max(axis=0))
    b = np.where(s2 < c2.mean(axis=0), c2.min(axis=0), c2.max(axis=0))
    on_a = np.abs(c1 - a) < np.abs(c2 - b)
    for _ in range(2):
        na, nb = on_a.sum(axis=0), (~on_a).sum(axis=0)
        a = np.where(na > 0, (c1 * on_a).sum(axis=0) / np.maximum(na, 1), a)
        b = np.where(nb > 0, (c2 * ~on_a).sum(axis=0) / np.maximum(nb, 1), b)
        on_a = np.abs(c1 - a) < np.abs(c2 - b)
    d = np.where(on_a, c1 - a, c2 - b)
    return (d * d).sum(axis=0)


def fit_rectangle(points, sensor, noise=0.01, end_seen=None, max_depth=MAX_DEPTH,
                  increment=None):
    """A rectangle through ``(N, 2)`` points in scan order seen from ``sensor``: the L-shape
    fit (the orientation in [0, 90°) minimising :func:`_l_cost`, a 1° search refined to
    0.02°). Returns ``(Shape, rms)`` [m], or None with fewer than ``MIN_FACE_POINTS`` points.

    Two faces (each at least :data:`MIN_FACE_POINTS` points over :data:`MIN_FACE_LENGTH`): the
    corner is where their lines meet, each face's length is from the corner to its farthest
    point plus half a beam spacing (the true edge lies between that point and the next beam),
    the centre half of each length in from the corner. A face's end point is placed on its
    face's line where its beam meets it, weighed with the point's own place by their
    variances (a laser errs in range: where the beams graze the face, a range error, or a
    footprint straddling the step to the next beam's hit, moves the point along the face).
    One face: the centre lies behind its middle by half the unseen depth, anywhere in (0,
    ``max_depth`` / 2]: reported at the middle of that interval with its uniform variance,
    ``center_fixed`` False.
    ``end_seen(point_index) -> int`` says whether the beam just past a face's outer end went
    past it (a silhouette edge), and how many beams out the first one that said so is
    (:meth:`ScanView.end_seen`; the edge lies within that many beam spacings): if none did
    (0: something nearer hides it, or the scan ends there) the face may go on, and the centre
    along it is not fixed either. None: every end is seen by the next beam. ``increment``
    [rad]: the beams' angular step; with it, the spacing at a face's end is the distance
    between neighbouring beams' hits there (range × step / the sine of the angle between beam
    and face: it grows where the beams graze the face), otherwise the median spacing of the
    face's points. ``noise`` [m]: the least residual std assumed."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    n = len(p)
    if n < MIN_FACE_POINTS:
        return None
    coarse = np.radians(np.arange(0.0, 90.0, 1.0))
    t0 = float(coarse[int(np.argmin(_l_costs(p, coarse, sensor)))])
    fine = t0 + np.radians(np.arange(-1.0, 1.0001, 0.02))
    best = float(fine[int(np.argmin(_l_costs(p, fine, sensor)))])
    cost, a, b, on_a = _l_cost(p, float(best), sensor)
    theta = float(best)
    e1 = np.array([math.cos(theta), math.sin(theta)])
    e2 = np.array([-math.sin(theta), math.cos(theta)])
    c1, c2 = p @ e1, p @ e2
    rms = math.sqrt(cost / n)
    sigma2 = max(cost / max(n - 3, 1), noise * noise)
    sensor = np.asarray(sensor, dtype=float)
    sgn1 = 1.0 if sensor @ e1 < a else -1.0            # the box lies away from the sensor
    sgn2 = 1.0 if sensor @ e2 < b else -1.0
    idx = np.arange(n)

    def face(mask, along, at):
        """A face's points: how many, their span, the index of the outer end, spacing."""
        k = int(np.count_nonzero(mask))
        if k == 0:
            return 0, 0.0, None, 0.0
        u = along[mask]
        span = float(u.max() - u.min())
        order = np.sort(u)
        spacing = float(np.median(np.diff(order))) if k > 1 else 0.0
        return k, span, idx[mask], spacing

    ka, span_a, ia, sp_a = face(on_a, c2, a)
    kb, span_b, ib, sp_b = face(~on_a, c1, b)
    good_a = ka >= MIN_FACE_POINTS and span_a >= MIN_FACE_LENGTH
    good_b = kb >= MIN_FACE_POINTS and span_b >= MIN_FACE_LENGTH
    res = np.where(on_a, c1 - a, c2 - b)[np.argsort(idx)]
    k_inf = correlation_inflation(res)
    seen = end_seen if end_seen is not None else (lambda i: 1)
    pts = p                     # (all of them: the one-face branch below narrows ``p``)

    def spacing_at(r, sin):
        """[m] the step along a face between neighbouring beams' hits at range ``r`` [m],
        ``sin`` the sine of the angle between the beams and the face."""
        return r * abs(increment) / max(sin, MIN_GRAZE)

    def beyond(i, along, spacing):
        """[m] the stretch past the face's end point ``i`` (along unit ``along``) in which
        its edge lies: the beams out to the first that went past, a spacing each."""
        if increment is not None:
            v = pts[i] - sensor
            r = float(np.hypot(*v))
            spacing = spacing_at(r, abs(float(v[0] * along[1] - v[1] * along[0])) / max(r, 1e-9))
        return max(int(seen(i)), 1) * spacing

    def end_on_line(i, normal, at, axis, k_face):
        """Where face end point ``i`` lies along ``axis`` (unit) on its face's line (the
        points with ``p @ normal == at``), and the variance [m²] of that. A laser's error is
        in range, along the beam: the end is where the end beam meets the line (its error
        the line's offset's, over the sine of the angle between beam and face), or the
        point's own place along the face (its range error's share along the face: the noise
        and, where the beams graze the face, up to the step in range to the next beam's hit,
        which a beam's footprint straddles); the two weighed by their variances."""
        v = pts[i] - sensor
        r = float(np.hypot(*v))
        ray = v / max(r, 1e-9)
        sin, cos = abs(float(ray @ normal)), abs(float(ray @ axis))
        own = float(pts[i] @ axis)
        step = spacing_at(r, sin) * cos if increment is not None else 0.0
        var_own = (noise * noise + step * step / 3.0) * cos * cos
        if sin < MIN_GRAZE:
            return own, var_own
        met = float((sensor + (at - float(sensor @ normal)) / float(ray @ normal) * ray) @ axis)
        var_met = k_inf * sigma2 / k_face / (sin * sin)
        w = var_met / (var_met + var_own)
        return w * own + (1.0 - w) * met, var_own * var_met / (var_own + var_met)

    if good_a and good_b:
        # the corner, and each face from it to its farthest point (+ half the stretch past
        # it in which its edge lies)
        ua, ub = np.abs(c2[on_a] - b), np.abs(c1[~on_a] - a)
        end_a = int(ia[int(np.argmax(ua))])
        end_b = int(ib[int(np.argmax(ub))])
        wa, wb = beyond(end_a, e2, sp_a), beyond(end_b, e1, sp_b)
        at_a, var_ea = end_on_line(end_a, e1, a, e2, ka)
        at_b, var_eb = end_on_line(end_b, e2, b, e1, kb)
        la = abs(at_a - b) + 0.5 * wa
        lb = abs(at_b - a) + 0.5 * wb
        # in the axes (e1, e2): the box spans a .. a + sgn1 lb, b .. b + sgn2 la
        var1 = k_inf * sigma2 / ka + (wb ** 2 / 12.0 + var_eb) / 4.0
        var2 = k_inf * sigma2 / kb + (wa ** 2 / 12.0 + var_ea) / 4.0
        fixed, notes = True, []
        if not seen(end_b):
            var1 += (max_depth / 2.0) ** 2 / 12.0
            fixed = False
            notes.append('the face along %.0f deg may go on behind what hides its end'
                         % math.degrees(theta))
        if not seen(end_a):
            var2 += (max_depth / 2.0) ** 2 / 12.0
            fixed = False
            notes.append('the face along %.0f deg may go on behind what hides its end'
                         % math.degrees(theta + math.pi / 2))
        centre = (a + sgn1 * lb / 2.0) * e1 + (b + sgn2 * la / 2.0) * e2
        # the orientation from both faces' lines (a line of k points over span L: std
        # sigma / (L sqrt(k / 12)))
        info = sum(kk * ll * ll / 12.0 for kk, ll in ((ka, span_a), (kb, span_b)))
        ostd = math.sqrt(k_inf * sigma2 / info)
        cov = _axes_cov(e1, e2, var1 + (ostd * la / 2.0) ** 2, var2 + (ostd * lb / 2.0) ** 2)
        # length along the longer side
        if lb >= la:
            extent, orient, estd = (lb, la), theta, (wb / math.sqrt(12), wa / math.sqrt(12))
        else:
            extent, orient, estd = (la, lb), theta + math.pi / 2, (wa / math.sqrt(12),
                                                                  wb / math.sqrt(12))
        note = 'two faces seen' + ('; ' + '; '.join(notes) if notes else '')
        return Shape('rectangle', (float(centre[0]), float(centre[1])), cov, extent,
                     _half_turn(orient), ostd, estd, fixed, note, points=p), rms
    # one face: a straight segment, the line through the points of the L's longer face (the
    # other's few points, a face seen edge-on, do not fix its depth)
    if not (good_a or good_b):
        good_a = span_a >= span_b
    keep = on_a if good_a else ~on_a
    l_rms = rms
    p_all, p = p, p[keep]
    n = len(p)
    if n < MIN_FACE_POINTS:
        return None
    mean = p.mean(axis=0)
    u, sv, vt = np.linalg.svd(p - mean, full_matrices=False)
    d = vt[0]
    nrm = np.array([-d[1], d[0]])
    if nrm @ (mean - sensor) < 0:
        nrm = -nrm                                      # pointing away from the sensor
    along = (p - mean) @ d
    off = (p - mean) @ nrm
    rms = l_rms
    sigma2 = max(off @ off / max(n - 2, 1), noise * noise)
    order = np.sort(along)
    spacing = float(np.median(np.diff(order))) if n > 1 else 0.0
    where = np.flatnonzero(keep)
    lo, hi = int(where[np.argmin(along)]), int(where[np.argmax(along)])
    w_lo, w_hi = beyond(lo, d, spacing), beyond(hi, d, spacing)
    base = float(mean @ d)
    at_lo, var_lo = end_on_line(lo, nrm, float(mean @ nrm), d, n)
    at_hi, var_hi = end_on_line(hi, nrm, float(mean @ nrm), d, n)
    at_lo, at_hi = min(at_lo, at_hi) - base, max(at_lo, at_hi) - base
    length = at_hi - at_lo + 0.5 * (w_lo + w_hi)
    if length < MIN_FACE_LENGTH:
        return None
    var_along = (w_lo ** 2 + w_hi ** 2) / 48.0 + (var_lo + var_hi) / 4.0 + k_inf * sigma2 / n
    fixed_along = seen(lo) and seen(hi)
    notes = ['one face seen: the centre lies (0, %.2f] m behind its middle (the depth is not '
             'seen; its std covers it)' % (max_depth / 2.0)]
    centre_along = 0.5 * (at_hi + at_lo) + 0.25 * (w_hi - w_lo)
    if not fixed_along:
        var_along += (max_depth / 2.0) ** 2 / 12.0
        notes.append('an end is hidden: the face may go on')
    depth_half = max_depth / 4.0
    centre = mean + centre_along * d + depth_half * nrm
    var_depth = k_inf * sigma2 / n + (max_depth / 2.0) ** 2 / 12.0
    cov = _axes_cov(d, nrm, var_along, var_depth)
    ostd = math.sqrt(k_inf * sigma2 / max(n * length * length / 12.0, 1e-12))
    return Shape('rectangle', (float(centre[0]), float(centre[1])), cov, (length, math.nan),
                 _half_turn(math.atan2(d[1], d[0])), ostd,
                 (math.sqrt((w_lo ** 2 + w_hi ** 2) / 12.0), math.nan), False, '; '.join(notes),
                 points=p_all), rms


def _axes_cov(e1, e2, v1, v2):
    """The ``(2, 2)`` covariance with variances ``v1``, ``v2`` along unit vectors e1, e2."""
    return v1 * np.outer(e1, e1) + v2 * np.outer(e2, e2)


def _half_turn(a):
    """An orientation of a symmetric shape, in (-pi/2, pi/2]."""
    a = math.fmod(a, math.pi)
    if a <= -math.pi / 2:
        a += math.pi
    elif a > math.pi / 2:
        a -= math.pi
    return a


# --- legs ----------------------------------------------------------------------------------
@dataclass
class Leg:
    """One small round arc: ``center`` [m], ``radius`` [m] (estimated), its points' indices
    ``index`` into the caller's point array, ``var`` [m²] of the centre (isotropic)."""
    center: np.ndarray
    radius: float
    index: np.ndarray
    var: float
    low: float = None       # [m] the least radius the arc allows (its points' half span)
    round_cut: bool = False  # something nearer cuts its arc (:func:`arc_cut`) and a circle
                             # of the scan's common radius fits it: alone, it is the part of a
                             # cylinder like the others left in view, not a person's leg
    cut: bool = False       # something nearer cuts its arc (:func:`arc_cut`): its width is
                            # only the part left in view
    single: bool = False    # one beam hit it alone: a thin leg whose other beam an edge blended
                            # (a mixed pixel) or missed; it joins a table or chair, never alone

    @property
    def least(self):
        return self.radius if self.low is None else self.low


def leg(points, sensor, increment, noise=0.01, round_checked=False):
    """A small round arc (a leg) fitted to ``(N, 2)`` points: the radius from the arc's width
    (its points' span across the beam plus one beam spacing, halved), the centre from a circle
    fit with that radius (3 points or more) or one radius behind the nearest point along its
    beam. Returns ``(center, radius, var, least radius)``, or None when wider than :data:`LEG_MAX_WIDTH` or,
    with 5 points or more and a radius of 3 ``noise`` or more, flat (a line fits them better
    than that circle and than one of the widest leg's radius, ``LEG_MAX_WIDTH / 2``: a trouser
    leg is flatter than the calf in it)."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    sensor = np.asarray(sensor, dtype=float)
    mean = p.mean(axis=0)
    dist = float(np.hypot(*(mean - sensor)))
    if dist <= 0:
        return None
    ray = (mean - sensor) / dist
    across = (p - sensor) @ np.array([-ray[1], ray[0]])
    spacing = dist * increment
    width = float(across.max() - across.min()) + spacing
    if width > LEG_MAX_WIDTH:
        return None
    r = 0.5 * width
    near = int(np.argmin(np.hypot(*(p - sensor).T)))
    if len(p) >= 3:
        cx, cy, _, rms = circle_fit(p, r, sensor)
        centre = np.array([cx, cy])
        if len(p) >= 5 and not round_checked and r >= 3.0 * noise:
            # round, not flat: the circle of that radius fits at least as well as a line
            # (a flat end of something, seen square on, is as narrow as a leg; an arc whose
            # depth, about its radius, is within 3 noise stds cannot tell)
            q = p - p.mean(axis=0)
            line_rms = float(np.linalg.svd(q, compute_uv=False)[-1]) / math.sqrt(len(p))
            # cloth round a calf is flatter than the calf: flat when a line fits better than
            # the circle of its width and than the widest leg's (radius LEG_MAX_WIDTH / 2)
            flat_rms = circle_fit(p, LEG_MAX_WIDTH / 2.0, sensor)[3]
            if line_rms < min(rms, flat_rms):
                return None
        if not np.all(np.isfinite(centre)) or np.hypot(*(centre - p[near])) > 2 * r + 0.02:
            centre = p[near] + r * (p[near] - sensor) / np.hypot(*(p[near] - sensor))
    else:
        centre = p[near] + r * (p[near] - sensor) / np.hypot(*(p[near] - sensor))
    # the radius is known to about a beam spacing: the centre's range moves with it; and
    # the range noise does not average down over the arc's few points: the centre rests on
    # the nearest (or, fitted, on the front ones), and an edge beam's footprint straddles the
    # leg's edge (its range blended toward what lies behind)
    var = noise * noise + spacing * spacing / 12.0
    return centre, r, var, 0.5 * (width - spacing)


def veiled_leg_beams(beams, r, raw, veiled, noise=0.01):
    """Beams to give back to a thin leg: the veil filter (:func:`tiago_nav.scan.usable_ranges`)
    drops the first beam behind a nearer edge, and a table's or chair's leg seen by two beams
    just behind a nearer leg keeps one point, too few to be a leg. A beam ``j`` is given back
    when ``veiled[j]`` (the veil rule dropped it: ``r[j]`` NaN, ``raw[j]`` a hit), it lies
    beside a kept point ``k`` of ``beams`` (``r[k]`` finite) whose range ``raw[j]`` matches
    within :data:`FURNITURE_LEG_RADIUS` plus 3 ``noise`` [m], and ``k`` is alone (the beam on its
    other side is not at its range: a surface's edge point has its neighbours). ``r``, ``raw``
    [m] and ``veiled`` (bool) per beam of the scan. Returns the sorted beam indices."""
    r = np.asarray(r, dtype=float)
    raw = np.asarray(raw, dtype=float)
    n = len(r)
    tol = FURNITURE_LEG_RADIUS + 3.0 * noise
    out = set()
    for k in np.asarray(beams, dtype=int):
        if not np.isfinite(r[k]):
            continue
        for step in (-1, 1):
            j, o = k + step, k - step
            if not (0 <= j < n and veiled[j] and abs(raw[j] - r[k]) <= tol):
                continue
            if 0 <= o < n and np.isfinite(r[o]) and abs(r[o] - r[k]) <= tol:
                continue                        # k has a neighbour at its range: not alone
            out.add(int(j))
    return np.array(sorted(out), dtype=int)


def split_pair(points, sensor, increment, noise=0.01):
    """Two legs side by side seen as one run of ``(N, 2)`` points in scan order: at most
    :data:`PERSON_PAIR_WIDTH` wide, and the point farthest from ``sensor`` between the two ends
    (at least 3 points either side) lies behind the nearest point of each side by more than
    ``max(3 noise, 0.02)`` [m] (a notch between two fronts: one surface bulging toward the sensor
    has none), each side a leg (:func:`leg`, at least 3 points) of a person's width
    (:func:`person_sized`). Returns ``(left, right)``, each ``(index array, leg)`` with
    :func:`leg`'s tuple, or None."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    n = len(p)
    if n < 7 or float(np.hypot(*(p.max(axis=0) - p.min(axis=0)))) > PERSON_PAIR_WIDTH:
        return None
    rng = np.hypot(*(p - np.asarray(sensor, dtype=float)).T)
    j = 3 + int(np.argmax(rng[3:n - 3]))
    notch = float(rng[j]) - max(float(rng[:j].min()), float(rng[j + 1:].min()))
    if notch <= max(3.0 * noise, 0.02):
        return None
    out = []
    for idx in (np.arange(0, j), np.arange(j + 1, n)):
        found = leg(p[idx], sensor, increment, noise)
        if found is None or not person_sized(found[1], found[3]):
            return None
        out.append((idx, found))
    return tuple(out)


def person_sized(radius, least):
    """Whether a leg of ``radius`` [m] (from its arc's width) whose points alone allow
    ``least`` [m] is a person's: both within :data:`PERSON_LEG_RADIUS`."""
    return PERSON_LEG_RADIUS[0] <= least and radius <= PERSON_LEG_RADIUS[1]


def group_furniture(legs, free=None, hits=None):
    """Legs of tables and chairs: sets of 3 or 4 legs at the corners of one rectangle.

    ``legs``: list of :class:`Leg` (furniture-thin ones); ``hits``: ``(K, 2)`` points [m] a
    beam hit alone (a thin leg too far or too thin for two beams): a piece has nothing inside
    it at its legs' height but its legs, so legs with :data:`INSIDE_HITS` such hits inside
    their rectangle (and not at a corner) are none (two chairs' legs whose other legs one beam
    each hit between them); ``free(xy, radius, leg) -> bool``:
    whether the scan saw the disc of ``radius`` [m] about ``xy`` [m] empty of a leg of radius
    ``leg`` (:meth:`ScanView.free`), so that three legs whose fourth corner, within
    :data:`SIDE_TOL`, is seen empty of a leg like theirs are no table (None: never; a thin
    leg a beam or two hit, too few for a leg, or that slipped between beams, is still
    there); nor are legs with another leg inside their rectangle or on its sides (anywhere
    but at its corners). Candidates are corners ``j`` with two neighbours at
    :data:`FURNITURE_SIDE` distances and a right angle within :data:`RIGHT_ANGLE_TOL`; a fourth leg within :data:`SIDE_TOL` of the completed corner joins.
    No leg in two groups: of the sets of groups, the one that explains the most legs
    (:func:`_best_packing`). A leg one beam hit (:attr:`Leg.single`) completes a group of
    legs seen whole, one a group at most, and counts as a hit, not a leg, where it stands
    inside another group's rectangle. Returns ``(groups, rest)``: lists of index lists into
    ``legs``."""
    n = len(legs)
    c = np.array([l.center for l in legs]).reshape(-1, 2)
    single = np.array([l.single for l in legs], dtype=bool)
    cands = []
    for j in range(n):
        for i in range(n):
            for k in range(i + 1, n):
                if j in (i, k):
                    continue
                u, v = c[i] - c[j], c[k] - c[j]
                lu, lv = float(np.hypot(*u)), float(np.hypot(*v))
                if not (FURNITURE_SIDE[0] <= lu <= FURNITURE_SIDE[1]
                        and FURNITURE_SIDE[0] <= lv <= FURNITURE_SIDE[1]):
                    continue
                err = math.asin(min(1.0, abs(float(u @ v)) / (lu * lv)))   # off 90 deg
                if err > RIGHT_ANGLE_TOL:
                    continue
                fourth = c[i] + c[k] - c[j]
                dist4 = np.hypot(*(c - fourth).T)
                dist4[[i, j, k]] = np.inf
                m = int(np.argmin(dist4)) if n > 3 else -1
                group = [j, i, k]
                singles = int(np.count_nonzero(single[group]))
                if singles > 1:
                    continue                            # two legs of one beam each: too little
                if m >= 0 and dist4[m] <= SIDE_TOL and not (singles and single[m]):
                    group.append(m)
                elif free is not None and free(fourth, SIDE_TOL, min(l.radius for l in (
                        legs[i], legs[j], legs[k]))):
                    continue                            # the fourth corner is seen empty
                radii = [legs[g].radius for g in group]
                if max(radii) - min(radii) > 0.03:
                    continue                            # one piece has one kind of leg
                # no other leg stands inside it or on its sides, only at its corners (a table's
                # legs with a chair's, or two chairs' legs together, are no piece)
                e1, e2 = u / lu, v / lv
                inside = _inside(c, c[j], e1, e2, lu, lv, SIDE_TOL)
                inside[group] = False
                inside[single] = False                  # one beam's hits count as hits
                if np.any(inside) or (hits is not None and np.count_nonzero(_inside(
                        hits, c[j], e1, e2, lu, lv, 0.0)) >= INSIDE_HITS):
                    continue
                # its outline: the corners in turn, the unseen fourth where it would stand
                far = c[group[3]] if len(group) == 4 else fourth
                cands.append((group, err, np.array([c[j], c[i], far, c[k]])))
    groups = _best_packing(cands, n)
    used = {i for g in groups for i in g}
    return groups, [i for i in range(n) if i not in used]


def _inside(points, corner, e1, e2, lu, lv, margin):
    """``(K,)`` bool: which of ``(K, 2)`` points [m] lie inside the rectangle of sides ``lu``
    along ``e1`` and ``lv`` along ``e2`` (unit vectors) from ``corner`` [m], grown by
    ``margin`` [m] (on its sides), and farther than :data:`SIDE_TOL` from each of its corners
    (where its own legs stand)."""
    rel = np.asarray(points, dtype=float).reshape(-1, 2) - corner
    a1, a2 = rel @ e1, rel @ e2
    inside = (a1 > -margin) & (a1 < lu + margin) & (a2 > -margin) & (a2 < lv + margin)
    for cx, cy in ((0.0, 0.0), (lu, 0.0), (0.0, lv), (lu, lv)):
        inside &= np.hypot(a1 - cx, a2 - cy) > SIDE_TOL
    return inside


def _overlap(p, q, margin):
    """Whether two convex polygons (``(4, 2)`` corners in turn [m]) overlap by more than
    ``margin`` [m] along every axis of their sides (separating axes)."""
    for poly in (p, q):
        for e in np.diff(np.vstack((poly, poly[:1])), axis=0):
            ax = np.array([-e[1], e[0]]) / max(float(np.hypot(*e)), 1e-12)
            a, b = p @ ax, q @ ax
            if min(a.max(), b.max()) - max(a.min(), b.min()) <= margin:
                return False
    return True


def _best_packing(cands, n, budget=20000):
    """The set of leg groups (``cands``: ``(group, right-angle error, outline)``, each group a
    list of leg indices below ``n``, its outline the rectangle's ``(4, 2)`` corners), no two
    sharing a leg or overlapping (by more than :data:`SIDE_TOL`: a piece's legs stand outside
    any other piece, as :func:`group_furniture` asks of each), that explains the most legs,
    then has the most four-leg groups, then the least summed error. Chairs round a table put
    legs of different pieces at right angles too: a group that takes legs of two chairs, or
    crosses the table, leaves them unexplained. An exact search (each leg in turn: in none of
    the groups, or in one of those that fit) of at most ``budget`` steps, from the greedy
    choice (four legs first, then best right angle), which stays when the search ends without
    a better one. Returns the groups, four-leg ones first."""
    order = sorted(range(len(cands)), key=lambda m: (-len(cands[m][0]), cands[m][1]))
    clash = {}

    def fits(m, chosen, used):
        if not used.isdisjoint(cands[m][0]):
            return False
        for o in chosen:
            key = (min(m, o), max(m, o))
            if key not in clash:
                clash[key] = _overlap(cands[m][2], cands[o][2], SIDE_TOL)
            if clash[key]:
                return False
        return True

    def score(chosen):
        return (sum(len(cands[m][0]) for m in chosen), sum(len(cands[m][0]) == 4 for m in chosen),
                -sum(cands[m][1] for m in chosen))

    greedy, used = [], set()
    for m in order:
        if fits(m, greedy, used):
            greedy.append(m)
            used.update(cands[m][0])
    best = [greedy, score(greedy)]
    by_leg = [[m for m in order if i in cands[m][0]] for i in range(n)]
    steps = [0]

    def search(i, chosen, used, covered):
        steps[0] += 1
        if steps[0] > budget:
            return
        while i < n and (i in used or not by_leg[i]):
            i += 1
        # even every leg left in a group cannot beat the best: stop here
        if covered + sum(1 for j in range(i, n) if j not in used and by_leg[j]) < best[1][0]:
            return
        if i == n:
            sc = score(chosen)
            if sc > best[1]:
                best[0], best[1] = list(chosen), sc
            return
        for m in by_leg[i]:
            if fits(m, chosen, used):
                chosen.append(m)
                search(i + 1, chosen, used | set(cands[m][0]), covered + len(cands[m][0]))
                chosen.pop()
        search(i + 1, chosen, used, covered)           # leg i in no group

    search(0, [], set(), 0)
    return [cands[m][0] for m in sorted(best[0], key=order.index)]


def furniture_shape(legs, group):
    """The ``legs`` :class:`Shape` of a leg group (3 or 4 :class:`Leg` s, the corner first,
    then its two neighbours, then the opposite corner when seen): the rectangle's centre (the
    middle of the diagonal(s)), its sides as ``extent`` (leg centre to leg centre, length the
    longer), its orientation along the longer side."""
    c = np.array([legs[g].center for g in group])
    var = np.array([legs[g].var for g in group])
    j, i, k = c[0], c[1], c[2]
    if len(group) == 4:
        centre = c.mean(axis=0)
        vc = var.sum() / 16.0
    else:
        centre = 0.5 * (i + k)                          # the middle of the seen diagonal
        vc = (var[1] + var[2]) / 4.0
    u, v = i - j, k - j
    if len(group) == 4:                                 # both pairs of opposite sides
        m = c[3]
        lu = 0.5 * (np.hypot(*u) + np.hypot(*(m - k)))
        lv = 0.5 * (np.hypot(*v) + np.hypot(*(m - i)))
    else:
        lu, lv = float(np.hypot(*u)), float(np.hypot(*v))
    long_vec = u if lu >= lv else v
    ext = (float(max(lu, lv)), float(min(lu, lv)))
    side = float(min(lu, lv))
    ostd = math.sqrt(2.0 * float(var.max())) / max(side, 1e-3)
    return Shape('legs', (float(centre[0]), float(centre[1])), vc * np.eye(2), ext,
                 _half_turn(math.atan2(long_vec[1], long_vec[0])), ostd,
                 (math.sqrt(2 * float(var.max())),) * 2, True,
                 '%d legs of a table or chair seen' % len(group), legs=c,
                 leg_radius=float(np.mean([legs[g].radius for g in group])), kind='furniture')


def _nearest_pairs(pairs):
    """Disjoint pairs from ``(distance, a, b)`` candidates, nearest first: ``[[a, b], ...]``."""
    used, out = set(), []
    for _, a, b in sorted(pairs):
        if a not in used and b not in used:
            out.append([a, b])
            used.update((a, b))
    return out


def pair_people(legs, sensor=None):
    """People: pairs of person-sized legs (:func:`person_sized`, seen by at least
    :data:`MIN_PERSON_LEG_POINTS` beams) at most
    :data:`PERSON_LEG_SPACING` apart, nearest pairs first (the least radius an arc allows, its
    points' half span, must be a calf's: a beam spacing far away widens a table's leg too), and
    the person-sized legs left alone but those of :attr:`Leg.round_cut`. With the ``sensor``'s
    position [m], a leg too narrow for a calf whose arc something nearer cuts (:attr:`Leg.cut`)
    pairs with a person-sized leg nearer to the sensor within the spacing: a walker's back leg
    of which the front one leaves a sliver in view (it is never a person alone). Returns
    ``(pairs, singles)``, index lists into ``legs``."""
    n = len(legs)
    # a person's leg for sure: even the least radius its arc allows is a calf's (far away a
    # beam spacing widens a table's leg as much)
    ok = [i for i in range(n) if person_sized(legs[i].radius, legs[i].least)
          and (legs[i].index is None or len(legs[i].index) >= MIN_PERSON_LEG_POINTS)]
    pairs = []
    for a in range(len(ok)):
        for b in range(a + 1, len(ok)):
            d = float(np.hypot(*(legs[ok[a]].center - legs[ok[b]].center)))
            if d <= PERSON_LEG_SPACING:
                pairs.append((d, ok[a], ok[b]))
    if sensor is not None:
        sliver = [i for i in range(n) if i not in ok and legs[i].cut
                  and legs[i].radius <= PERSON_LEG_RADIUS[1]
                  and (legs[i].index is None or len(legs[i].index) >= MIN_PERSON_LEG_POINTS)]
        for i in sliver:
            behind = float(np.hypot(*(legs[i].center - sensor)))
            for j in ok:
                d = float(np.hypot(*(legs[i].center - legs[j].center)))
                if d <= PERSON_LEG_SPACING and float(np.hypot(*(legs[j].center - sensor))) < behind:
                    pairs.append((d, j, i))
    out = _nearest_pairs(pairs)
    used = {i for pair in out for i in pair}
    # a cylinder half hidden behind a nearer one leaves an arc a calf's width in view
    return out, [i for i in ok if i not in used and not legs[i].round_cut]


def person_shape(legs, group):
    """The ``legs`` :class:`Shape` of a person: the middle of the legs seen (one or two)."""
    c = np.array([legs[g].center for g in group])
    centre = c.mean(axis=0)
    var = float(np.mean([legs[g].var for g in group])) / len(group)
    if len(group) == 1:
        # the other leg is hidden: the person's centre is within a stride's half of this one
        var += (PERSON_LEG_SPACING / 2.0) ** 2 / 3.0
        note = 'one leg of a person seen (the other hidden): the centre is within %.1f m' % (
            PERSON_LEG_SPACING / 2.0)
    else:
        note = 'two legs of a person seen, %.2f m apart' % float(np.hypot(*(c[0] - c[1])))
    span = float(np.hypot(*(c[0] - c[-1]))) + 2 * max(legs[g].radius for g in group)
    return Shape('legs', (float(centre[0]), float(centre[1])), var * np.eye(2),
                 (span, 2 * max(legs[g].radius for g in group)), math.nan, math.nan,
                 (math.nan, math.nan), len(group) == 2, note, legs=c,
                 leg_radius=float(np.mean([legs[g].radius for g in group])), kind='person')


# --- one scan's objects --------------------------------------------------------------------
class ScanView:
    """What one scan says about places (beam geometry in the plane frame of the points):
    ``ranges`` [m] (REP 117, NaN for beams a filter dropped), the beams' first angle
    ``angle_min`` and step ``increment`` [rad] in the laser frame, the laser's pose ``(x, y,
    yaw)`` in the points' frame, ``range_max`` [m] and ``range_min`` [m]: a finite range below
    it is invalid (REP 117; a Hokuyo writes its error codes there), it says nothing, as NaN
    (``-inf``, too close, is something nearer). ``r`` holds the ranges so read, ``ranges`` the
    ones given (what :func:`segments` counts as a beam with no hit between two points).
    ``raw`` [m]: for the beams the veil filter dropped, their ranges before it (NaN
    elsewhere; None: not known), read the same way (:meth:`end_seen` of a box's face)."""

    def __init__(self, ranges, angle_min, increment, laser_pose, range_max, range_min=0.0,
                 raw=None):
        self.ranges = np.asarray(ranges, dtype=float)
        self.r = self._read(self.ranges, range_min)
        self.raw = None if raw is None else self._read(np.asarray(raw, dtype=float), range_min)
        self.angle_min, self.inc = float(angle_min), float(increment)
        self.pose = tuple(float(v) for v in laser_pose)
        self.range_max = float(range_max)

    @staticmethod
    def _read(r, range_min):
        r = r.copy()
        # (compared only where finite: NaN < x warns on older numpy)
        r[np.less(r, range_min, out=np.zeros(len(r), dtype=bool), where=np.isfinite(r))] = np.nan
        return r

    def _past(self, j, dist, r=None):
        """Whether beam ``j`` went past range ``dist`` (a return well behind it, or none); a
        beam a filter dropped (NaN) says nothing: None. ``r``: the ranges to read (``self.r``)."""
        r = self.r if r is None else r
        if not 0 <= j < len(r):
            return False                 # outside the scan: not seen
        v = float(r[j])
        if v != v:
            return None
        return v == math.inf or (dist + FREE_MARGIN < v <= self.range_max) or v > self.range_max

    def free(self, xy, radius=0.0, leg=0.0):
        """Whether the scan saw the disc of ``radius`` [m] about ``xy`` [m] empty: every beam
        that crosses it (the nearest one at least) went past it, and at least one of them
        said so (a beam a filter dropped says nothing). With ``leg`` [m], empty of a leg of
        that radius: also no room for one between the beams that went past (the first and
        last beams across the disc among them, neighbours at most a leg's width apart at
        its range): a thin leg slips between beams far away, or where one was dropped."""
        x, y, yaw = self.pose
        dist = math.hypot(xy[0] - x, xy[1] - y)
        bearing = math.atan2(xy[1] - y, xy[0] - x) - yaw
        bearing = math.atan2(math.sin(bearing), math.cos(bearing))
        half = math.asin(min(1.0, radius / max(dist, 1e-9)))
        c = (bearing - self.angle_min) / self.inc
        lo = min(int(math.ceil(c - half / abs(self.inc))), int(round(c)))
        hi = max(int(math.floor(c + half / abs(self.inc))), int(round(c)))
        said = [self._past(j, dist + radius) for j in range(lo, hi + 1)]
        if not (all(v is not False for v in said) and any(v for v in said)):
            return False
        if leg <= 0:
            return True
        past = [j for j, v in zip(range(lo, hi + 1), said) if v]
        widest = max(np.diff([lo] + past + [hi]).max(initial=0), 1)
        return bool(said[0] and said[-1] and widest * max(dist - radius, 0.0) * abs(self.inc)
                    < 2.0 * leg)

    def beam_of(self, xy):
        """Index of the beam nearest the bearing of each ``(N, 2)`` point [m] (outside
        ``[0, len(ranges))`` where the fan does not reach it)."""
        x, y, yaw = self.pose
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        b = np.arctan2(xy[:, 1] - y, xy[:, 0] - x) - yaw
        b = np.arctan2(np.sin(b), np.cos(b))
        return np.round((b - self.angle_min) / self.inc).astype(int)

    def end_seen(self, beam, step, dist, veiled=False, noise=0.01):
        """Whether the object's edge at beam ``beam`` is a silhouette edge: the next beam
        outward (``step`` ±1; past those a filter dropped, two at most) went past range
        ``dist`` [m]. Returns how many beams out that one is (1, 2 or 3: the edge lies
        within that many beam spacings of beam ``beam``), 0 when it did not go past
        (something nearer hides the edge, or the scan ends). A beam a filter dropped is
        looked past; with ``veiled``, one whose return before the veil filter (``raw``) went
        past counts as past (the veil filter drops the first beam behind every silhouette
        edge, and hits where beams graze a face: those are looked past). Such a beam whose
        return lies more than 3 ``noise`` [m] before the next beam's (a mixed pixel: its
        footprint straddles the edge, part on the object) puts the edge up to one beam
        further: ``k + 1``."""
        for k in (1, 2, 3):
            j = beam + k * step
            past = self._past(j, dist)
            if past is None and veiled and self.raw is not None and self._past(j, dist, self.raw):
                nxt = self.r[j + step] if 0 <= j + step < len(self.r) else math.nan
                return k + 1 if math.isfinite(nxt) and self.raw[j] < nxt - 3.0 * noise else k
            if past is not None:
                return k if past else 0
        return 0


def describe(points, beams, view, noise=0.01, gap=0.08, extra=()):
    """The non-round objects among ``(N, 2)`` points in scan order (beam indices ``beams``,
    the :class:`ScanView` ``view`` of their scan): each run of neighbours (:func:`segments`)
    wider than :data:`LEG_MAX_WIDTH` is a rectangle (:func:`fit_rectangle`) when its residual
    is within ``max(3 noise, 0.02)`` m, otherwise ``unknown``; each narrower run is a leg
    (:func:`leg`). Legs at the corners of a rectangle are one table or chair
    (:func:`group_furniture`), person-sized legs within a stride one person
    (:func:`pair_people`); what is left is reported alone (``legs`` not fixed: a table's or
    chair's other legs hidden, a person's other leg hidden). A point a beam hit alone, the
    beams either side past it, may be a thin leg whose other beam a mixed pixel took: it may
    complete a table or chair (:attr:`Leg.single`; placed by :func:`_single_in`), never
    stands for one or a person alone. Returns ``(shapes, legs_left)``:
    :class:`Shape` s and, for the caller to pair with its own small circles, nothing more
    (``legs_left`` is the :class:`Leg` list of every leg found, for the benchmarks).
    ``extra``: ``(Leg, points)`` pairs found elsewhere (small circles the caller fitted) that
    may join a table, a chair or a person; one that joins nothing is not reported here. The
    :class:`Shape` s built with them have ``used`` set to their indices in ``extra``."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    beams = np.asarray(beams)
    sensor = np.array(view.pose[:2])
    out, legs = [], []
    runs = []
    for coarse in segments(p, beams, sensor, view.inc, gap, view.ranges, FACE_INCIDENCE, noise):
        fine = [coarse[f] for f in segments(p[coarse], beams[coarse], sensor, view.inc, gap,
                                            view.ranges)]
        # an oblique face breaks into pieces between beams: one run, unless its pieces are
        # each as narrow as legs (a person's two legs side by side)
        narrow = all(np.hypot(*(p[f].max(axis=0) - p[f].min(axis=0))) <= LEG_MAX_WIDTH
                     for f in fine)
        if len(fine) > 1 and not narrow:
            fit = fit_rectangle(p[coarse], sensor, noise)
            if fit is not None and flat(fit[1], noise):
                runs.append(coarse)
                continue
        runs.extend(fine)
    lone = []                   # points a beam hit alone, the beams either side past them
    for seg in runs:
        q = p[seg]
        if len(q) < 2:
            if _stands_apart(seg, beams, p, sensor, view, hidden=False):
                lone.extend(seg)
            continue
        span = float(np.hypot(*(q.max(axis=0) - q.min(axis=0))))
        if span <= LEG_MAX_WIDTH and _stands_apart(seg, beams, p, sensor, view):
            found = leg(q, sensor, view.inc, noise)
            if found is None and _stands_apart(seg, beams, p, sensor, view, hidden=False):
                # flat but whole (nothing nearer cuts either end) and of a calf's width: a
                # trouser leg hangs flat at a laser's height; a box's face this narrow is cut
                # by what hides the rest of it, or seen with its side as an L
                found = leg(q, sensor, view.inc, noise, round_checked=True)
                if found is not None and not person_sized(found[1], found[3]):
                    found = None
            if found is not None:
                legs.append(Leg(found[0], found[1], seg, found[2], found[3],
                                cut=arc_cut(q, view)))
                continue
        elif span <= PERSON_PAIR_WIDTH and _stands_apart(seg, beams, p, sensor, view):
            two = split_pair(q, sensor, view.inc, noise)
            if two is not None:                 # a person's two legs side by side
                for idx, found in two:
                    legs.append(Leg(found[0], found[1], seg[idx], found[2], found[3]))
                continue
        fit = _fit_run(q, beams[seg], view, noise)
        if fit is not None and flat(fit[1], noise):
            fit[0].index = seg
            out.append(fit[0])
        else:
            out.append(unknown(q))
    out = _join_hidden(out, p, beams, sensor, view, noise)
    n_own = len(legs)
    extra_pts = {}
    for k, (l, q) in enumerate(extra):
        extra_pts[len(legs)] = (k, np.asarray(q, dtype=float))
        legs.append(l)

    for i in lone:              # one beam each: a thin leg whose other beam an edge blended
        found = leg(p[[i]], sensor, view.inc, noise)
        legs.append(Leg(found[0], found[1], np.array([i]), found[2], found[3], single=True))

    def pts_of(i):
        return extra_pts[i][1] if i in extra_pts else p[legs[i].index]

    def used_of(idx):
        return [extra_pts[i][0] for i in idx if i in extra_pts]

    thin = [i for i, l in enumerate(legs) if l.radius <= FURNITURE_LEG_RADIUS]
    groups, _ = group_furniture([legs[i] for i in thin], view.free,
                                p[np.asarray(lone, dtype=int)])
    grouped = set()
    for g in groups:
        idx = [thin[i] for i in g]
        grouped.update(idx)
        for i in idx:
            if legs[i].single:
                legs[i] = _single_in(legs[i], p[legs[i].index[0]], sensor, noise,
                                     [legs[o].radius for o in idx if not legs[o].single])
        s = furniture_shape(legs, idx)
        s.points = np.concatenate([pts_of(i) for i in idx])
        s.used = used_of(idx)
        out.append(s)
    rest = [i for i in range(len(legs)) if i not in grouped]
    pairs, singles = pair_people([legs[i] for i in rest], sensor)
    done = set()
    for g in pairs + [[s] for s in singles]:
        idx = [rest[i] for i in g]
        done.update(idx)
        s = person_shape(legs, idx)
        s.points = np.concatenate([pts_of(i) for i in idx])
        s.used = used_of(idx)
        out.append(s)
    # thin legs left alone (not stubs of something larger: 3 points or more, the beams either
    # side going past them): furniture whose other legs hide, two of one piece together
    alone = [i for i in rest if i not in done and i < n_own and len(legs[i].index) >= 3
             and legs[i].radius <= FURNITURE_LEG_RADIUS
             and _isolated(legs[i].index, beams, p, sensor, view)]
    for g in pair_furniture([legs[i] for i in alone]):
        idx = [alone[i] for i in g]
        s = lone_furniture_shape(legs, idx)
        s.points = np.concatenate([p[legs[i].index] for i in idx])
        out.append(s)
    return out, legs[:n_own]


def _single_in(one, hit, sensor, noise, radii):
    """A one-beam :class:`Leg` ``one`` (its ``hit`` [m]) placed in a piece whose other legs
    have ``radii`` [m]: one piece has one kind of leg, so its centre is their mean radius
    behind the hit along the beam from ``sensor``; the beam hit anywhere across the leg, so
    its centre is that radius's uniform spread across it (variance r²/3) off, plus the range
    ``noise`` [m]."""
    r = float(np.mean(radii))
    ray = (hit - sensor) / float(np.hypot(*(hit - sensor)))
    return Leg(hit + r * ray, r, one.index, noise * noise + r * r / 3.0, 0.0, single=True)


def pair_furniture(legs):
    """Thin legs left alone (list of :class:`Leg`) two by two: legs of one kind (radii within
    0.03 m) a piece's side or diagonal apart (:data:`FURNITURE_SIDE`), nearest pairs first;
    the rest alone. Returns index lists into ``legs``."""
    n = len(legs)
    pairs = []
    for a in range(n):
        for b in range(a + 1, n):
            d = float(np.hypot(*(legs[a].center - legs[b].center)))
            if FURNITURE_SIDE[0] <= d <= FURNITURE_SIDE[1] * math.sqrt(2.0) \
                    and abs(legs[a].radius - legs[b].radius) <= 0.03:
                pairs.append((d, a, b))
    out = _nearest_pairs(pairs)
    used = {i for pair in out for i in pair}
    return out + [[i] for i in range(n) if i not in used]


def lone_furniture_shape(legs, group):
    """The ``legs`` :class:`Shape` of one or two legs of a table or chair whose other legs are
    hidden (``center_fixed`` false). One leg: the piece's centre within half the longest side
    (:data:`FURNITURE_SIDE`) of it, any way round. Two: they are a side (the centre
    off their middle across it, up to half the longest side, either way) or a diagonal (the
    centre their middle): the middle is reported, the covariance uniform over that segment."""
    c = np.array([legs[g].center for g in group])
    var = np.array([legs[g].var for g in group])
    r = float(np.mean([legs[g].radius for g in group]))
    half = FURNITURE_SIDE[1] / 2.0
    if len(group) == 1:
        return Shape('legs', (float(c[0, 0]), float(c[0, 1])),
                     (var[0] + half ** 2 / 3.0) * np.eye(2),
                     note='one leg of a table or chair seen (the others hidden or out of view): '
                     'the piece\'s centre is within %.1f m of it' % half, center_fixed=False,
                     legs=c, leg_radius=r, kind='furniture')
    centre = c.mean(axis=0)
    e = (c[1] - c[0]) / float(np.hypot(*(c[1] - c[0])))
    n = np.array([-e[1], e[0]])
    cov = var.sum() / 4.0 * np.eye(2) + half ** 2 / 3.0 * np.outer(n, n)
    return Shape('legs', (float(centre[0]), float(centre[1])), cov,
                 note='two legs of a table or chair seen, %.2f m apart (the others hidden or out '
                 'of view): the piece\'s centre is on the line across their middle, within '
                 '%.1f m of it' % (float(np.hypot(*(c[1] - c[0]))), half), center_fixed=False,
                 legs=c, leg_radius=r, kind='furniture')


def _fit_run(q, b, view, noise):
    """:func:`fit_rectangle` of the ``(N, 2)`` points ``q`` [m] of beams ``b`` (scan order) of
    the :class:`ScanView` ``view``, each face's end judged by the beam past it."""
    sensor = np.array(view.pose[:2])
    lo, hi = int(np.min(b)), int(np.max(b))

    def end_seen(i):
        j = int(b[i])
        d = float(np.hypot(*(q[i] - sensor)))
        return view.end_seen(j, -1 if (j - lo) <= (hi - j) else 1, d, veiled=True, noise=noise)
    return fit_rectangle(q, sensor, noise, end_seen, increment=view.inc)


def flat(rms, noise):
    """Whether an L-shape fit's residual ``rms`` [m] is a box's (within 3 ``noise`` [m], the
    range noise, and at least 2 cm)."""
    return rms <= max(3.0 * noise, 0.02)


def face_pieces(points, beams, pieces, round_mask, sensor, increment, ranges, noise=0.01,
                gap=0.08):
    """The ``pieces`` (index arrays into the ``(N, 2)`` points [m], scan order, beam indices
    ``beams``) taken for circles that are the end of a box's face: the clustering cuts a long
    face where its points stray from their centroid, and its last few points, nearly straight,
    fit a circle (or a leg) too. A piece is one when a run of neighbours (:func:`segments` over
    an oblique face, :data:`FACE_INCIDENCE`) joins it to points not taken for circles
    (``round_mask`` False), one rectangle fits it with them (:func:`fit_rectangle`, residual
    :func:`flat`), and it lies on one face of that rectangle with at least
    :data:`MIN_FACE_POINTS` of them, each of its ends within the spacing of neighbouring beams'
    hits on that face (range × sin(step) / sin(angle between beam and face − step), plus 3
    ``noise``) of the point beside it, no beam between them past both by
    :data:`FREE_MARGIN`. ``sensor`` ``(x, y)`` [m]; ``increment`` [rad] the beams' step;
    ``ranges`` the scan's, indexed by ``beams`` (NaN says nothing). Returns the pieces'
    positions in ``pieces``."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    if not len(pieces):
        return []
    runs = segments(p, beams, sensor, increment, gap, ranges, FACE_INCIDENCE, noise)
    run_of = np.empty(len(p), dtype=int)
    for k, run in enumerate(runs):
        run_of[run] = k
    out = []
    for k, idx in enumerate(pieces):
        run = runs[run_of[idx[0]]]
        rest = run[~round_mask[run]]
        if len(rest) < MIN_FACE_POINTS or not np.all(run_of[idx] == run_of[idx[0]]):
            continue
        both = np.union1d(idx, rest)
        fit = fit_rectangle(p[both], sensor, noise)
        if fit is None or not flat(fit[1], noise):
            continue
        # on a face the rest shows too (a leg beside the face's end would be the L's other
        # face on its own), ...
        theta = fit[0].orientation
        on_a = _l_cost(p[both], theta, sensor)[3]
        mine = np.isin(both, idx)
        for side, along in ((on_a, theta + math.pi / 2), (~on_a, theta)):
            if np.all(side[mine]) and np.count_nonzero(side & ~mine) >= MIN_FACE_POINTS:
                break
        else:
            continue
        # ... and next to its points as the beams' spacing on that face puts them, no beam
        # between them going past (a leg standing past the face's end is farther, or seen
        # apart from it)
        d = np.array([math.cos(along), math.sin(along)])
        inside = np.isin(run, idx)
        ok = True
        for e in np.flatnonzero(inside[1:] != inside[:-1]):
            i, j = run[e], run[e + 1]
            ray = p[i] - sensor
            r = float(np.hypot(*ray))
            lo, hi = sorted((int(beams[i]), int(beams[j])))
            between = np.asarray(ranges[lo + 1:hi], dtype=float) if ranges is not None else []
            if np.any(between > max(r, float(np.hypot(*(p[j] - sensor)))) + FREE_MARGIN):
                ok = False
                break
            sin = abs(float(ray[0] * d[1] - ray[1] * d[0])) / max(r, 1e-9)
            dphi = abs(increment) * max(hi - lo, 1)
            graze = math.asin(min(sin, 1.0)) - dphi
            allow = (r * math.sin(dphi) / math.sin(graze) if graze > 0 else math.inf) + 3.0 * noise
            ok = ok and float(np.hypot(*(p[j] - p[i]))) <= allow
        if ok:
            out.append(k)
    return out


def _join_hidden(found, p, beams, sensor, view, noise):
    """Rectangles that are pieces of one box cut by something nearer in front of it: two pieces
    next to each other in the scan, every beam between them hitting nearer than both, whose
    points one rectangle fits (:func:`fit_rectangle`) are one box."""
    rects = sorted((s for s in found if s.shape == 'rectangle' and s.index is not None),
                   key=lambda s: int(beams[s.index].min()))
    others = [s for s in found if not (s.shape == 'rectangle' and s.index is not None)]
    out = []
    for s in rects:
        if out:
            a = out[-1]
            lo, hi = int(beams[a.index].max()), int(beams[s.index].min())
            between = view.r[lo + 1:hi]
            near = min(float(np.min(np.hypot(*(p[a.index] - sensor).T))),
                       float(np.min(np.hypot(*(p[s.index] - sensor).T))))
            hits = between[np.isfinite(between)]
            if hi > lo + 1 and len(hits) and np.all(hits < near - 0.05):
                idx = np.concatenate((a.index, s.index))
                fit = _fit_run(p[idx], beams[idx], view, noise)
                if fit is not None and flat(fit[1], noise):
                    joined = fit[0]
                    joined.index = idx
                    joined.note += '; seen in pieces either side of something nearer'
                    out[-1] = joined
                    continue
        out.append(s)
    return others + out


def _stands_apart(index, beams, points, sensor, view, hidden=True):
    """Whether a run (``index`` into ``points``) stands apart from what is beside it, as a leg
    does: the beam next to it on each side either went past it (:data:`FREE_MARGIN` behind or
    no return) or, with ``hidden``, hit something nearer that hides it; a beam a filter
    dropped is looked past. A neighbour at about its range is the rest of a larger surface (a
    wall's end seen edge-on)."""
    b = np.asarray(beams)[index]
    d = float(np.min(np.hypot(*(points[index] - sensor).T)))
    return all(v is None or (hidden and v < d - NEARER) or v > d + FREE_MARGIN
               for v in _beside(b, view, 2))


def _beside(beams, view, look):
    """The range [m] of the first beam outside the run of beam indices ``beams`` on each side
    that has one, looking ``look`` beams out (past those a filter dropped); None on a side
    where there is none, or the scan ends."""
    out = []
    for j0, step in ((int(np.min(beams)) - 1, -1), (int(np.max(beams)) + 1, 1)):
        v = None
        for j in range(j0, j0 + look * step, step):
            if not 0 <= j < len(view.r):
                break
            if view.r[j] == view.r[j]:
                v = float(view.r[j])
                break
        out.append(v)
    return out


def _isolated(index, beams, points, sensor, view):
    """Whether the beams either side of a run (``index`` into ``points``) went past it."""
    b = np.asarray(beams)[index]
    d = float(np.max(np.hypot(*(points[index] - sensor).T)))
    return view.end_seen(int(b.min()), -1, d) and view.end_seen(int(b.max()), 1, d)


def arc_cut(points, view):
    """Whether something nearer cuts an end of the arc of ``(N, 2)`` points [m] (in the frame
    of the :class:`ScanView` ``view``): the next beam outward at either end that has a range
    (past up to two a filter dropped) hit more than :data:`NEARER` nearer than the arc's nearest
    point. The arc may then be the part of something wider that is left in view."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    d = float(np.min(np.hypot(*(p - np.array(view.pose[:2])).T)))
    return any(v is not None and v < d - NEARER for v in _beside(view.beam_of(p), view, 3))


def unknown(points):
    """An ``unknown`` :class:`Shape`: the centre of the points' bounding box, its half sizes'
    squares as the covariance (the object is somewhere around what was seen)."""
    q = np.asarray(points, dtype=float)
    lo, hi = q.min(axis=0), q.max(axis=0)
    c = 0.5 * (lo + hi)
    half = np.maximum(0.5 * (hi - lo), 0.05)
    return Shape('unknown', (float(c[0]), float(c[1])), np.diag(half ** 2), center_fixed=False,
                 note='neither round, nor straight, nor legs', points=q)


def rectangle_not_circle(points, sensor, circle_rms, noise=0.01):
    """Whether a cluster a circle fits (residual ``circle_rms`` [m]) is a box: an L-shape fit
    (:func:`fit_rectangle`, ``noise`` [m]) fits it with 0.7 of its residual or less. A cylinder's arc is
    fitted by a circle to the noise and by an L worse."""
    p = np.asarray(points, dtype=float)
    if len(p) < 2 * MIN_FACE_POINTS or np.hypot(*(p.max(axis=0) - p.min(axis=0))) <= LEG_MAX_WIDTH:
        return False
    fit = fit_rectangle(p, sensor, noise)
    return fit is not None and fit[1] < 0.7 * circle_rms
