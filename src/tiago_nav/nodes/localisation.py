"""localisation node: ``map → odom`` on tf from scans matched to the static map
(library: :mod:`tiago_nav.localisation.localiser`).

Subscribes ``/scan`` (sensor_msgs/LaserScan), ``/map`` (nav_msgs/OccupancyGrid, latched) and
``/initialpose`` (geometry_msgs/PoseWithCovarianceStamped, as AMCL takes it: resets the pose);
looks up tf ``odom → base_footprint`` and ``base_footprint → <laser frame>`` at each scan's stamp;
publishes tf ``map → odom`` (on ``tf_topic``, ``/tf`` by default) and ``/amcl_pose``
(PoseWithCovarianceStamped in ``map``).

Scans: any beam count and angular range (REP 117 values). Outside lockstep they wait in a
queue of ``scan_queue_size`` and are processed in order by one thread, so none is lost while a
search runs; when the queue is full the oldest is skipped. Every skipped scan (queue full, no
map yet, no odometry tf at its stamp) is counted and logged with the counts so far, and the
counts go on ``/diagnostics`` (sent every ``diagnostic_period`` and at once when the state
changes, as diagnostic_updater does). The map may
come after the scans (those before it are skipped) and be replaced; its origin may be rotated
(MapMetaData's origin with a yaw): the localiser then works in the grid's own frame and the
node turns what it takes in and gives out between that frame and ``map``.

``map → odom`` is sent at every scan stamped with the scan's time plus ``transform_tolerance``
(as AMCL does) and, unlike AMCL, also re-sent at ``republish_rate`` stamped now plus
``transform_tolerance``: tf consumers asking for "now" then never extrapolate past the last
transform, even while the laser is slow or silent, at the price of using an estimate up to
``transform_tolerance`` old and of one message per re-send (about 0.2 ms of CPU each). In lockstep the re-sends happen at the
ticks, and only when no scan's send reaches past the tick (the laser is silent).
"""
import collections
import math
import sys
import threading
import time
from dataclasses import dataclass

import numpy as np
import rospy
import tf2_ros
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import OccupancyGrid
from sensor_msgs.msg import LaserScan
from std_msgs.msg import String
from std_srvs.srv import Empty, EmptyResponse
from tf2_msgs.msg import TFMessage

from tiago_nav.clock import Ticker
from tiago_nav.geometry import compose
from tiago_nav.localisation.fields import (distance_field, from_grid, likelihood_pyramid, to_grid,
                                           turn_covariance)
from tiago_nav.localisation.health import LEVEL_NAMES
from tiago_nav.localisation.localiser import LocaliserConfig
from tiago_nav.localisation.recovery import RecoveringLocaliser
from tiago_nav.params import ParamError, nested, param, validate
from tiago_nav.ros import params as rosparams
from tiago_nav.ros.clock import RosClock, reaches_past
from tiago_nav.ros.lockstep import (CYCLE_WAIT, STARTUP_WAIT, LockstepParticipant, direct_publisher,
                                    held, held_tf, lookup_at)
from tiago_nav.ros.params import start_pose
from tiago_nav.ros.reset import NodeReset, track
from tiago_nav.ros.conversions import (COV_INDEX, covariance_6x6, gridmap_in_grid_frame, pose_from_msg, pose_from_transform,
                                       pose_msg, transform_stamped)
from tiago_nav.ros.tcpros import concurrent_handshakes
from tiago_nav.ros.topics import OthersTransformListener, Subscription
from tiago_nav.scan import FrozenScanCheck
from tiago_nav.sim.world import WorldError


REPUBLISH_OFFSET = rospy.Duration(0, 100000)   # 0.1 ms
REPUBLISH_NAP = 0.01    # [s wall] about this late a re-send of map -> odom (outside lockstep;
                        # rosbag play's /clock steps every 10 ms: a shorter poll finds no change)

# registrations in a row observing every direction before the node logs that the geometry
# recovered from a degenerate one
RECOVERED_AFTER = 3


@dataclass(frozen=True)
class Params:
    """Parameters of the localisation node (scan-to-map matching publishing map -> odom)."""
    world: str = param('', '[path] world file whose robot_start is the initial pose when '
                           'initial_pose is empty')
    initial_pose: list = param([], '[m, m, deg] initial pose [x, y, yaw] of base_footprint in '
                                   'map_frame (empty: the world\'s robot_start)')
    map_frame: str = param('map', 'frame of the static map, parent of the published transform',
                           nonempty=True)
    odom_frame: str = param('odom', 'odometry frame (child of the published transform)',
                            nonempty=True)
    base_frame: str = param('base_footprint', "robot's base frame", nonempty=True)
    scan_topic: str = param('/scan', 'laser scans (sensor_msgs/LaserScan)', nonempty=True)
    map_topic: str = param('/map', 'static map (nav_msgs/OccupancyGrid, latched)', nonempty=True)
    initialpose_topic: str = param('/initialpose', 'pose resets '
                                   '(geometry_msgs/PoseWithCovarianceStamped)', nonempty=True)
    pose_topic: str = param('/amcl_pose', 'estimated pose out '
                            '(geometry_msgs/PoseWithCovarianceStamped)', nonempty=True)
    tf_topic: str = param('/tf', 'topic map -> odom is published on (tf2_msgs/TFMessage); another '
                                 'one keeps it out of the tf tree, e.g. to compare it with a '
                                 'ground-truth map -> odom', nonempty=True)
    transform_tolerance: float = param(0.1, '[s] map -> odom is stamped this far in the future',
                                       ge=0)
    republish_rate: float = param(10.0, '[Hz] map -> odom is re-sent this often between scans',
                                  gt=0)
    tf_timeout: float = param(0.5, '[s] wait at most this long for the odometry tf at a scan\'s '
                                   'stamp', gt=0)
    scan_queue_size: int = param(
        30, 'scans waiting to be processed, in order (outside lockstep, where every scan is '
            'taken in): a search after a (re)set takes longer than a scan period, and the scans '
            'meanwhile wait; when the queue is full the oldest is skipped, counted and logged',
        ge=1)
    diagnostic_period: float = param(
        1.0, '[s] /diagnostics is sent this often (as diagnostic_updater does), and at once when '
             'the state (ok / degraded / lost) changes', gt=0)
    state_topic: str = param('~state', 'latched std_msgs/String: "ok", "degraded" or "lost", '
                             'sent when it changes (what /diagnostics says, for nodes that '
                             'must not drive on a lost pose)', nonempty=True)
    localiser: LocaliserConfig = nested(LocaliserConfig)

    def __post_init__(self):
        validate(self)
        if self.initial_pose and (len(self.initial_pose) != 3 or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                for v in self.initial_pose)):
            raise ParamError('expected [x, y, yaw_deg], got %r' % (self.initial_pose,),
                             'initial_pose')


class ScanQueue:
    """Scans processed in order by one thread (outside lockstep): :meth:`put` never blocks
    the subscriber; when ``size`` scans wait, the oldest is skipped and ``on_skip(msg)``
    told. :meth:`close` (a reset's stop, :func:`tiago_nav.ros.reset.track`) ends the thread
    after the scan in hand."""

    def __init__(self, process, size, on_skip):
        self.process, self.size, self.on_skip = process, int(size), on_skip
        self.queue = collections.deque()
        self.cond = threading.Condition()
        self.closed = False
        self.thread = threading.Thread(target=self._run, name='scan queue', daemon=True)
        self.thread.start()
        track(self)

    def put(self, msg):
        skipped = None
        with self.cond:
            if self.closed:
                return
            if len(self.queue) >= self.size:
                skipped = self.queue.popleft()
            self.queue.append(msg)
            self.cond.notify()
        if skipped is not None:
            self.on_skip(skipped)

    def _run(self):
        while True:
            with self.cond:
                while not self.queue and not self.closed:
                    self.cond.wait(0.5)     # (a timeout: shutdown is noticed)
                if self.closed:
                    return
                msg = self.queue.popleft()
            self.process(msg)

    def close(self):
        with self.cond:
            self.closed = True
            self.queue.clear()
            self.cond.notify_all()


def diagnostic_status(health, pose, covariance, name='localisation', hardware_id='',
                      relocalising=False, skipped=None):
    """A diagnostic_msgs/DiagnosticStatus of a :class:`tiago_nav.localisation.health.Health`:
    level OK / WARN (degraded) / ERROR (lost), the reason as message, and key values (state,
    the fit, rejected corrections, the pose and its standard deviations, and the scans skipped
    so far by reason, ``skipped``: a mapping reason -> count)."""
    st = DiagnosticStatus()
    st.level = health.level
    st.name, st.hardware_id, st.message = name, hardware_id, health.message
    sd = np.sqrt(np.maximum(np.diag(np.asarray(covariance, dtype=float)), 0.0))
    values = [('state', LEVEL_NAMES[health.level]),
              ('relocalising', 'true' if relocalising else 'false'),
              ('fit', 'nan' if health.fit != health.fit else '%.3f' % health.fit),
              ('rejected corrections', '%d of %d' % (health.rejected, health.scans)),
              ('x [m]', '%.3f' % pose[0]), ('y [m]', '%.3f' % pose[1]),
              ('yaw [deg]', '%.1f' % math.degrees(pose[2])),
              ('std x [m]', '%.3f' % sd[0]), ('std y [m]', '%.3f' % sd[1]),
              ('std yaw [deg]', '%.1f' % math.degrees(sd[2]))]
    skipped = skipped or {}
    values.append(('skipped scans', '%d' % sum(skipped.values())))
    values += [('skipped scans (%s)' % r, '%d' % n) for r, n in sorted(skipped.items())]
    st.values = [KeyValue(k, v) for k, v in values]
    return st


class LocalisationNode:
    def __init__(self, params):
        self.p = params
        self.pose = start_pose(params)
        self.localiser = None
        self.lock = threading.Lock()
        self.frozen = FrozenScanCheck()
        self.degenerate = False     # the last logged state of the scan geometry
        self.clear_streak = 0       # registrations in a row observing every direction
        self.map_to_odom = None
        self.frame = (0.0, 0.0, 0.0)    # the grid's frame in map (a rotated map origin)
        self.skipped = collections.Counter()    # scans skipped, by reason
        self.sent = collections.deque(maxlen=64)    # recent stamps sent (tf refuses repeats)
        self.sent_ns = set()        # the same, in nanoseconds (a repeat found without comparing
                                    # rospy.Time objects one by one at each send)
        self.tf = tf2_ros.Buffer(cache_time=rospy.Duration(30))
        # its own map -> odom is never looked up: not decoded again
        self.listener = OthersTransformListener(self.tf)
        # latched: a node that starts while simulated time stands still (the simulator waits
        # for work or for everyone to join) still gets map -> odom
        # written in the sending thread (a queue's writer thread costs a thread switch per
        # message and subscriber; a frozen subscriber is dropped after SEND_TIMEOUT)
        self.pub_tf = direct_publisher(params.tf_topic, TFMessage, latch=True)
        self.map_ready = threading.Event()
        self.pub_pose = direct_publisher(params.pose_topic, PoseWithCovarianceStamped)
        self.pub_diag = rospy.Publisher('/diagnostics', DiagnosticArray, queue_size=5)
        self.pub_state = rospy.Publisher(params.state_topic, String, queue_size=1, latch=True)
        self.state = None           # the last state sent on state_topic
        self.diag = None            # the last /diagnostics sent: (stamp, level, status)
        self.diag_lock = threading.Lock()   # the decision to send and the send, in order
        self.srv_global = rospy.Service('/global_localization', Empty, self.on_global_localization)
        Subscription(params.map_topic, OccupancyGrid, self.on_map, queue_size=1)
        rospy.Subscriber(params.initialpose_topic, PoseWithCovarianceStamped, self.on_initialpose,
                         queue_size=1)
        # lockstep: an idle participant that answers a tick once the scans up to it are taken
        # in and their corrections sent (so move_base's cycle at that tick finds them); every
        # scan is taken in, in order, and the between-scan republishes happen at the ticks
        self.intake = threading.Condition()
        self.last_scan_stamp = None
        # it takes part once it sends map -> odom (it has the map, a scan and the odometry tf)
        self.lockstep = LockstepParticipant(1.0 / params.republish_rate, ready=self.on_tick,
                                            inputs=lambda: self.map_to_odom is not None)
        # every scan is taken in, in order: in lockstep in the subscriber's thread (the tick
        # waits for it), else through a queue with a thread of its own
        self.scans = None if self.lockstep.enabled else ScanQueue(
            self.on_scan, params.scan_queue_size, lambda msg: self.skip(msg, 'queue full'))
        Subscription(params.scan_topic, LaserScan,
                     self.on_scan if self.scans is None else self.scans.put,
                     queue_size=None, buff_size=2 ** 20)

    def skip(self, msg, reason, detail=''):
        """Count the scan ``msg`` as skipped for ``reason`` and log it (throttled) with the
        counts so far."""
        self.skipped[reason] += 1
        rospy.logwarn_throttle(
            5.0, 'localisation: scan at %.3f skipped (%s%s); skipped so far: %s',
            msg.header.stamp.to_sec(), reason, ': %s' % detail if detail else '',
            ', '.join('%d (%s)' % (n, r) for r, n in sorted(self.skipped.items())))

    def on_map(self, msg):
        try:
            grid, frame = gridmap_in_grid_frame(msg)
        except ValueError as e:
            rospy.logerr('localisation: unusable %s: %s', self.p.map_topic, e)
            return
        field = distance_field(grid, self.p.localiser.map_surface_depth)
        with self.lock:
            # the start pose is where odom begins (REP 105: odom's origin is the robot's start),
            # so motion before the first scan taken in is predicted, not assumed zero
            pose, odom = (from_grid(self.frame, self.localiser.pose), self.localiser.odom) \
                if self.localiser is not None else (self.pose, (0.0, 0.0, 0.0))
            self.frame = frame
            self.localiser = RecoveringLocaliser(grid, to_grid(frame, pose), self.p.localiser, odom,
                                                 field, likelihood_pyramid(grid))
        self.map_ready.set()
        rospy.loginfo('localisation: map %dx%d at %.3f m%s; starting at (%.2f, %.2f, %.1f deg)',
                      msg.info.width, msg.info.height, msg.info.resolution,
                      ', origin turned %.1f deg' % math.degrees(frame[2]) if frame[2] else '',
                      pose[0], pose[1], math.degrees(pose[2]))

    def on_initialpose(self, msg):
        if msg.header.frame_id.lstrip('/') != self.p.map_frame:
            rospy.logerr('localisation: %s in frame %r ignored: poses must be in %r',
                         self.p.initialpose_topic, msg.header.frame_id, self.p.map_frame)
            return
        pose = pose_from_msg(msg.pose.pose)
        cov = np.asarray(msg.pose.covariance, dtype=float).reshape(6, 6)[np.ix_(COV_INDEX, COV_INDEX)]
        with self.lock:
            self.pose = pose
            if self.localiser is not None:
                self.localiser.reset(to_grid(self.frame, pose),
                                     turn_covariance(cov, -self.frame[2]) if np.any(cov) else None)
        rospy.loginfo('localisation: reset to (%.2f, %.2f, %.1f deg)', pose[0], pose[1],
                      math.degrees(pose[2]))

    def on_global_localization(self, _req):
        """``/global_localization`` (std_srvs/Empty, as AMCL's): the pose is searched for over
        the whole map from the next scans."""
        with self.lock:
            if self.localiser is None:
                rospy.logwarn('localisation: /global_localization before any map: ignored')
                return EmptyResponse()
            self.localiser.global_localization()
        rospy.loginfo('localisation: global localisation requested: searching the whole map')
        return EmptyResponse()

    def on_tick(self, tick):
        """Before an idle lockstep answer: every scan up to the tick's is taken in; then the
        latest estimate is re-sent, stamped at the tick, unless a scan's send already reaches
        past the tick (while scans flow, each is stamped ``transform_tolerance`` ahead of the
        last: a re-send would only cost every tf listener a message)."""
        upto = tick.scan_stamp
        if upto is not None and not upto.is_zero():
            patience = held()           # wall time: ROS time stands still here
            with self.intake:
                while (self.last_scan_stamp is None or self.last_scan_stamp < upto) \
                        and not patience.over() and not rospy.is_shutdown():
                    self.intake.wait(patience.left(0.1))
        with self.lock:
            covered = reaches_past(self.sent, tick.stamp)
        if not covered:
            self.send_transform(tick.stamp + REPUBLISH_OFFSET)

    def on_scan(self, msg):
        try:
            self._on_scan(msg)
        finally:
            with self.intake:
                self.last_scan_stamp = msg.header.stamp
                self.intake.notify_all()

    def _startup_wait(self):
        """[s wall] how long a scan waits for its map and transforms: in lockstep, until the
        first scan is taken in, :data:`STARTUP_WAIT` (simulated time stands still at its start
        until this node has joined, so a scan skipped then would never be followed by another;
        the URDF's fixed frames and the map may come after the first scan), then
        :data:`CYCLE_WAIT` (a transform is then waited for while its sources live:
        :meth:`_lookup`)."""
        return STARTUP_WAIT if self.map_to_odom is None else CYCLE_WAIT

    def _lookup(self, target, source, stamp):
        if self.lockstep.enabled:
            return lookup_at(self.tf, target, source, stamp, STARTUP_WAIT if self.map_to_odom is None
                             else held_tf(self.tf, target, source))
        return self.tf.lookup_transform(target, source, stamp, rospy.Duration(self.p.tf_timeout))

    def _on_scan(self, msg):
        stamp = msg.header.stamp
        if self.lockstep.enabled:
            self.map_ready.wait(self._startup_wait())
        try:
            odom = pose_from_transform(self._lookup(self.p.odom_frame, self.p.base_frame, stamp).transform)
            laser = pose_from_transform(self._lookup(self.p.base_frame, msg.header.frame_id, stamp).transform)
        except tf2_ros.TransformException as e:
            self.skip(msg, 'no odometry tf', str(e))
            return
        with self.lock:
            if self.localiser is None:
                skipped = 'no %s yet' % self.p.map_topic
            elif self.localiser.due(odom):
                skipped = None
                if self.frozen(msg.ranges, compose(odom, laser)):
                    pts = ()                # a stuck driver's repeat: follow odometry
                else:
                    pts = self.localiser.scan_points(msg.ranges, msg.angle_min,
                                                     msg.angle_increment, msg.range_min,
                                                     msg.range_max, laser)
                before = self.localiser.health.level
                up = self.localiser.update(odom, pts, laser[:2])
                m2o, pose, cov, rejected = up.map_to_odom, up.pose, up.covariance, up.reason
                change = self.degeneracy(up) if up.corrected else None
            else:                           # about where the last registered scan was taken
                # (a re-acquired direction's pending correction takes its step here too)
                skipped = None
                before = self.localiser.health.level
                pose, cov = self.localiser.follow(odom)
                m2o, rejected, change = self.localiser.map_to_odom, '', None
            if not skipped:                 # from the grid's frame to map (a rotated origin)
                self.map_to_odom = from_grid(self.frame, m2o)
                pose, cov = from_grid(self.frame, pose), turn_covariance(cov, self.frame[2])
                health, relocalising = self.localiser.health, self.localiser.relocalising
        if skipped:
            self.skip(msg, skipped)
            return
        if change:
            rospy.loginfo('localisation: %s', change)
        if health.level != before:
            log = {0: rospy.loginfo, 1: rospy.logwarn, 2: rospy.logerr}[health.level]
            log('localisation: %s', health.message)
        self.publish_health(stamp, health, pose, cov, relocalising)
        if rejected and not relocalising:
            rospy.logwarn_throttle(5.0, 'localisation: correction rejected (%s); following '
                                   'odometry', rejected)
        # the first estimate also at the scan's own stamp, in the same (latched) message: sent
        # only ahead of it, tf could not give map -> odom at the start, where simulated time
        # may stand still
        self.send_transform(stamp, also_now=not self.sent)
        self.publish_pose(stamp, pose, cov)

    def degeneracy(self, update):
        """What to log about the scan geometry after an accepted registration ``update``, or
        None: once when some direction becomes unobservable (e.g. entering a corridor), and once
        when every direction has been observable for :data:`RECOVERED_AFTER` registrations in a
        row (so a corridor's end seen on and off does not log per scan)."""
        if update.weak:
            self.clear_streak = 0
            if self.degenerate:
                return None
            self.degenerate = True
            return ('scan geometry is degenerate at (%.2f, %.2f): the %s is unobservable from '
                    'the scan and follows odometry (its standard deviation grows with the '
                    'distance driven, in /amcl_pose\'s covariance)'
                    % (update.pose[0], update.pose[1], update.weak))
        if not self.degenerate:
            return None
        self.clear_streak += 1
        if self.clear_streak < RECOVERED_AFTER:
            return None
        self.degenerate = False
        return ('scan geometry constrains every direction again at (%.2f, %.2f)'
                % (update.pose[0], update.pose[1]))

    def publish_health(self, stamp, health, pose, covariance, relocalising):
        """``/diagnostics`` every ``diagnostic_period`` of the scans' time and at once when the
        level changes, and ``state_topic`` when the state changes."""
        with self.diag_lock:
            last = self.diag
            if last is None or health.level != last[1] or stamp < last[0] or \
                    (stamp - last[0]).to_sec() >= self.p.diagnostic_period:
                st = diagnostic_status(health, pose, covariance,
                                       '%s: pose' % rospy.get_name().lstrip('/'),
                                       self.p.map_frame, relocalising, dict(self.skipped))
                self.diag = (stamp, health.level, st)
                self._send_diagnostics(stamp, st)
        name = LEVEL_NAMES[health.level]
        if name != self.state:
            self.state = name
            self.pub_state.publish(String(name))

    def diagnostics_heartbeat(self, now):
        """Re-send the last status stamped ``now`` when none has gone for ``diagnostic_period``
        (the laser silent): a monitor sees the node alive and what it last knew."""
        with self.diag_lock:
            last = self.diag
            if last is None or (now >= last[0] and (now - last[0]).to_sec()
                                < self.p.diagnostic_period):
                return
            self.diag = (now, last[1], last[2])
            self._send_diagnostics(now, last[2])

    def _send_diagnostics(self, stamp, status):
        out = DiagnosticArray()
        out.header.stamp = stamp
        out.status = [status]
        self.pub_diag.publish(out)

    def publish_pose(self, stamp, pose, covariance):
        out = PoseWithCovarianceStamped()
        out.header.stamp, out.header.frame_id = stamp, self.p.map_frame
        out.pose.pose = pose_msg(pose)
        out.pose.covariance = covariance_6x6(covariance)
        self.pub_pose.publish(out)

    def send_transform(self, stamp, also_now=False):
        """Send the latest ``map → odom`` stamped ``stamp + transform_tolerance`` (and, with
        ``also_now``, ``stamp`` too, in the same message)."""
        stamps = ([stamp] if also_now else []) + [stamp + rospy.Duration(self.p.transform_tolerance)]
        with self.lock:
            m2o = self.map_to_odom
            # tf refuses a repeated stamp
            stamps = [t for t in stamps if t.to_nsec() not in self.sent_ns]
            if m2o is None or not stamps:
                return
            for t in stamps:
                if len(self.sent) == self.sent.maxlen:
                    self.sent_ns.discard(self.sent[0].to_nsec())
                self.sent.append(t)
                self.sent_ns.add(t.to_nsec())
        self.pub_tf.publish(TFMessage([transform_stamped(m2o, self.p.map_frame, self.p.odom_frame, t)
                                       for t in stamps]))

    def run(self):
        run(lambda: self, self.lockstep.enabled, self.p.republish_rate)


def run(current, lockstep, republish_rate):
    """The node's loop until shutdown; ``current()`` gives its state now (a reset replaces it;
    None between a reset's stop and start). In lockstep the republishes happen at the ticks."""
    # asleep for the time left to the next re-send at the rate ROS time keeps, not polling
    # every 2 ms: a re-send a few milliseconds late is as good (it is stamped when sent), and
    # each wake costs about 0.1 ms of CPU
    ticker = Ticker(RosClock(), 1.0 / republish_rate, nap=REPUBLISH_NAP,
                    longest=1.0 / republish_rate)
    if lockstep:
        rospy.spin()
        return
    while not rospy.is_shutdown():
        if ticker.tick():
            # offset off the scans' stamps: tf keeps the first transform of a stamp, and a
            # republish must not take the stamp a scan being processed needs for its newer
            # estimate
            node = current()
            if node is not None:
                now = rospy.Time.now()
                node.send_transform(now + REPUBLISH_OFFSET)
                node.diagnostics_heartbeat(now)


def main():
    concurrent_handshakes()
    rospy.init_node('localisation')
    try:
        reset = NodeReset(lambda: LocalisationNode(rosparams.read(Params)), stop=None)
    except ParamError as e:
        named = str(e).startswith('parameter ') or not e.name
        rospy.logfatal('localisation: %s', e if named else 'parameter %s: %s'
                       % (rospy.resolve_name('~' + e.name), e.reason))
        sys.exit(2)
    except WorldError as e:
        rospy.logfatal('localisation: parameter %s: %s', rospy.resolve_name('~world'), e)
        sys.exit(2)
    reset.build = started
    first = reset.state         # (not kept in this frame: a reset frees it)
    lockstep, rate = first.lockstep.enabled, first.p.republish_rate
    del first
    try:
        run(lambda: reset.state, lockstep, rate)
    except rospy.ROSInterruptException:
        pass


def started():
    """A reset's new state (``~reset/start``): as at start, and once it has sent its first
    ``map → odom`` (latched), so that the nodes reset after it get that one, not the last
    run's."""
    node = LocalisationNode(rosparams.read(Params))
    end = time.monotonic() + STARTUP_WAIT
    while not node.sent:
        if time.monotonic() > end or rospy.is_shutdown():
            raise RuntimeError('no map -> odom within %g s of the reset' % STARTUP_WAIT)
        time.sleep(0.01)
    return node
