"""The command-line client of ``tiago_controller`` (``nodes/client``): argument parsing and
validation (no ROS needed) and the run loop (needs an initialised rospy node).

``rosrun tiago_nav client X Y YAW_DEG [--corridor|--no-corridor] [--server-timeout S]``
Exit codes: 0 the task succeeded, 1 it was aborted or preempted (or the server never came),
2 bad input (nothing was sent).
"""
import threading
import time

from tiago_nav.ros.actions import TaskClient, wait_server  # noqa: F401  (TRANSITIONAL)
from tiago_nav.mission import (GoalError, STATE_NAMES, fmt_pose, obstacle_table, parse_number,
                               validate_goal)

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2

USAGE = ('usage: rosrun tiago_nav client X Y YAW_DEG [--corridor | --no-corridor] '
         '[--server-timeout SECONDS]\n'
         '  X, Y     pose B in the map frame [m]\n'
         '  YAW_DEG  heading at pose B [deg], between -360 and 360\n'
         '  --corridor / --no-corridor  drive the corridor with the laser-only law first '
         '(default: --corridor;\n'
         '             --corridor=true|false also works, e.g. from a launch file)\n'
         '  --server-timeout  how long to wait for the tiago_controller server [s] (default 15)')

PROMPTS = ('x [m]: ', 'y [m]: ', 'yaw [deg]: ')


class UsageError(ValueError):
    """Bad command-line input; the message says what is wrong."""


def parse_client_args(argv, interactive=False, ask=input):
    """Parse the client's arguments (``argv`` without the program name and without ROS
    remappings, see ``rospy.myargv``).

    Missing X/Y/YAW are asked for with ``ask(prompt)`` when ``interactive`` (a terminal);
    otherwise they are a :class:`UsageError`. Every value is validated
    (:func:`tiago_nav.mission.validate_goal`). Returns a dict with ``x``, ``y``, ``yaw_deg``,
    ``use_corridor_law``, ``server_timeout`` or ``{'help': True}``.
    """
    positional, corridor, server_timeout = [], True, 15.0
    args = list(argv)
    i = 0
    while i < len(args):
        a = args[i]
        if a in ('-h', '--help'):
            return {'help': True}
        if a == '--corridor':
            corridor = True
        elif a == '--no-corridor':
            corridor = False
        elif a.startswith('--corridor='):
            v = a.split('=', 1)[1].strip().lower()
            if v in ('true', '1', 'yes', 'on'):
                corridor = True
            elif v in ('false', '0', 'no', 'off'):
                corridor = False
            else:
                raise UsageError('--corridor=%s: expected true or false' % a.split('=', 1)[1])
        elif a.startswith('--server-timeout'):
            if '=' in a:
                val = a.split('=', 1)[1]
            elif i + 1 < len(args):
                i += 1
                val = args[i]
            else:
                raise UsageError('--server-timeout needs a value in seconds')
            try:
                server_timeout = parse_number(val, '--server-timeout')
            except GoalError as e:
                raise UsageError(str(e)) from None
            if server_timeout <= 0:
                raise UsageError('--server-timeout: must be > 0 s, got %g' % server_timeout)
        elif a.startswith('--'):
            raise UsageError('unknown option %s' % a)
        else:
            positional.append(a)
        i += 1
    if len(positional) > 3:
        raise UsageError('too many values: %s (expected X Y YAW_DEG)' % ' '.join(positional))
    if len(positional) < 3:
        if not interactive:
            raise UsageError('missing %s (expected X Y YAW_DEG)'
                             % ', '.join(('X', 'Y', 'YAW_DEG')[len(positional):]))
        for prompt in PROMPTS[len(positional):]:
            try:
                positional.append(ask(prompt))
            except EOFError:
                raise UsageError('input ended before %s was given' % prompt.split(' ')[0]) from None
    try:
        x, y, yaw = validate_goal(*positional)
    except GoalError as e:
        raise UsageError(str(e)) from None
    return {'x': x, 'y': y, 'yaw_deg': yaw, 'use_corridor_law': corridor,
            'server_timeout': server_timeout}


def feedback_line(t, state, status, pose=None):
    """One line per feedback change: sim time [s], state name, sentence, pose."""
    name = STATE_NAMES[state] if 0 <= state < len(STATE_NAMES) else 'STATE_%d' % state
    return '[%7.2f s] %-14s %s%s' % (t, name, status, '   @ %s' % fmt_pose(pose) if pose else '')


def obstacle_rows(obstacles):
    """tiago_nav/Obstacle messages → rows of :func:`tiago_nav.mission.obstacle_table`."""
    return [(o.center.x, o.center.y, o.center_robot.x, o.center_robot.y, o.radius, o.num_points)
            for o in obstacles]


def run(goal, out=print, server_timeout=15.0, action='tiago_controller', on_result=None):
    """Send ``goal`` (dict from :func:`parse_client_args`) to the TiagoTask server and follow it.

    Needs an initialised rospy node (started with ``disable_signals=True`` so that Ctrl-C
    arrives here as KeyboardInterrupt: the goal is then cancelled and the client waits, with a
    timeout, for the server to confirm the robot stopped). Returns the exit code.
    """
    import rospy
    from actionlib_msgs.msg import GoalStatus
    from tiago_nav.msg import TiagoTaskGoal
    from tiago_nav.ros.conversions import pose_from_msg

    client = TaskClient(action)
    out('waiting for the %s action server (up to %g s)...' % (rospy.resolve_name(action),
                                                              server_timeout))
    if not wait_server(client, server_timeout):
        out('error: no %s action server after %g s; is demo.launch running?'
            % (rospy.resolve_name(action), server_timeout))
        return EXIT_FAILED
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
    try:
        while not client.wait_for_result(0.2):
            if rospy.is_shutdown():
                raise KeyboardInterrupt
    except KeyboardInterrupt:
        out('interrupted: cancelling the task and waiting for the robot to stop...')
        client.cancel_goal()
        t0 = time.monotonic()
        while client.get_state() in (GoalStatus.PENDING, GoalStatus.ACTIVE, GoalStatus.PREEMPTING,
                                     GoalStatus.RECALLING) and time.monotonic() - t0 < 15.0:
            time.sleep(0.1)
    state = client.get_state()
    result = client.get_result()
    text = client.get_goal_status_text()
    if on_result is not None:
        on_result(state, result)
    if state == GoalStatus.SUCCEEDED and result is not None:
        out('SUCCEEDED: %s' % (result.message or text))
        out('final pose: %s' % fmt_pose(pose_from_msg(result.final_pose.pose)))
        out('obstacles (map frame, and robot frame base_footprint at scan time):')
        for line in obstacle_table(obstacle_rows(result.obstacles)):
            out(line)
        return EXIT_OK
    name = {GoalStatus.ABORTED: 'ABORTED', GoalStatus.PREEMPTED: 'PREEMPTED',
            GoalStatus.REJECTED: 'REJECTED', GoalStatus.RECALLED: 'RECALLED',
            GoalStatus.LOST: 'LOST'}.get(state, 'not finished (state %d)' % state)
    out('%s: %s' % (name, (result.message if result is not None and result.message else text)
                    or 'no reason given'))
    return EXIT_FAILED
