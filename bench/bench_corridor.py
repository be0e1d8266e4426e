#!/usr/bin/python3
"""Corridor control law vs move_base through the same narrow corridor.

Trials: seeded start offsets (+-0.15 m from the centre line) and headings (+-15 deg), 1 m in
front of straight corridors 0.8, 1.07 and 1.5 m wide (5 m long, test worlds built by
tiago_nav.sim.worlds.corridor_world) and, in the shipped world, around its robot_start.
Figures per trial, all from ground truth: success (stopped with the base out of the corridor,
no contact), time to exit (goal sent -> the base centre passes the first wall end, sim time),
time to stop (goal sent -> standstill), RMS lateral offset from the centre line after the
corridor's first metre, minimum wall clearance of the base's disc.

1. the law in process (tiago_nav_tools.testing.corridor.run_in_simulator with the simulator library's laser);
2. through ROS (navigation.launch): the corridor_controller action, then move_base with a goal
   at the pose where the law stopped (same start, same end), when nodes/navigation is a real
   node (not the placeholder).

3. bends (``--bends``, or alone with ``--bends-only``, which keeps the rest of corridor.json):
   the shipped worlds/corridor_bend_{30,45,60,90}.yaml (1.1 m wide). The law in process from
   seeded starts around the world's start (where it stops, contact, clearance), and the whole
   mission to each world's pose B with the law on through the batch evaluator (``rosrun
   tiago_nav evaluate``; run this inside a private network namespace as docs/evaluation.md
   says), profiles tiago and ideal, 2 seeds: success, collisions, minimum clearance of the
   base's disc to any wall or cylinder from the ground-truth path (exact, segment geometry) and
   the evaluator's own (its 5 cm distance grid), and the corridor stage's last sentence.

Writes bench/results/corridor.json and corridor.png. Usage: bench/bench_corridor.py [--quick]
[--no-ros] [--bends | --bends-only]
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
try:
    import tiago_nav.msg  # noqa: F401  (the sourced workspace: library and messages)
except ImportError:        # not sourced: the library from the source tree (in-process trials only)
    sys.path.insert(0, os.path.join(ROOT, 'src'))
RESULTS = os.path.join(ROOT, 'bench', 'results')

from tiago_nav_tools.benchmarks import launch_models, meta  # noqa: E402
from tiago_nav.corridor.law import CorridorParams  # noqa: E402
from tiago_nav.geometry import wrap_angle  # noqa: E402
from tiago_nav.robot import ROBOT_RADIUS  # noqa: E402
from tiago_nav.sim.worlds import corridor_world  # noqa: E402
from tiago_nav_tools.testing.corridor import run_in_simulator  # noqa: E402
from tiago_nav_tools.testing.harness import free_port, stop_process  # noqa: E402
from tiago_nav.sim.simulator import SimConfig, Simulator  # noqa: E402
from tiago_nav.sim.world import World, clearance, load_world  # noqa: E402

ROBOT_R = ROBOT_RADIUS
SHIPPED = os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml')


# --- worlds and ground truth -------------------------------------------------------------------
def worlds():
    out = []
    for w in (0.8, 1.07, 1.5):
        out.append(('straight %.2f m' % w, World.from_dict(corridor_world(w, 5.0, name='corridor_%g' % w)),
                    (-1.0, 0.0, 0.0)))
    shipped = load_world(SHIPPED)
    out.append(('shipped (%.2f m)' % shipped.corridor.width, shipped, shipped.start_pose))
    return out


def corridor_geometry(world):
    """Ground truth of ``world.corridor``: axis direction, centre-line offset, and where its two
    walls start and end along the axis (from the walls parallel to it, nearest each side)."""
    c = world.corridor
    (ax, ay), (ex, ey) = c.entry, c.exit
    th = math.atan2(ey - ay, ex - ax)
    length = math.hypot(ex - ax, ey - ay)
    faces, starts, ends = {}, [], []
    for w in world.walls:
        u = (w.x - ax) * math.cos(th) + (w.y - ay) * math.sin(th)
        v = -(w.x - ax) * math.sin(th) + (w.y - ay) * math.cos(th)
        if abs(math.sin(w.yaw - th)) < 0.1 and -0.5 < u < length and abs(v) < c.width:
            side = 1 if v > 0 else -1
            faces.setdefault(side, []).append(v - side * w.width / 2)
            starts.append(u - w.length / 2)
            ends.append((side, u + w.length / 2))
    centre = 0.5 * (np.mean(faces[1]) + np.mean(faces[-1]))
    first_end = min(max(e for s, e in ends if s == side) for side in (1, -1))
    return {'theta': th, 'origin': (ax, ay), 'centre': float(centre), 'start': max(min(starts), 0.0),
            'end': float(first_end)}


def metrics(world, track, t0, duration, collisions, done):
    """Figures of a trajectory ``track`` (N, 4: t, x, y, yaw) in the map frame; ``t0`` is when
    the goal was sent, ``duration`` goal -> result [s]."""
    g = corridor_geometry(world)
    th = g['theta']
    ox, oy = g['origin']
    along = (track[:, 1] - ox) * math.cos(th) + (track[:, 2] - oy) * math.sin(th)
    across = -(track[:, 1] - ox) * math.sin(th) + (track[:, 2] - oy) * math.cos(th) - g['centre']
    sel = (along > g['start'] + 1.0) & (along < g['end'])
    final_along = along[-1]
    exited = final_along - ROBOT_R > g['end'] - 0.05
    heading = abs(wrap_angle(track[-1, 3] - th))
    # time to exit: the base centre past the first wall end (where the corridor stops being one)
    gate = np.flatnonzero(along >= g['end'])
    speed = np.hypot(np.diff(track[:, 1]), np.diff(track[:, 2])) / np.maximum(np.diff(track[:, 0]), 1e-6)
    moving = np.flatnonzero(speed > 0.01)
    return {'success': bool(done and exited and collisions == 0),
            'time_to_exit': round(float(track[gate[0], 0] - t0), 2) if gate.size else None,
            'time_to_stop': round(float(track[moving[-1] + 1, 0] - t0), 2) if moving.size else None,
            'time_to_result': round(float(duration), 2),
            'lateral_rms_after_1m': (round(float(np.sqrt(np.mean(across[sel] ** 2))), 4)
                                     if sel.any() else None),
            'min_clearance': round(clearance(world, track[:, 1:3], ROBOT_R, cylinders=False), 3),
            'collisions': int(collisions),
            'final_along_past_end': round(float(final_along - g['end']), 3),
            'final_heading_error_deg': round(math.degrees(heading), 1)}


def starts(base, n, seed):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        dy = float(rng.uniform(-0.15, 0.15))
        dyaw = float(rng.uniform(-15.0, 15.0))
        x, y, yaw = base
        out.append((x - dy * math.sin(yaw), y + dy * math.cos(yaw), math.degrees(yaw) + dyaw))
    return out


# --- in process ----------------------------------------------------------------------------------
def library_trial(world, start):
    sim = Simulator(world, SimConfig(laser_noise=0.01, seed=1), start_pose=(start[0], start[1],
                                                                            math.radians(start[2])))
    track = []
    t_done = [None]

    def on_step(s, c):
        track.append((s.time,) + tuple(s.pose))
        if c.state == 'done' and t_done[0] is None:
            t_done[0] = s.time
    try:
        cmd, _ = run_in_simulator(sim, timeout=60.0, on_step=on_step)
        done = cmd.state == 'done'
        return metrics(world, np.array(track), 0.0, t_done[0] if t_done[0] else sim.time,
                       sim.collisions, done), np.array(track)
    finally:
        sim.close()


# --- through ROS -----------------------------------------------------------------------------
def ros_trial(world_path, start, method, goal_pose, rtf):
    """One launch of navigation.launch; runs in a child process (one master per rospy process).
    Returns the raw record (track, duration, collisions, state, final pose)."""
    args = [sys.executable, os.path.abspath(__file__), '--ros-trial',
            json.dumps({'world': world_path, 'start': start, 'method': method,
                        'goal': goal_pose, 'rtf': rtf})]
    out = subprocess.run(args, stdout=subprocess.PIPE, text=True, timeout=240)
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith('{')]
    if not lines:
        return {'error': 'no result (exit code %d)' % out.returncode}
    return json.loads(lines[-1])


def ros_child(spec):
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI='http://localhost:%d' % port)
    os.environ['ROS_MASTER_URI'] = env['ROS_MASTER_URI']
    launch = subprocess.Popen(
        ['roslaunch', '-p', str(port), 'tiago_nav', 'navigation.launch', 'world:=' + spec['world'],
         'real_time_factor:=%g' % spec['rtf'],
         'robot_start:=[%f, %f, %f]' % tuple(spec['start'])],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        import actionlib
        import rospy
        from actionlib_msgs.msg import GoalStatus
        from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal
        from nav_msgs.msg import Odometry
        from std_msgs.msg import UInt32

        from tiago_nav.geometry import compose
        from tiago_nav.msg import CorridorAction, CorridorGoal
        from tiago_nav.ros.conversions import pose_from_msg, pose_stamped
        import rosgraph
        deadline = time.time() + 30.0        # /use_sim_time must be set before init_node reads it
        while time.time() < deadline:
            try:
                if rosgraph.Master('/bench_corridor').hasParam('/use_sim_time'):
                    break
            except Exception:                 # master not up yet
                pass
            time.sleep(0.2)
        else:
            print(json.dumps({'error': 'the launch did not come up within 30 s'}))
            return
        rospy.init_node('bench_corridor', anonymous=True, disable_signals=True)
        start = (spec['start'][0], spec['start'][1], math.radians(spec['start'][2]))
        track = []
        collisions = [0]
        rospy.Subscriber('/mobile_base_controller/odom', Odometry, lambda m: track.append(
            (m.header.stamp.to_sec(),) + compose(start, pose_from_msg(m.pose.pose))))
        rospy.Subscriber('/sim/collisions', UInt32, lambda m: collisions.__setitem__(0, m.data))
        if spec['method'] == 'corridor':
            client = actionlib.SimpleActionClient('corridor_controller', CorridorAction)
            goal = CorridorGoal()
        else:
            client = actionlib.SimpleActionClient('move_base', MoveBaseAction)
            goal = MoveBaseGoal(target_pose=pose_stamped(tuple(spec['goal']), 'map'))
        if not client.wait_for_server(rospy.Duration(60.0)):
            print(json.dumps({'error': '%s server not up' % spec['method']}))
            return
        rospy.sleep(0.5)
        t0 = rospy.Time.now().to_sec()
        goal_stamp = rospy.Time.now()
        if spec['method'] != 'corridor':
            goal.target_pose.header.stamp = goal_stamp
        client.send_goal(goal)
        finished = client.wait_for_result(rospy.Duration(90.0))
        t1 = rospy.Time.now().to_sec()
        if not finished:
            client.cancel_goal()
        state = client.get_state()
        rospy.sleep(0.5)
        tr = [p for p in track if p[0] >= t0 - 0.1]
        print(json.dumps({'track': tr, 't0': t0, 'duration': t1 - t0, 'collisions': collisions[0],
                          'succeeded': bool(finished and state == GoalStatus.SUCCEEDED),
                          'status': client.get_goal_status_text()}))
    finally:
        stop_process(launch)


# --- report ---------------------------------------------------------------------------------
def summary(rows):
    ok = [r for r in rows if r.get('success')]
    rms = [r['lateral_rms_after_1m'] for r in rows if r.get('lateral_rms_after_1m') is not None]

    def stat(key, fn):
        vals = [r[key] for r in ok if r.get(key) is not None]
        return round(float(fn(vals)), 2) if vals else None
    return {'trials': len(rows), 'success_rate': round(len(ok) / len(rows), 3) if rows else None,
            'time_to_exit_mean': stat('time_to_exit', np.mean),
            'time_to_exit_max': stat('time_to_exit', np.max),
            'time_to_stop_mean': stat('time_to_stop', np.mean),
            'lateral_rms_max': round(float(np.max(rms)), 4) if rms else None,
            'min_clearance': round(float(np.min([r['min_clearance'] for r in rows])), 3) if rows else None}


def plot(results, tracks, path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    names = list(results)
    fig, axes = plt.subplots(len(names), 1, figsize=(11, 2.6 * len(names)))
    for ax, name in zip(np.atleast_1d(axes), names):
        world = tracks[name]['world']
        g = corridor_geometry(world)
        for w in world.walls:
            c = np.vstack((w.corners(), w.corners()[:1]))
            ax.fill(c[:, 0], c[:, 1], color='0.6')
        for i, tr in enumerate(tracks[name]['library']):
            ax.plot(tr[:, 1], tr[:, 2], color='tab:blue', lw=0.8, alpha=0.7,
                    label='corridor law (in process)' if i == 0 else None)
        for i, tr in enumerate(tracks[name].get('ros_corridor', [])):
            ax.plot(tr[:, 1], tr[:, 2], color='tab:green', lw=1.2,
                    label='corridor_controller (ROS)' if i == 0 else None)
        for i, tr in enumerate(tracks[name].get('ros_move_base', [])):
            ax.plot(tr[:, 1], tr[:, 2], color='tab:red', lw=1.2,
                    label='move_base (ROS)' if i == 0 else None)
        ox, oy = g['origin']
        ax.set_xlim(ox - 1.8, ox + g['end'] + 1.2)
        ax.set_ylim(oy - 1.0, oy + 1.0)
        ax.set_aspect('equal')
        s = results[name]['corridor_law']
        ax.set_title('%s: law %.0f%% ok, exit %.2f s mean, RMS <= %.4f m, clearance >= %.3f m'
                     % (name, 100 * s['success_rate'], s['time_to_exit_mean'] or 0,
                        s['lateral_rms_max'] or 0, s['min_clearance']), fontsize=9)
        ax.legend(loc='upper left', fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


BEND_WORLDS = [os.path.join(ROOT, 'worlds', 'corridor_bend_%d.yaml' % b) for b in (30, 45, 60, 90)]
BEND_PROFILES = {
    'tiago': {'laser_model': 'tiago', 'odometry_model': 'drift', 'localisation': 'scan_matching',
              'laser_noise': 0.01},
    'ideal': {'laser_model': 'ideal', 'odometry_model': 'ideal', 'localisation': 'ground_truth',
              'laser_noise': 0.01}}


def inner_corner(world_path):
    """The inner corner (x, y) [m] of a bend world (scripts/make_bend_worlds.py: the bend at
    x = 3 m, to the left)."""
    world = load_world(world_path)
    b = math.radians(pose_b_of(world_path)[2])
    h = 0.5 * world.corridor.width
    return 3.0 - h * math.tan(abs(b) / 2), math.copysign(h, b)


def corner_clearance(corner, xy):
    """Least distance [m] from the base's disc at the points ``xy`` (N, 2) to ``corner``."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    return float(np.hypot(xy[:, 0] - corner[0], xy[:, 1] - corner[1]).min()) - ROBOT_R


def pose_b_of(path):
    """Pose B [x, y, yaw_deg] from a bend world's header comment (``Pose B: [x, y, yaw]``)."""
    with open(path) as f:
        for line in f:
            if 'Pose B: [' in line:
                return [float(v) for v in line.split('Pose B: [')[1].split(']')[0].split(',')]
    raise ValueError('%s: no "Pose B: [x, y, yaw]" in its header' % path)


def bends(n_lib, seeds, use_ros):
    """Part 3 of the module docstring: ``{'worlds': {name: ...}, 'met': ...}``."""
    out = {'definitions': {
        'law.stopped': 'the corridor goal\'s end: done (SUCCEEDED) or the reason it was not',
        'law.stop_before_corner': 'the final base centre along the first leg minus the inner '
                                  'corner\'s position along it [m] (negative: before the corner)',
        'min_clearance': 'min distance from the base disc (r %g) to any wall or cylinder over the '
                         'run, exact from the ground-truth path [m]' % ROBOT_R,
        'inner_corner_clearance': 'min distance from the base disc to the bend\'s inner corner '
                                  '(where the inner walls of the two legs meet) [m]'},
        'worlds': {}}
    header = '%-18s %-8s %6s %10s %10s' % ('bend world', 'run', 'ok', 'collisions', 'clear min')
    print(header)
    for path in BEND_WORLDS:
        world = load_world(path)
        name = world.name
        bend = math.radians(pose_b_of(path)[2])
        # the inner corner along the first leg (scripts/make_bend_worlds.py: bend at x = 3 m)
        corner = 3.0 - 0.5 * world.corridor.width * math.tan(abs(bend) / 2)
        rows = []
        for s in starts(world.start_pose, n_lib, 300):
            sim = Simulator(world, SimConfig(laser_noise=0.01, seed=1),
                            start_pose=(s[0], s[1], math.radians(s[2])))
            track = []
            try:
                cmd, _ = run_in_simulator(sim, timeout=60.0,
                                          on_step=lambda q, c: track.append(tuple(q.pose)))
                tr = np.array(track)
                c = clearance(world, tr[:, :2], ROBOT_R)
                rows.append({'start': [round(v, 3) for v in s],
                             'stopped': 'done' if cmd.state == 'done' else cmd.reason,
                             'reason': cmd.reason, 'collisions': int(sim.collisions),
                             'min_clearance': round(c, 3),
                             'inner_corner_clearance': round(corner_clearance(inner_corner(path),
                                                                              tr[:, :2]), 3),
                             'stop_before_corner': round(float(tr[-1, 0]) - corner, 3),
                             'final_lateral': round(float(tr[-1, 1]), 3),
                             'success': bool(cmd.state == 'done' and sim.collisions == 0
                                             and c >= 0.05)})
            finally:
                sim.close()
        res = {'bend_deg': round(math.degrees(bend), 1), 'width': world.corridor.width,
               'pose_b': pose_b_of(path),
               'law': {'trials': len(rows), 'success': sum(r['success'] for r in rows),
                       'collisions': sum(r['collisions'] for r in rows),
                       'min_clearance': min(r['min_clearance'] for r in rows),
                       'inner_corner_clearance': min(r['inner_corner_clearance'] for r in rows),
                       'stop_before_corner': [min(r['stop_before_corner'] for r in rows),
                                              max(r['stop_before_corner'] for r in rows)],
                       'trials_detail': rows}}
        out['worlds'][name] = res
        print('%-18s %-8s %6s %10d %10.3f' % (name, 'law', '%d/%d' % (res['law']['success'], len(rows)),
                                             res['law']['collisions'], res['law']['min_clearance']),
              flush=True)
    if use_ros:
        for name, rows in mission_trials(seeds).items():
            res = out['worlds'][name]
            res['missions'] = {'runs': len(rows), 'success': sum(r['success'] for r in rows),
                               'collisions': sum(r['collisions'] for r in rows),
                               'min_clearance': min(r['min_clearance'] for r in rows),
                               'inner_corner_clearance': min(r['inner_corner_clearance'] for r in rows),
                               'runs_detail': rows}
            m = res['missions']
            print('%-18s %-8s %6s %10d %10.3f' % (name, 'mission', '%d/%d' % (m['success'], m['runs']),
                                                 m['collisions'], m['min_clearance']), flush=True)
    ws = out['worlds'].values()
    out['met'] = {
        'law_stops_clear': all(w['law']['success'] == w['law']['trials'] for w in ws),
        'missions_succeed': (all(w['missions']['success'] == w['missions']['runs'] for w in ws)
                             if use_ros else None),
        'no_collision': all(w['law']['collisions'] == 0 and w.get('missions', {}).get('collisions', 0) == 0
                            for w in ws),
        'min_clearance': min(min(w['law']['min_clearance'], w.get('missions', {}).get('min_clearance', 1.0))
                             for w in ws) >= 0.05}
    return out


def mission_trials(seeds):
    """The missions of part 3 through the batch evaluator: ``{world name: [run, ...]}``."""
    import csv
    tmp = tempfile.mkdtemp(prefix='bench_corridor_bends_')
    suite = {'name': 'corridor_bends',
             'defaults': {'real_time_factor': 0, 'sim_time_limit': 180, 'wall_time_limit': 300,
                          'detection_tolerance': 0.05},
             'worlds': [{'file': p, 'poses': [pose_b_of(p)]} for p in BEND_WORLDS],
             'profiles': BEND_PROFILES, 'corridor_law': [True],
             'seeds': {'count': seeds, 'start': 1}}
    suite_path = os.path.join(tmp, 'suite.yaml')
    with open(suite_path, 'w') as f:
        yaml.safe_dump(suite, f)
    out_dir = os.path.join(tmp, 'out')
    subprocess.run(['rosrun', 'tiago_nav', 'evaluate', suite_path, '--out', out_dir, '--workers', '1'],
                   stdout=subprocess.DEVNULL, timeout=3600)
    worlds = {p: load_world(p) for p in BEND_WORLDS}
    by_world = {}
    with open(os.path.join(out_dir, 'results.csv')) as f:
        for r in csv.DictReader(f):
            run = os.path.join(out_dir, 'runs', r['run_id'])
            with open(os.path.join(run, 'raw.json')) as f2:
                raw = json.load(f2)
            with open(os.path.join(run, 'spec.json')) as f2:
                spec = json.load(f2)
            world = worlds[spec['world_path']]
            path = np.array(raw.get('path') or [[np.nan, np.nan, 0.0]])[:, :2]
            corridor = [fb[2] for fb in raw.get('feedback', []) if fb[1] == 1]
            nav = [fb[2] for fb in raw.get('feedback', []) if fb[1] == 2]
            by_world.setdefault(world.name, []).append({
                'run_id': r['run_id'], 'profile': r['profile'], 'seed': int(r['seed']),
                'outcome': r['outcome'], 'reason': r['reason'],
                'success': r['outcome'] == 'succeeded', 'collisions': int(r['collisions'] or 0),
                'min_clearance': round(float(r['min_clearance_m']), 3),
                'inner_corner_clearance': round(corner_clearance(inner_corner(spec['world_path']),
                                                                 path), 3),
                'corridor_last': corridor[-1] if corridor else None,
                'navigating_first': nav[0] if nav else None})
    return by_world


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--quick', action='store_true', help='fewer trials')
    ap.add_argument('--no-ros', action='store_true', help='in-process trials only')
    ap.add_argument('--rtf', type=float, default=4.0, help='simulator real_time_factor for ROS trials')
    ap.add_argument('--bends', action='store_true', help='also part 3: the bent corridors')
    ap.add_argument('--bends-only', action='store_true',
                    help='part 3 only, kept in corridor.json beside the other parts\' last figures')
    ap.add_argument('--ros-trial', help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.ros_trial:
        ros_child(json.loads(args.ros_trial))
        return
    os.makedirs(RESULTS, exist_ok=True)
    if args.bends_only:
        path = os.path.join(RESULTS, 'corridor.json')
        with open(path) as f:
            out = json.load(f)
        out['bends'] = run_bends(args)
        with open(path, 'w') as f:
            json.dump(out, f, indent=2)
        print('targets met (bends): %s' % out['bends']['met'])
        print('wrote bench/results/corridor.json (bends)')
        return
    n_lib = 4 if args.quick else 12
    n_ros = 1 if args.quick else 2
    use_ros = not args.no_ros
    out = {'params': vars(CorridorParams()), 'definitions': {
        'time_to_exit': 'goal sent -> base centre past the first corridor wall end [s, sim time]',
        'time_to_stop': 'goal sent -> standstill [s, sim time]',
        'move_base_goal': 'the pose where corridor_controller stopped in the same trial, facing along '
                          'the corridor (same start, same end)',
        'min_clearance': 'min distance from the base disc (r %g) to any wall over the run [m]' % ROBOT_R,
        'lateral_rms_after_1m': 'RMS of the offset from the ground-truth centre line, from 1 m into '
                                'the corridor to its first wall end [m]'}, 'targets': {
        'faster_than_move_base': True, 'lateral_rms_after_1m_max': 0.03, 'min_clearance_min': 0.05},
        'worlds': {}, 'move_base_available': use_ros}
    tracks = {}
    tmp = tempfile.mkdtemp(prefix='bench_corridor_')
    header = '%-18s %-15s %6s %8s %8s %8s %9s %9s' % ('world', 'method', 'ok', 'exit avg', 'exit max',
                                                        'stop avg', 'RMS max', 'clear min')
    print(header)
    for wi, (name, world, base) in enumerate(worlds()):
        trial_starts = starts(base, n_lib, 100 + wi)
        rows, trs = [], []
        for s in trial_starts:
            m, tr = library_trial(world, s)
            m['start'] = [round(v, 3) for v in s]
            rows.append(m)
            trs.append(tr)
        res = {'corridor_law': summary(rows), 'trials': {'corridor_law': rows}}
        tracks[name] = {'world': world, 'library': trs}
        if use_ros:
            if world.source == '<dict>':
                path = os.path.join(tmp, 'corridor_%d.yaml' % wi)
                with open(path, 'w') as f:
                    yaml.safe_dump(corridor_world(*_world_args(world)), f)
            else:
                path = world.source
            g = corridor_geometry(world)
            for method in ('corridor', 'move_base'):
                res['trials']['ros_' + method] = []
                tracks[name]['ros_' + method] = []
            for s in trial_starts[:n_ros]:
                rc = ros_trial(path, s, 'corridor', None, args.rtf)
                goal = None
                for method, rec in (('corridor', rc), ('move_base', None)):
                    if method == 'move_base':
                        if goal is None:
                            break
                        rec = ros_trial(path, s, 'move_base', goal, args.rtf)
                    if 'error' in rec or len(rec.get('track', [])) < 2:
                        res['trials']['ros_' + method].append({
                            'success': False, 'error': rec.get('error', 'no track'),
                            'time_to_exit': None, 'min_clearance': None})
                        continue
                    tr = np.array(rec['track'])
                    m = metrics(world, tr, rec['t0'], rec['duration'], rec['collisions'], rec['succeeded'])
                    m['status'] = rec['status']
                    m['start'] = [round(v, 3) for v in s]
                    res['trials']['ros_' + method].append(m)
                    tracks[name]['ros_' + method].append(tr)
                    if method == 'corridor':
                        # move_base gets the pose where the law stopped, facing along the corridor
                        goal = (float(tr[-1, 1]), float(tr[-1, 2]), g['theta'])
            for method in ('corridor', 'move_base'):
                good = [r for r in res['trials']['ros_' + method] if r.get('time_to_exit') is not None]
                res['ros_' + method] = summary(good) if good else {'trials': 0}
            pairs = list(zip(res['trials']['ros_corridor'], res['trials']['ros_move_base']))
            res['exit_time_gain_over_move_base'] = [
                round(mb['time_to_exit'] - c['time_to_exit'], 2)
                if c.get('time_to_exit') is not None and mb.get('time_to_exit') is not None else None
                for c, mb in pairs]
            res['faster_than_move_base'] = bool(pairs) and all(
                c.get('success') and (not mb.get('success') or mb.get('time_to_exit') is None
                                      or c['time_to_exit'] < mb['time_to_exit'])
                for c, mb in pairs)
        out['worlds'][name] = res
        for key in ('corridor_law', 'ros_corridor', 'ros_move_base'):
            s = res.get(key)
            if not s or not s.get('trials'):
                continue
            print('%-18s %-15s %6s %8s %8s %8s %9s %9s' % (
                name, key, '%d/%d' % (round(s['success_rate'] * s['trials']), s['trials']),
                s['time_to_exit_mean'], s['time_to_exit_max'], s['time_to_stop_mean'],
                s['lateral_rms_max'], s['min_clearance']), flush=True)
    law = [w['corridor_law'] for w in out['worlds'].values()]
    out['met'] = {
        'lateral_rms_after_1m': max(s['lateral_rms_max'] for s in law) <= 0.03,
        'min_clearance': min(s['min_clearance'] for s in law) >= 0.05,
        'success': all(s['success_rate'] == 1.0 for s in law),
        'faster_than_move_base': (all(w.get('faster_than_move_base') for w in out['worlds'].values())
                                  if use_ros else None)}
    plot(out['worlds'], tracks, os.path.join(RESULTS, 'corridor.png'))
    laser, odometry = launch_models()
    out['meta'] = meta(vars(args), quick=args.quick,
                       real_time_factor='in process; ROS trials %g' % args.rtf if use_ros else 'in process',
                       laser_model='ideal in process' + ('; %s in ROS trials' % laser if use_ros else ''),
                       odometry_model='ideal in process' + ('; %s in ROS trials' % odometry if use_ros else ''))
    if args.bends:
        out['bends'] = run_bends(args)
    with open(os.path.join(RESULTS, 'corridor.json'), 'w') as f:
        json.dump(out, f, indent=2)
    if not use_ros:
        print('move_base comparison skipped (%s)' % ('--no-ros' if args.no_ros else
                                                      'nodes/navigation is still a placeholder'))
    print('targets met: %s' % out['met'])
    print('wrote bench/results/corridor.json and corridor.png')


def run_bends(args):
    """Part 3 with its own meta (it may run apart from parts 1 and 2)."""
    res = bends(2 if args.quick else 6, 1 if args.quick else 2, not args.no_ros)
    res['meta'] = meta(vars(args), quick=args.quick,
                       real_time_factor='in process; missions 0 (lockstep)',
                       laser_model='ideal in process; missions: profiles %s' % ', '.join(BEND_PROFILES),
                       odometry_model='ideal in process; missions: per profile')
    return res


def _world_args(world):
    """Arguments that rebuild a straight test corridor from its World (for the ROS trials)."""
    return (world.corridor.width, world.corridor.exit[0] - world.corridor.entry[0], 0.0, None,
            tuple(world.robot_start), 0.15, None, world.name)


if __name__ == '__main__':
    main()
