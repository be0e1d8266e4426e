"""Reproducibility as a user sees it: a fresh demo.launch at ``real_time_factor:=0``, then
(optionally) a corridor_controller goal, missions and a move_base goal sent by plain actionlib
clients (no lockstep participation) after a wall delay; everything a user can read of them is
recorded: each result's fields,
the feedback published (state, sentence, stamp), the final true pose (/sim/ground_truth) and
the stamp of each result. With ``--starve S`` every node of the stack is stopped in turn for S
wall seconds while the goals run (:class:`~tiago_nav_tools.testing.harness.Starver`): a
machine starved far beyond any load, which must change nothing a user reads.

A process can join one ROS master only, so each run is a child process:
``python3 -m tiago_nav_tools.testing.repro --delay 1.5 [--world W] [--launch-args "..."]`` prints
``RESULT <json>`` last. :func:`run_child` starts one and returns its record;
:func:`differences` compares two records (used by test/ros/test_reproducible.py and
bench/bench_lockstep.py).
"""
import argparse
import json
import math
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
COURSE_WORLD = os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml')
COURSE_GOAL = (11.0, 0.0, -45.0, True)
SECOND_GOAL = (12.5, -1.6, 90.0, False)    # after the first mission, from pose B
NAV_GOAL = (11.5, -2.6, 180.0)             # a move_base goal sent directly, after both
CORRIDOR_GOAL = 3.0     # [m] max_distance of a corridor_controller goal sent directly (--corridor)


def _yaw(q):
    return 2.0 * math.atan2(q.z, q.w)


def _pose(p):
    return [p.position.x, p.position.y, _yaw(p.orientation)]


def _result_stamp(client):
    """[s] the stamp the server gave its result (the client's own clock, read when the result
    arrives, depends on timing: the base may still be braking)."""
    return client.gh.comm_state_machine.latest_result.header.stamp.to_sec()


def _at_rest(odom):
    t = odom.twist.twist
    return t.linear.x == 0.0 and t.angular.z == 0.0


def task_record(result, state, text, feedback):
    """A TiagoTask's outcome as plain values: GoalStatus ``state``, status ``text``, the
    result's fields and the ``feedback`` published [(stamp s, state, status)]."""
    rec = {'status': state, 'text': text, 'feedback': feedback}
    if result is not None:
        rec.update(message=result.message, final_state=result.state,
                   final_pose=_pose(result.final_pose.pose),
                   final_pose_stamp=result.final_pose.header.stamp.to_sec(),
                   obstacles=[[o.center.x, o.center.y, o.center_robot.x, o.center_robot.y,
                               o.radius, o.num_points] for o in result.obstacles])
    return rec


def goal_feedback(published, client, result, wait=10.0):
    """The feedback of ``client``'s goal among ``published`` [(goal id, record)], once the one
    whose state the result names has come (waiting up to ``wait`` wall seconds): ROS orders
    nothing across topics, so the result can arrive before the last feedback, and a straggler
    of the goal before can arrive after this one was sent."""
    goal_id = client.gh.comm_state_machine.action_goal.goal_id.id
    wanted = getattr(result, 'state', None)
    end = time.monotonic() + wait
    while wanted is not None and time.monotonic() < end and not any(
            g == goal_id and rec[1] == wanted for g, rec in list(published)):
        time.sleep(0.01)
    return [rec for g, rec in list(published) if g == goal_id]


def run(world, goals, nav_goal, delay, launch_args=(), timeout=240.0, corridor=None, starve=0.0):
    """One launch of ``world``; after ``delay`` wall seconds a corridor_controller goal of
    ``max_distance=corridor`` [m] (None: none) is sent with a plain SimpleActionClient, then
    each of ``goals`` ``(x, y, yaw_deg, use_corridor_law)`` to tiago_controller (one after the
    other, each ``delay`` after the last ended), then ``nav_goal`` ``(x, y, yaw_deg)`` (or None)
    to move_base; with ``starve`` [s wall] > 0, each node of the stack
    (:data:`~tiago_nav_tools.testing.harness.STARVED`) is stopped in turn for that long
    meanwhile. Returns the record (see the module)."""
    import actionlib
    import rospy
    from actionlib_msgs.msg import GoalStatus
    from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
    from nav_msgs.msg import Odometry
    from tiago_nav.msg import (CorridorAction, CorridorGoal, TiagoTaskAction,
                               TiagoTaskActionFeedback, TiagoTaskGoal)
    from tiago_nav.ros.conversions import pose_stamped
    from tiago_nav_tools.testing.harness import Harness, Starver

    h = Harness(world, real_time_factor=0.0, observe=False, extra_args=list(launch_args))
    rec = {'world': world, 'delay_s': delay, 'launch_args': list(launch_args), 'tasks': [],
           'starve_s': starve}
    starver = None
    try:
        h.connect(timeout=120.0)
        if starve > 0:
            starver = Starver.of_nodes(starve)
        truth = {}
        rospy.Subscriber('/sim/ground_truth', Odometry, lambda m: truth.__setitem__('m', m),
                         queue_size=1)
        published = []          # (goal id, [stamp s, state, status]) of every feedback message
        rospy.Subscriber('/tiago_controller/feedback', TiagoTaskActionFeedback,
                         lambda m: published.append((m.status.goal_id.id, [
                             m.header.stamp.to_sec(), m.feedback.state, m.feedback.status])),
                         queue_size=None)
        if corridor is not None:
            time.sleep(delay)
            cc = actionlib.SimpleActionClient('corridor_controller', CorridorAction)
            if not cc.wait_for_server(rospy.Duration(30.0)):
                raise RuntimeError('no corridor_controller action server')
            cc.send_goal(CorridorGoal(max_distance=corridor))
            if not cc.wait_for_result(rospy.Duration(timeout)):
                raise RuntimeError('no corridor_controller result within %g s' % timeout)
            res = cc.get_result()
            rec['corridor'] = {'status': cc.get_state(), 'text': cc.get_goal_status_text(),
                               'ended_s': _result_stamp(cc)}
            if res is not None:
                rec['corridor'].update(exit_pose=_pose(res.exit_pose.pose),
                                       exit_frame=res.exit_pose.header.frame_id,
                                       exit_stamp=res.exit_pose.header.stamp.to_sec(),
                                       distance=res.distance, reason=res.reason)
        client = actionlib.SimpleActionClient('tiago_controller', TiagoTaskAction)
        if not client.wait_for_server(rospy.Duration(30.0)):
            raise RuntimeError('no tiago_controller action server')
        for x, y, yaw, use_corridor_law in goals:
            time.sleep(delay)
            t0 = time.monotonic()
            client.send_goal(TiagoTaskGoal(x=x, y=y, yaw_deg=yaw, use_corridor_law=use_corridor_law))
            if not client.wait_for_result(rospy.Duration(timeout)):
                raise RuntimeError('no result within %g s' % timeout)
            result = client.get_result()
            task = task_record(result, client.get_state(), client.get_goal_status_text(),
                               goal_feedback(published, client, result))
            task.update(wall_s=time.monotonic() - t0, ended_s=_result_stamp(client))
            rec['tasks'].append(task)
        if nav_goal is not None:
            time.sleep(delay)
            mb = actionlib.SimpleActionClient('move_base', MoveBaseAction)
            if not mb.wait_for_server(rospy.Duration(30.0)):
                raise RuntimeError('no move_base action server')
            x, y, yaw = nav_goal
            mb.send_goal(MoveBaseGoal(target_pose=pose_stamped((x, y, math.radians(yaw)), 'map',
                                                               rospy.Time.now())))
            if not mb.wait_for_result(rospy.Duration(timeout)):
                raise RuntimeError('no move_base result within %g s' % timeout)
            rec['nav'] = {'status': mb.get_state(), 'text': mb.get_goal_status_text(),
                          'ended_s': _result_stamp(mb)}
        # the true pose once the base is at rest (then nothing moves: the simulator waits for
        # work); ground truth goes out with each scan while simulated time runs
        end = time.monotonic() + 10.0
        while time.monotonic() < end and not ('m' in truth and _at_rest(truth['m'])):
            time.sleep(0.01)
        if starver is not None:
            starver.finish()
            rec['stops'] = starver.stops
        rec['truth'] = _pose(truth['m'].pose.pose) if 'm' in truth else None
        rec['truth_stamp'] = truth['m'].header.stamp.to_sec() if 'm' in truth else None
        rec['collisions'] = h.collisions
        rec['succeeded'] = all(t['status'] == GoalStatus.SUCCEEDED for t in rec['tasks']) and \
            rec.get('corridor', {}).get('status', GoalStatus.SUCCEEDED) == GoalStatus.SUCCEEDED
    except Exception as e:      # noqa: BLE001  (a broken run is a failed run, with its reason)
        rec.update(succeeded=False, error='%s: %s' % (type(e).__name__, e))
    finally:
        if starver is not None:
            starver.finish()
        h.close()
    return rec


def run_child(delay, world=COURSE_WORLD, launch_args=(), goals='course,second', nav=True,
              timeout=400.0, corridor=False, starve=0.0):
    """:func:`run` in a child process (its own ROS node); its record, or one with ``error``."""
    cmd = [sys.executable, '-m', 'tiago_nav_tools.testing.repro', '--delay', repr(delay), '--world',
           world, '--launch-args', ' '.join(launch_args), '--goals', goals]
    if not nav:
        cmd.append('--no-nav')
    if corridor:
        cmd.append('--corridor')
    if starve:
        cmd += ['--starve', repr(starve)]
    try:
        out = subprocess.run(cmd, stdout=subprocess.PIPE, text=True, timeout=timeout).stdout
    except subprocess.TimeoutExpired:
        return {'succeeded': False, 'error': 'no result within %g s' % timeout}
    return next((json.loads(line[7:]) for line in out.splitlines() if line.startswith('RESULT ')),
                {'succeeded': False, 'error': 'no result'})


def differences(a, b, tol=1e-7):
    """Where two records differ (list of strings; empty when they agree): every number to
    ``tol`` [m, rad, s], everything else exactly. Wall times, delays and the launch log are
    not compared."""
    skip = {'wall_s', 'delay_s', 'starve_s', 'stops'}
    out = []

    def walk(x, y, path):
        if isinstance(x, dict) and isinstance(y, dict):
            for k in sorted(set(x) | set(y)):
                if k not in skip:
                    walk(x.get(k), y.get(k), path + '.' + k)
        elif isinstance(x, list) and isinstance(y, list):
            if len(x) != len(y):
                out.append('%s: %d items against %d' % (path, len(x), len(y)))
            for i, (u, v) in enumerate(zip(x, y)):
                walk(u, v, '%s[%d]' % (path, i))
        elif isinstance(x, float) or isinstance(y, float):
            if x is None or y is None or abs(x - y) > tol:
                out.append('%s: %r against %r' % (path, x, y))
        elif x != y:
            out.append('%s: %r against %r' % (path, x, y))
    walk(a, b, '')
    return out


GOALS = {'course': COURSE_GOAL, 'second': SECOND_GOAL}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--delay', type=float, default=0.0, help='[s wall] before each goal')
    ap.add_argument('--world', default=COURSE_WORLD)
    ap.add_argument('--launch-args', default='')
    ap.add_argument('--goals', default='course,second',
                    help='comma-separated: course, second, or x:y:yaw:corridor(0/1)')
    ap.add_argument('--no-nav', action='store_true', help='no move_base goal at the end')
    ap.add_argument('--corridor', action='store_true',
                    help='first a corridor_controller goal (max_distance %g m)' % CORRIDOR_GOAL)
    ap.add_argument('--starve', type=float, default=0.0,
                    help='[s wall] stop each node of the stack in turn this long while the goals '
                    'run (0: no)')
    args = ap.parse_args(argv)
    goals = []
    for g in filter(None, args.goals.split(',')):
        if g in GOALS:
            goals.append(GOALS[g])
        else:
            x, y, yaw, c = g.split(':')
            goals.append((float(x), float(y), float(yaw), c == '1'))
    rec = run(os.path.abspath(args.world), goals, None if args.no_nav else NAV_GOAL, args.delay,
              args.launch_args.split(), corridor=CORRIDOR_GOAL if args.corridor else None,
              starve=args.starve)
    print('RESULT ' + json.dumps(rec), flush=True)
    return 0 if rec.get('succeeded') else 1


if __name__ == '__main__':
    sys.exit(main())
