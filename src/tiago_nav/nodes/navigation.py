"""The ``move_base`` node (``nodes/navigation``): ROS wiring around
:class:`tiago_nav.nav.runner.GoalRunner` and :class:`tiago_nav.nav.navigator.Navigator`.

/map (latched) -> static costmap; /scan (placed in map with tf2 at its stamp) -> obstacle layer;
tf map -> base_footprint -> pose; commands on /mobile_base_controller/cmd_vel. Under
``/use_lockstep`` the control loop is a lockstep participant (:mod:`tiago_nav.ros.lockstep`):
each cycle takes in every scan up to the cycle's scan stamp (idle too, before each idle
answer), uses the pose at the cycle's odometry stamp, and answers with its command. Serves the
``move_base`` action (move_base_msgs/MoveBaseAction), /move_base_simple/goal, ~plan,
~global_costmap/costmap, ~make_plan and ~clear_costmaps, all only once /map, a first scan and
the robot's transform are in (each waited for with a timeout; the node exits 1 naming what is
missing). Its speed and
acceleration limits, goal tolerances and inflation can be changed while it runs
(dynamic_reconfigure, cfg/MoveBase.cfg): during a goal a change comes in force between two
control cycles (:class:`tiago_nav.params.ParamChanges`).
"""
import math
import sys
import threading
from dataclasses import dataclass

import rospy
import tf2_ros
from geometry_msgs.msg import PoseStamped, Twist
from move_base_msgs.msg import MoveBaseAction, MoveBaseActionGoal, MoveBaseFeedback, MoveBaseResult
from nav_msgs.msg import OccupancyGrid, Path
from nav_msgs.srv import GetPlan, GetPlanResponse
from sensor_msgs.msg import LaserScan
from std_msgs.msg import String
from std_srvs.srv import Empty, EmptyResponse

from tiago_nav.cfg import MoveBaseConfig
from tiago_nav.geometry import compose
from tiago_nav.gridmap import GridMap
from tiago_nav.nav.costmap import MapScan, occupancy_values
from tiago_nav.nav.navigator import NavConfig, Navigator
from tiago_nav.nav.planner import PlanError
from tiago_nav.nav.runner import (ABORTED, PREEMPTED, SUCCEEDED, GoalError, GoalRunner,
                                  PoseUnavailable, frame_or, no_transform)
from tiago_nav.params import ParamChanges, nested, param, validate
from tiago_nav.ros.clock import RosClock
from tiago_nav.ros.conversions import (goal_from_pose, gridmap_from_msg, gridmap_to_msg,
                                       pose_from_transform, pose_stamped)
from tiago_nav.ros.lockstep import (STARTUP_WAIT, USE_LOCKSTEP,
                                    ClaimingActionServer, LockstepParticipant, direct_publisher,
                                    goal_since, held, held_tf, lookup_at, wait_for_transform)
from tiago_nav.ros.params import read_or_exit
from tiago_nav.ros import reconfigure
from tiago_nav.ros.tcpros import concurrent_handshakes
from tiago_nav.ros.reset import NodeReset, adopt, persistent
from tiago_nav.ros.topics import Subscription, wait_for_message
from tiago_nav.scan import FrozenScanCheck


@dataclass(frozen=True)
class Params:
    """Defaults of nodes/navigation (node name move_base). Units: m, rad, s (ROS time unless
    marked wall), m/s. Algorithms: src/tiago_nav/nav/ (costmap, planner, controller,
    navigator, runner)."""
    global_frame: str = param('map', 'frame of the map, plans and goals', nonempty=True)
    robot_base_frame: str = param('base_footprint', "the robot's base frame", nonempty=True)
    odom_frame: str = param('odom', 'the odometry frame: scans and the robot pose are placed in '
                            'the map with the newest global_frame -> odom_frame (localisation) '
                            'and odometry at their own time', nonempty=True)
    scan_topic: str = param('/scan', 'sensor_msgs/LaserScan in', nonempty=True)
    map_topic: str = param('/map', 'nav_msgs/OccupancyGrid in (latched)', nonempty=True)
    localisation_state_topic: str = param(
        '/localisation/state', 'std_msgs/String in (latched): the localisation\'s "ok", '
        '"degraded" or "lost"; while "lost" the base stops (nav.localisation_patience); no '
        'publisher: never lost', nonempty=True)
    cmd_vel_topic: str = param('/mobile_base_controller/cmd_vel', 'geometry_msgs/Twist out',
                               nonempty=True)
    controller_frequency: float = param(10.0, '[Hz] control cycle and feedback rate', gt=0)
    transform_tolerance: float = param(0.5, '[s wall] wait for a transform of a scan or a goal',
                                       gt=0)
    map_timeout: float = param(30.0, '[s wall] wait for /map at start-up', gt=0)
    ready_timeout: float = param(30.0, '[s wall] then wait for a first scan and the transform '
                                 'map -> base_footprint before serving goals', gt=0)
    costmap_publish_frequency: float = param(
        1.0, '[Hz] ~global_costmap/costmap (what the planner sees, the laser\'s marks and the '
        'inflation), with each scan at most this often and only while someone subscribes; 0: '
        'never', ge=0)
    nav: NavConfig = nested(NavConfig)

    def __post_init__(self):
        validate(self)


class NotReady(RuntimeError):
    """Something the node needs did not come in time; the message names it."""


class ActionIO:
    """The goal runner's io (see :mod:`tiago_nav.nav.runner`) over an actionlib
    SimpleActionServer, publishers and a pose source; all ROS time comes from ``clock``, so
    fakes can stand for every part. ``participant``: the lockstep participant whose cycle
    each command answers, and ``sense()``: take in the cycle's scans (both optional)."""

    def __init__(self, server, cmd_pub, plan_pub, clock, pose, to_map, frame, participant=None,
                 sense=None):
        self.server, self.cmd_pub, self.plan_pub, self.clock = server, cmd_pub, plan_pub, clock
        self.pose, self.to_map, self.frame = pose, to_map, frame
        self.participant, self._sense = participant, sense

    def sense(self):
        if self._sense is not None:
            self._sense()

    def _stamp(self):
        return rospy.Time.from_sec(max(self.clock.now(), 0.0))

    def send_cmd(self, v, w):
        cmd = Twist()
        cmd.linear.x, cmd.angular.z = v, w
        self.cmd_pub.publish(cmd)
        if self.participant is not None:
            self.participant.answer(cmd)

    def publish_plan(self, path):
        msg = Path()
        msg.header.frame_id = self.frame
        msg.header.stamp = self._stamp()
        if path is not None:
            for i in range(len(path)):
                nxt = path[min(i + 1, len(path) - 1)]
                yaw = math.atan2(nxt[1] - path[i][1], nxt[0] - path[i][0])
                msg.poses.append(pose_stamped((path[i][0], path[i][1], yaw), self.frame, msg.header.stamp))
        self.plan_pub.publish(msg)

    def publish_feedback(self, pose):
        self.server.publish_feedback(MoveBaseFeedback(base_position=pose_stamped(pose, self.frame,
                                                                                 self._stamp())))

    def preempt_requested(self):
        return self.server.is_preempt_requested()

    def finish(self, status, text):
        {SUCCEEDED: self.server.set_succeeded, ABORTED: self.server.set_aborted,
         PREEMPTED: self.server.set_preempted}[status](MoveBaseResult(), text)


class MoveBase:
    """The node: waits for what it needs, then advertises its action, topic and services."""

    def __init__(self, p, server=None):
        """``server``: the action server of an earlier state (a reset keeps it, with its
        clients' connections); None: make one."""
        self.p = p
        self.clock = RosClock()
        self.lock = threading.Lock()
        self.tf = tf2_ros.Buffer()
        self.listener = tf2_ros.TransformListener(self.tf)
        self.map_frame = p.global_frame
        self.cmd_pub = rospy.Publisher(p.cmd_vel_topic, Twist, queue_size=1)
        self.plan_pub = rospy.Publisher('~plan', Path, queue_size=1, latch=True)
        # in lockstep (the evaluator records every one) written in the scan's thread, as the
        # simulator's sensor streams are: a queue of one drops one its thread has not sent yet
        self.costmap_pub = direct_publisher('~global_costmap/costmap', OccupancyGrid, latch=True) \
            if rospy.get_param(USE_LOCKSTEP, False) else \
            rospy.Publisher('~global_costmap/costmap', OccupancyGrid, queue_size=1, latch=True)
        self.costmap_sent = None            # the period of the last costmap published
        rospy.loginfo('move_base: waiting for %s', p.map_topic)
        try:
            msg = wait_for_message(p.map_topic, OccupancyGrid, p.map_timeout)
        except rospy.ROSException:
            raise NotReady('no map on %s within %g s (is the simulator or a map server running?)'
                           % (p.map_topic, p.map_timeout)) from None
        self.map_frame = msg.header.frame_id.lstrip('/') or self.map_frame
        self.nav = Navigator(gridmap_from_msg(msg), p.nav)
        self.scan_problem = 'no message on %s' % p.scan_topic
        self.intake = threading.Condition()
        self.frozen = FrozenScanCheck()
        self.last_scan_stamp = None         # rospy.Time of the newest scan taken in
        self.server = None                  # the action server, once move_base serves goals
        self.lockstep = LockstepParticipant(1.0 / p.controller_frequency, ready=self.on_tick,
                                            inputs=self._inputs_flow)
        # in lockstep every scan, in order (the cycle waits for its own); else the newest only
        Subscription(p.scan_topic, LaserScan, self.on_scan, tcp_nodelay=True,
                     queue_size=None if self.lockstep.enabled else 1)
        self.localisation_state = ''
        rospy.Subscriber(p.localisation_state_topic, String, self.on_localisation_state,
                         queue_size=1)
        self._wait(lambda: self.nav.scan_stamp is not None,
                   lambda: 'no usable laser scan within %g s: %s' % (p.ready_timeout, self.scan_problem))
        self._wait(self._has_pose,
                   lambda: 'no transform %s -> %s within %g s (is odometry/localisation running?)'
                   % (self.map_frame, p.robot_base_frame, p.ready_timeout))
        # goals only once the simulator holds for this node (a goal begun before runs free)
        self.lockstep.wait_joined(p.ready_timeout)
        fresh = server is None
        if fresh:
            with persistent():
                server = ClaimingActionServer('move_base', MoveBaseAction, self.execute,
                                              self.lockstep)
        self.server = adopt(server, self.execute, self.lockstep)
        io = ActionIO(self.server, self.cmd_pub, self.plan_pub, self.clock, self.cycle_pose,
                      self.to_map, self.map_frame, self.lockstep, self.sense)
        self.changes = ParamChanges(p, self._reconfigure)
        io.localisation_lost = self.localisation_lost
        self.runner = GoalRunner(self.nav, io, 1.0 / p.controller_frequency, self.lock, self._log,
                                 ticker=self.lockstep if self.lockstep.enabled else None,
                                 changes=self.changes)
        self.goal_pub = rospy.Publisher('move_base/goal', MoveBaseActionGoal, queue_size=1)
        rospy.Subscriber('move_base_simple/goal', PoseStamped, self.on_simple_goal, queue_size=1)
        rospy.Service('~make_plan', GetPlan, self.on_make_plan)
        rospy.Service('~clear_costmaps', Empty, self.on_clear)
        if fresh:
            self.server.start()
        rospy.loginfo('move_base: ready (map %dx%d, %.2f m)', msg.info.width, msg.info.height,
                      msg.info.resolution)

    def _reconfigure(self, p):
        """Put the parameters ``p`` in force (:attr:`changes` calls it between control cycles,
        or at once while no goal runs)."""
        with self.lock:
            self.nav.reconfigure(p.nav)
            self.p = p

    def _has_pose(self):
        return self.tf.can_transform(self.map_frame, self.p.robot_base_frame, rospy.Time(0))

    def _inputs_flow(self):
        """A scan taken in and the robot's pose in the map: what move_base waits for before it
        is ready, and before it takes part in lockstep."""
        return self.nav.scan_stamp is not None and self._has_pose()

    @staticmethod
    def _log(level, text):
        (rospy.loginfo if level == 'info' else rospy.logwarn)('move_base: %s', text)

    def _wait(self, ready, problem):
        """Poll ``ready()`` in wall time for ``ready_timeout``; :class:`NotReady` with
        ``problem()`` otherwise."""
        t_end = self.clock.wall() + self.p.ready_timeout
        while not ready():
            if self.clock.shutdown():
                raise NotReady('shut down while starting')
            if self.clock.wall() > t_end:
                raise NotReady(problem())
            self.clock.sleep(0.05)

    def _transform(self, source, stamp):
        """``map <- source`` at ``stamp`` as ``(x, y, yaw)`` and its stamp [s], waiting up to
        ``transform_tolerance`` wall seconds (:func:`~tiago_nav.ros.lockstep.lookup_at`: not
        for data tf no longer holds, since a backlog of scans that each waited here could
        never catch up with the simulator)."""
        t = lookup_at(self.tf, self.map_frame, source, stamp, self.p.transform_tolerance)
        return pose_from_transform(t.transform), t.header.stamp.to_sec()

    def _in_map(self, source, stamp):
        """``map <- source`` as ``(x, y, yaw)``: ``odom <- source`` at ``stamp`` (waiting as
        :meth:`_transform` does) after the newest ``map <- odom``, so that a localisation
        lagging behind the odometry (a loaded machine) delays nothing; ``map <- source``
        directly when there is no odom frame."""
        odom = self.p.odom_frame
        wait_for_transform(self.tf, odom, source, stamp, self.p.transform_tolerance)
        try:
            m2o = self.tf.lookup_transform(self.map_frame, odom, rospy.Time(0))
            if self.lockstep.enabled and not stamp.is_zero():
                # lockstep: map -> odom at exactly this stamp (which is the newest depends on
                # timing); waiting only for a stamp newer than what tf holds (older ones, e.g.
                # before the localisation's first correction, take the newest)
                if stamp > m2o.header.stamp:
                    m2o = lookup_at(self.tf, self.map_frame, odom, stamp,
                                    held_tf(self.tf, self.map_frame, odom))
                elif self.tf.can_transform(self.map_frame, odom, stamp):
                    m2o = self.tf.lookup_transform(self.map_frame, odom, stamp)
            o2s = self.tf.lookup_transform(odom, source, stamp)
        except tf2_ros.TransformException:
            return self._transform(source, stamp)
        return (compose(pose_from_transform(m2o.transform), pose_from_transform(o2s.transform)),
                o2s.header.stamp.to_sec())

    # --- inputs -----------------------------------------------------------------------------
    def on_tick(self, tick):
        """Before an idle lockstep answer while starting: the obstacle layer holds the tick's
        scans (otherwise the simulator runs ahead of the scans move_base takes in, in order,
        until tf no longer holds their transforms and move_base never gets ready). Once
        serving, an idle answer waits for nothing: the scans are taken in meanwhile, in order,
        and a goal's first cycle waits for every scan up to its own (:meth:`sense`)."""
        if self.server is None:
            self.take_in(tick.scan_stamp)

    def sense(self):
        """At each control cycle in lockstep: the obstacle layer holds every scan up to the
        cycle's scan stamp."""
        if self.lockstep.lockstep:
            self.take_in(self.lockstep.scan_stamp)

    def take_in(self, upto):
        """Wait (while the simulator lives: :func:`~tiago_nav.ros.lockstep.held`) until the scan
        stamped ``upto`` (rospy.Time) and every one before it have been taken in. The scans are
        taken in as they arrive, in order: in lockstep none after ``upto`` exists before this
        cycle's answer."""
        if upto is None or upto.is_zero():
            return
        patience = held()
        with self.intake:
            while self.last_scan_stamp is None or self.last_scan_stamp < upto:
                if patience.over() or self.clock.shutdown():
                    self.scan_problem = 'the scan stamped %.3f s did not arrive: %s' % (
                        upto.to_sec(), patience.reason or 'shutting down')
                    rospy.logwarn_throttle(5.0, 'move_base: %s' % self.scan_problem)
                    return
                self.intake.wait(patience.left(0.1))

    def on_scan(self, scan):
        try:
            self._add_scan(scan)
        finally:
            with self.intake:
                self.last_scan_stamp = scan.header.stamp
                self.intake.notify_all()

    def _add_scan(self, scan):
        if self.lockstep.enabled and not self.lockstep.joined.is_set():
            # simulated time stands still at its start until the expected participants have
            # joined: a scan dropped now (the localisation not sending map -> odom yet) would
            # never be followed by another
            wait_for_transform(self.tf, self.map_frame, scan.header.frame_id, scan.header.stamp,
                               STARTUP_WAIT)
        try:
            lp, _ = self._in_map(scan.header.frame_id, scan.header.stamp)
            t = self.tf.lookup_transform(self.p.robot_base_frame, scan.header.frame_id, scan.header.stamp)
        except tf2_ros.TransformException as e:
            self.scan_problem = 'scans cannot be placed in %s: %s' % (self.map_frame, e)
            rospy.logwarn_throttle(5.0, 'move_base: scan dropped, no transform: %s' % e)
            return
        if self.frozen(scan.ranges, lp):
            self.scan_problem = 'the laser repeats its last scan while the robot moves (a stuck driver?)'
            rospy.logwarn_throttle(5.0, 'move_base: scan ignored: %s' % self.scan_problem)
            return
        ms = MapScan(lp, scan.ranges, scan.angle_min, scan.angle_increment, scan.range_min,
                     scan.range_max, scan.header.stamp.to_sec(), pose_from_transform(t.transform))
        with self.lock:
            self.nav.add_scan(ms)
            costmap = self._costmap_due(ms.stamp)
        if costmap is not None:
            self.costmap_pub.publish(gridmap_to_msg(costmap, self.map_frame, scan.header.stamp))

    def _costmap_due(self, stamp):
        """The costmap as a :class:`GridMap` of occupancy values, when one is due with the scan
        stamped ``stamp`` [s]: the first scan of each period of costmap_publish_frequency (by
        the stamps, so that in lockstep the same scans publish it whenever a subscriber came),
        while someone subscribes; else None."""
        f = self.p.costmap_publish_frequency
        period = math.floor(stamp * f + 1e-9) if f > 0 else None
        if period is None or period == self.costmap_sent or \
                self.costmap_pub.get_num_connections() == 0:
            return None
        self.costmap_sent = period
        cm = self.nav.costmap
        return GridMap(occupancy_values(cm.cost), cm.resolution, cm.grid.origin)

    def on_localisation_state(self, msg):
        self.localisation_state = msg.data

    def localisation_lost(self):
        """Why the pose must not be driven on ('' when the localisation does not say it is
        lost)."""
        if self.localisation_state != 'lost':
            return ''
        return 'the localisation (%s) reports the robot pose lost (reason on /diagnostics)' \
            % self.p.localisation_state_topic

    def cycle_pose(self):
        """The control loop's pose: at the cycle's odometry stamp in lockstep, else the newest."""
        return self.pose(self.lockstep.odom_stamp if self.lockstep.lockstep else None)

    def pose(self, stamp=None):
        """``((x, y, yaw), stamp)`` of the base in map: odometry at ``stamp`` (rospy.Time,
        waiting while its source lives) or the newest odometry (None), after
        the newest map -> odom (:meth:`_in_map`); or :class:`PoseUnavailable`."""
        base = self.p.robot_base_frame
        try:
            if stamp is None:
                stamp = self.tf.lookup_transform(self.p.odom_frame, base, rospy.Time(0)).header.stamp
            else:
                lookup_at(self.tf, self.p.odom_frame, base, stamp,
                          held_tf(self.tf, self.p.odom_frame, base))
            return self._in_map(base, stamp)
        except tf2_ros.TransformException as e:
            raise no_transform(PoseUnavailable, self.map_frame, self.p.robot_base_frame,
                               e) from None

    def to_map(self, frame, pose):
        """``(x, y, yaw)`` in ``frame`` → map, or :class:`GoalError`."""
        frame = frame_or(frame, self.map_frame)
        if frame == self.map_frame:
            return pose
        try:
            t, _ = self._transform(frame, rospy.Time(0))
        except tf2_ros.TransformException as e:
            raise no_transform(GoalError, frame, self.map_frame, e) from None
        return compose(t, pose)

    def on_simple_goal(self, ps):
        g = MoveBaseActionGoal()
        g.header.stamp = rospy.Time.now()
        g.goal_id.stamp = g.header.stamp
        g.goal.target_pose = ps
        self.goal_pub.publish(g)

    def on_make_plan(self, req):
        resp = GetPlanResponse()
        resp.plan.header.frame_id = self.map_frame
        try:
            if req.start.header.frame_id:
                start = self.to_map(req.start.header.frame_id, goal_from_pose(req.start.pose))
            else:
                start = self.pose()[0]
            goal = self.to_map(req.goal.header.frame_id, goal_from_pose(req.goal.pose))
            with self.lock:
                path = self.nav.make_plan(start[:2], goal[:2])
        except (PlanError, GoalError, PoseUnavailable) as e:
            rospy.logwarn('move_base: make_plan failed: %s', e)
            return resp
        stamp = rospy.Time.now()
        for p in path:
            resp.plan.poses.append(pose_stamped((p[0], p[1], goal[2]), self.map_frame, stamp))
        return resp

    def on_clear(self, _):
        with self.lock:
            self.nav.clear_costmaps()
        rospy.loginfo('move_base: obstacle layer cleared')
        return EmptyResponse()

    def stop(self):
        self.cmd_pub.publish(Twist())

    def retire(self):
        """A reset's stop: a goal that comes before the next state is built is aborted."""
        self.server.execute_callback = lambda goal: self.server.set_aborted(
            MoveBaseResult(), 'move_base is being reset')

    # --- the action -------------------------------------------------------------------------
    def execute(self, goal):
        p = goal.target_pose
        # the goal's cycles are those after its stamp, however late it arrived
        self.lockstep.claim(goal_since(self.server.current_goal.get_goal_id().stamp,
                                       self.lockstep.now()))
        try:
            self.runner.run(p.header.frame_id,
                            (p.pose.position.x, p.pose.position.y, p.pose.position.z),
                            (p.pose.orientation.x, p.pose.orientation.y, p.pose.orientation.z,
                             p.pose.orientation.w))
        finally:
            self.lockstep.release()


def main():
    concurrent_handshakes()
    rospy.init_node('move_base')
    params = read_or_exit(Params, 'move_base')
    try:
        reset = NodeReset(lambda: MoveBase(params))
    except (NotReady, ValueError) as e:
        rospy.logfatal('move_base: not starting: %s', e)
        sys.exit(1)
    server = reset.state.server
    dynamic = []        # the dynamic_reconfigure server, made once

    def rebuild():
        """A reset: the parameters as they are now, the same action server."""
        node = MoveBase(read_or_exit(Params, 'move_base'), server)
        reconfigure.show(dynamic[0] if dynamic else None, node.p)
        return node
    reset.build = rebuild
    reset.stop_fn = lambda node: node.retire()
    dynamic.append(reconfigure.serve(MoveBaseConfig, Params,
                                     lambda: getattr(reset.state, 'changes', None), 'move_base'))
    rospy.on_shutdown(lambda: reset.state is not None and reset.state.stop())
    rospy.spin()
