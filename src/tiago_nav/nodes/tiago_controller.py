"""The ``tiago_controller`` node: serves the TiagoTask action (tiago_nav/TiagoTaskAction) by
chaining the corridor_controller action (optional), move_base and the obstacle_detection service.

The decisions are :class:`tiago_nav.mission.MissionRunner`'s; this module only wires it to ROS
(:class:`RosBackend`). Publishes ``~obstacle_markers`` (visualization_msgs/MarkerArray,
latched) and ``~goal_pose`` (geometry_msgs/PoseStamped, latched: the current pose B), and
commands a stop on ``cmd_vel_topic`` whenever a goal ends.
"""
import math
import sys
import threading
import time
from dataclasses import dataclass

import actionlib
import rospy
import tf2_ros
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped, Twist
from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
from nav_msgs.msg import Path
from visualization_msgs.msg import MarkerArray

from tiago_nav import mission
from tiago_nav.mission import DetectionError, Goal, MissionConfig, MissionRunner, Poll
from tiago_nav.msg import (CorridorAction, CorridorGoal, TiagoTaskAction, TiagoTaskFeedback,
                           TiagoTaskResult)
from tiago_nav.params import ParamError, nested, param, validate
from tiago_nav.ros import params as ros_params
from tiago_nav.ros.actions import server_connected
from tiago_nav.ros.conversions import pose_from_transform, pose_stamped
from tiago_nav.ros.markers import obstacle_markers
from tiago_nav.srv import DetectObstacles, DetectObstaclesRequest

FEEDBACK_HEAD_START = 0.1    # [s wall] between the last feedback and the result

_POLL = {GoalStatus.PENDING: mission.ACTIVE, GoalStatus.ACTIVE: mission.ACTIVE,
         GoalStatus.PREEMPTING: mission.ACTIVE, GoalStatus.RECALLING: mission.ACTIVE,
         GoalStatus.SUCCEEDED: mission.SUCCEEDED, GoalStatus.ABORTED: mission.ABORTED,
         GoalStatus.PREEMPTED: mission.PREEMPTED, GoalStatus.RECALLED: mission.PREEMPTED,
         GoalStatus.REJECTED: mission.REJECTED, GoalStatus.LOST: mission.LOST}


@dataclass
class Params:
    """Parameters of the tiago_controller node (the TiagoTask proxy).

    Stage timeouts count in ROS time (simulated under /use_sim_time); server_timeout,
    detection_timeout and clock_timeout in wall time, so nothing hangs if /clock stops.
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
    global_frame: str = param('map', 'frame of pose B and of the reported poses', nonempty=True)
    robot_frame: str = param('base_footprint', 'the robot base frame', nonempty=True)

    def __post_init__(self):
        validate(self)


class RosBackend:
    """The runner's view of ROS: action clients, the detection service, tf, cmd_vel."""

    def __init__(self, params):
        self.p = params
        self.cfg = params.mission
        self.global_frame, self.robot_frame = params.global_frame, params.robot_frame
        self.clients = {
            'corridor': actionlib.SimpleActionClient(params.corridor_action, CorridorAction),
            'navigation': actionlib.SimpleActionClient(params.move_base_action, MoveBaseAction)}
        self.feedbacks = {}
        self.tf = tf2_ros.Buffer(rospy.Duration(10.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf)
        self.cmd = rospy.Publisher(params.cmd_vel_topic, Twist, queue_size=1)
        self._path = None
        rospy.Subscriber(params.plan_topic, Path, self._on_path, queue_size=1)
        self.server = None            # the SimpleActionServer, set by the node

    # --- clock (tiago_nav.clock protocol) ------------------------------------------------------
    def now(self):
        return rospy.get_time()

    def wall(self):
        return time.monotonic()

    def sleep(self, seconds):
        time.sleep(seconds)           # wall clock: never blocks if /clock stops

    def shutdown(self):
        return rospy.is_shutdown()

    def preempt_requested(self):
        return rospy.is_shutdown() or (self.server is not None and self.server.is_preempt_requested())

    # --- robot -------------------------------------------------------------------------------
    def pose(self):
        try:
            t = self.tf.lookup_transform(self.global_frame, self.robot_frame, rospy.Time(0))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                tf2_ros.ExtrapolationException):
            return None
        return pose_from_transform(t.transform)

    def _on_path(self, msg):
        if msg.header.frame_id in ('', self.global_frame, '/' + self.global_frame):
            self._path = [(p.pose.position.x, p.pose.position.y) for p in msg.poses]

    def path(self):
        return self._path

    def stop_robot(self):
        if not rospy.is_shutdown():
            try:
                self.cmd.publish(Twist())
            except rospy.ROSException:
                pass

    # --- actions -----------------------------------------------------------------------------
    def server_ready(self, stage):
        return server_connected(self.clients[stage])

    def send_goal(self, stage, goal):
        self.feedbacks[stage] = None
        if stage == 'corridor':
            msg = CorridorGoal(max_speed=goal[0], max_distance=goal[1])
        else:
            self._path = None
            msg = MoveBaseGoal(target_pose=pose_stamped(goal, self.global_frame, rospy.Time.now()))
        self.clients[stage].send_goal(msg, feedback_cb=lambda fb: self.feedbacks.__setitem__(stage, fb))

    def poll(self, stage):
        c = self.clients[stage]
        status = _POLL.get(c.get_state(), mission.ACTIVE)
        if status == mission.ACTIVE:
            return Poll(mission.ACTIVE, feedback=self.feedbacks.get(stage))
        return Poll(status, c.get_goal_status_text(), c.get_result(), self.feedbacks.get(stage))

    def cancel(self, stage):
        try:
            self.clients[stage].cancel_goal()
        except Exception as e:       # a dead server must not stop the cancel path
            rospy.logwarn('cancelling the %s goal: %s', stage, e)

    # --- detection ---------------------------------------------------------------------------
    def detect(self, timeout):
        name = self.p.detection_service
        try:
            rospy.wait_for_service(name, timeout=self.cfg.server_timeout)
        except rospy.ROSException:
            raise DetectionError('no %s service after %g s (is it running?)'
                                 % (rospy.resolve_name(name), self.cfg.server_timeout)) from None
        proxy = rospy.ServiceProxy(name, DetectObstacles)
        box = {}

        def call():
            try:
                box['response'] = proxy(DetectObstaclesRequest())
            except Exception as e:   # ServiceException, connection errors, ROSInterrupt
                box['error'] = e
        worker = threading.Thread(target=call, daemon=True)
        worker.start()
        worker.join(timeout)
        if worker.is_alive():
            raise DetectionError('the %s service did not answer within %g s' % (name, timeout))
        if 'error' in box:
            raise DetectionError('the %s service failed: %s' % (name, box['error']))
        resp = box['response']
        if not resp.success:
            raise DetectionError(resp.message or 'the %s service failed without a reason' % name)
        return list(resp.obstacles), resp.message

    # --- feedback ----------------------------------------------------------------------------
    def publish_feedback(self, state, status, pose):
        fb = TiagoTaskFeedback(state=state, status=status)
        if pose is not None:
            fb.pose = pose_stamped(pose, self.global_frame, rospy.Time.now())
        if self.server is not None:
            self.server.publish_feedback(fb)


class TiagoController:
    """The node: the TiagoTask action server around a :class:`MissionRunner`."""

    def __init__(self, params):
        self.p = params
        self.backend = RosBackend(params)
        self.runner = MissionRunner(self.backend, params.mission, log=rospy.loginfo)
        self.markers = rospy.Publisher('~obstacle_markers', MarkerArray, queue_size=1, latch=True)
        self.goal_pose = rospy.Publisher('~goal_pose', PoseStamped, queue_size=1, latch=True)
        self.server = actionlib.SimpleActionServer(params.action_name, TiagoTaskAction,
                                                   self.execute, auto_start=False)
        self.backend.server = self.server
        rospy.on_shutdown(self.on_shutdown)
        self.server.start()
        rospy.loginfo('tiago_controller: serving %s (corridor %s, move_base %s, detection %s)',
                      rospy.resolve_name(params.action_name),
                      rospy.resolve_name(params.corridor_action),
                      rospy.resolve_name(params.move_base_action),
                      rospy.resolve_name(params.detection_service))

    def execute(self, goal):
        self.publish_markers([])
        if all(math.isfinite(v) for v in (goal.x, goal.y, goal.yaw_deg)):
            self.goal_pose.publish(pose_stamped((goal.x, goal.y, math.radians(goal.yaw_deg)),
                                                self.p.global_frame, rospy.Time.now()))
        outcome = self.runner.run(Goal(goal.x, goal.y, goal.yaw_deg, goal.use_corridor_law))
        result = TiagoTaskResult(obstacles=outcome.obstacles, message=outcome.message)
        if outcome.final_pose is not None:
            result.final_pose = pose_stamped(outcome.final_pose, self.p.global_frame,
                                             rospy.Time.now())
        # feedback and result travel on separate topics: give the last feedback a head start, or
        # clients (whose goal is then done) drop it
        time.sleep(FEEDBACK_HEAD_START)
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
        """Ctrl-C: the running goal is cancelled by the runner; tell the base to stop too."""
        try:
            self.backend.cmd.publish(Twist())
        except Exception:        # publishers may already be closed
            pass

    def publish_markers(self, obstacles):
        self.markers.publish(obstacle_markers(obstacles, self.p.global_frame, labels=True))


def main():
    rospy.init_node('tiago_controller')
    try:
        TiagoController(ros_params.read(Params))
    except ParamError as e:
        rospy.logfatal('tiago_controller: %s', e)
        sys.exit(2)
    rospy.spin()
