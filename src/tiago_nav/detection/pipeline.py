"""The obstacle_detection pipeline on one scan.

``circle_fit`` (default) and ``centroid``: scan → points in map → map subtraction (distance
transform) → centroid clustering → obstacle-shape filter → one centre per cluster.
``discontinuity``: the classic pipeline on the raw scan, without the map: range-jump segmentation,
each segment that stands out in front of its neighbours is an obstacle whose closest point is
pushed back by a fixed depth along its beam.
"""
import math
from dataclasses import dataclass, field, replace

import numpy as np

from tiago_nav.detection.centres import centroid, circle_fit
from tiago_nav.detection.clustering import centroid_clusters
from tiago_nav.detection.subtraction import MapDistance, subtract
from tiago_nav.geometry import scan_to_points, transform_points

METHODS = ('circle_fit', 'centroid', 'discontinuity')


@dataclass(frozen=True)
class DetectionParams:
    """Defaults of the node (config/detection.yaml). Lengths in metres."""
    scan_minus_map_threshold: float = 0.12  # points closer than this to the map are the map's
    cluster_threshold: float = 0.4          # centroid distance to join or merge a cluster
    gap: float = 0.08                       # a cluster's points must touch within this (at 1 m;
                                            # grows with range as the beams spread)
    min_points: int = 5                     # fewer points: noise
    min_radius: float = 0.03                # fitted radius outside [min, max]: not an obstacle
    max_radius: float = 0.6
    max_fit_rms: float = 0.03               # residual of the circle fit above this: not round
    obstacle_radius: float = 0.0            # > 0: fit centres with this radius fixed
    max_range: float = 10.0                 # ignore beams longer than this
    jump: float = 0.15                      # discontinuity: range jump that separates segments
    depth: float = 0.2                      # discontinuity: closest point pushed back this far
    max_width: float = 1.0                  # discontinuity: wider segments are walls


@dataclass
class Detection:
    """One obstacle: centre ``(x, y)`` [m] in the map frame, radius [m], supporting points."""
    center: tuple
    radius: float
    num_points: int
    points: np.ndarray = field(repr=False, default=None)


class ObstacleDetector:
    """Holds the map's distance transform (computed once per map) and runs the pipeline."""

    def __init__(self, grid, params=DetectionParams()):
        self.grid = grid
        self.params = params
        self.distance = MapDistance(grid)

    def detect(self, ranges, angle_min, angle_increment, range_min, range_max, laser_pose,
               method='circle_fit', **overrides):
        """Obstacles in one scan.

        ``ranges`` [m] of beams from ``angle_min`` [rad] in steps of ``angle_increment`` in
        base_laser_link; ``laser_pose`` ``(x, y, yaw)`` is base_laser_link in the map frame at the
        scan's time. ``overrides`` replace fields of the params for this call (0 or None keeps
        the default). Returns :class:`Detection` s sorted by distance from the laser.
        Raises ValueError for an unknown method.
        """
        if method not in METHODS:
            raise ValueError('unknown method %r (expected one of %s)' % (method, ', '.join(METHODS)))
        p = replace(self.params, **{k: v for k, v in overrides.items() if v})
        r = np.asarray(ranges, dtype=float)
        if method == 'discontinuity':
            found = _discontinuity(r, angle_min, angle_increment, range_min,
                                   min(range_max, p.max_range), laser_pose, p)
        else:
            found = self._clusters(r, angle_min, angle_increment, range_min,
                                   min(range_max, p.max_range), laser_pose, method, p)
        lx, ly = laser_pose[0], laser_pose[1]
        return sorted(found, key=lambda d: math.hypot(d.center[0] - lx, d.center[1] - ly))

    def _clusters(self, r, angle_min, inc, rmin, rmax, laser_pose, method, p):
        local, _ = scan_to_points(r, angle_min, inc, rmin, rmax)
        pts = transform_points(laser_pose, local)
        keep = subtract(pts, self.distance, p.scan_minus_map_threshold)
        pts = pts[keep]
        sensor = np.array(laser_pose[:2])
        out = []
        for idx in centroid_clusters(pts, p.cluster_threshold, _gap(pts, sensor, inc, p.gap)):
            c = pts[idx]
            if len(c) < p.min_points:
                continue
            cx, cy, rad, rms = circle_fit(c)
            if not _is_obstacle(c, (cx, cy), rad, rms, sensor, p):
                continue
            if method == 'circle_fit':
                if p.obstacle_radius > 0:
                    cx, cy, rad, _ = circle_fit(c, p.obstacle_radius, sensor)
            else:
                cx, cy = centroid(c)
            out.append(Detection((cx, cy), rad, len(c), c))
        return out


def _gap(pts, sensor, inc, gap):
    """The neighbour distance [m] below which points belong together: ``gap`` at 1 m, growing
    with the beams' spacing at the farthest point (grazing beams spread up to ~3 spacings)."""
    if len(pts) == 0:
        return gap
    far = float(np.max(np.hypot(*(pts - sensor).T)))
    return max(gap, 3.0 * far * inc)


def _is_obstacle(c, centre, rad, rms, sensor, p):
    """A round obstacle seen from ``sensor``: a fitted radius in range, a small residual, and an
    arc that bulges toward the sensor (its centre lies beyond its points)."""
    if not (p.min_radius <= rad <= p.max_radius) or rms > p.max_fit_rms:
        return False
    to_centre = np.hypot(centre[0] - sensor[0], centre[1] - sensor[1])
    to_points = float(np.mean(np.hypot(*(c - sensor).T)))
    return to_centre > to_points


def _discontinuity(r, angle_min, inc, rmin, rmax, laser_pose, p):
    """Range-jump segmentation of the raw scan (no map)."""
    valid = np.isfinite(r) & (r >= rmin) & (r <= rmax)
    rr = np.where(valid, r, np.inf)
    n = len(rr)
    # segment boundaries where the range jumps (or validity changes)
    jumps = np.flatnonzero(~(np.abs(np.diff(rr)) <= p.jump)) + 1
    starts = np.concatenate(([0], jumps))
    ends = np.concatenate((jumps, [n]))
    ang = angle_min + inc * np.arange(n)
    out = []
    for s, e in zip(starts, ends):
        if not valid[s] or e - s < p.min_points:
            continue
        # a dip: both neighbours (when present) are farther away
        left = rr[s - 1] if s > 0 else np.inf
        right = rr[e] if e < n else np.inf
        near = rr[s:e]
        if not (left > near[0] + p.jump and right > near[-1] + p.jump):
            continue
        width = 2 * np.min(near) * math.tan((e - s) * inc / 2)
        if width > p.max_width:
            continue
        k = s + int(np.argmin(near))
        d = rr[k] + p.depth
        local = np.array([[d * math.cos(ang[k]), d * math.sin(ang[k])]])
        cx, cy = transform_points(laser_pose, local)[0]
        pts = transform_points(laser_pose, np.column_stack((near * np.cos(ang[s:e]),
                                                            near * np.sin(ang[s:e]))))
        out.append(Detection((float(cx), float(cy)), p.depth, e - s, pts))
    return out
