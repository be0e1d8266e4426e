"""The static background of a laser standing still where there is no map.

The detection reports what the static map does not explain. A laser standing in a room nobody
mapped has no such map: everything would be unmapped, and a room's clutter (chair and table
legs, bins, door frames, cable ducts) passes as people's legs scan after scan. What stays put
is the room: over scans taken from one pose, each beam returns to the same surface whenever
nothing passes in front of it. :func:`background_ranges` keeps, per beam, the farthest range
a share of its hits gather at in most stretches of the recording (a person walking past covers
a beam for a moment at ranges that change; a person who stands in front of a wall hides it for
a while, and the wall is still the farthest surface seen there; a person who stands where the
beam sees nothing behind them is there for a stretch of the recording, not all along; only
someone who stands there for most of it is background, as a parked chair is);
:func:`background_map` draws those points into an occupancy grid that the pipeline subtracts
as it does a static map.

Frames: the laser's pose ``(x, y, yaw)`` [m, m, rad] in the map frame the grid is drawn in;
ranges [m] (REP 117).
"""
import math

import numpy as np

from tiago_nav.gridmap import OCCUPIED, GridMap
from tiago_nav.scan import HIT, classify


def background_ranges(scans, range_min, range_max, share=0.3, tolerance=0.05, min_hits=3,
                      parts=10, present=0.6):
    """Per beam, the static background's range [m] over ``scans`` (a ``(K, n)`` array or a
    list of ``(n,)`` range arrays of one laser at one pose, in the order they were taken): the
    farthest range within ``tolerance`` [m] of which at least ``share`` of the beam's hits (and
    ``min_hits``) lie, hit in at least ``present`` of the ``parts`` equal stretches of the
    recording (there all along, not for a while), the median of those hits; NaN where there is
    none (a beam that sees only what passes, at ranges that change, or what stood there for a
    while only). The farthest: a person standing in front of a wall for a while hides it, and
    the wall is still what stays; a share of the hits, not of the scans: a dark or glossy
    surface that returns in a few scans only is still there. Raises ValueError with no scans,
    scans of different lengths, ``share`` or ``present`` outside (0, 1] or ``parts`` < 1."""
    try:
        r = np.asarray(scans, dtype=float)
    except ValueError:
        raise ValueError('background_ranges: the scans must all have the same number of beams')
    if r.ndim != 2 or len(r) == 0:
        raise ValueError('background_ranges: need a (K, n) array of K >= 1 scans, got shape %s'
                         % (r.shape,))
    if not 0.0 < share <= 1.0:
        raise ValueError('background_ranges: share must be in (0, 1], got %g' % share)
    if not 0.0 < present <= 1.0 or int(parts) != parts or parts < 1:
        raise ValueError('background_ranges: present must be in (0, 1] and parts an integer '
                         '>= 1, got %g and %r' % (present, parts))
    ok = classify(r, range_min, range_max) == HIT
    out = np.full(r.shape[1], np.nan)
    part = np.minimum((np.arange(len(r)) * parts) // len(r), parts - 1)   # the scans' tenth
    need = max(1, int(math.ceil(present * min(parts, len(r)))))
    for j in np.flatnonzero(ok.sum(axis=0) >= min_hits):
        order = np.argsort(r[ok[:, j], j])
        h = r[ok[:, j], j][order]
        when = part[ok[:, j]][order]
        # hits within the tolerance of each hit: where that is a share of them, a surface
        near = (np.searchsorted(h, h + tolerance, side='right')
                - np.searchsorted(h, h - tolerance, side='left'))
        for k in np.flatnonzero(near >= max(min_hits, share * len(h)))[::-1]:   # farthest first
            on = np.abs(h - h[k]) <= tolerance
            if len(np.unique(when[on])) >= need:        # there all along, not for a while
                out[j] = float(np.median(h[on]))
                break
    return out


def background_map(background, angle_min, increment, laser_pose=(0.0, 0.0, 0.0), reach=None,
                   resolution=0.05):
    """An occupancy grid [``resolution`` m cells] of the background ranges ``background`` (of
    :func:`background_ranges`, beams from ``angle_min`` [rad] in steps of ``increment``): each
    finite range's point is an occupied cell, everything else free. The grid spans ``reach``
    [m] (None: the farthest background point plus a cell) around the laser at ``laser_pose``
    (map frame)."""
    b = np.asarray(background, dtype=float)
    keep = np.isfinite(b)
    a = laser_pose[2] + angle_min + increment * np.flatnonzero(keep)
    x = laser_pose[0] + b[keep] * np.cos(a)
    y = laser_pose[1] + b[keep] * np.sin(a)
    if reach is None:
        reach = (float(b[keep].max()) if np.any(keep) else 1.0) + resolution
    n = int(math.ceil(2.0 * reach / resolution)) + 2
    origin = (laser_pose[0] - reach - resolution, laser_pose[1] - reach - resolution)
    data = np.zeros((n, n), dtype=np.int8)
    col = np.floor((x - origin[0]) / resolution).astype(int)
    row = np.floor((y - origin[1]) / resolution).astype(int)
    inside = (col >= 0) & (col < n) & (row >= 0) & (row < n)
    data[row[inside], col[inside]] = OCCUPIED
    return GridMap(data, resolution, origin)
