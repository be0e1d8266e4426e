"""The obstacle_detection node: the ``obstacle_detection`` service (tiago_nav/DetectObstacles)
on one fresh scan minus the latched map. ROS wiring only: the decisions are
:class:`tiago_nav.detection.service.DetectionService`'s.

Waits (all in wall time, each bounded):

* start-up: the latched map, up to ``~map_timeout``; the service is advertised only once a
  usable map has arrived, otherwise the node logs a fatal error and exits with status 1;
* in each call: a scan stamped at or after the call, or at or after the request's
  ``scan_stamp`` when it is not zero (the last :data:`SCANS_HELD` scans are held for this), up to
  ``~scan_timeout`` (so a call that comes before the first scan waits for it; a ``scan_stamp``'s
  scan, published before the request, is waited for on while its publisher lives and is
  connected), then each
  transform at the scan's time, up to ``~tf_timeout``. Running out of either is an answer with
  ``success: false``, never a hang.
"""
import collections
import sys
import threading
import time
from dataclasses import dataclass

import rospy
import tf2_ros
from geometry_msgs.msg import Point, Pose2D, PoseWithCovarianceStamped, Vector3
from nav_msgs.msg import OccupancyGrid
from sensor_msgs.msg import LaserScan
from visualization_msgs.msg import MarkerArray

from tiago_nav.detection import METHODS, DetectionParams
from tiago_nav.detection.detectors import detector_for
from tiago_nav.detection.service import DetectionService, Failure
from tiago_nav.ros.clock import topic_dead
from tiago_nav.msg import Obstacle
from tiago_nav.params import nested, param, validate
from tiago_nav.ros.conversions import gridmap_from_msg, pose_from_transform, scan_from_msg
from tiago_nav.ros.lockstep import lookup_at
from tiago_nav.ros.markers import obstacle_markers
from tiago_nav.ros.params import read_or_exit
from tiago_nav.ros.tcpros import concurrent_handshakes
from tiago_nav.ros.reset import NodeReset
from tiago_nav.ros.topics import Subscription
from tiago_nav.srv import DetectObstacles, DetectObstaclesResponse

SCANS_HELD = 64     # scans kept for requests with a scan_stamp (4 s of the 15 Hz laser)


@dataclass(frozen=True)
class Params:
    """Defaults of nodes/obstacle_detection (private parameters).

    The pipeline's fields (lengths in metres) and the node's: default method, waits, frames and
    topics.
    """
    detection: DetectionParams = nested(DetectionParams)
    method: str = param('circle_fit', 'default method (a request\'s "" means this)',
                        choices=METHODS)
    scan_timeout: float = param(2.0, '[s wall] a call waits this long for a scan stamped at or '
                                'after it', gt=0)
    tf_timeout: float = param(1.0, '[s wall] a call waits this long for each transform at the '
                              'scan\'s time', gt=0)
    map_timeout: float = param(30.0, '[s wall] at start-up, wait this long for a usable map before '
                               'giving up (fatal, exit 1); the service is advertised after it',
                               gt=0)
    rest_scans: int = param(
        5, '[scans] combine the scan a call names with the held scans just before it that were '
        'taken from the same pose (odom_frame -> laser within 1 mm and 0.05 deg), this many in '
        'all: the per-beam median of their hits (1: the one scan)', ge=1, le=SCANS_HELD)
    min_informative_fraction: float = param(
        0.5, '[fraction] a scan with fewer valid beams (REP 117: hit, no return or too close) '
        'is too broken to judge: the call fails', ge=0, le=1)
    map_topic: str = param('/map', 'the static map (nav_msgs/OccupancyGrid, latched)',
                           nonempty=True)
    scan_topic: str = param('/scan', 'the laser (sensor_msgs/LaserScan)', nonempty=True)
    pose_topic: str = param(
        '/amcl_pose', 'the localisation\'s estimate (geometry_msgs/PoseWithCovarianceStamped): '
        'its covariance at the scan\'s time is the laser pose\'s when no pose correction was '
        'applied (none received: the pose is taken as exact)', nonempty=True)
    map_frame: str = param('map', 'frame of the map and of the obstacles\' centres',
                           nonempty=True)
    robot_frame: str = param('base_footprint', 'frame of the obstacles\' center_robot',
                             nonempty=True)
    odom_frame: str = param('odom', 'odometry frame: scans with the laser at one pose in it '
                            'were taken at rest (rest_scans)', nonempty=True)

    def __post_init__(self):
        validate(self)


def obstacle_msg(found):
    """:class:`tiago_nav.detection.service.Found` → tiago_nav/Obstacle."""
    return Obstacle(center=Point(found.center[0], found.center[1], 0.0),
                    center_robot=Point(found.center_robot[0], found.center_robot[1], 0.0),
                    radius=found.radius, num_points=found.num_points,
                    center_std=found.center_std, radius_std=found.radius_std,
                    center_covariance=list(found.center_covariance),
                    center_robot_covariance=list(found.center_robot_covariance),
                    center_variance_terms=list(found.center_variance_terms),
                    shape=found.shape, extent=list(found.extent),
                    extent_std=list(found.extent_std), orientation=found.orientation,
                    orientation_std=found.orientation_std, center_fixed=found.center_fixed,
                    note=found.note, motion=found.motion,
                    velocity=Vector3(found.velocity[0], found.velocity[1], 0.0),
                    velocity_std=found.velocity_std)


class RosSensors:
    """The service's sensors (see :mod:`tiago_nav.detection.service`): the newest scan of
    ``scan_topic``, tf, and the localisation's covariances on ``pose_topic``."""

    def __init__(self, scan_topic, pose_topic='/amcl_pose'):
        self.scans = collections.deque(maxlen=SCANS_HELD)
        self.poses = collections.deque(maxlen=SCANS_HELD)   # (stamp, 3 x 3 covariance)
        self.cond = threading.Condition()
        self.tf = tf2_ros.Buffer(cache_time=rospy.Duration(30))
        self.listener = tf2_ros.TransformListener(self.tf)
        self.topic = Subscription(scan_topic, LaserScan, self.on_scan, queue_size=SCANS_HELD).name
        Subscription(pose_topic, PoseWithCovarianceStamped, self.on_pose, queue_size=SCANS_HELD)

    def on_pose(self, msg):
        c = msg.pose.covariance          # 6 x 6 of (x, y, z, roll, pitch, yaw), row-major
        cov = tuple(tuple(c[6 * i + j] for j in (0, 1, 5)) for i in (0, 1, 5))
        with self.cond:
            if self.poses and msg.header.stamp < self.poses[-1][0]:
                self.poses.clear()          # ROS time went back (a restarted simulator)
            self.poses.append((msg.header.stamp, cov))

    def pose_covariance(self, stamp):
        """The localisation's ``(3, 3)`` covariance of ``(x, y, yaw)`` stamped last at or before
        ``stamp`` (rospy.Time), None when none is held."""
        with self.cond:
            held = [c for t, c in self.poses if t <= stamp]
        return held[-1] if held else None

    @property
    def scan(self):
        """The newest scan, or None."""
        return self.scans[-1] if self.scans else None

    def on_scan(self, msg):
        with self.cond:
            if self.scans and msg.header.stamp < self.scans[-1].header.stamp:
                self.scans.clear()          # ROS time went back (a restarted simulator)
            self.scans.append(msg)
            self.cond.notify_all()

    def scan_at(self, stamp, timeout, published=False):
        """The first scan stamped at or after ``stamp`` (rospy.Time), waiting up to ``timeout``
        wall seconds for it; None if it does not come; :class:`Failure` when the scans held
        no longer reach back to it. ``published``: the scan is known to have been published
        (a request's ``scan_stamp``, named by a lockstep cycle): past ``timeout`` it is waited
        for again while the scan's publisher lives and is connected (a starved process is only
        late), and :class:`Failure` names the fact when it is dead."""
        deadline = time.monotonic() + timeout
        with self.cond:
            while not rospy.is_shutdown():
                for i, s in enumerate(self.scans):
                    if s.header.stamp >= stamp:
                        if i == 0 and len(self.scans) == self.scans.maxlen and s.header.stamp > stamp:
                            raise Failure('the scan at %.3f s is no longer held (the oldest held '
                                          'is at %.3f s)' % (stamp.to_sec(), s.header.stamp.to_sec()))
                        return scan_from_msg(s, seconds=False)
                left = deadline - time.monotonic()
                if left <= 0:
                    if not published:
                        return None
                    dead = topic_dead(self.topic)
                    if dead:
                        raise Failure('no %s stamped at or after %.3f s: %s'
                                      % (self.topic, stamp.to_sec(), dead))
                    rospy.logwarn('obstacle_detection: the scan at %.3f s has not come within '
                                  '%.1f s; its publisher lives: waiting on', stamp.to_sec(),
                                  timeout)
                    deadline = time.monotonic() + timeout
                    continue
                self.cond.wait(min(left, 0.1))
        return None

    def scans_before(self, scan, count):
        """Up to ``count`` held scans stamped just before the :class:`Scan` ``scan``, newest
        first."""
        with self.cond:
            held = [s for s in self.scans if s.header.stamp < scan.stamp]
        return [scan_from_msg(s, seconds=False) for s in reversed(held[-count:])] if count > 0 else []

    def fresh_scan(self, timeout):
        """The first scan stamped at or after now (ROS time), or None after ``timeout`` wall
        seconds or on shutdown."""
        return self.scan_at(rospy.Time.now(), timeout)

    def transform(self, target, source, stamp, timeout):
        """``(x, y, yaw)`` of ``source`` in ``target`` at ``stamp``; LookupError if none
        within ``timeout`` wall seconds (tf2's own timeout would run in ROS time, which passes
        faster than wall time when the simulator runs ahead of real time)."""
        try:
            t = lookup_at(self.tf, target, source, stamp, timeout)
        except tf2_ros.TransformException as e:
            raise LookupError(str(e)) from None
        return pose_from_transform(t.transform)


class DetectionNode:
    """Subscribes to the map, serves ``obstacle_detection``, draws each answer on
    ``~obstacles`` (visualization_msgs/MarkerArray in the map frame)."""

    def __init__(self, params):
        self.params = params
        self.logic = DetectionService(params)
        self.map_ready = threading.Event()
        self.sensors = RosSensors(params.scan_topic, params.pose_topic)
        self.markers = rospy.Publisher('~obstacles', MarkerArray, queue_size=1, latch=True)
        Subscription(params.map_topic, OccupancyGrid, self.on_map, queue_size=1)
        self.service = None

    def on_map(self, msg):
        try:
            grid = gridmap_from_msg(msg)
            self.logic.set_map(grid, detector_for(grid, self.params.detection))
            self.map_ready.set()
            rospy.loginfo('obstacle_detection: map %dx%d at %.3f m', msg.info.width,
                          msg.info.height, msg.info.resolution)
        except ValueError as e:
            self.logic.map_unusable(str(e))
            rospy.logerr('obstacle_detection: %s', self.logic.map_error)

    def wait_for_map(self):
        """Wait up to ``~map_timeout`` (wall) for a usable map: False when none came in time or
        on shutdown."""
        deadline = time.monotonic() + self.params.map_timeout
        while not rospy.is_shutdown() and time.monotonic() < deadline:
            if self.map_ready.wait(min(0.1, max(deadline - time.monotonic(), 0.0))):
                return True
        return False

    def advertise_when_ready(self, handle=None):
        """:meth:`wait_for_map`, then advertise the service (answered by ``handle``, default
        this state's :meth:`handle`). Returns False, without advertising, when no map came."""
        if not self.wait_for_map():
            return False
        self.service = rospy.Service('obstacle_detection', DetectObstacles, handle or self.handle)
        rospy.loginfo('obstacle_detection: ready')
        return True

    def handle(self, req):
        answer = self.logic.handle(req.method, req.scan_minus_map_threshold,
                                   req.cluster_threshold, self.sensors, req.scan_stamp)
        obstacles = [obstacle_msg(o) for o in answer.obstacles]
        if answer.success:
            rospy.logdebug('obstacle_detection: %s; pipeline %.1f ms', answer.message,
                           self.logic.elapsed_ms)
            self.markers.publish(obstacle_markers(obstacles, self.params.map_frame, answer.stamp))
        else:
            rospy.logwarn('obstacle_detection: %s', answer.message)
        return DetectObstaclesResponse(answer.success, obstacles, answer.message,
                                       Pose2D(*answer.pose_correction), answer.pose_corrected)


def main():
    concurrent_handshakes()
    rospy.init_node('obstacle_detection')
    params = read_or_exit(Params, 'obstacle_detection')
    reset = NodeReset(lambda: DetectionNode(params))
    node = reset.state

    def handle(req):        # the service outlives resets: the current state answers
        state = reset.state
        if state is None:
            raise rospy.ServiceException('obstacle_detection is being reset')
        return state.handle(req)
    if not node.advertise_when_ready(handle):
        if rospy.is_shutdown():
            return
        rospy.logfatal('obstacle_detection: no usable map on %s within ~map_timeout = %.1f s '
                       '(%s): the service is not advertised', node.params.map_topic,
                       node.params.map_timeout, node.logic.map_error)
        sys.exit(1)
    reset.build = rebuilt
    del node                    # (not kept in this frame: a reset frees it)
    rospy.spin()


def rebuilt():
    """A reset's new state: as at start (no scan held), once it has the map."""
    node = DetectionNode(read_or_exit(Params, 'obstacle_detection'))
    if not node.wait_for_map():
        raise RuntimeError('no usable map on %s within %g s (%s)' % (
            node.params.map_topic, node.params.map_timeout, node.logic.map_error))
    return node
