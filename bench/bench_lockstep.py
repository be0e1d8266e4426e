#!/usr/bin/python3
"""Lockstep benchmark: the course mission (and a few navigation goals after it) at
``real_time_factor:=0``, with and without lockstep, on an idle machine, with a busy loop on
each core, or starved (each node of the stack, the simulator included, stopped in turn for 3 s
of wall time while the goals run: :class:`tiago_nav_tools.testing.harness.Starver`).

Each run is a fresh demo.launch (same world, same seed) whose goal a plain actionlib
SimpleActionClient sends after a random wall delay (0 to ``--max-delay`` s), as a user's script
would, so that runs can be compared: success, collisions, wall time per mission, simulated/wall
ratio, the final pose (ground truth and odometry, to the last bit), the spread of the result's
final pose and obstacle centres, the CPU time the launch's processes used during the mission, in
all and per process (divided by the cores: the least wall time the mission could take on this
machine) and, with lockstep, the simulator's figures for the lag between a command's cycle and
its application and the participants it dropped (its log line ``lockstep: N commands, lag
max ...``).
Writes bench/results/lockstep.json and lockstep.png.

Usage: bench/bench_lockstep.py [--n 20] [--nav 2] [--modes on,off] [--loads idle,busy,starved]
                               [--task mission|nav] [--max-delay 3] [--out bench/results/lockstep.json]
"""
import argparse
import json
import math
import os
import re
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, 'bench', 'results')
WORLD = os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml')
COURSE = (11.0, 0.0, -45.0)
TARGET_WALL = 3.0
STARVE = 3.0        # [s wall] --loads starved: each node stopped this long in turn
LAG_LINE = re.compile(r'lockstep: (\d+) commands, lag max ([\d.]+) s, p95 ([\d.]+) s, (\d+) drops')


def nav_goal(client, h, x, y, yaw_deg):
    """One move_base goal to ``(x, y, yaw_deg)`` in map, from a plain SimpleActionClient: its
    record."""
    import rospy
    from actionlib_msgs.msg import GoalStatus
    from move_base_msgs.msg import MoveBaseGoal
    from tiago_nav.ros.conversions import pose_stamped
    c0, t0, s0 = h.collisions or 0, time.monotonic(), rospy.get_time()
    client.send_goal(MoveBaseGoal(target_pose=pose_stamped((x, y, math.radians(yaw_deg)), 'map',
                                                           rospy.Time.now())))
    done = client.wait_for_result(rospy.Duration(120.0))
    return {'goal': [x, y, yaw_deg], 'succeeded': done and client.get_state() == GoalStatus.SUCCEEDED,
            'wall_s': time.monotonic() - t0, 'sim_s': rospy.get_time() - s0,
            'collisions': (h.collisions or 0) - c0, 'text': client.get_goal_status_text()}


def mission_plain(h, x, y, yaw_deg):
    """The course mission from a plain actionlib SimpleActionClient (as a user's script sends
    it: no lockstep participation), timed from the goal to the result; its record with the
    result's final pose and obstacle centres, and the CPU each process used meanwhile."""
    import actionlib
    import rospy
    from actionlib_msgs.msg import GoalStatus
    from tiago_nav.msg import TiagoTaskAction, TiagoTaskGoal
    client = actionlib.SimpleActionClient('tiago_controller', TiagoTaskAction)
    if not client.wait_for_server(rospy.Duration(30.0)):
        raise RuntimeError('no tiago_controller server')
    cpu0 = h.cpu_by_process()       # (a walk over /proc: before the clock starts)
    c0, t0, s0 = h.collisions or 0, time.monotonic(), rospy.get_time()
    client.send_goal(TiagoTaskGoal(x=x, y=y, yaw_deg=yaw_deg, use_corridor_law=True))
    done = client.wait_for_result(rospy.Duration(180.0))
    wall = time.monotonic() - t0
    cpu1 = h.cpu_by_process()
    by_process = {k: v - cpu0.get(k, 0.0) for k, v in cpu1.items() if v - cpu0.get(k, 0.0) > 0}
    result = client.get_result()
    rec = {'succeeded': bool(done) and client.get_state() == GoalStatus.SUCCEEDED,
           'message': client.get_goal_status_text(), 'wall_s': wall,
           'cpu_s': sum(by_process.values()), 'cpu_by_process_s': by_process,
           'sim_s': rospy.get_time() - s0, 'collisions': (h.collisions or 0) - c0,
           'obstacles': len(result.obstacles) if result else 0, 'mission_start_s': s0}
    if result is not None:
        rec['result_pose'] = _pose_of(result.final_pose.pose)
        rec['centres'] = [[o.center.x, o.center.y] for o in result.obstacles]
    return rec


def _pose_of(p):
    return [p.position.x, p.position.y, 2 * math.atan2(p.orientation.z, p.orientation.w)]


def _pose(m):
    return _pose_of(m.pose.pose)


def settle_pose(last, timeout=10.0):
    """The final pose once the robot is at rest: ground truth ('truth') and odometry ('odom')
    from the newest messages in ``last`` (topic -> nav_msgs/Odometry), once both stayed
    exactly the same over 0.5 s of simulated time (``timeout`` [s wall])."""
    topics = {'truth': '/sim/ground_truth', 'odom': '/mobile_base_controller/odom'}
    t_end = time.monotonic() + timeout
    out = {}
    while time.monotonic() < t_end:
        if all(t in last for t in topics.values()):
            before = {k: last[t] for k, t in topics.items()}
            stamp = max(m.header.stamp.to_sec() for m in before.values())
            while time.monotonic() < t_end and any(
                    last[t].header.stamp.to_sec() < stamp + 0.5 for t in topics.values()):
                time.sleep(0.01)
            out = {k: _pose(last[t]) for k, t in topics.items()}
            if all(out[k] == _pose(m) for k, m in before.items()):
                return out
        time.sleep(0.01)
    return out


def run_one(lockstep, nav_goals, seed, task, launch_args=(), delay=0.0, starve=0.0):
    """Child process: one launch, then after ``delay`` wall seconds the course mission
    (``task`` 'mission') or one move_base goal to pose B ('nav'), from a plain client, then
    ``nav_goals`` move_base goals, with ``starve`` > 0 each node of the stack stopped in turn
    for that long [s wall] meanwhile; prints ``RESULT <json>`` last."""
    import actionlib
    import numpy as np
    import rospy
    from move_base_msgs.msg import MoveBaseAction
    from nav_msgs.msg import Odometry
    from tiago_nav.sim.world import load_world
    from tiago_nav_tools.evaluate.matching import sample_goals
    from tiago_nav_tools.testing.harness import Harness, Starver

    h = Harness(WORLD, real_time_factor=0.0, observe=False,
                extra_args=['lockstep:=%s' % ('true' if lockstep else 'false')] + list(launch_args))
    rec = {'lockstep': lockstep, 'task': task}
    last = {}
    starver = None
    try:
        h.connect(timeout=120.0)
        if starve > 0:
            starver = Starver.of_nodes(starve)
        client = None
        if task == 'nav' or nav_goals:      # a move_base client only where it sends goals
            client = actionlib.SimpleActionClient('move_base', MoveBaseAction)
            client.wait_for_server(rospy.Duration(10.0))
        time.sleep(delay)
        rec['delay_s'] = delay
        if task == 'nav':
            g = nav_goal(client, h, *COURSE)
            rec.update(succeeded=g['succeeded'], message=g['text'], wall_s=g['wall_s'],
                       sim_s=g['sim_s'], collisions=g['collisions'])
        else:
            rec.update(mission_plain(h, *COURSE))
        # subscribed only now: a mission's client does not read odometry (nor /scan or /tf,
        # which the harness leaves alone here: observe=False)
        for topic in ('/sim/ground_truth', '/mobile_base_controller/odom'):
            rospy.Subscriber(topic, Odometry, lambda m, t=topic: last.__setitem__(t, m),
                             queue_size=1)
        rec.update(settle_pose(last))
        rng = np.random.default_rng(seed)
        rec['nav'] = [nav_goal(client, h, *g) for g in
                      sample_goals(load_world(WORLD), nav_goals, rng, start=COURSE[:2] + (0.0,))]
    except Exception as e:      # noqa: BLE001  (a broken run is a failed run, with its reason)
        rec.update(succeeded=rec.get('succeeded', False), error='%s: %s' % (type(e).__name__, e))
    finally:
        if starver is not None:
            starver.finish()
            rec['stops'] = starver.stops
        h.close()
    with open(h.log_path) as f:
        found = LAG_LINE.findall(f.read())
    if found:
        n, lag_max, p95, drops = found[-1]
        rec['lag'] = {'commands': int(n), 'max_s': float(lag_max), 'p95_s': float(p95),
                      'drops': int(drops)}
    print('RESULT ' + json.dumps(rec), flush=True)


def start_hogs(n):
    """``n`` busy loops (one per core); ended by pid with :func:`stop_hogs`."""
    return [subprocess.Popen([sys.executable, '-c', 'while True: pass']) for _ in range(n)]


def stop_hogs(hogs):
    for p in hogs:
        p.terminate()
        p.wait()


def summarise(runs):
    ok = [r for r in runs if r.get('succeeded')]
    walls = [r['wall_s'] for r in runs if 'wall_s' in r]
    ratios = [r['sim_s'] / r['wall_s'] for r in runs if r.get('wall_s')]
    nav = [g for r in runs for g in r.get('nav', [])]
    truths = [r['truth'] for r in ok if r.get('truth')]
    odoms = [tuple(r['odom']) for r in ok if r.get('odom')]
    spread = _spread(truths)
    centres = [r['centres'] for r in ok if r.get('centres') is not None]
    counts = {len(c) for c in centres}
    centre_spread = max((_spread([c[i] for c in centres]) for i in range(min(counts))),
                        default=None) if len(counts) == 1 and centres else None
    by_process = {}
    for r in runs:
        for k, v in r.get('cpu_by_process_s', {}).items():
            by_process.setdefault(k, []).append(v)
    lags = [r['lag'] for r in runs if 'lag' in r]
    loads = [r['loadavg_1min'] for r in runs if 'loadavg_1min' in r]
    cpus = [r['cpu_s'] for r in runs if 'cpu_s' in r]
    return {'runs': len(runs), 'succeeded': len(ok),
            'loadavg_1min_mean': sum(loads) / len(loads) if loads else None,
            'collisions': sum(r.get('collisions', 0) for r in runs),
            'wall_s_mean': sum(walls) / len(walls) if walls else None,
            'wall_s_max': max(walls) if walls else None,
            'cpu_s_mean': sum(cpus) / len(cpus) if cpus else None,
            'sim_per_wall_mean': sum(ratios) / len(ratios) if ratios else None,
            'final_pose_spread_m': spread,
            'result_pose_spread_m': _spread([r['result_pose'] for r in ok if r.get('result_pose')]),
            'obstacle_counts': sorted(counts),
            'centre_spread_m': centre_spread,
            'cpu_by_process_s_mean': {k: sum(v) / len(v) for k, v in sorted(by_process.items())},
            'distinct_final_odometry': len(set(odoms)),
            'nav_goals': len(nav), 'nav_succeeded': sum(1 for g in nav if g['succeeded']),
            'nav_collisions': sum(g['collisions'] for g in nav),
            'lag_max_s': max(x['max_s'] for x in lags) if lags else None,
            'drops': sum(x['drops'] for x in lags) if lags else None}


def _spread(points):
    """[m] the largest distance between two of ``points`` ``[(x, y, ...)]``, None for none."""
    if not points:
        return None
    return max(math.hypot(a[0] - b[0], a[1] - b[1]) for a in points for b in points)


def table(report):
    """The summary as markdown lines, one row per condition."""
    rows = ['| condition | course %ss ok | collisions | wall/mission mean (max) | sim/wall | '
            'true final pose spread | reported pose spread | centre spread | distinct final '
            'odometry | nav goals ok | lag max | drops | load average |' % report['task'],
            '|---' * 13 + '|']
    for c in report['conditions']:
        s = c['summary']
        spread = s['final_pose_spread_m']
        cells = [c['label'], '%d/%d' % (s['succeeded'], s['runs']),
                 str(s['collisions'] + s['nav_collisions']),
                 '%s (%s) s' % (fmt(s['wall_s_mean']), fmt(s['wall_s_max'])),
                 fmt(s['sim_per_wall_mean'], '%.1f'),
                 '-' if spread is None else '%.3f mm' % (spread * 1000),
                 fmt(s.get('result_pose_spread_m'), '%.3f m'),
                 fmt(s.get('centre_spread_m'), '%.3f m'),
                 str(s['distinct_final_odometry']), '%d/%d' % (s['nav_succeeded'], s['nav_goals']),
                 fmt(s['lag_max_s'], '%.3f s'), fmt(s['drops'], '%d'),
                 fmt(s.get('loadavg_1min_mean'), '%.1f')]
        rows.append('| ' + ' | '.join(cells) + ' |')
    return rows


def cpu_lines(report):
    """Per condition, the CPU a mission cost and the wall time it bounds on these cores."""
    cores = report.get('cores') or 1
    lines = []
    for c in report['conditions']:
        cpu = c['summary'].get('cpu_s_mean')
        if cpu is not None:
            lines.append('%s: %.2f s of CPU per mission (every node, roscore and roslaunch); on %d '
                         'cores no mission can take less than %.2f s of wall time'
                         % (c['label'], cpu, cores, cpu / cores))
            per = c['summary'].get('cpu_by_process_s_mean') or {}
            if per:
                lines.append('  by process: ' + ', '.join(
                    '%s %.2f s' % kv for kv in sorted(per.items(), key=lambda kv: -kv[1])))
    return lines


def fmt(v, f='%.2f'):
    return '-' if v is None else f % v


def plot(report, path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(13, 4.5))
    for k, c in enumerate(report['conditions']):
        walls = [r.get('wall_s', 0) for r in c['runs']]
        colors = ['tab:green' if r.get('succeeded') and not r.get('collisions') else 'tab:red'
                  for r in c['runs']]
        a1.scatter([k] * len(walls), walls, c=colors, s=18)
        pts = [r['truth'] for r in c['runs'] if r.get('truth')]
        if pts:
            x0, y0 = pts[0][0], pts[0][1]
            a2.scatter([(p[0] - x0) * 1000 for p in pts], [(p[1] - y0) * 1000 for p in pts],
                       label=c['label'], s=18)
    a1.axhline(TARGET_WALL, color='k', ls='--', lw=1, label='target 3 s (idle, lockstep)')
    a1.set_xticks(range(len(report['conditions'])))
    a1.set_xticklabels([c['label'] for c in report['conditions']], fontsize=8)
    a1.set_ylabel('wall time per course mission [s]')
    a1.set_title('real_time_factor 0: green succeeded without collision, red not', fontsize=9)
    a1.legend(fontsize=8)
    a2.set_xlabel('final x - first run\'s final x [mm]')
    a2.set_ylabel('final y - first run\'s final y [mm]')
    a2.set_title('final ground-truth pose of each run, same seed', fontsize=9)
    a2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--n', type=int, default=20, help='course missions per condition')
    ap.add_argument('--nav', type=int, default=2, help='navigation goals after each mission')
    ap.add_argument('--seed', type=int, default=7, help='seed of the navigation goals')
    ap.add_argument('--modes', default='on,off', help='lockstep on and/or off')
    ap.add_argument('--loads', default='idle,busy',
                    help='idle, busy (a busy loop per core), starved (each node stopped in '
                         'turn for %g s while the goals run) or loaded (no busy loops of its '
                         'own: the machine is loaded by other work, whose load is recorded)'
                         % STARVE)
    ap.add_argument('--task', default='mission', choices=('mission', 'nav'),
                    help='the course mission, or one move_base goal to its pose B')
    ap.add_argument('--out', default=os.path.join(RESULTS, 'lockstep.json'))
    ap.add_argument('--launch-args', default='', help='more demo.launch arguments, e.g. '
                    '"localisation:=ground_truth odometry_model:=ideal"')
    ap.add_argument('--max-delay', type=float, default=3.0,
                    help='[s wall] each run sends its goal after a random delay up to this')
    ap.add_argument('--run', choices=('on', 'off'), help=argparse.SUPPRESS)
    ap.add_argument('--delay', type=float, default=0.0, help=argparse.SUPPRESS)
    ap.add_argument('--starve', type=float, default=0.0, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.run:
        run_one(args.run == 'on', args.nav, args.seed, args.task, args.launch_args.split(),
                args.delay, args.starve)
        return 0
    import numpy as np
    delays = np.random.default_rng(args.seed).uniform(0.0, args.max_delay, size=10 ** 4)
    report = {'task': args.task, 'n': args.n, 'nav_goals_per_run': args.nav, 'seed': args.seed,
              'cores': os.cpu_count(), 'conditions': []}
    t0 = time.monotonic()
    for load in args.loads.split(','):
        for mode in args.modes.split(','):
            label = '%slockstep %s, %s' % ('' if args.task == 'mission' else 'nav goal, ', mode, load)
            print('%s: %d course %ss at real_time_factor 0' % (label, args.n, args.task), flush=True)
            hogs = start_hogs(os.cpu_count() or 2) if load == 'busy' else []
            runs = []
            try:
                for i in range(args.n):
                    delay = float(delays[i % len(delays)])
                    out = subprocess.run([sys.executable, os.path.abspath(__file__), '--run', mode,
                                          '--nav', str(args.nav), '--seed', str(args.seed),
                                          '--task', args.task, '--launch-args', args.launch_args,
                                          '--delay', repr(delay),
                                          '--starve', repr(STARVE if load == 'starved' else 0.0)],
                                         stdout=subprocess.PIPE, text=True).stdout
                    rec = next((json.loads(l[7:]) for l in out.splitlines()
                                if l.startswith('RESULT ')), {'succeeded': False, 'error': 'no result'})
                    rec['loadavg_1min'] = os.getloadavg()[0]
                    runs.append(rec)
                    print('  #%-2d %-6s wall %5s s  cpu %5s s  sim %5s s  collisions %d  '
                          'nav %d/%d  final %s  lag max %s  %s' % (
                              i, 'ok' if rec.get('succeeded') else 'FAILED',
                              fmt(rec.get('wall_s')), fmt(rec.get('cpu_s')), fmt(rec.get('sim_s')),
                              rec.get('collisions', 0),
                              sum(g['succeeded'] for g in rec.get('nav', [])), len(rec.get('nav', [])),
                              rec.get('truth'), fmt(rec.get('lag', {}).get('max_s'), '%.3f'),
                              rec.get('error', '') or ('' if rec.get('succeeded') else rec.get('message'))),
                          flush=True)
            finally:
                stop_hogs(hogs)
            s = summarise(runs)
            report['conditions'].append({'label': label, 'lockstep': mode == 'on', 'load': load,
                                         'summary': s, 'runs': runs})
            print('  => %s' % json.dumps(s), flush=True)
    report['bench_wall_s'] = time.monotonic() - t0
    from tiago_nav_tools.benchmarks import launch_models, meta
    laser, odometry = launch_models(args.launch_args.split())
    report['meta'] = meta({k: v for k, v in vars(args).items() if k != 'run'}, quick=False,
                          real_time_factor=0.0, laser_model=laser, odometry_model=odometry)
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, 'w') as f:
        json.dump(report, f, indent=2)
    png = os.path.splitext(args.out)[0] + '.png'
    plot(report, png)
    print('wrote %s and %s' % (args.out, png))
    print('\n'.join(table(report) + cpu_lines(report)))
    return 0


if __name__ == '__main__':
    sys.exit(main())
