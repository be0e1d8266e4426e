"""Scoring the shapes detection reports (docs/detection.md#shapes) against the world's movable
obstacles: the one set of rules that the evaluator (a run's ``detection_shapes``, summary.md's
shapes table) and bench/bench_shapes.py judge shapes by. No ROS.

* **Label**: a ``cylinder`` is a ``circle``, a ``box`` a ``rectangle``, a ``table`` or a
  ``chair`` its ``legs`` grouped into one object (:data:`EXPECT`).
* **Extent** ``(length, width)`` [m]: a cylinder's is its diameter twice, a box's its sides, a
  table's or chair's the rectangle of its legs' centres (what the laser measures of it). Each
  reported side is compared with the true side it lies along (the reported ``orientation``
  says which; without one the longer with the longer); the error is the largest over the sides
  the detection reports (a NaN side is not observed: not scored).
* **Orientation** [deg]: of the footprint's length, modulo 180° (a rectangle turned half a
  turn is the same rectangle), modulo 90° for a square footprint (sides within
  :data:`SQUARE_TOL`) and for a box whose length the detection does not claim (it reports one
  side only, or its centre is not fixed: a face may go on behind what hides it, so which side
  is the longer is not known; the reported heading is then a face's).
* **Where the targets apply** (docs/detection.md's, the issue's acceptance): a box seen on two
  faces whole, a table or chair on three legs or more (:func:`seen_parts` of the noise-free
  cast); targets :data:`TARGET_CENTRE` and :data:`TARGET_ORIENTATION`.

Map (= world) frame; lengths in metres, angles in radians unless a name says ``_deg``.
"""
import math

import numpy as np

EXPECT = {'cylinder': 'circle', 'box': 'rectangle', 'table': 'legs', 'chair': 'legs'}
TARGET_CENTRE = 0.03          # [m] box, table and chair centres where the target applies
TARGET_ORIENTATION = 5.0      # [deg] their orientation there
TARGET_SHAPES = ('box', 'table', 'chair')
SQUARE_TOL = 0.05             # [m] a footprint whose sides differ by less is square
SHAPES = ('cylinder', 'box', 'table', 'chair')   # the order of the summary's rows


def label_agrees(true_shape, label):
    """Whether the reported ``label`` (``circle``, ``rectangle``, ``legs``, ``unknown``) is
    the one a ``true_shape`` (a world's ``cylinder``, ``box``, ``table``, ``chair``) must get."""
    return EXPECT.get(true_shape) == label


def true_extent(obj):
    """``(long, short, heading)``: the sides [m] of ``obj``'s footprint as the laser measures
    it (:mod:`tiago_nav.sim.world` shapes: a cylinder's diameter, a box's sides, a table's or
    chair's legs' centres) and the heading [rad] of the longer side (None for a cylinder)."""
    if obj.shape == 'cylinder':
        return 2.0 * obj.radius, 2.0 * obj.radius, None
    if obj.length >= obj.width:
        return obj.length, obj.width, obj.yaw
    return obj.width, obj.length, obj.yaw + math.pi / 2


def _finite(v):
    return v is not None and isinstance(v, (int, float)) and math.isfinite(v)


def length_claimed(extent, center_fixed):
    """Whether a detection claims which side is the length: it reports both sides and a fixed
    centre (two faces of a box seen whole, a table's legs grouped)."""
    e = list(extent or ())
    return len(e) == 2 and all(_finite(v) for v in e) and bool(center_fixed)


def orientation_period(obj, claimed=True):
    """[rad] the period a reported orientation of ``obj`` is judged modulo: pi/2 for a square
    footprint and for a box whose length the detection does not claim (``claimed``:
    :func:`length_claimed`), pi otherwise."""
    long_, short, _ = true_extent(obj)
    if long_ - short < SQUARE_TOL or (obj.shape == 'box' and not claimed):
        return math.pi / 2
    return math.pi


def orientation_error(orientation, obj, claimed=True):
    """[deg] error of a reported ``orientation`` [rad] (the length's heading, map frame) of
    ``obj``, modulo :func:`orientation_period`; None for a cylinder or a NaN orientation (not
    observable)."""
    if obj.shape == 'cylinder' or not _finite(orientation):
        return None
    period = orientation_period(obj, claimed)
    d = (orientation - true_extent(obj)[2]) % period
    return math.degrees(min(d, period - d))


def extent_error(extent, orientation, obj):
    """[m] the largest error of the reported sides ``extent`` ``(length, width)`` (NaN: not
    observed) against ``obj``'s (:func:`true_extent`), each compared with the true side it
    lies along by the reported ``orientation`` [rad] (a NaN one: the longer with the longer);
    None when no side is observed."""
    e = list(extent or ())[:2]
    if not any(_finite(v) for v in e):
        return None
    long_, short, heading = true_extent(obj)
    ref = (long_, short)
    if heading is not None and _finite(orientation):
        d = (orientation - heading) % math.pi
        if min(d, math.pi - d) > math.pi / 4:
            ref = (short, long_)                  # the reported length lies along the width
    return max(abs(v - t) for v, t in zip(e, ref) if _finite(v))


def seen_parts(obj, hit_points):
    """What the noise-free cast saw of ``obj`` from its ``(K, 2)`` usable hit points [m]: the
    faces of a box seen whole (>= 4 hits spanning 90 % of the face, less 5 cm), the legs of a
    table or chair with >= 2 hits; 0 for a cylinder."""
    p = np.asarray(hit_points, dtype=float).reshape(-1, 2)
    if obj.shape == 'box':
        c, s = math.cos(obj.yaw), math.sin(obj.yaw)
        u = (p - (obj.x, obj.y)) @ np.array([[c, -s], [s, c]])
        dx = np.abs(np.abs(u[:, 0]) - obj.length / 2)
        dy = np.abs(np.abs(u[:, 1]) - obj.width / 2)
        faces = np.where(dx < dy, 2 * (u[:, 0] > 0), 1 + 2 * (u[:, 1] > 0))
        n = 0
        for f in range(4):
            q = u[faces == f]
            along = q[:, 1] if f in (0, 2) else q[:, 0]
            full = obj.width if f in (0, 2) else obj.length
            # the face seen whole: its hits span 90 % of it (a face cut by something nearer,
            # or by the end of the fan, leaves the centre unfixed along it)
            if len(q) >= 4 and float(along.max() - along.min()) >= 0.9 * full - 0.05:
                n += 1
        return n
    if obj.shape in ('table', 'chair'):
        legs = obj.legs()
        if not len(p):
            return 0
        near = np.argmin(np.hypot(p[:, None, 0] - legs[None, :, 0], p[:, None, 1] - legs[None, :, 1]),
                         axis=1)
        return int(sum(np.count_nonzero(near == k) >= 2 for k in range(len(legs))))
    return 0


def target_applies(obj, parts):
    """Whether the centre and orientation targets apply to ``obj`` seen as ``parts``
    (:func:`seen_parts`): a box on two faces, a table or chair on three legs."""
    return (obj.shape == 'box' and parts >= 2) or (obj.shape in ('table', 'chair') and parts >= 3)


def parts_in_view(scene, base_pose, profile, indices):
    """``{index: seen_parts}`` for the movable obstacles ``indices`` of ``scene``
    (:class:`tiago_nav.sim.scene.Scene`) from ``base_pose`` ``(x, y, yaw)``: their hits in a
    noise-free cast on the ``profile``'s usable beams (:mod:`tiago_nav_tools.evaluate.inview`)."""
    from tiago_nav_tools.evaluate import inview
    ranges, ids = scene.cast(tuple(base_pose))
    ranges = np.asarray(ranges, dtype=float)
    ids = np.asarray(ids)
    angles = np.asarray(scene.laser.angles(), dtype=float)
    lx, ly, lyaw = scene.laser_pose(tuple(base_pose))
    usable = (np.abs(angles) <= inview.usable_angle(profile)) & (ranges <= inview.MAX_RANGE) \
        & np.isfinite(ranges)
    pts = np.column_stack((lx + ranges * np.cos(angles + lyaw), ly + ranges * np.sin(angles + lyaw)))
    out = {}
    for i in indices:
        obj = scene.world.movable_obstacles[i]
        out[i] = seen_parts(obj, pts[(ids == scene.movable_ids[i]) & usable])
    return out


def score(obstacles, rows, found_detail, parts=None):
    """Per true obstacle, its shape's scores: a list of dicts, one per row of ``rows``
    (``{'index', 'in_view', 'found', 'error'}``: an obstacle in view or matched, ``found`` the
    index of the found obstacle matched to it or None, ``error`` its centre error [m]).

    ``obstacles``: the world's movable obstacles; ``found_detail``: the reported
    tiago_nav/Obstacle messages as dicts (``shape``, ``extent``, ``orientation``,
    ``center_fixed``); ``parts``: ``{index: seen_parts}`` (None: not known).

    Each dict: ``index``, ``in_view``, ``shape`` (true), ``matched``, ``label`` (reported, None
    unmatched), ``label_agrees``, ``centre_error_m``, ``extent_error_m`` (None where no side is
    observed), ``orientation_error_deg`` (None where not observable), ``extent`` (reported,
    None for an unobserved side), ``true_extent`` ``[long, short]``, ``length_claimed``,
    ``center_fixed``, ``seen_parts``, ``target_applies``."""
    out = []
    for r in rows:
        i = r['index']
        obj = obstacles[i]
        long_, short, _ = true_extent(obj)
        k = (parts or {}).get(i)
        d = {'index': i, 'in_view': bool(r['in_view']), 'shape': obj.shape,
             'matched': r.get('found') is not None, 'label': None, 'label_agrees': None,
             'centre_error_m': r.get('error'), 'extent_error_m': None,
             'orientation_error_deg': None, 'extent': None, 'true_extent': [long_, short],
             'length_claimed': None, 'center_fixed': None, 'seen_parts': k,
             'target_applies': None if k is None else target_applies(obj, k)}
        j = r.get('found')
        if j is not None and j < len(found_detail or []):
            f = found_detail[j]
            label = f.get('shape') or None
            ext = [float(v) if _finite(v) else None for v in list(f.get('extent') or [])[:2]] or None
            orient = f.get('orientation')
            orient = float(orient) if _finite(orient) else None
            claimed = length_claimed(f.get('extent'), f.get('center_fixed', True))
            d.update(label=label, label_agrees=label_agrees(obj.shape, label),
                     extent=ext, length_claimed=claimed, center_fixed=f.get('center_fixed'),
                     extent_error_m=extent_error([math.nan if v is None else v for v in ext or ()],
                                                 math.nan if orient is None else orient, obj),
                     orientation_error_deg=orientation_error(orient, obj, claimed))
        out.append(d)
    return out


def summarise(results):
    """summary.json's ``shapes``: per profile, candidate and true shape, over the judged runs'
    ``detection_shapes``: ``in_view`` (obstacles in view), ``found`` (of them, matched),
    ``found_share``, ``matched`` (every matched one, glimpsed too: the errors' population),
    ``label_agrees`` (of the matched) and its share, centre, extent and orientation errors
    (``*_median``, ``*_p95``: nearest rank; ``*_n``: how many observed), and where the targets
    apply (``target_n``, ``target_centre_p95_m``, ``target_orientation_p95_deg``,
    ``target_centre_share`` and ``target_orientation_share``: within :data:`TARGET_CENTRE`,
    :data:`TARGET_ORIENTATION`). Sorted by profile, candidate, then :data:`SHAPES`."""
    from tiago_nav_tools.evaluate import metrics as M
    groups = {}
    for r in results:
        for s in r.get('detection_shapes') or []:
            groups.setdefault((str(r.get('profile')), str(r.get('candidate')), s['shape']), []).append(s)
    out = []

    def order(key):
        p, c, s = key
        return (p, c, SHAPES.index(s) if s in SHAPES else len(SHAPES), s)

    for key in sorted(groups, key=order):
        rows = groups[key]
        view = [s for s in rows if s['in_view']]
        found = [s for s in view if s['matched']]
        matched = [s for s in rows if s['matched']]
        agree = sum(bool(s['label_agrees']) for s in matched)
        g = {'profile': key[0], 'candidate': key[1], 'shape': key[2], 'in_view': len(view),
             'found': len(found), 'found_share': len(found) / len(view) if view else None,
             'matched': len(matched), 'label_agrees': agree,
             'label_share': agree / len(matched) if matched else None}
        for name, field in (('centre', 'centre_error_m'), ('extent', 'extent_error_m'),
                            ('orientation', 'orientation_error_deg')):
            v = [s[field] for s in matched if s[field] is not None]
            g[name + '_n'] = len(v)
            g[name + '_median'] = M.median(v)
            g[name + '_p95'] = M.percentile(v, 95)
        there = [s for s in matched if s['target_applies']]
        c = [s['centre_error_m'] for s in there if s['centre_error_m'] is not None]
        o = [s['orientation_error_deg'] for s in there if s['orientation_error_deg'] is not None]
        g.update(target_n=len(there) if key[2] in TARGET_SHAPES else 0,
                 target_centre_p95_m=M.percentile(c, 95) if key[2] in TARGET_SHAPES else None,
                 target_centre_share=(sum(e <= TARGET_CENTRE for e in c) / len(c))
                 if c and key[2] in TARGET_SHAPES else None,
                 target_orientation_p95_deg=M.percentile(o, 95) if key[2] in TARGET_SHAPES else None,
                 target_orientation_share=(sum(e <= TARGET_ORIENTATION for e in o) / len(o))
                 if o and key[2] in TARGET_SHAPES else None)
        out.append(g)
    return out
