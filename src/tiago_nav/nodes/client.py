"""The ``client`` node: sends pose B to the tiago_controller proxy and follows the task.

``rosrun tiago_nav client X Y YAW_DEG [--corridor | --no-corridor] [--server-timeout S]
[--frame FRAME]`` validates pose B before anything is sent (exit 2 on bad input, and on a
``--frame`` that tf does not know within :data:`FRAME_WAIT`), prints each feedback change on one
line and then the obstacles found, their centres in FRAME (``map`` by default; transformed with
tf); Ctrl-C cancels the task and waits for the robot to stop.
Exit 0 when the task succeeded, 1 when it was aborted or preempted. The ROS-free parts
(arguments, lines, table) are :mod:`tiago_nav.mission.client`.
"""
import sys
import time

import rospy
import tf2_ros
from actionlib_msgs.msg import GoalStatus

from tiago_nav.mission.client import (EXIT_FAILED, EXIT_OK, EXIT_USAGE, MAP_FRAME,
                                      SERVER_TIMEOUT, USAGE, UsageError, centres_in_frame,
                                      feedback_line, obstacle_rows, obstacle_table, shape_lines,
                                      parse_client_args, table_title)
from tiago_nav.mission.sentences import fmt_pose
from tiago_nav.ros.actions import TaskClient, server_connected, wait_server
from tiago_nav.ros.conversions import known_frames, pose_from_msg, pose_from_transform
from tiago_nav.ros.tcpros import concurrent_handshakes

CANCEL_TIMEOUT = 15.0     # [s wall] after Ctrl-C, wait this long for the server to confirm
SERVER_LOST = 3.0         # [s wall] a task whose server has been gone this long is lost
FRAME_WAIT = 5.0          # [s wall] wait this long for tf to know --frame (before sending)
_NAMES = {GoalStatus.ABORTED: 'ABORTED', GoalStatus.PREEMPTED: 'PREEMPTED',
          GoalStatus.REJECTED: 'REJECTED', GoalStatus.RECALLED: 'RECALLED',
          GoalStatus.LOST: 'LOST'}


class FrameLookup:
    """The pose of a frame in ``map`` from tf (a listener started at construction)."""

    def __init__(self, frame):
        self.frame = frame
        self.tf = tf2_ros.Buffer()
        self.listener = tf2_ros.TransformListener(self.tf)

    def wait(self, timeout=FRAME_WAIT):
        """'' once tf can transform map -> frame, else a sentence naming the frame (after
        ``timeout`` wall seconds)."""
        t_end = time.monotonic() + timeout
        while True:
            try:
                self.tf.lookup_transform(MAP_FRAME, self.frame, rospy.Time(0))
                return ''
            except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                    tf2_ros.ExtrapolationException) as e:
                if time.monotonic() > t_end or rospy.is_shutdown():
                    known = sorted(known_frames(self.tf.all_frames_as_yaml()))
                    return ('unknown frame %r: no transform %s -> %s within %g s (%s); frames tf '
                            'knows: %s' % (self.frame, MAP_FRAME, self.frame, timeout, e,
                                           ', '.join(known) or 'none'))
            time.sleep(0.05)

    def pose(self):
        """``(x, y, yaw)`` of the frame in map, now (tf exceptions propagate)."""
        return pose_from_transform(self.tf.lookup_transform(MAP_FRAME, self.frame, rospy.Time(0),
                                                            rospy.Duration(1.0)).transform)


def run(goal, out=print, server_timeout=SERVER_TIMEOUT, action='tiago_controller', on_result=None,
        frame=None):
    """Send ``goal`` (dict from :func:`tiago_nav.mission.client.parse_client_args`) to the
    TiagoTask server ``action`` and follow it, printing with ``out``; return the exit code.

    Needs an initialised rospy node (started with ``disable_signals=True`` so that Ctrl-C
    arrives here as KeyboardInterrupt: the goal is then cancelled and the client waits, up to
    ``CANCEL_TIMEOUT``, for the server to confirm the robot stopped). ``on_result(state,
    result)``, when given, receives the final GoalStatus and TiagoTaskResult. ``frame``, a
    :class:`FrameLookup`, shows the obstacles in its frame (None: in map).
    """
    from tiago_nav.msg import TiagoTaskGoal    # generated: only in a built workspace, and
    # bad input is refused (exit 2) before this is needed
    client = TaskClient(action)
    out('waiting for the %s action server (up to %g s)...' % (rospy.resolve_name(action),
                                                              server_timeout))
    if not wait_server(client, server_timeout):
        out('error: no %s action server after %g s; is demo.launch running?'
            % (rospy.resolve_name(action), server_timeout))
        return EXIT_FAILED
    if rospy.rostime.is_wallclock() and rospy.get_param('/use_sim_time', False):
        out('warning: /use_sim_time was set after this client started: it shows wall times')
    last = [None]

    def on_feedback(fb):
        key = (fb.state, fb.status)
        if key != last[0]:
            last[0] = key
            pose = pose_from_msg(fb.pose.pose) if fb.pose.header.frame_id else None
            out(feedback_line(rospy.get_time(), fb.state, fb.status, pose))

    g = TiagoTaskGoal(x=goal['x'], y=goal['y'], yaw_deg=goal['yaw_deg'],
                      use_corridor_law=goal['use_corridor_law'])
    out('sending pose B (%.2f, %.2f, %.1f deg), corridor law %s'
        % (g.x, g.y, g.yaw_deg, 'on' if g.use_corridor_law else 'off'))
    client.send_goal(g, feedback_cb=on_feedback)
    gone_since = None
    try:
        while not client.wait_for_result(0.2):
            if rospy.is_shutdown():
                raise KeyboardInterrupt
            now = time.monotonic()
            if server_connected(client):
                gone_since = None
            elif gone_since is None:
                gone_since = now
            elif now - gone_since > SERVER_LOST:
                out('ABORTED: tiago_controller failed: the %s action server went away (gone for '
                    '%g s)' % (rospy.resolve_name(action), SERVER_LOST))
                return EXIT_FAILED
    except KeyboardInterrupt:
        out('interrupted: cancelling the task and waiting for the robot to stop...')
        client.cancel_goal()
        client.wait_for_result(CANCEL_TIMEOUT)   # the result, not only the status, has come
    state = client.get_state()
    result = client.get_result()
    text = client.get_goal_status_text()
    if on_result is not None:
        on_result(state, result)
    if state == GoalStatus.SUCCEEDED and result is not None:
        out('SUCCEEDED: %s' % (result.message or text))
        out('final pose: %s' % fmt_pose(pose_from_msg(result.final_pose.pose)))
        rows = obstacle_rows(result.obstacles)
        shown = MAP_FRAME
        if frame is not None and frame.frame != MAP_FRAME:
            try:
                rows, shown = centres_in_frame(rows, frame.pose()), frame.frame
            except (tf2_ros.TransformException, ValueError) as e:
                out('error: cannot show the obstacles in frame %r (%s); in %s instead:'
                    % (frame.frame, e, MAP_FRAME))
        out(table_title(shown))
        for line in obstacle_table(rows):
            out(line)
        if result.obstacles:
            out('shapes (map frame):')
            for line in shape_lines(result.obstacles):
                out(line)
        return EXIT_OK
    name = _NAMES.get(state, 'not finished (state %d)' % state)
    out('%s: %s' % (name, (result.message if result is not None and result.message else text)
                    or 'no reason given'))
    return EXIT_FAILED


def main():
    """The executable: parse (exit 2 on bad input, before ROS is touched), run, exit."""
    argv = rospy.myargv(sys.argv)[1:]
    try:
        goal = parse_client_args(argv, interactive=sys.stdin.isatty())
    except UsageError as e:
        sys.stderr.write('client: error: %s\n%s\n' % (e, USAGE))
        return EXIT_USAGE
    except KeyboardInterrupt:
        sys.stderr.write('\nclient: interrupted, nothing sent\n')
        return EXIT_USAGE
    if goal.get('help'):
        print(USAGE)
        return EXIT_OK
    concurrent_handshakes()
    rospy.init_node('client', anonymous=True, disable_signals=True)

    def out(line):
        print(line, flush=True)
    try:
        frame = None
        if goal['frame'] != MAP_FRAME:
            frame = FrameLookup(goal['frame'])
            problem = frame.wait()
            if problem:
                sys.stderr.write('client: error: --frame %s: %s\n' % (goal['frame'], problem))
                return EXIT_USAGE
        return run(goal, out=out, server_timeout=goal['server_timeout'], frame=frame)
    except KeyboardInterrupt:
        out('interrupted before the goal was sent')
        return EXIT_FAILED
    finally:
        rospy.signal_shutdown('client done')
