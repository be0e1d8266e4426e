"""The obstacle_detection pipeline on one scan.

``circle_fit`` (default) and ``centroid``: scan → points in map → map subtraction (distance
transform) → centroid clustering → obstacle-shape filter → one centre per cluster.
The circle fit also uses the beams beside each cluster that went past it (a fitted circle may
not block them), and when an arc is too short for its radius to be measured (radius standard
error above ``max_radius_std``: a partly hidden obstacle) it fits the centre with a known
radius: ``obstacle_radius`` if set, else the median radius of the scan's well-measured
obstacles when those agree within ``radius_spread``; otherwise the free fit stands.
``shared_radius``: that median is also used for the well-measured obstacles whose own radius
agrees with it (within two standard errors).
With just one well-measured obstacle, its radius is a soft prior (std ``single_radius_std``)
for the short arcs it does not contradict (a chi-square test on their residuals).
The beams beside a cluster that the veil filter dropped (the first beam behind every silhouette
edge seen against a farther background) are looked past: the beams after them still count as
passing.

How sure each obstacle is (:class:`Detection`'s ``covariance``, ``center_std``,
``radius_std``; map frame), the sum of independent terms (:attr:`Detection.terms`):

* ``fit``: the centre relative to the laser (:attr:`Detection.fit_covariance`):
  :func:`tiago_nav.detection.centres.circle_covariance` of the fit that placed it (its points'
  Jacobian and residuals, widened when the residuals are correlated; a radius prior adds its
  information, a configured radius has none to estimate). ``centroid``: the points' spread over
  their number plus the centroid's offset from the fitted centre (its bias), squared.
  ``discontinuity``: the assumed depth as the std of everything (no fit);
* ``position`` and ``heading``: the laser pose's error carried to the centre,
  ``G Σ Gᵀ`` with ``G = [I | ℓ]``, ``ℓ = (-(c_y - l_y), c_x - l_x)`` the heading's lever arm
  (range × σ_yaw across the beam): ``heading`` is ``ℓ ℓᵀ σ_yaw²``, ``position`` the rest
  (the translation's covariance and its correlation with the heading). ``Σ``: the pose
  correction's (the registration's, :func:`tiago_nav.localisation.localiser.register_with_information`;
  along directions the scan does not observe the given pose's, which the correction kept)
  when it was applied, otherwise the given pose's (``pose_covariance`` of :meth:`locate`: the
  localisation's at the scan's time; None: the pose is taken as exact);
* ``raster``: what the 5 cm map leaves of the laser's pose. A straight wall lies anywhere
  within its raster cell, with an unknown offset and tilt that keep it inside the cell over
  its length (uniform over ``|a| + |t| L / 2 <= w / 2``: the offset at the middle of what is
  seen is triangular, variance ``w² / 24``). Along an axis the true position is within the
  intersection of the intervals the walls facing it allow
  (:func:`tiago_nav.localisation.localiser.refine_on_raster`, whose middle the correction takes), of
  width ``w``: variance ``w² / 24``; ``resolution² / 24`` (one wall's cell) along an axis no
  wall bounds, and for the given pose of a localisation (which registers to the same raster)
  when no correction was applied. The walls' offsets and tilts reach the registered heading
  (:func:`raster_heading_variance`), carried across the beam by the range as the heading's.

The map frame's centre carries all four; the robot frame's (``center_robot``, the laser on the
robot) the fit's alone.
``discontinuity``: the classic pipeline on the raw scan, without the map: range-jump segmentation,
each segment that stands out in front of its neighbours is an obstacle whose closest point is
pushed back by a fixed depth along its beam.

Pose correction (``correct_pose``, circle_fit and centroid): a centre in the map frame inherits
the error of the laser pose it is placed with (the localisation's estimate at the scan's time).
The scan's static part (the points the map subtraction explains) is already matched to the map,
so before clustering it is registered to the map's distance field with the localisation's own
registration (:func:`tiago_nav.localisation.localiser.register`, started from the given pose) and the
obstacles are placed with the corrected pose. Too few static points (``min_static_points``) or
a registration its gate rejects leave the given pose (:class:`PoseCorrection` says why).
``discontinuity`` is the classic map-free baseline: it reads no map, so it places its centres
with the given pose, uncorrected (its PoseCorrection says so).
"""
import math
from dataclasses import dataclass, field, replace

import numpy as np

from tiago_nav.detection.centres import (centroid, circle_covariance, circle_fit,
                                        correlation_inflation, radius_std)
import tiago_nav.detection.shapes as shapes
from tiago_nav.detection.clustering import centroid_clusters
from tiago_nav.detection.subtraction import MapDistance, subtract
from tiago_nav.geometry import transform_points, wrap_angle
from tiago_nav.gridmap import DistanceField
from tiago_nav.localisation.localiser import (LocaliserConfig, refine_on_raster,
                                    register_with_information)
from tiago_nav.params import ParamError, param, validate
from tiago_nav.scan import beam_angles, hits, scan_to_points, usable_ranges

METHODS = ('circle_fit', 'centroid', 'discontinuity')


@dataclass(frozen=True)
class DetectionParams:
    """The pipeline's parameters (lengths in metres, the map frame)."""
    # map subtraction and clustering
    scan_minus_map_threshold: float = param(
        0.12, '[m] scan points closer than this to an occupied map cell are the map\'s', ge=0)
    cluster_threshold: float = param(0.4, '[m] centroid clustering: join/merge distance', ge=0)
    gap: float = param(0.08, '[m] a cluster\'s points touch within this, or 3 beam spacings at '
                       'their range (+1 per invalid beam between them)', ge=0)
    # the obstacle-shape filter
    min_points: int = param(5, '[points] smaller clusters are noise', ge=0)
    min_radius: float = param(0.03, '[m] a fitted radius below this is not an obstacle', ge=0)
    max_radius: float = param(0.6, '[m] a fitted radius above this is not an obstacle', ge=0)
    max_fit_rms: float = param(0.03, '[m] circle-fit residual above this: not round', ge=0)
    # the circle fit
    obstacle_radius: float = param(0.0, '[m] > 0 fixes the radius of the circle fit (0: fit it)',
                                   ge=0)
    max_radius_std: float = param(
        0.02, '[m] a fitted radius with a std error above this (a short, hidden arc): fit the '
        'centre with the median radius of the scan\'s well-measured obstacles', ge=0)
    radius_spread: float = param(0.03, '[m] ... when those radii agree within this', ge=0)
    shared_radius: bool = param(
        True, 'when the scan\'s well-measured radii agree (radius_spread), fit every obstacle '
        'whose own radius is within 2 std errors of their median with that radius too: a fixed '
        'radius pinned by several obstacles reduces the centre\'s error along the beam')
    single_radius_std: float = param(
        0.06, '[m] when just one obstacle of the scan is well measured, its radius is a prior of '
        'this std for the short arcs that do not contradict it (the fit is the compromise of '
        'both; 0: not used)', ge=0)
    range_noise: float = param(0.01, '[m] the laser\'s range noise std (least residual assumed '
                               'when judging a fitted radius\'s precision)', ge=0)
    max_range: float = param(10.0, '[m] beams longer than this are ignored', ge=0)
    # shapes other than circles (circle_fit only)
    shapes: bool = param(
        False, 'also report what is not round: boxes (rectangle, an L-shape fit), tables\' and '
        'chairs\' legs grouped into one object and people\'s legs (legs), and unknown (see '
        'tiago_nav.detection.shapes; off by default: it reads a cylinder half hidden behind '
        'another of another radius as a person\'s leg (the course suite\'s centre RMS 2.2 cm, '
        'not 1.5), and its targets are not met: docs/detection.md#shapes)')
    # the discontinuity method
    jump: float = param(0.15, '[m] discontinuity method: range jump between segments', ge=0)
    depth: float = param(0.2, '[m] discontinuity method: closest point pushed back this far', ge=0)
    max_width: float = param(1.0, '[m] discontinuity method: wider segments are walls', ge=0)
    # the pose correction
    correct_pose: bool = param(
        True, 'register the scan\'s static part (points within scan_minus_map_threshold of the '
        'map) to the map and place the obstacles with the corrected laser pose (circle_fit, '
        'centroid; discontinuity reads no map and is never corrected)')
    min_static_points: int = param(
        80, '[points] fewer static points than this (or fewer within 0.1 m of the map after '
        'registering): too little map to register, the given pose is kept and the answer says '
        'so', ge=3)

    def __post_init__(self):
        validate(self)
        if self.min_radius > self.max_radius:
            raise ParamError('must be <= max_radius (%g), got %g'
                             % (self.max_radius, self.min_radius), 'min_radius')


TERMS = ('fit', 'position', 'heading', 'raster')    # the covariance's terms (module doc)


@dataclass
class Detection:
    """One obstacle: centre ``(x, y)`` [m] in the map frame, radius [m], supporting points,
    and ``covariance``: ``(3, 3)`` of ``(x, y, radius)`` [m², map frame] (None: not known), the
    sum of the ``(2, 2)`` centre terms ``terms`` (:data:`TERMS`, see the module's doc);
    ``fit_covariance``: the fit's own ``(3, 3)`` (the centre relative to the laser, map axes)."""
    center: tuple
    radius: float
    num_points: int
    points: np.ndarray = field(repr=False, default=None)
    covariance: np.ndarray = field(repr=False, default=None)
    fit_covariance: np.ndarray = field(repr=False, default=None)
    terms: dict = field(repr=False, default=None)
    # the shape (tiago_nav.detection.shapes): 'circle', 'rectangle', 'legs' or 'unknown';
    # extent (length, width) [m] along orientation [rad, map frame] and across (NaN: not
    # observed); center_fixed False when the points bound the centre without fixing it (the
    # covariance then spans what is possible); note: what was seen; legs: (K, 2) leg centres
    shape: str = 'circle'
    extent: tuple = None
    orientation: float = math.nan
    orientation_std: float = math.nan
    extent_std: tuple = (math.nan, math.nan)
    center_fixed: bool = True
    note: str = ''
    legs: np.ndarray = field(repr=False, default=None)
    kind: str = ''
    # motion over the scans at rest (tiago_nav.detection.motion): 'static', 'moving' or
    # 'unknown' (one scan); velocity (vx, vy) [m/s, map frame] (NaN: not measured)
    motion: str = 'unknown'
    velocity: tuple = (math.nan, math.nan)
    velocity_std: float = math.nan

    def __post_init__(self):
        if self.extent is None:
            self.extent = (2.0 * self.radius, 2.0 * self.radius)
        if self.fit_covariance is None and self.covariance is not None:
            self.fit_covariance = np.asarray(self.covariance, dtype=float)
        if self.terms is None and self.fit_covariance is not None:
            self.terms = {'fit': np.asarray(self.fit_covariance, dtype=float)[:2, :2]}

    @property
    def center_covariance(self):
        """The centre's ``(2, 2)`` covariance [m², map frame] (``inf`` when not known)."""
        if self.covariance is None:
            return np.full((2, 2), np.inf)
        return np.asarray(self.covariance, dtype=float)[:2, :2]

    @property
    def center_std(self):
        """[m] the centre's standard deviation along its least certain direction: the square
        root of the largest eigenvalue of :attr:`center_covariance` (``inf``: not known)."""
        c = self.center_covariance
        if not np.all(np.isfinite(c)):
            return math.inf
        return float(math.sqrt(max(np.linalg.eigvalsh(c).max(), 0.0)))

    @property
    def radius_std(self):
        """[m] the radius's standard deviation (0: the radius was given; ``inf``: not known)."""
        if self.covariance is None:
            return math.inf
        v = float(np.asarray(self.covariance, dtype=float)[2, 2])
        return math.sqrt(v) if v >= 0 else math.inf


@dataclass(frozen=True)
class PoseCorrection:
    """What the pose correction did to one scan's laser pose (map frame).

    ``applied``: whether the obstacles were placed with the corrected pose; ``laser_pose``:
    the pose they were placed with ``(x, y, yaw)`` [m, m, rad] (the given one when not
    applied); ``delta``: ``laser_pose`` minus the given pose, ``(dx, dy, dyaw)`` [m, m, rad]
    (zeros when not applied); ``static_points``: scan points the map explains; ``inliers``:
    of them, within the localisation's ``inlier_distance`` of the map after registering;
    ``reason``: why no correction was applied ('' when it was); ``covariance``: ``(3, 3)`` of
    ``laser_pose`` ``(x, y, yaw)`` [m², m·rad, rad²] (None: taken as exact), ``raster``: the
    variances [m², m², rad²] that the map's raster adds to its x, y and heading (see the
    module's doc).
    """
    applied: bool
    laser_pose: tuple
    delta: tuple = (0.0, 0.0, 0.0)
    static_points: int = 0
    inliers: int = 0
    reason: str = ''
    covariance: np.ndarray = field(repr=False, default=None, compare=False)
    raster: tuple = (0.0, 0.0, 0.0)

    def describe(self):
        """One phrase for a service answer's message."""
        if self.applied:
            return ('pose corrected by (%+.3f m, %+.3f m, %+.2f deg) from %d static points'
                    % (self.delta[0], self.delta[1], math.degrees(self.delta[2]),
                       self.static_points))
        return 'pose not corrected: %s' % self.reason


@dataclass
class Result:
    """One scan's detections and the pose correction they were placed with."""
    detections: list
    correction: PoseCorrection


# The registration of the static part: the localisation's, with its gate (a correction larger
# than max_correction / max_correction_yaw_deg is implausible at a stop) and its subsampling
# (at most max_points, 240, evenly: the correction's precision is far below the map raster's
# bias with them, and the registration's cost halves on a full scan). 6 Gauss-Newton
# iterations (3 loss scales) instead of 12: the start is the localisation's estimate, a few cm
# off; over 30 course scans with 2 cm / 0.7 deg errors the result moved at most 0.3 mm /
# 0.01 deg, at about half the cost.
REGISTRATION = LocaliserConfig(iterations=6, raster_band=False)


class ObstacleDetector:
    """Holds the map's distance transform (computed once per map), and its signed distance
    field for the pose correction (built at the first correction), and runs the pipeline."""

    def __init__(self, grid, params=DetectionParams()):
        self.grid = grid
        self.params = params
        self.distance = MapDistance(grid)
        self._field = None
        if params.correct_pose:        # a per-map cost: paid with the map, not by the first call
            self.field

    @property
    def field(self):
        """The map's :class:`tiago_nav.gridmap.DistanceField` (built once, when first
        needed)."""
        if self._field is None:
            self._field = DistanceField(self.grid)
        return self._field

    def detect(self, ranges, angle_min, angle_increment, range_min, range_max, laser_pose,
               method='circle_fit', laser_in_base=None, pose_covariance=None, **overrides):
        """Obstacles in one scan: the :class:`Detection` s of :meth:`locate` (see there)."""
        return self.locate(ranges, angle_min, angle_increment, range_min, range_max, laser_pose,
                           method, laser_in_base, pose_covariance, **overrides).detections

    def locate(self, ranges, angle_min, angle_increment, range_min, range_max, laser_pose,
               method='circle_fit', laser_in_base=None, pose_covariance=None, **overrides):
        """Obstacles in one scan, and the pose correction they were placed with.

        ``ranges`` [m] of beams from ``angle_min`` [rad] in steps of ``angle_increment`` in
        base_laser_link; ``laser_pose`` ``(x, y, yaw)`` is base_laser_link in the map frame at the
        scan's time, ``laser_in_base`` in base_footprint (from tf; None: no body to filter);
        ``pose_covariance``: ``(3, 3)`` of ``laser_pose`` [m², m·rad, rad²] (the localisation's
        at the scan's time; None: ``laser_pose`` is exact).
        Only the beams :func:`tiago_nav.scan.usable_ranges` keeps are used (no self-hits, no
        veils; the classic ``discontinuity`` method keeps the veils: it reads the raw scan). ``overrides`` replace fields of the params for this call (0 or None keeps the
        default). Returns a :class:`Result`: :class:`Detection` s sorted by distance from the
        laser, and the :class:`PoseCorrection` (``correct_pose``).
        Raises ValueError for an unknown method.
        """
        if method not in METHODS:
            raise ValueError('unknown method %r (expected one of %s)' % (method, ', '.join(METHODS)))
        changed = {k: v for k, v in overrides.items() if v}
        p = replace(self.params, **changed) if changed else self.params
        given = None if pose_covariance is None else np.asarray(pose_covariance, dtype=float)
        body = (dict(radius=0.0, margin=0.0) if laser_in_base is None
                else dict(laser_pose=tuple(laser_in_base)))
        raw = np.asarray(ranges, dtype=float)
        if method == 'discontinuity':
            # the classic pipeline reads the raw scan, less the robot's own body (no veil filter)
            body['shadow_angle'] = 0.0
        r = usable_ranges(raw, angle_min, angle_increment, range_min, range_max, **body)
        if method == 'discontinuity':
            # the beams the filter dropped are left out, not read as far (a gap is no edge)
            keep = ~(np.isnan(r) & ~np.isnan(raw))
            found = _discontinuity(r[keep], beam_angles(angle_min, angle_increment, len(r))[keep],
                                   angle_increment, range_min, min(range_max, p.max_range),
                                   laser_pose, p)
            correction = PoseCorrection(False, tuple(laser_pose),
                                        reason='the discontinuity method reads no map')
        else:
            veiled = None
            if p.shapes and method == 'circle_fit':
                # the beams the veil rule dropped (not the body's): a thin leg's may come back
                veiled = np.isnan(r) & ~np.isnan(usable_ranges(
                    raw, angle_min, angle_increment, range_min, range_max,
                    **dict(body, shadow_angle=0.0)))
            found, correction = self._clusters(r, angle_min, angle_increment, range_min,
                                               range_max, min(range_max, p.max_range),
                                               tuple(laser_pose), method, p, raw, given, veiled)
        if not correction.applied and given is not None:
            # placed with the given pose: the localisation's covariance, and the raster it
            # registers to (one wall's cell along each axis)
            cell = self.grid.resolution ** 2 / 24.0
            correction = replace(correction, covariance=given, raster=(cell, cell, 0.0))
        for d in found:
            add_pose_terms(d, correction)
        lx, ly = correction.laser_pose[0], correction.laser_pose[1]
        return Result(sorted(found, key=lambda d: math.hypot(d.center[0] - lx, d.center[1] - ly)),
                      correction)

    def correct(self, local, laser_pose, static, p, given=None):
        """The :class:`PoseCorrection` of the laser pose ``laser_pose`` (map) from the scan
        points ``local`` [m] (laser frame) the map explains (mask ``static``); ``given``: the
        covariance of ``laser_pose`` (None: exact), which the correction keeps along the
        directions the scan does not observe."""
        n = int(np.count_nonzero(static))
        if not p.correct_pose:
            return PoseCorrection(False, laser_pose, static_points=n,
                                  reason='correct_pose is off')
        if n < p.min_static_points:
            return PoseCorrection(False, laser_pose, static_points=n,
                                  reason='only %d scan points on the map (min_static_points %d)'
                                  % (n, p.min_static_points))
        c = REGISTRATION
        pts = local[static]
        if n > c.max_points:
            pts = pts[np.linspace(0, n - 1, c.max_points).round().astype(int)]
        pose, cov, _, info = register_with_information(self.field, pts, laser_pose, c)
        if info.degenerate and given is not None:
            weak = info.weak_projector()
            cov = cov + weak @ given @ weak.T
        # the raster's band with every static point: more of them on each wall than the
        # registration's subsample
        pose, _, widths = refine_on_raster(self.field, local[static], pose, noise=p.range_noise,
                                           widths=True)
        cell = self.grid.resolution
        raster = tuple((cell if w is None else w) ** 2 / 24.0 for w in widths) + (
            raster_heading_variance(self.field, local[static], pose, c.robust_scale),)
        res = self.field(transform_points(pose, pts))[0]
        # inliers among the points used, scaled to the static part
        inliers = int(round(np.sum(np.abs(res) < c.inlier_distance) * n / len(pts)))
        delta = (pose[0] - laser_pose[0], pose[1] - laser_pose[1],
                 wrap_angle(pose[2] - laser_pose[2]))
        reason = ''
        if inliers < p.min_static_points:
            reason = ('only %d of %d static points within %.2f m of the map after registering '
                      '(min_static_points %d)' % (inliers, n, c.inlier_distance,
                                                  p.min_static_points))
        elif math.hypot(delta[0], delta[1]) > c.max_correction \
                or abs(delta[2]) > math.radians(c.max_correction_yaw_deg):
            reason = ('the registration\'s correction (%.2f m, %.1f deg) is implausible'
                      % (math.hypot(delta[0], delta[1]), math.degrees(abs(delta[2]))))
        if reason:
            return PoseCorrection(False, laser_pose, static_points=n, inliers=inliers,
                                  reason=reason)
        return PoseCorrection(True, pose, delta, n, inliers, covariance=cov, raster=raster)

    def _clusters(self, r, angle_min, inc, rmin, laser_max, rmax, laser_pose, method, p,
                  raw=None, given=None, veiled=None):
        """The detections of the circle_fit and centroid methods (see :meth:`locate`): ``r``
        the usable ranges [m], ``raw`` the scan's own (None: ``r``), for the beams beside a
        cluster that the veil filter dropped; ``veiled``: the beams the veil rule dropped
        (bool per beam; None: none given back to thin legs, :func:`shapes.veiled_leg_beams`)."""
        raw = r if raw is None else raw
        local, beam = scan_to_points(r, angle_min, inc, rmin, rmax)
        # invalid beams (NaN, inf, out of limits) just before each valid one: a hole in the scan
        # must not split an obstacle
        holes = np.diff(np.concatenate(([-1], beam))) - 1
        pts = transform_points(laser_pose, local)
        keep = subtract(pts, self.distance, p.scan_minus_map_threshold)
        correction = self.correct(local, laser_pose, ~keep, p, given)
        if correction.applied:
            laser_pose = correction.laser_pose
            pts = transform_points(laser_pose, local)
            keep = subtract(pts, self.distance, p.scan_minus_map_threshold)
        pts, beam, holes = pts[keep], beam[keep], holes[keep]
        sensor = np.array(laser_pose[:2])
        rng = np.hypot(*(pts - sensor).T) if len(pts) else np.empty(0)
        cands, cand_idx = [], []
        round_pts = np.zeros(len(pts), dtype=bool)
        for idx in centroid_clusters(pts, p.cluster_threshold, _gap(rng, inc, p.gap, holes)):
            c = pts[idx]
            if len(c) < p.min_points:
                continue
            passing = _passing_rays(r, beam[idx], rng[idx], angle_min, inc, laser_pose[2],
                                    laser_max, raw)
            margin = PASSING_MARGIN * inc * float(rng[idx].max())
            cx, cy, rad, rms = circle_fit(c, sensor=sensor, passing=passing, margin=margin)
            if _is_obstacle(c, (cx, cy), rad, rms, sensor, p) and not (
                    p.shapes and method == 'circle_fit'
                    and (shapes.rectangle_not_circle(c, sensor, rms, p.range_noise)
                         or shapes.split_pair(c, sensor, inc, p.range_noise) is not None)):
                cands.append((c, cx, cy, rad, rms, radius_std(c, cx, cy, rad, p.range_noise),
                              passing, margin))
                cand_idx.append(idx)
                round_pts[idx] = True
        if p.shapes and method == 'circle_fit':
            # the end of a box's face that the clustering cut off is no circle: its points go
            # back to the face
            drop = shapes.face_pieces(pts, beam, cand_idx, round_pts, sensor, inc, r,
                                      p.range_noise, p.gap)
            for k in drop:
                round_pts[cand_idx[k]] = False
            cands = [c for k, c in enumerate(cands) if k not in drop]
        # The radius to assume where an arc is too short to measure it: the configured one, or,
        # when at least two obstacles of this scan are well measured and agree (all within
        # radius_spread), their median. With shared_radius, an obstacle whose own radius agrees
        # with that median (within 2 of its std errors) is fitted with it too: the radius and the
        # centre's range trade off in a free fit, so a radius pinned by several obstacles places
        # each centre better along its beams (the course scene, four cylinders of 0.183 m: centre
        # RMS 6-11 mm per obstacle -> 4-6.5 mm). When just one is well measured, its radius is a
        # soft prior (std single_radius_std) for the short arcs it does not contradict (the
        # prior's fit raises the points' squared residuals by less than a chi-square test with
        # one degree of freedom allows): the fit is then the compromise of the arc's radius and
        # that one, each by its precision (a cylinder half hidden behind a nearer one, seen by 6
        # beams at 6.5 m, has a radius std error of 4-10 cm on its own: its free fit put the
        # centre 8 cm off, 0.29 m for 0.22 m).
        # Otherwise the free fit stands, and its covariance says how little it knows.
        prior, prior_std, soft = p.obstacle_radius, 0.0, None
        if prior <= 0:
            good = [(k[3], k[5]) for k in cands if k[5] <= p.max_radius_std]
            radii = [g[0] for g in good]
            if len(good) >= 2 and max(radii) - min(radii) <= p.radius_spread:
                prior = float(np.median(radii))
                # what the median knows of the radius (for the covariance only)
                prior_std = max(float(np.median([g[1] for g in good])) / math.sqrt(len(good)),
                                (max(radii) - min(radii)) / 2.0)
            elif len(good) == 1 and p.single_radius_std > 0:
                soft = (radii[0], p.single_radius_std)
        out, shared = [], []        # shared: the circles fitted with that common radius
        for c, cx, cy, rad, rms, std, passing, margin in cands:
            cov = None
            if method == 'centroid':
                # the centroid lies between the centre and the sensor: its error is of the order
                # of its offset from the fitted centre, plus the points' spread over their number
                gx, gy = centroid(c)
                bias2 = (gx - cx) ** 2 + (gy - cy) ** 2
                cov = np.zeros((3, 3))
                cov[:2, :2] = np.cov(np.asarray(c, dtype=float).T) / len(c) + bias2 * np.eye(2)
                cov[2, 2] = circle_covariance(c, cx, cy, rad)[2, 2]
                cx, cy = gx, gy
            elif p.obstacle_radius > 0 or (prior > 0 and (
                    std > p.max_radius_std
                    or (p.shared_radius and abs(rad - prior) <= min(p.radius_spread, 2 * std)))):
                fx, fy, frad, frms = circle_fit(c, prior, sensor, passing, margin)
                if frms <= p.max_fit_rms:
                    # the shared radius is known no better than its spread, nor than this arc's
                    # own radius disagrees with it (the covariance only: a cylinder of another
                    # size among alike ones is then reported as less sure)
                    known = max(prior_std, abs(rad - prior))
                    cx, cy, rad = fx, fy, frad
                    cov = circle_covariance(
                        c, cx, cy, rad, fixed=p.obstacle_radius > 0,
                        radius_prior=None if p.obstacle_radius > 0 else (prior, known))
                    shared.append(len(out))
            elif soft is not None and std > p.max_radius_std:
                fx, fy, frad, frms = circle_fit(c, 0.0, sensor, passing, margin,
                                                radius_prior=soft, noise=p.range_noise)
                # the prior must not contradict the arc: its points' squared residuals may grow
                # by no more than a chi-square test with one degree of freedom allows (95 %,
                # 3.84 noise variances; the noise: the free fit's residuals, at least
                # range_noise)
                n_c = len(c)
                s2 = max(n_c * rms * rms / max(n_c - 3, 1), p.range_noise ** 2)
                if frms <= p.max_fit_rms and n_c * (frms * frms - rms * rms) <= CHI2_1 * s2:
                    cx, cy, rad = fx, fy, frad
                    cov = circle_covariance(c, cx, cy, rad, radius_prior=soft)
            if cov is None:
                cov = circle_covariance(c, cx, cy, rad)
            out.append(Detection((cx, cy), rad, len(c), c, cov))
        if p.shapes and method == 'circle_fit':
            view = shapes.ScanView(r, angle_min, inc, laser_pose, rmax, rmin,
                                   None if veiled is None else np.where(veiled, raw, np.nan))
            sp, sb = pts[~round_pts], beam[~round_pts]
            back = (shapes.veiled_leg_beams(sb, r, raw, veiled, p.range_noise)
                    if veiled is not None else np.empty(0, dtype=int))
            if back.size:
                ang = angle_min + inc * back
                bp = transform_points(laser_pose, np.column_stack((raw[back] * np.cos(ang),
                                                                   raw[back] * np.sin(ang))))
                ok = subtract(bp, self.distance, p.scan_minus_map_threshold)
                sp, sb = np.vstack((sp, bp[ok])), np.concatenate((sb, back[ok]))
                order = np.argsort(sb, kind='stable')
                sp, sb = sp[order], sb[order]
            others = _shape_detections(sp, sb, view, out, p, prior, [out[k] for k in shared])
            out = out + others      # (after the small circles that joined them left out)
        return out, correction


def pose_terms(center, laser_pose, covariance, raster=(0.0, 0.0, 0.0)):
    """The laser pose's share of a centre's covariance [m², map frame]: ``{'position',
    'heading', 'raster'}`` ``(2, 2)`` each (see the module's doc) for the centre ``(x, y)`` [m]
    placed with ``laser_pose`` ``(x, y, yaw)`` whose covariance is ``covariance`` ``(3, 3)``
    (None: exact) and to which the raster adds ``raster`` (variances along x, y [m²] and of the
    heading [rad²])."""
    lever = np.array([-(center[1] - laser_pose[1]), center[0] - laser_pose[0]])
    out = {'position': np.zeros((2, 2)), 'heading': np.zeros((2, 2)),
           'raster': np.diag([float(raster[0]), float(raster[1])])
           + np.outer(lever, lever) * float(raster[2] if len(raster) > 2 else 0.0)}
    if covariance is not None:
        s = np.asarray(covariance, dtype=float)
        cross = np.outer(s[:2, 2], lever)
        out['position'] = s[:2, :2] + cross + cross.T
        out['heading'] = np.outer(lever, lever) * s[2, 2]
    return out


def raster_heading_variance(field, points, pose, scale, inlier=0.05):
    """[rad²] the heading's variance that the map's raster leaves in a registration of the
    ``(N, 2)`` laser-frame ``points`` at ``pose`` (map frame) on ``field``.

    Each axis-aligned wall's surface lies somewhere in its raster cell, unknown: its points
    share one offset ``a`` and one tilt ``t`` (a wall a little off the axis has the same
    raster), uniform over what keeps the surface inside the cell over the length ``L`` seen
    (``|a| + |t| L / 2 <= resolution / 2``: variances ``resolution² / 24`` and
    ``resolution² / (6 L²)``), independent from wall to wall (:func:`tiago_nav.localisation.localiser.refine_on_raster` groups the points into
    walls the same way: the points facing one raster edge line, at least ``RASTER_GROUP_MIN``);
    on any other surface (an oblique wall's staircase, a static cylinder's outline) the points
    of one raster cell share one. Two walls facing one axis at different places turn the registered
    heading by the difference of their offsets over their distance. The registration's
    Gauss-Newton step for residual offsets ``b`` is ``-(JᵀWJ)⁻¹ JᵀW b`` (Cauchy weights at
    ``scale`` [m]), so the offsets' covariance reaches the pose as
    ``A⁻¹ (Σ_walls σ² s_g s_gᵀ) A⁻¹``, ``s_g`` the sum of ``w J`` over a wall's points; its
    heading entry is returned (the translation's share is the raster intervals' own)."""
    from tiago_nav.localisation.localiser import AXIS_COS, RASTER_GROUP_MIN
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(p) < 3:
        return 0.0
    q = transform_points(tuple(pose), p)
    r, gx, gy = field(q)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    dqx = -s * p[:, 0] - c * p[:, 1]
    dqy = c * p[:, 0] - s * p[:, 1]
    j = np.column_stack((gx, gy, gx * dqx + gy * dqy))
    w = 1.0 / (1.0 + (r / scale) ** 2)
    a = (j * w[:, None]).T @ j
    res = field.grid.resolution
    g = np.hypot(gx, gy)
    ok = (np.abs(r) <= inlier) & (g > 0.5)
    b = np.zeros((3, 3))
    wj = j * w[:, None]
    walled = np.zeros(len(p), dtype=bool)
    for axis, grad in ((0, gx), (1, gy)):
        face = ok & (np.abs(grad) >= AXIS_COS * g)
        if not np.any(face):
            continue
        sign = np.sign(grad)
        line = q[:, axis] - sign * r
        key = np.round(line / (res / 8.0)).astype(int) * 2 + (sign > 0)
        for k in np.unique(key[face]):
            sel = face & (key == k)
            if np.count_nonzero(sel) < RASTER_GROUP_MIN:
                continue
            walled |= sel
            # the surface within the band: an offset and a tilt, uniform over what keeps it
            # inside along the length seen (|a| + |t| L / 2 <= res / 2: var a = res² / 24,
            # var t = res² / (6 L²))
            along = q[sel, 1 - axis]
            length = max(float(along.max() - along.min()), res)
            s0 = wj[sel].sum(axis=0)
            s1 = (wj[sel] * (along - along.mean())[:, None]).sum(axis=0)
            b += np.outer(s0, s0) * res * res / 24.0 + np.outer(s1, s1) * res * res / (
                6.0 * length * length)
    # any other surface (an oblique wall's staircase, a static cylinder's outline): one
    # offset per raster cell, independent from cell to cell
    other = ok & ~walled
    if np.any(other):
        cells = np.floor(q[other] / res).astype(int)
        _, label = np.unique(cells, axis=0, return_inverse=True)
        sums = np.zeros((int(np.max(label)) + 1, 3))
        np.add.at(sums, np.ravel(label), wj[other])
        b += sums.T @ sums * res * res / 12.0
    if not np.any(b):
        return 0.0
    inv = np.linalg.pinv(a)
    return float(max((inv @ b @ inv)[2, 2], 0.0))


def add_pose_terms(d, correction):
    """Add to the :class:`Detection` ``d`` (its fit's covariance alone) the laser pose's
    share (:func:`pose_terms`) of the :class:`PoseCorrection` it was placed with."""
    fit = np.asarray(d.fit_covariance, dtype=float)
    terms = {'fit': fit[:2, :2]}
    terms.update(pose_terms(d.center, correction.laser_pose, correction.covariance,
                            correction.raster))
    total = fit.copy()
    if np.all(np.isfinite(fit[:2, :2])):
        total[:2, :2] = sum(terms[k] for k in TERMS)
    d.covariance, d.terms = total, terms


def _gap(ranges, inc, gap, holes=0):
    """Per point, the neighbour distance [m] below which points belong together: ``gap``, or
    three beam spacings at the point's range [m] when larger (beams spread with range, and more
    on oblique surfaces), plus one spacing per invalid beam (``holes``) just before the point."""
    return np.maximum(gap, (3.0 + np.asarray(holes)) * np.asarray(ranges, dtype=float) * inc)


CHI2_1 = 3.84        # the chi-square distribution's 95 % quantile with one degree of freedom
PASSING_BEAMS = 3     # beams each side of a cluster checked for going past it
PASSING_MARGIN = 0.25  # a passing beam may graze the fitted circle by this many beam spacings


def _passing_rays(r, beams, ranges, angle_min, inc, yaw, laser_max, raw=None):
    """Unit directions (map frame) of the beams beside a cluster (beam indices ``beams``,
    ranges ``ranges`` [m]) that went past it: walking out from each end of the cluster, up to
    ``PASSING_BEAMS`` beams with no return (+inf, REP 117) or a valid return (<= ``laser_max``)
    well behind the cluster's farthest point. The walk stops at the first beam that says nothing
    (NaN, out of limits: it may be a dropout on the obstacle itself) or hits something nearer.

    ``r`` are the usable ranges (:func:`tiago_nav.scan.usable_ranges`), ``raw`` the scan's own
    (None: ``r``). The veil filter drops the first beam behind every silhouette edge seen
    against a farther background (the step from the edge to it lies along the beam, as a mixed
    pixel's does), so a beam it dropped whose raw return lies well behind the cluster is not
    taken as passing (a mixed pixel's beam may still graze the obstacle) but does not end the
    walk either: it has a return, and it is behind, so the obstacle's edge is at most there.
    Without this every silhouette edge against a wall would have no passing beam, and a short
    arc's circle would grow unchecked on that side."""
    lo, hi, n = int(beams.min()), int(beams.max()), len(r)
    raw = r if raw is None else raw
    behind = float(ranges.max()) + 0.1
    keep = []
    for start, step in ((lo - 1, -1), (hi + 1, 1)):
        j = start
        while 0 <= j < n and abs(j - start) < PASSING_BEAMS:
            v = float(r[j])
            if v != v and j == start and behind < float(raw[j]) <= laser_max:
                j += step            # the veil filter's drop at the edge: look past it
                continue
            if not (v == math.inf or (behind < v <= laser_max)):
                break
            keep.append(j)
            j += step
    a = yaw + angle_min + inc * np.asarray(keep, dtype=float)
    return np.column_stack((np.cos(a), np.sin(a))).reshape(-1, 2)


def _is_obstacle(c, centre, rad, rms, sensor, p):
    """A round obstacle seen from ``sensor``: a fitted radius in range, a small residual, and an
    arc that bulges toward the sensor (its centre lies beyond its points)."""
    if not (p.min_radius <= rad <= p.max_radius) or rms > p.max_fit_rms:
        return False
    to_centre = np.hypot(centre[0] - sensor[0], centre[1] - sensor[1])
    to_points = float(np.mean(np.hypot(*(c - sensor).T)))
    return to_centre > to_points


def _discontinuity(r, ang, inc, rmin, rmax, laser_pose, p):
    """Range-jump segmentation of the scan (no map): ranges ``r`` [m] of the beams at angles
    ``ang`` [rad] (consecutive beams of a step ``inc``, some left out)."""
    n = len(r)
    valid = hits(r, rmin, rmax)
    points = np.column_stack((r * np.cos(ang), r * np.sin(ang)))
    rr = np.where(valid, r, np.inf)
    # REP 117: -inf is something nearer than range_min (no dip in front of it); NaN and
    # out-of-limit values say nothing and count as far, as +inf (no return) does
    rr[np.isneginf(r)] = 0.0
    # segment boundaries where the range jumps (or validity changes)
    with np.errstate(invalid='ignore'):
        jumps = np.flatnonzero(~(np.abs(np.diff(rr)) <= p.jump)) + 1
    starts = np.concatenate(([0], jumps))
    ends = np.concatenate((jumps, [n]))
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
        width = 2 * np.min(near) * math.tan((ang[e - 1] - ang[s] + inc) / 2)
        if width > p.max_width:
            continue
        k = s + int(np.argmin(near))
        d = rr[k] + p.depth
        local = np.array([[d * math.cos(ang[k]), d * math.sin(ang[k])]])
        cx, cy = transform_points(laser_pose, local)[0]
        pts = transform_points(laser_pose, points[s:e])     # a segment is all hits
        # no fit: the centre and the radius are the assumed depth's guess, off by about as much
        out.append(Detection((float(cx), float(cy)), p.depth, e - s, pts,
                             np.eye(3) * p.depth ** 2))
    return out


def _shape_detections(points, beams, view, circles, p, common=0.0, shared=()):
    """The :class:`Detection` s of what is not round (:func:`tiago_nav.detection.shapes.describe`
    on ``points``, map frame, the beams ``beams`` of the :class:`shapes.ScanView` ``view``); the
    small ``circles`` (an arc no wider than a leg, :data:`shapes.LEG_MAX_WIDTH`) that join a
    table's, a chair's or a person's legs become part of that ``legs`` object, and so does one
    of a person's leg's size alone (:func:`tiago_nav.detection.shapes.person_sized`: a person
    whose other leg is hidden); they are removed from ``circles``, in place. The others stay
    circles, and so does one alone that was fitted with the scan's ``common`` radius [m]
    (wider than a calf; ``shared``: the circles so fitted) and whose arc something nearer cuts
    (:func:`shapes.arc_cut`): its width is then only what the nearer thing left in view of a
    cylinder like the others."""
    sensor = np.array(view.pose[:2])
    small, extra = [], []
    for d in circles:
        # a leg's radius from its arc's width (a fitted radius on a few points is noisy, and
        # cloth round a calf is no cylinder: its fitted radius may be a wide one's)
        est = shapes.leg(d.points, sensor, view.inc, p.range_noise, round_checked=True)
        if est is not None:
            small.append(d)
            cut = shapes.arc_cut(d.points, view)
            round_cut = (cut and common > shapes.PERSON_LEG_RADIUS[1]
                         and any(d is e for e in shared))
            extra.append((shapes.Leg(est[0], est[1], None, est[2], est[3], round_cut, cut),
                          d.points))
    found, _ = shapes.describe(points, beams, view, p.range_noise, p.gap, extra)
    for s in found:
        for k in s.used:
            circles.remove(small[k])
    out = []
    for s in found:
        cov = np.zeros((3, 3))
        cov[:2, :2] = s.covariance
        half = 0.5 * math.hypot(*[v for v in s.extent if v == v]) if any(
            v == v for v in s.extent) else 0.0
        cov[2, 2] = math.nan if not s.center_fixed else float(np.nanmax(
            [v * v for v in s.extent_std] + [0.0]))
        d = Detection(s.center, half, len(s.points), s.points, cov, shape=s.shape,
                      extent=s.extent, orientation=s.orientation,
                      orientation_std=s.orientation_std, extent_std=s.extent_std,
                      center_fixed=s.center_fixed, note=s.note, legs=s.legs, kind=s.kind)
        out.append(d)
    return out
