"""The ``tiago_controller`` node: serves the TiagoTask action (tiago_nav/TiagoTaskAction) by
chaining the corridor_controller action (optional), move_base and the obstacle_detection service.

The decisions are :class:`tiago_nav.mission.MissionRunner`'s; this module only wires it to ROS
(:class:`RosBackend`). Subscribes ``scan_topic`` (to judge whether a corridor leads toward pose
B) and ``plan_topic``. Publishes ``~obstacle_markers`` (visualization_msgs/MarkerArray,
latched) and ``~goal_pose`` (geometry_msgs/PoseStamped, latched: the current pose B), and
commands a stop on ``cmd_vel_topic`` whenever a goal ends. On shutdown (Ctrl-C, rosnode kill)
it cancels its corridor and move_base goals and stops the base.
"""
import math
import threading
import time
from dataclasses import dataclass

import actionlib
import rosgraph
import rospy
import tf2_ros
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped, Twist
from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
from nav_msgs.msg import Path
from sensor_msgs.msg import LaserScan
from visualization_msgs.msg import MarkerArray

from tiago_nav import mission
from tiago_nav.mission import DetectionError, Goal, MissionConfig, MissionRunner, Poll, StageError
from tiago_nav.mission.entrance import corridor_ahead
from tiago_nav.clock import Patience
from tiago_nav.lockstep import Settled
from tiago_nav.mission.runner import (Cancelled, no_corridor_scan, no_service, service_failed,
                                      service_silent, service_verdict)
from tiago_nav.msg import (CorridorAction, CorridorActionFeedback, CorridorGoal, TiagoTaskAction,
                           TiagoTaskFeedback, TiagoTaskResult)
from tiago_nav.params import nested, param, validate
from tiago_nav.ros import params as ros_params
from tiago_nav.ros.actions import server_connected
from tiago_nav.ros.clock import RosClock, node_exited
from tiago_nav.ros.conversions import pose_from_transform, pose_stamped
from tiago_nav.ros.lockstep import (CYCLE_WAIT, ClaimingActionServer, LockstepParticipant, Peers,
                                    ScanCache, goal_since, held, held_by, held_tf, lookup_at)
from tiago_nav.ros.markers import obstacle_markers
from tiago_nav.ros.reset import NodeReset, adopt, on_shutdown, persistent
from tiago_nav.ros.tcpros import concurrent_handshakes
from tiago_nav.ros.topics import Reconnect, action_subscribers
from tiago_nav.scan import scan_to_points, usable_ranges
from tiago_nav.srv import DetectObstacles, DetectObstaclesRequest

SERVICE_PROBE = 0.2          # [s wall] one try to reach the detection service
SHUTDOWN_FLUSH = 0.3         # [s wall] on shutdown, time for the cancels and the stop to go out
_TF_ERRORS = (tf2_ros.LookupException, tf2_ros.ConnectivityException,
              tf2_ros.ExtrapolationException)

_ACTIVE = (GoalStatus.PENDING, GoalStatus.ACTIVE)     # SimpleActionClient.get_state() values
_POLL = {GoalStatus.PENDING: mission.ACTIVE, GoalStatus.ACTIVE: mission.ACTIVE,
         GoalStatus.PREEMPTING: mission.ACTIVE, GoalStatus.RECALLING: mission.ACTIVE,
         GoalStatus.SUCCEEDED: mission.SUCCEEDED, GoalStatus.ABORTED: mission.ABORTED,
         GoalStatus.PREEMPTED: mission.PREEMPTED, GoalStatus.RECALLED: mission.PREEMPTED,
         GoalStatus.REJECTED: mission.REJECTED, GoalStatus.LOST: mission.LOST}


@dataclass(frozen=True)
class Params:
    """Parameters of the tiago_controller node (the TiagoTask proxy).

    Stage timeouts count in ROS time (simulated under /use_sim_time); server_timeout,
    detection_timeout and clock_timeout in wall time, so nothing hangs if /clock stops (a
    stage is abandoned only once the simulator is found dead, not merely slow).
    """
    mission: MissionConfig = nested(MissionConfig)
    action_name: str = param('tiago_controller', 'the TiagoTask action served', nonempty=True)
    corridor_action: str = param('corridor_controller', 'the corridor law action',
                                 nonempty=True)
    move_base_action: str = param('move_base', 'the navigation action', nonempty=True)
    detection_service: str = param('obstacle_detection', 'the detection service', nonempty=True)
    cmd_vel_topic: str = param('/mobile_base_controller/cmd_vel', 'stop commands go here',
                               nonempty=True)
    plan_topic: str = param('/move_base/plan', "move_base's plan (nav_msgs/Path), for the "
                            'distance to go', nonempty=True)
    scan_topic: str = param('/scan', 'the laser (sensor_msgs/LaserScan): does a corridor lead '
                            'toward pose B?', nonempty=True)
    global_frame: str = param('map', 'frame of pose B and of the reported poses', nonempty=True)
    robot_frame: str = param('base_footprint', 'the robot base frame', nonempty=True)
    lockstep_period: float = param(0.1, '[s] in lockstep (/use_lockstep), the proxy decides on '
                                   "the simulator's cycles of this period: a whole number of "
                                   'physics steps', gt=0)

    def __post_init__(self):
        validate(self)


class RosBackend:
    """The runner's view of ROS: action clients, the detection service, tf, cmd_vel."""

    def __init__(self, params):
        self.p = params
        self._clock = RosClock()
        self.cfg = params.mission
        self.global_frame, self.robot_frame = params.global_frame, params.robot_frame
        self.clients = {
            'corridor': actionlib.SimpleActionClient(params.corridor_action, CorridorAction),
            'navigation': actionlib.SimpleActionClient(params.move_base_action, MoveBaseAction)}
        self.feedbacks = {}
        # in lockstep, the plan and the corridor's feedback a cycle uses are those of the cycles
        # before it (tiago_nav.lockstep.Settled): the newest ones may still be on their way
        self.settled = {'path': Settled(params.lockstep_period),
                        'corridor': Settled(params.lockstep_period)}
        subs = [rospy.Subscriber(rospy.resolve_name(params.corridor_action) + '/feedback',
                                 CorridorActionFeedback, self._on_corridor_feedback,
                                 queue_size=None)]
        self.tf = tf2_ros.Buffer(rospy.Duration(10.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf)
        self.cmd = rospy.Publisher(params.cmd_vel_topic, Twist, queue_size=1)
        subs.append(rospy.Subscriber(params.plan_topic, Path, self._on_path, queue_size=None))
        self._scan = (None, -math.inf)    # the newest scan and its arrival [s wall]
        subs.append(rospy.Subscriber(params.scan_topic, LaserScan, self._on_scan, queue_size=1))
        # a subscriber that missed its publisher at start-up (tiago_nav.ros.topics) is connected
        # again: actionlib's status subscriber among them, without which a server never counts
        # as there
        self.reconnect = Reconnect(subs + [self.tf_listener.tf_sub, self.tf_listener.tf_static_sub]
                                   + [s for c in self.clients.values() for s in action_subscribers(c)])
        self.server = None            # the SimpleActionServer, set by the node
        # lockstep (docs/lockstep.md): the mission decides on its own cycles
        self.lockstep = LockstepParticipant(params.lockstep_period)
        self.peers = Peers() if self.lockstep.enabled else None
        self.scans = ScanCache(params.scan_topic) if self.lockstep.enabled else None
        # it takes part once a scan and the robot's pose in the map have come (its cycles wait
        # for both at exact stamps)
        self.lockstep.inputs = lambda: self.scans.latest() is not None and self.tf.can_transform(
            self.global_frame, self.robot_frame, rospy.Time(0))
        self._in_cycle = False        # a cycle has begun and is not answered yet
        self._stop = False            # this cycle's answer carries a stop
        self._sent = None             # the stage whose goal was sent in this cycle
        self._active = None           # the stage whose goal runs
        self._ran_at = {}             # stage -> True when its server was still at work at this cycle
        self._cycle = None            # this mission's newest cycle's LockstepTick (exact stamps)

    # --- clock (tiago_nav.clock protocol) ------------------------------------------------------
    def now(self):
        return rospy.get_time()

    def wall(self):
        return time.monotonic()

    def source_dead(self):
        return self._clock.source_dead()

    def sleep(self, seconds):
        """Out of lockstep: ``seconds`` of wall time (never blocks if /clock stops). In lockstep,
        while a mission runs: the end of this cycle and the start of the next one (the runner
        polls once per cycle)."""
        if not self._cycles():
            time.sleep(seconds)
            return
        self._finish_cycle()
        self._begin_cycle()

    # --- lockstep: the proxy's cycles ----------------------------------------------------------
    # Inside a cycle (simulated time held at its stamp) the proxy knows exactly what its servers
    # did up to it: each server's answer for its last deadline at or before the stamp says
    # whether its goal still ran (an answer with a command) or had ended (an idle answer, sent
    # after the goal's result); the result is then waited for. So the proxy sees a stage end,
    # and sends the next stage's goal, at the same simulated instant in every run. A goal sent
    # in a cycle is stamped with it and the cycle is answered only once the server has accepted
    # it (the server's participant claimed its cycles on arrival: ClaimingActionServer). Servers
    # that do not take part (no answers seen) are judged by their action state, as out of
    # lockstep. Detection and everything after it happen at the last cycle's instant: its
    # answer says the proxy needs no more simulated time, so a simulator that waits for work
    # stands still there; the scan detection uses and the reported pose are that cycle's.
    def begin(self, stamp, use_corridor_law):
        """A mission starts (its goal stamped ``stamp``, rospy.Time). In lockstep, once the
        servers it needs are there (:meth:`wait_for_chain`; simulated time stands still
        meanwhile when the simulator waits for work), the proxy's cycles after that stamp are
        its own."""
        self._active, self._sent, self._stop, self._ran_at = None, None, False, {}
        self._cycle = None
        if self.lockstep.enabled:
            self.wait_for_chain(use_corridor_law)
            self.lockstep.claim(goal_since(stamp, self.lockstep.now()))

    def wait_for_chain(self, use_corridor_law):
        """Wait up to ``server_timeout`` wall seconds for the action servers and the service a
        mission uses (a goal can come while they are still starting, e.g. on a loaded
        machine); a stage whose server is still missing then fails with its own message."""
        stages = (['corridor'] if use_corridor_law else []) + ['navigation']
        service = rospy.resolve_name(self.p.detection_service)
        t0 = time.monotonic()
        while not rospy.is_shutdown() and time.monotonic() - t0 < self.cfg.server_timeout:
            missing = [self.p.corridor_action if s == 'corridor' else self.p.move_base_action
                       for s in stages if not self.server_ready(s)]
            if not _service_registered(service):
                missing.append(service)
            if not missing:
                return
            rospy.loginfo_throttle(5.0, 'tiago_controller: the mission waits for %s'
                                   % ', '.join(missing))
            time.sleep(self.cfg.poll_period)

    def end(self):
        """The mission is over (or about to ask for detection): answer the open cycle, saying
        that the proxy needs no more simulated time, and give the cycles back."""
        if self.lockstep.enabled:
            self._finish_cycle(busy=False)
            self.lockstep.release()

    def _cycles(self):
        return self.lockstep.enabled and self.lockstep.core.claimed and not rospy.is_shutdown()

    def _begin_cycle(self):
        """Wait for the proxy's next cycle; then for what the active stage's server did up to it."""
        if self._in_cycle or not self._cycles():
            return
        self._ran_at = {}
        if not self.lockstep.tick():
            return                     # shutting down, or ROS time stopped: the runner's guards act
        self._in_cycle = True
        if self.lockstep.lockstep:
            self._cycle = self.lockstep.tick_msg
        stage = self._active
        if not self.lockstep.lockstep or stage is None:
            return
        node = self._server_node(stage)
        ack = self.peers.covering(node, self.lockstep.stamp, held_by(node)) if node else None
        if ack is None:
            return                     # not a participant: its action state decides
        self._ran_at[stage] = ack.has_command
        if not ack.has_command:        # its goal had ended: its result is on the way
            patience = held_by(node)
            client = self.clients[stage]
            while client.get_state() in _ACTIVE and not patience.over() \
                    and not rospy.is_shutdown():
                time.sleep(0.001)

    def _finish_cycle(self, busy=True):
        """Answer the open cycle (with a stop when one was asked for), once a goal sent in it
        has been accepted; ``busy`` False: the proxy needs no more simulated time."""
        if not self._in_cycle:
            return
        if self._sent is not None:
            client = self.clients[self._sent]
            node = self._server_node(self._sent)
            patience = held_by(node) if node else Patience.of(CYCLE_WAIT)
            while client.get_state() == GoalStatus.PENDING and not patience.over() \
                    and not rospy.is_shutdown():
                time.sleep(0.001)
            self._sent = None
        self.lockstep.answer(Twist() if self._stop else None, busy=busy)
        self._stop, self._in_cycle = False, False

    def _server_node(self, stage):
        """The node serving ``stage``'s action (the callerid of its status messages), or None."""
        msg = self.clients[stage].action_client.last_status_msg
        return msg._connection_header.get('callerid') if msg else None

    def shutdown(self):
        return rospy.is_shutdown()

    def preempt_requested(self):
        return rospy.is_shutdown() or (self.server is not None and self.server.is_preempt_requested())

    # --- robot -------------------------------------------------------------------------------
    def stamp(self):
        """rospy.Time of what the proxy reports now: in lockstep, once the mission has had a
        cycle, that cycle's (the last one's after the mission stopped taking part); else now."""
        return self._cycle.odom_stamp if self._cycle is not None else rospy.Time.now()

    def pose(self):
        """The robot's pose in the map: in lockstep at the mission's newest cycle (exact: the
        same in every run), else the newest tf has."""
        try:
            if self._cycle is not None:
                t = lookup_at(self.tf, self.global_frame, self.robot_frame,
                              self._cycle.odom_stamp,
                              held_tf(self.tf, self.global_frame, self.robot_frame))
            else:
                t = self.tf.lookup_transform(self.global_frame, self.robot_frame, rospy.Time(0))
        except tf2_ros.TransformException:
            return None
        return pose_from_transform(t.transform)

    def _on_scan(self, msg):
        self._scan = (msg, time.monotonic())

    def _on_path(self, msg):
        if msg.header.frame_id in ('', self.global_frame, '/' + self.global_frame):
            self.settled['path'].add(msg.header.stamp.to_sec(),
                                     [(p.pose.position.x, p.pose.position.y) for p in msg.poses])

    def _on_corridor_feedback(self, msg):
        self.settled['corridor'].add(msg.header.stamp.to_sec(), msg.feedback)

    def _cycle_stamp(self):
        """[s] the open lockstep cycle's time, None out of one (running free)."""
        return self.lockstep.stamp.to_sec() if self._in_cycle and self.lockstep.lockstep else None

    def path(self):
        return self.settled['path'].get(self._cycle_stamp())

    def stop_robot(self):
        self._stop = True             # in lockstep the stop travels in the cycle's answer
        if not rospy.is_shutdown():
            try:
                self.cmd.publish(Twist())
            except rospy.ROSException:
                pass

    def halt(self):
        """On shutdown: cancel the corridor and move_base goals and command a stop (publishing
        still works inside rospy's shutdown hooks), then give the messages time to go out."""
        for stage, client in self.clients.items():
            if client.gh is not None and client.get_state() in _ACTIVE:
                self.cancel(stage)
        try:
            self.cmd.publish(Twist())
        except Exception as e:       # the publisher may already be closed
            rospy.logwarn('stopping the base on shutdown: %s', e)
        time.sleep(SHUTDOWN_FLUSH)

    # --- is there a corridor toward pose B? ------------------------------------------------
    def corridor_ahead(self, goal):
        """Whether a corridor ahead leads toward pose B, judged on a scan that arrived after
        this call and the robot's pose at its stamp; :class:`StageError` of the corridor stage
        when no such scan can be placed within ``server_timeout`` wall seconds (a newer scan is
        tried while waiting: tf may not reach back to the first one, e.g. a localisation that
        started late)."""
        if self._cycles():
            t0 = time.monotonic()
            while True:                # a scan tf cannot place yet (localisation starting): next cycle
                try:
                    scan, robot, laser = self._cycle_scan()
                    return self._judge_corridor(goal, scan, robot, laser)
                except StageError:
                    if rospy.is_shutdown() or time.monotonic() - t0 > self.cfg.server_timeout:
                        raise
                self.sleep(self.cfg.poll_period)
        t0 = time.monotonic()
        while True:
            scan, seen = self._scan
            if seen >= t0:
                try:
                    laser = self._pose(self.robot_frame, scan.header.frame_id, rospy.Time(0))
                    robot = self._pose(self.global_frame, self.robot_frame, scan.header.stamp)
                    break
                except _TF_ERRORS as e:
                    why = 'no transform to place the scan and judge the corridor: %s' % e
            else:
                why = no_corridor_scan(rospy.resolve_name(self.p.scan_topic), self.cfg.server_timeout)
            if rospy.is_shutdown() or time.monotonic() - t0 > self.cfg.server_timeout:
                raise StageError('corridor', why)
            time.sleep(self.cfg.poll_period)
        return self._judge_corridor(goal, scan, robot, laser)

    def _cycle_scan(self):
        """In lockstep: the scan the current cycle names and the robot's and the laser's poses
        at its stamp; :class:`StageError` of the corridor stage when they do not come."""
        self._begin_cycle()
        stamp = self.lockstep.scan_stamp
        scan = self.scans.wait_for_scan(stamp, held()) if stamp else self.scans.latest()
        if scan is None:
            raise StageError('corridor', 'no laser scan on %s for the cycle at %.3f s: cannot tell '
                             'whether a corridor leads toward pose B'
                             % (rospy.resolve_name(self.p.scan_topic), rospy.get_time()))
        try:
            robot = pose_from_transform(lookup_at(self.tf, self.global_frame, self.robot_frame,
                                                  scan.header.stamp,
                                                  held_tf(self.tf, self.global_frame,
                                                          self.robot_frame)).transform)
            laser = self._pose(self.robot_frame, scan.header.frame_id, rospy.Time(0))
        except _TF_ERRORS as e:
            raise StageError('corridor', 'no transform to place the scan and judge the corridor: '
                             '%s' % e) from None
        return scan, robot, laser

    def _judge_corridor(self, goal, scan, robot, laser):
        ranges = usable_ranges(scan.ranges, scan.angle_min, scan.angle_increment, scan.range_min,
                               scan.range_max, laser)       # no self-hits, no veils
        points, _ = scan_to_points(ranges, scan.angle_min, scan.angle_increment, scan.range_min,
                                   scan.range_max)
        ahead = corridor_ahead(points, laser, robot, goal.pose)
        rospy.loginfo('corridor toward (%.2f, %.2f): %s', goal.x, goal.y,
                      'yes' if ahead else 'no')
        return ahead

    def _pose(self, target, source, stamp):
        """The pose of ``source`` in ``target`` at ``stamp`` from tf (raises tf's errors)."""
        return pose_from_transform(self.tf.lookup_transform(target, source, stamp).transform)

    # --- actions -----------------------------------------------------------------------------
    def server_ready(self, stage):
        return server_connected(self.clients[stage])

    def send_goal(self, stage, goal):
        """Send ``stage``'s goal; in lockstep inside a cycle, stamped with it."""
        self._begin_cycle()
        self.feedbacks[stage] = None
        sent = self._cycle_stamp()
        self.settled['corridor' if stage == 'corridor' else 'path'].reset(
            sent if sent is not None else rospy.get_time())
        if stage == 'corridor':
            msg = CorridorGoal(max_speed=goal[0], max_distance=goal[1])
        else:
            msg = MoveBaseGoal(target_pose=pose_stamped(goal, self.global_frame, rospy.Time.now()))
        self.clients[stage].send_goal(msg, feedback_cb=lambda fb: self.feedbacks.__setitem__(stage, fb))
        if self._in_cycle:
            self._sent = stage
        self._active = stage

    def _feedback(self, stage):
        cycle = self._cycle_stamp()
        if cycle is not None and stage in self.settled:
            return self.settled[stage].get(cycle)
        return self.feedbacks.get(stage)

    def poll(self, stage):
        c = self.clients[stage]
        if self._ran_at.get(stage):   # in lockstep: its server was still at work at this cycle
            return Poll(mission.ACTIVE, feedback=self._feedback(stage))
        status = _POLL.get(c.get_state(), mission.ACTIVE)
        if status == mission.ACTIVE:
            return Poll(mission.ACTIVE, feedback=self._feedback(stage))
        return Poll(status, c.get_goal_status_text(), c.get_result(), self._feedback(stage))

    def cancel(self, stage):
        try:
            self.clients[stage].cancel_goal()
        except Exception as e:       # a dead server must not stop the cancel path
            rospy.logwarn('cancelling the %s goal: %s', stage, e)

    # --- detection ---------------------------------------------------------------------------
    def detect(self, timeout):
        """One obstacle_detection call; in lockstep on the scan of the mission's last cycle,
        simulated time standing still at that cycle (see :meth:`end`)."""
        self.end()
        name = self.p.detection_service
        self._wait_service(name)
        proxy = rospy.ServiceProxy(name, DetectObstacles)
        request = DetectObstaclesRequest()
        if self._cycle is not None:
            request.scan_stamp = self._cycle.scan_stamp
        box = {}

        def call():
            try:
                box['response'] = proxy(request)
            except Exception as e:   # ServiceException, connection errors, ROSInterrupt
                box['error'] = e
        worker = threading.Thread(target=call, daemon=True)
        worker.start()
        resolved = rospy.resolve_name(name)
        waited = 0.0
        while True:
            worker.join(timeout)
            if not worker.is_alive():
                break
            # unanswered: a call whose connection closed has already failed (its node died);
            # one still open waits on while the node lives, however slow
            waited += timeout
            dead = self._service_dead(resolved)
            if dead:
                raise DetectionError(dead)
            if self.preempt_requested():
                raise Cancelled()
            rospy.logwarn('tiago_controller: %s; its node lives: waiting on',
                          service_silent(resolved, waited))
        if 'error' in box:
            raise DetectionError(service_failed(name, box['error']))
        resp = box['response']
        return resp.success, list(resp.obstacles), resp.message

    def _wait_service(self, name):
        """Wait (wall clock) for the service ``name`` to answer: up to ``server_timeout`` while
        it is not registered (a node still starting); while it is registered and does not
        answer, until its node is found dead (:meth:`_service_dead`: a killed process leaves
        its registration behind, its port refuses connections), waiting on while it lives.
        :class:`DetectionError` saying which otherwise; :class:`Cancelled` on a cancel."""
        resolved = rospy.resolve_name(name)
        master = rosgraph.Master(rospy.get_name())
        t0 = time.monotonic()
        while True:
            try:
                rospy.wait_for_service(resolved, timeout=SERVICE_PROBE)
                return
            except rospy.ROSException:
                pass
            now = time.monotonic()
            if rospy.is_shutdown():
                raise DetectionError('node shutting down')
            if self.preempt_requested():
                raise Cancelled()
            try:
                master.lookupService(resolved)
            except (rosgraph.MasterError, OSError):
                if now - t0 > self.cfg.server_timeout:
                    raise DetectionError(no_service(resolved, self.cfg.server_timeout)) from None
                continue
            dead = self._service_dead(resolved)
            if dead:
                raise DetectionError(dead)

    def _service_dead(self, resolved):
        """:func:`tiago_nav.mission.runner.service_verdict` on the facts of the service
        ``resolved``: registered with the master, and its node's process there."""
        master = rosgraph.Master(rospy.get_name())
        try:
            _, _, services = master.getSystemState()
        except (rosgraph.MasterError, OSError):
            return 'the ROS master cannot be reached'
        nodes = next((n for s, n in services if s == resolved), [])
        exited = None
        for node in nodes:
            try:
                exited = node_exited(master.lookupNode(node), rospy.get_name())
            except (rosgraph.MasterError, OSError):
                exited = None
        return service_verdict(resolved, bool(nodes), exited)

    # --- feedback ----------------------------------------------------------------------------
    def publish_feedback(self, state, status, pose):
        fb = TiagoTaskFeedback(state=state, status=status)
        if pose is not None:
            fb.pose = pose_stamped(pose, self.global_frame, self.stamp())
        if self.server is not None:
            self.server.publish_feedback(fb)


class TiagoController:
    """The node: the TiagoTask action server around a :class:`MissionRunner`."""

    def __init__(self, params, server=None):
        """``server``: the action server of an earlier state (a reset keeps it, with its
        clients' connections); None: make one."""
        self.p = params
        self.backend = RosBackend(params)
        self.runner = MissionRunner(self.backend, params.mission, log=rospy.loginfo)
        self.markers = rospy.Publisher('~obstacle_markers', MarkerArray, queue_size=1, latch=True)
        self.goal_pose = rospy.Publisher('~goal_pose', PoseStamped, queue_size=1, latch=True)
        # (the proxy claims its cycles itself, once the servers it needs are there: begin())
        fresh = server is None
        if fresh:
            with persistent():
                server = ClaimingActionServer(params.action_name, TiagoTaskAction, self.execute,
                                              None)
        self.server = adopt(server, self.execute, None)
        self.backend.server = self.server
        on_shutdown(self.on_shutdown)       # (held weakly: a reset drops this state)
        # missions only once the simulator holds for the proxy: one begun before would decide
        # its stages in wall time
        self.backend.lockstep.wait_joined(params.mission.server_timeout)
        if fresh:
            self.server.start()
        rospy.loginfo('tiago_controller: serving %s (corridor %s, move_base %s, detection %s)',
                      rospy.resolve_name(params.action_name),
                      rospy.resolve_name(params.corridor_action),
                      rospy.resolve_name(params.move_base_action),
                      rospy.resolve_name(params.detection_service))

    def execute(self, goal):
        """The action's execute callback: run the mission; any unexpected exception here still
        stops the base and aborts the task with the exception's text."""
        try:
            self._execute(goal)
        except Exception as e:
            message = 'tiago_controller failed: unexpected error: %s: %s' % (type(e).__name__, e)
            rospy.logerr('task aborted: %s', message)
            self.backend.stop_robot()
            if self.server.is_active():
                self.server.set_aborted(TiagoTaskResult(message=message), message)

    def _execute(self, goal):
        self.backend.begin(self.server.current_goal.get_goal_id().stamp, goal.use_corridor_law)
        try:
            self._run(goal)
        finally:
            self.backend.end()

    def _run(self, goal):
        self.publish_markers([])
        if all(math.isfinite(v) for v in (goal.x, goal.y, goal.yaw_deg)):
            self.goal_pose.publish(pose_stamped((goal.x, goal.y, math.radians(goal.yaw_deg)),
                                                self.p.global_frame, rospy.Time.now()))
        outcome = self.runner.run(Goal(goal.x, goal.y, goal.yaw_deg, goal.use_corridor_law))
        self.backend.end()
        # feedback and result travel on separate topics, and a client drops feedback that
        # comes after the result: the result carries the last feedback state too
        result = TiagoTaskResult(obstacles=outcome.obstacles, message=outcome.message,
                                 state=self.runner.state if self.runner.state is not None else 0)
        if outcome.final_pose is not None:
            result.final_pose = pose_stamped(outcome.final_pose, self.p.global_frame,
                                             self.backend.stamp())
        try:
            if outcome.status == mission.SUCCEEDED:
                rospy.loginfo('task succeeded: %s', outcome.message)
                self.publish_markers(outcome.obstacles)
                self.server.set_succeeded(result, outcome.message)
            elif outcome.status == mission.PREEMPTED:
                rospy.logwarn('task preempted: %s', outcome.message)
                self.server.set_preempted(result, outcome.message)
            else:
                rospy.logerr('task aborted: %s', outcome.message)
                self.server.set_aborted(result, outcome.message)
        except rospy.ROSException as e:   # shutting down
            rospy.logwarn('could not report the result: %s', e)

    def on_shutdown(self):
        """Ctrl-C or rosnode kill: the process may end before the runner's own cancel path
        runs, so cancel the child goals and stop the base here."""
        self.backend.halt()

    def publish_markers(self, obstacles):
        self.markers.publish(obstacle_markers(obstacles, self.p.global_frame, labels=True))


def _service_registered(name):
    """True when the master knows a provider of the service ``name`` (resolved)."""
    try:
        rosgraph.Master(rospy.get_name()).lookupService(name)
        return True
    except (rosgraph.MasterError, OSError):
        return False


def main():
    concurrent_handshakes()
    rospy.init_node('tiago_controller')
    reset = NodeReset(lambda: TiagoController(ros_params.read_or_exit(Params, 'tiago_controller')))
    server = reset.state.server
    reset.build = lambda: TiagoController(ros_params.read_or_exit(Params, 'tiago_controller'),
                                          server)
    rospy.spin()
