"""Motion over the scans a robot at rest takes: what moved between them is reported as moving,
with its velocity, and never as a static obstacle.

A robot standing still sees its static surroundings at the same range in every scan, to the
range noise. A beam whose hits differ by more than :data:`CHANGE` between the oldest and the
newest scan of the window (or hits in one and not in the other) saw something move. The
per-beam median of the window places what stayed put; an object on changed beams is smeared in
that median, so it is taken from the newest scan alone, and its velocity is its centre's
displacement from the same object in the oldest scan (the nearest of a compatible size within
what :data:`MAX_SPEED` allows) over the time between them. What would be static but stands
where a scan from the same pose up to a :data:`STRIDE` earlier saw free came there meanwhile,
and moved (a walker's planted leg). Frames: the map's (points, centres, the laser's pose);
metres, radians, seconds.
"""
import math

import numpy as np

from tiago_nav.detection.shapes import PERSON_LEG_RADIUS, PERSON_LEG_SPACING
from tiago_nav.scan import HIT, NO_RETURN, classify

CHANGE = 0.1          # [m] a beam's hit moved by more than this: ten times the range noise
STRIDE = 1.0          # [s] a walker's stride: a foot stands on the floor for about 0.6 s of
                      # it, and its place was seen free this long before at most
ARRIVED_SHARE = 0.8   # an object on beams that saw this share of its points' places free came
                      # there (a thin leg's edge beam that flickers is a share of its points)
MAX_SPEED = 2.5       # [m/s] a person walks at up to 2 m/s: an object moves at most this fast
CHANGED_SHARE = 0.3   # an object with this share of its points on changed beams moved


def changed_beams(newest, oldest, range_min, range_max, change=CHANGE):
    """``(n,)`` bool: the beams whose hit differs by more than ``change`` [m] between two scans
    of one sensor at one pose (``newest``, ``oldest`` ranges [m], REP 117), or that hit in one
    and not in the other. A beam saying nothing in either (NaN) is not changed."""
    a, b = np.asarray(newest, dtype=float), np.asarray(oldest, dtype=float)
    ca, cb = classify(a, range_min, range_max), classify(b, range_min, range_max)
    both = (ca == HIT) & (cb == HIT)
    out = np.zeros(len(a), dtype=bool)
    out[both] = np.abs(a[both] - b[both]) > change
    one = (ca == HIT) != (cb == HIT)
    out |= one & ~np.isnan(a) & ~np.isnan(b)
    return out


def seen_free_before(newest, earlier, range_min, range_max, change=CHANGE):
    """``(n,)`` bool: the beams that hit in ``newest`` and reached more than ``change`` [m]
    farther in ``earlier`` (ranges [m] of one sensor at one pose, REP 117; a no-return reached
    the range's end): the place of the newest hit was seen free then."""
    a, b = np.asarray(newest, dtype=float), np.asarray(earlier, dtype=float)
    ca, cb = classify(a, range_min, range_max), classify(b, range_min, range_max)
    out = (ca == HIT) & (cb == NO_RETURN)
    both = (ca == HIT) & (cb == HIT)
    out[both] = b[both] > a[both] + change
    return out


def beams_of(points, laser_pose, angle_min, increment, n):
    """The beam index ``(K,)`` (clipped to ``[0, n)``) of each of ``(K, 2)`` points [m] seen
    from ``laser_pose`` ``(x, y, yaw)``, all in the map frame."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    a = np.arctan2(p[:, 1] - laser_pose[1], p[:, 0] - laser_pose[0]) - laser_pose[2]
    a = np.arctan2(np.sin(a), np.cos(a))
    return np.clip(np.round((a - angle_min) / increment).astype(int), 0, n - 1)


def moved(detection, changed, laser_pose, angle_min, increment, share=CHANGED_SHARE):
    """Whether at least ``share`` of the detection's points lie on ``changed`` beams."""
    if detection.points is None or not len(detection.points):
        return False
    b = beams_of(detection.points, laser_pose, angle_min, increment, len(changed))
    return float(np.mean(changed[b])) >= share


def velocity(detection, earlier, dt):
    """``((vx, vy), std)`` [m/s] of ``detection`` from the nearest of the ``earlier``
    detections (the oldest scan's) within ``MAX_SPEED * dt`` plus the sizes of both, ``dt``
    [s] before; ``((nan, nan), nan)`` when none is there (it came into view)."""
    best, d_best = None, math.inf
    for e in earlier:
        d = math.hypot(detection.center[0] - e.center[0], detection.center[1] - e.center[1])
        if d <= MAX_SPEED * dt + detection.radius + e.radius and d < d_best:
            best, d_best = e, d
    if best is None or dt <= 0:
        return (math.nan, math.nan), math.nan
    v = ((detection.center[0] - best.center[0]) / dt, (detection.center[1] - best.center[1]) / dt)
    var = 0.0
    for x in (detection, best):
        c = np.asarray(x.center_covariance, dtype=float)
        var += float(np.linalg.eigvalsh(c).max()) if np.all(np.isfinite(c)) else math.inf
    return v, math.sqrt(var) / dt


def leg_like(d):
    """Whether a detection may be one or two legs of a person: a ``legs`` object (the shapes
    detection's) of at most two legs. Circles are not: without the shapes detection, motion is
    judged object by object, as before."""
    return d.shape == 'legs' and (d.legs is None or len(d.legs) <= 2)


def never_a_person(d):
    """Whether a detection cannot be (a part of) a person: a table or a chair (3 or 4 legs), a
    rectangle, a circle wider than a calf (:data:`PERSON_LEG_RADIUS`). One or two legs, a
    calf-sized circle (a leg, when the shapes detection is off) and ``unknown`` may be."""
    if d.shape == 'legs':
        return d.legs is not None and len(d.legs) >= 3
    if d.shape == 'circle':
        return d.radius > PERSON_LEG_RADIUS[1]
    return d.shape == 'rectangle'


def there(d, dets, still=False):
    """Whether one of ``dets`` has the shape of ``d`` and its centre within :data:`CHANGE` of
    ``d``'s (with ``still``: and was not judged moving)."""
    return any(o.shape == d.shape and (not still or o.motion != 'moving') and math.hypot(
        o.center[0] - d.center[0], o.center[1] - d.center[1]) <= CHANGE for o in dets)


def stayed(d, newest, oldest):
    """Whether the median's detection ``d`` is in the ``newest`` and the ``oldest`` scans'
    detections alone, of its shape, within :data:`CHANGE` of its centre, and the newest one was
    not judged moving: it stood still while beams at its edges changed (a chair's thin leg hit
    by a beam in one scan and missed in the other, someone walking behind it)."""
    return there(d, newest, still=True) and there(d, oldest)


def leg_sized(d):
    """Whether a detection may be a person's leg or a part of one: :func:`leg_like`, or an
    ``unknown`` no wider than a calf (its points within ``2 * PERSON_LEG_RADIUS[1]`` of each
    other: a leg whose run the shapes detection could not read, a trouser leg's fold)."""
    if leg_like(d):
        return True
    if d.shape != 'unknown' or d.points is None or not len(d.points):
        return False
    p = np.asarray(d.points, dtype=float)
    return float(np.max(np.hypot(*(p[:, None, :] - p[None]).reshape(-1, 2).T))) \
        <= 2.0 * PERSON_LEG_RADIUS[1]


def _legs_of(d):
    return np.asarray(d.legs if d.legs is not None else [d.center], dtype=float).reshape(-1, 2)


def combine(still, newest, oldest, changed, dt, laser_pose, angle_min, increment,
            arrived=()):
    """The detections of a window of scans at rest: of ``newest`` (the newest scan's alone),
    those on changed beams (but what cannot be a person, :func:`never_a_person`, that
    ``oldest`` placed within :data:`CHANGE`: it did not move), ``'moving'`` with their
    :func:`velocity` from ``oldest`` (the oldest scan's), ``dt`` [s] earlier; of ``still``
    (the per-beam median's), those on unchanged beams, ``motion`` ``'static'`` with velocity
    0 (its std from the centre's over ``dt``), except a leg (:func:`leg_sized`: also an
    ``unknown`` no wider than a calf) within a stride (:data:`PERSON_LEG_SPACING`) of a
    moving one's leg: a walker's foot stands on the floor for most of a stride (the stance,
    about 0.6 s of a 1 s stride, longer than a window of scans at rest), so that leg is the
    moving person's planted one. It joins that person (its legs, their middle as the centre)
    and is not reported as a static object. A leg with no moving one near it but points of
    ``newest`` or ``oldest`` on changed beams within a stride is a walker's planted leg whose
    other leg swung beside or behind it (a person walking toward the laser hides one leg behind
    the other): ``'moving'``, its velocity not measured (NaN). One of ``still`` on changed
    beams is left to ``newest``'s, unless it cannot be a person (:func:`never_a_person`) and
    :func:`stayed`: then it is static (the newest scan's own detection of it, on fewer changed
    beams, was not judged moving, and nothing else would report it). ``arrived``: per scan at
    rest up to a :data:`STRIDE` before the newest and older than ``oldest``, per beam,
    :func:`seen_free_before`: an object still left static with :data:`ARRIVED_SHARE` of its
    points on such beams of one of them came there within a stride, as the robot stood still:
    a walker's planted leg (its stance began before the window and the other leg is hidden or
    out of view), or whatever came to rest there; ``'moving'``, its velocity not measured."""
    out, moving = [], []
    swung = [d.points[changed[beams_of(d.points, laser_pose, angle_min, increment,
                                       len(changed))]]
             for d in list(newest) + list(oldest) if d.points is not None and len(d.points)]
    swung = np.concatenate(swung) if swung else np.empty((0, 2))
    for d in newest:
        # what cannot be a person and is where the oldest scan placed it did not move: its
        # thin legs' edge beams changed (the median reports it)
        if moved(d, changed, laser_pose, angle_min, increment) and not (
                never_a_person(d) and there(d, oldest)):
            d.motion = 'moving'
            d.velocity, d.velocity_std = velocity(d, oldest, dt)
            moving.append(d)
    for d in still:
        if moved(d, changed, laser_pose, angle_min, increment) and not (
                never_a_person(d) and stayed(d, newest, oldest)):
            continue
        walker = None
        if leg_sized(d):
            legs = _legs_of(d)
            best = PERSON_LEG_SPACING
            for m in moving:
                if not leg_like(m):
                    continue
                gap = float(np.min(np.hypot(*(legs[:, None, :] - _legs_of(m)[None]).reshape(
                    -1, 2).T)))
                if gap <= best:
                    walker, best = m, gap
        if walker is not None:
            have = _legs_of(walker)
            new = [l for l in _legs_of(d) if np.min(np.hypot(*(have - l).T)) > 0.1]
            if new:
                walker.legs = np.vstack([have] + [np.reshape(l, (1, 2)) for l in new])
                walker.center = tuple(float(v) for v in walker.legs.mean(axis=0))
                walker.note = (walker.note + '; ' if walker.note else '') + (
                    'a planted leg that stood still over the scans at rest joined')
            continue
        if leg_sized(d) and len(swung) and float(np.min(np.hypot(
                *(_legs_of(d)[:, None, :] - swung[None]).reshape(-1, 2).T))) <= PERSON_LEG_SPACING:
            d.motion, d.velocity, d.velocity_std = 'moving', (math.nan, math.nan), math.nan
            d.note = (d.note + '; ' if d.note else '') + (
                'a planted leg: beams beside it changed (a walker\'s other leg)')
            moving.append(d)
            continue
        if any(moved(d, a, laser_pose, angle_min, increment, ARRIVED_SHARE) for a in arrived):
            d.motion, d.velocity, d.velocity_std = 'moving', (math.nan, math.nan), math.nan
            d.note = (d.note + '; ' if d.note else '') + (
                'came there: its place was seen free within a stride (%.1f s) before' % STRIDE)
            moving.append(d)
            continue
        d.motion, d.velocity = 'static', (0.0, 0.0)
        d.velocity_std = math.sqrt(2.0) * d.center_std / dt if dt > 0 else math.nan
        out.append(d)
    return out + moving
