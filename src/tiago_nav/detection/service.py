"""The obstacle_detection service's decisions on plain values (no ROS here): checking a request,
running the pipeline on one scan and composing the answer, std_srvs/Trigger style (``success``
false with the reason in ``message`` for every failure; true with no obstacles means "looked,
found none").

Frames: ``map`` (the static map and the results), the robot frame (``base_footprint``) and the
laser's (the scan's ``frame_id``), all named by the node's parameters. Units: metres, radians,
seconds.

:class:`DetectionService` reaches the sensors through a *sensors* object (the ROS one is in
:mod:`tiago_nav.nodes.obstacle_detection`; unit tests pass a fake) with four methods:

* ``fresh_scan(timeout)``: the first :class:`tiago_nav.scan.Scan` stamped at or after the call, or None after
  ``timeout`` wall seconds;
* ``scan_at(stamp, timeout, published)``: the first :class:`tiago_nav.scan.Scan` stamped at or after ``stamp``
  (a request's ``scan_stamp``: ``published`` True, the scan went out before the request),
  waiting up to ``timeout`` wall seconds for it (a published one: longer while its publisher
  lives); None when it does not come; :class:`Failure` when it is no longer held or its
  publisher is dead;
* ``scans_before(scan, count)``: up to ``count`` held scans stamped just before ``scan``,
  newest first (``[]`` when none is held);
* ``transform(target, source, stamp, timeout)``: the pose ``(x, y, yaw)`` of frame ``source`` in
  frame ``target`` at ``stamp``, waiting up to ``timeout`` wall seconds; raises
  :class:`LookupError` (its text says why) when there is none;
* ``pose_covariance(stamp)``: the localisation's ``(3, 3)`` covariance of the robot's pose
  ``(x, y, yaw)`` in the map frame [m², m·rad, rad²] at ``stamp`` (its last estimate stamped at
  or before it), or None when none is known (a ground-truth localisation publishes none: the
  pose is then taken as exact).

Scans at rest: the scan a call names is combined with the held scans just before it that were
taken from the same pose (the laser in the odometry frame within :data:`REST_TRANSLATION` and
:data:`REST_ROTATION`; ``rest_scans`` in all), by the per-beam median of their hits
(:func:`tiago_nav.scan.median_ranges`): a robot standing still sees the same scene in each, and
the median's range noise is about half a scan's for five. A scan taken while the robot moved
ends the run; a moving robot's call uses its one scan. The held scans from the same pose up to
a stride (:data:`tiago_nav.detection.motion.STRIDE`) before the named one, older than those,
say what came there meanwhile (:func:`tiago_nav.detection.motion.combine`).
"""
import math
import time
from dataclasses import dataclass

import numpy as np

from tiago_nav.detection import motion
from tiago_nav.detection.pipeline import METHODS, ObstacleDetector
from tiago_nav.geometry import compose, inverse, wrap_angle
from tiago_nav.scan import informative_fraction, median_ranges

# request fields that override a DetectionParams field (0 keeps the node's default)
REQUEST_THRESHOLDS = ('scan_minus_map_threshold', 'cluster_threshold')
REST_TRANSLATION = 0.001             # [m] two scans are from one pose within this ...
REST_ROTATION = math.radians(0.05)   # [rad] ... and this (odometry at rest does not move)
REST_TF_TIMEOUT = 0.1                # [s wall] for the transform at an earlier, held scan
STRIDE_SCANS = 48                    # held scans looked at for a stride back (1 s of a 40 Hz laser)


class Failure(Exception):
    """A call that gets no obstacles; ``str()`` is the message the caller sees."""


@dataclass(frozen=True)
class Found:
    """One obstacle of an answer."""
    center: tuple           # (x, y) [m] in the map frame
    center_robot: tuple     # (x, y) [m] in the robot frame at the scan's time
    radius: float           # [m]
    num_points: int         # scan points that support it
    center_std: float = math.inf           # [m] along the centre's least certain direction
    radius_std: float = math.inf           # [m] (0: the radius was configured)
    center_covariance: tuple = (math.inf, 0.0, 0.0, math.inf)   # [m²] map frame, row-major
    center_robot_covariance: tuple = (math.inf, 0.0, 0.0, math.inf)  # [m²] robot frame
    center_variance_terms: tuple = (math.inf, 0.0, 0.0, 0.0)  # [m²] fit, position, heading,
                                                              # raster along center_std's axis
    shape: str = 'circle'                  # 'circle', 'rectangle', 'legs' or 'unknown'
    extent: tuple = (math.nan, math.nan)   # [m] (length, width), NaN: not observed
    extent_std: tuple = (math.nan, math.nan)   # [m]
    orientation: float = math.nan          # [rad] map frame, in (-pi/2, pi/2]
    orientation_std: float = math.nan      # [rad]
    center_fixed: bool = True              # False: the centre is bounded, not fixed
    note: str = ''                         # what was seen
    motion: str = 'unknown'                # 'static', 'moving' or 'unknown' (one scan)
    velocity: tuple = (math.nan, math.nan)  # [m/s] map frame
    velocity_std: float = math.nan         # [m/s]


@dataclass(frozen=True)
class Answer:
    """The service's reply: ``obstacles`` nearest the robot first; ``stamp`` is the scan's
    (None when ``success`` is false)."""
    success: bool
    obstacles: tuple
    message: str
    stamp: object = None
    pose_correction: tuple = (0.0, 0.0, 0.0)   # (dx, dy, dyaw) [m, m, rad] added to the robot's
    pose_corrected: bool = False               # pose in map (corrected minus given)


def check_request(method, scan_minus_map_threshold, cluster_threshold, default_method):
    """The method a request asks for (``""``: ``default_method``).

    Raises :class:`Failure` naming the bad field: an unknown ``method``, a threshold that is
    negative or not finite (0 means the node's default).
    """
    method = method or default_method
    if method not in METHODS:
        raise Failure('bad request: unknown method %r: use one of %s'
                      % (method, ', '.join(METHODS)))
    for name, v in zip(REQUEST_THRESHOLDS, (scan_minus_map_threshold, cluster_threshold)):
        if not math.isfinite(v) or v < 0:
            raise Failure('bad request: %s must be >= 0 (0 = the node\'s default), got %g'
                          % (name, v))
    return method


def _sec(stamp):
    """A stamp (rospy.Time or seconds) in seconds."""
    return stamp.to_sec() if hasattr(stamp, 'to_sec') else float(stamp)


def _seconds(stamp):
    """A stamp (rospy.Time or seconds) as text, ``12.345 s``."""
    return '%.3f s' % (stamp.to_sec() if hasattr(stamp, 'to_sec') else float(stamp))


def check_scan(scan, min_fraction):
    """Raise :class:`Failure` when fewer than ``min_fraction`` of the beams of the :class:`tiago_nav.scan.Scan`
    say something (REP 117: a hit, no return or too close; NaN and finite values outside
    ``[range_min, range_max]`` say nothing): a NaN burst or a dead laser must not read as "no
    obstacles"."""
    f = informative_fraction(scan.ranges, scan.range_min, scan.range_max)
    if f < min_fraction:
        raise Failure('too few valid beams to judge: %.0f %% of the %d beams of this scan are '
                      'valid (NaN or outside [%g, %g] m otherwise), at least %.0f %% needed'
                      % (100 * f, len(scan.ranges), scan.range_min, scan.range_max,
                         100 * min_fraction))


def variance_terms(detection):
    """The variances [m²] of the :class:`tiago_nav.detection.Detection`'s terms
    (:data:`tiago_nav.detection.pipeline.TERMS`) along the least certain direction of its map
    covariance: they sum to ``center_std²``."""
    from tiago_nav.detection.pipeline import TERMS
    total = np.asarray(detection.center_covariance, dtype=float)
    if not np.all(np.isfinite(total)):
        return (math.inf,) + (0.0,) * (len(TERMS) - 1)
    v = np.linalg.eigh(total)[1][:, -1]
    return tuple(float(v @ detection.terms[k] @ v) if k in detection.terms else 0.0
                 for k in TERMS)


def found_obstacles(detections, laser_in_map, laser_in_robot):
    """:class:`Found` obstacles from the pipeline's detections (map frame), with their centres
    in the robot frame too, sorted by distance from the robot. The robot frame's covariance is
    the fit's alone (the laser is fixed on the robot), rotated into that frame.

    Args:
        detections: :class:`tiago_nav.detection.Detection` s, centres in the map frame.
        laser_in_map: ``(x, y, yaw)`` of the laser frame in the map frame at the scan's time.
        laser_in_robot: ``(x, y, yaw)`` of the laser frame in the robot frame.
    """
    to_robot = compose(laser_in_robot, inverse(laser_in_map))
    c, s = math.cos(to_robot[2]), math.sin(to_robot[2])
    rot = np.array([[c, -s], [s, c]])
    out = []
    for d in detections:
        rx, ry, _ = compose(to_robot, (d.center[0], d.center[1], 0.0))
        cov = d.center_covariance
        fit = np.asarray(d.fit_covariance, dtype=float)[:2, :2]
        robot = rot @ fit @ rot.T if np.all(np.isfinite(fit)) else np.full((2, 2), np.inf)
        out.append(Found((float(d.center[0]), float(d.center[1])), (rx, ry), float(d.radius),
                         int(d.num_points), d.center_std, d.radius_std,
                         tuple(float(v) for v in cov.ravel()),
                         tuple(float(v) for v in robot.ravel()), variance_terms(d),
                         d.shape, tuple(float(v) for v in d.extent),
                         tuple(float(v) for v in d.extent_std), float(d.orientation),
                         float(d.orientation_std), bool(d.center_fixed), d.note, d.motion,
                         tuple(float(v) for v in d.velocity), float(d.velocity_std)))
    out.sort(key=lambda o: math.hypot(*o.center_robot))
    return tuple(out)


def laser_covariance(robot_covariance, laser_in_map, laser_in_robot):
    """The ``(3, 3)`` covariance of the laser's pose in the map frame from the robot's
    (``robot_covariance``, of base_footprint's ``(x, y, yaw)`` in map; None gives None): the
    laser sits ``laser_in_robot`` on the robot, so the heading's error moves it across its
    offset."""
    if robot_covariance is None:
        return None
    robot = compose(laser_in_map, inverse(laser_in_robot))
    j = np.array([[1.0, 0.0, -(laser_in_map[1] - robot[1])],
                  [0.0, 1.0, laser_in_map[0] - robot[0]],
                  [0.0, 0.0, 1.0]])
    return j @ np.asarray(robot_covariance, dtype=float).reshape(3, 3) @ j.T


class DetectionService:
    """One DetectObstacles call after another, on the newest map.

    ``params`` has the fields of :class:`tiago_nav.nodes.obstacle_detection.Params`
    (``detection``, ``method``, ``scan_timeout``, ``tf_timeout``,
    ``min_informative_fraction``, ``rest_scans``, frames and topics).
    """

    def __init__(self, params):
        self.params = params
        self.detector = None
        self.map_error = 'no %s received yet' % params.map_topic
        self.elapsed_ms = None      # [ms] of the pipeline in the last successful call

    def set_map(self, grid, detector=None):
        """Use the :class:`tiago_nav.gridmap.GridMap` ``grid`` from now on (``detector``: its
        :class:`ObstacleDetector` with ``params.detection`` when already built; it holds only
        what the map and those parameters determine)."""
        self.detector = ObstacleDetector(grid, self.params.detection) if detector is None \
            else detector
        self.map_error = None

    def map_unusable(self, reason):
        """The newest map cannot be used (``reason``): calls fail until a usable one comes."""
        self.map_error = 'unusable %s: %s' % (self.params.map_topic, reason)   # set before the
        self.detector = None                                                  # detector goes

    def handle(self, method, scan_minus_map_threshold, cluster_threshold, sensors,
               scan_stamp=None):
        """Answer one request (the fields of DetectObstacles.srv) with ``sensors``;
        ``scan_stamp``: the request's (None or zero: the first scan after the call)."""
        try:
            method = check_request(method, scan_minus_map_threshold, cluster_threshold,
                                   self.params.method)
            detector = self.detector        # one map for the whole call (maps come meanwhile)
            if detector is None:
                raise Failure(self.map_error)
            if scan_stamp:
                scan = sensors.scan_at(scan_stamp, self.params.scan_timeout, published=True)
                if scan is None:
                    raise Failure('no %s stamped at or after %s received within %.1f s'
                                  % (self.params.scan_topic, _seconds(scan_stamp),
                                     self.params.scan_timeout))
            else:
                scan = sensors.fresh_scan(self.params.scan_timeout)
                if scan is None:
                    raise Failure('no %s received within %.1f s' % (self.params.scan_topic,
                                                                     self.params.scan_timeout))
            check_scan(scan, self.params.min_informative_fraction)
            laser_in_map, laser_in_robot = self._poses(scan, sensors)
            rest, before = self._at_rest(scan, sensors)
            given = laser_covariance(sensors.pose_covariance(scan.stamp), laser_in_map,
                                     laser_in_robot)
            return self._detect(detector, scan, rest, laser_in_map, laser_in_robot, method,
                                scan_minus_map_threshold, cluster_threshold, given, before)
        except Failure as e:
            return Answer(False, (), str(e))

    def _poses(self, scan, sensors):
        """The laser frame's pose in the map frame and in the robot frame at the scan's time."""
        p = self.params
        poses = []
        for target in (p.map_frame, p.robot_frame):
            try:
                poses.append(sensors.transform(target, scan.frame_id, scan.stamp, p.tf_timeout))
            except LookupError as e:
                raise Failure('no transform %s <- %s at the scan time within %.1f s: %s'
                              % (target, scan.frame_id, p.tf_timeout, e)) from None
        return poses

    def _at_rest(self, scan, sensors):
        """``(rest, before)``: ``scan`` and the held scans just before it taken from the same
        pose (newest first, ``rest_scans`` at most; see the module's doc), and the scans from
        that pose older than all of them and at most a stride
        (:data:`~tiago_nav.detection.motion.STRIDE`) before ``scan``: what stands where one of
        them saw free came there since (a walker's foot came down)."""
        p = self.params
        earlier = sensors.scans_before(scan, STRIDE_SCANS) if p.rest_scans > 1 else []
        if not earlier:
            return [scan], []
        shape = (len(scan.ranges), scan.angle_min, scan.angle_increment, scan.frame_id)
        try:
            ref = sensors.transform(p.odom_frame, scan.frame_id, scan.stamp, p.tf_timeout)
        except LookupError:
            return [scan], []
        out, before = [scan], []
        for s in earlier:
            if len(out) == p.rest_scans and _sec(scan.stamp) - _sec(s.stamp) > motion.STRIDE:
                break
            if (len(s.ranges), s.angle_min, s.angle_increment, s.frame_id) != shape:
                break
            try:
                pose = sensors.transform(p.odom_frame, s.frame_id, s.stamp, REST_TF_TIMEOUT)
            except LookupError:
                break
            if (math.hypot(pose[0] - ref[0], pose[1] - ref[1]) > REST_TRANSLATION
                    or abs(wrap_angle(pose[2] - ref[2])) > REST_ROTATION):
                break
            if len(out) < p.rest_scans:
                out.append(s)
            else:
                before.append(s)
        return out, before

    def _motion(self, detector, result, scan, rest, method, scan_minus_map_threshold,
                cluster_threshold, laser_in_map, laser_in_robot, given, before=()):
        """Judge the motion of ``result``'s detections (the median of the scans at rest
        ``rest``, newest first) in place (:mod:`tiago_nav.detection.motion`): where beams changed
        between the oldest and the newest scan, the newest scan's own detections on them are
        moving; what stands where one of ``before`` (scans at rest up to a stride earlier)
        saw free came there since."""
        oldest = rest[-1]
        dt = _sec(scan.stamp) - _sec(oldest.stamp)
        changed = motion.changed_beams(scan.ranges, oldest.ranges, scan.range_min,
                                       scan.range_max)
        arrived = [motion.seen_free_before(scan.ranges, b.ranges, scan.range_min,
                                           scan.range_max) for b in before]
        pose = result.correction.laser_pose
        if not np.any(changed[1:] & changed[:-1]):      # nothing moved (a lone dropout aside)
            result.detections[:] = motion.combine(result.detections, [], [], changed, dt, pose,
                                                  scan.angle_min, scan.angle_increment, arrived)
            return

        def one(s):
            return detector.locate(
                s.ranges, s.angle_min, s.angle_increment, s.range_min, s.range_max,
                laser_in_map, method, laser_in_base=laser_in_robot, pose_covariance=given,
                scan_minus_map_threshold=scan_minus_map_threshold,
                cluster_threshold=cluster_threshold).detections
        result.detections[:] = motion.combine(result.detections, one(scan), one(oldest),
                                              changed, dt, pose, scan.angle_min,
                                              scan.angle_increment, arrived)

    def _detect(self, detector, scan, rest, laser_in_map, laser_in_robot, method,
                scan_minus_map_threshold, cluster_threshold, given=None, before=()):
        t0 = time.perf_counter()
        ranges = scan.ranges if len(rest) == 1 else median_ranges(
            [s.ranges for s in rest], scan.range_min, scan.range_max)
        try:
            result = detector.locate(
                ranges, scan.angle_min, scan.angle_increment, scan.range_min,
                scan.range_max, laser_in_map, method, laser_in_base=laser_in_robot,
                pose_covariance=given,
                scan_minus_map_threshold=scan_minus_map_threshold,
                cluster_threshold=cluster_threshold)
            if len(rest) > 1:
                self._motion(detector, result, scan, rest, method, scan_minus_map_threshold,
                             cluster_threshold, laser_in_map, laser_in_robot, given, before)
        except Exception as e:   # never a crash: the caller learns what went wrong
            raise Failure('detection failed on this scan: %s: %s'
                          % (type(e).__name__, e)) from None
        self.elapsed_ms = (time.perf_counter() - t0) * 1e3    # (not in the message: the same
        corr = result.correction                              # call, the same answer)
        laser_used = corr.laser_pose if corr.applied else laser_in_map
        obstacles = found_obstacles(result.detections, laser_used, laser_in_robot)
        delta = (0.0, 0.0, 0.0)
        if corr.applied:
            # the robot's pose in map, corrected minus given (the laser is fixed on it)
            given = compose(laser_in_map, inverse(laser_in_robot))
            fixed = compose(laser_used, inverse(laser_in_robot))
            delta = (fixed[0] - given[0], fixed[1] - given[1], wrap_angle(fixed[2] - given[2]))
        phrase = corr.describe() if not corr.applied else (
            'pose corrected by (%+.3f m, %+.3f m, %+.2f deg) from %d static points'
            % (delta[0], delta[1], math.degrees(delta[2]), corr.static_points))
        rested = (' (the median of %d scans at rest, from %s)'
                  % (len(rest), _seconds(rest[-1].stamp)) if len(rest) > 1 else '')
        return Answer(True, obstacles, '%d obstacle(s) found with %s on the scan at %s%s; %s'
                      % (len(obstacles), method, _seconds(scan.stamp), rested, phrase),
                      scan.stamp, delta, corr.applied)
