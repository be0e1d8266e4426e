#!/usr/bin/python3
"""`make demo`: the whole mission, headless, in the course world.

Starts demo.launch (simulator faster than real time, /use_sim_time) on a private master, sends
pose B with the client library (feedback printed as it comes), then prints the obstacle table
next to the world's ground truth (the movable obstacles in laser view from the final pose) with
each error, writes a PNG of the run (map, robot path, final scan, true vs found obstacles),
shuts everything down and exits 0 only if the mission succeeded without a collision.

With --isolated it runs in a network namespace of its own with only loopback up (``unshare -n``
as root, ``unshare -rn`` with user namespaces): nothing of the demo is reachable from outside,
not even ROS's C++ nodes (rosout, robot_state_publisher), which listen on all interfaces
whatever ROS_IP says (docs/troubleshooting.md).

Usage: scripts/run_demo.py [--world W] [--x 11 --y 0 --yaw -45] [--no-corridor]
                           [--rtf 5] [--png bench/results/demo.png] [--isolated]
"""
import argparse
import json
import math
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

try:            # from the workspace (source .ws/devel/setup.bash): tiago_nav with its messages
    from tiago_nav_tools.evaluate.matching import plot_run, truth_table, visible_truth
    from tiago_nav_tools.testing.harness import Harness, HarnessError
    from tiago_nav_tools.benchmarks import launch_models, meta
    from tiago_nav.sim.world import load_world
    import tiago_nav.msg  # noqa: F401
except ImportError as e:
    sys.exit('run_demo: %s; source .ws/devel/setup.bash first (or run `make demo`)' % e)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--world', default=os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml'))
    ap.add_argument('--x', type=float, default=11.0)
    ap.add_argument('--y', type=float, default=0.0)
    ap.add_argument('--yaw', type=float, default=-45.0, help='[deg]')
    ap.add_argument('--no-corridor', dest='corridor', action='store_false')
    ap.add_argument('--rtf', type=float, default=5.0, help='simulator real_time_factor (0: flat out)')
    ap.add_argument('--laser-noise', type=float, default=0.01)
    ap.add_argument('--launch-arg', action='append', default=[], metavar='NAME:=VALUE',
                    help='a further demo.launch argument, e.g. laser_model:=ideal (repeatable)')
    ap.add_argument('--png', default=os.path.join(ROOT, 'bench', 'results', 'demo.png'))
    ap.add_argument('--isolated', action='store_true',
                    help='run in a network namespace of its own with only loopback up')
    args = ap.parse_args()
    if args.isolated:
        return isolated([a for a in sys.argv[1:] if a != '--isolated'])
    world = load_world(args.world)
    print('== demo: %s, pose B (%.2f, %.2f, %.0f deg), corridor law %s, simulator at %s'
          % (world.name, args.x, args.y, args.yaw, 'on' if args.corridor else 'off',
             'full speed' if args.rtf == 0 else '%gx real time' % args.rtf), flush=True)
    h = Harness(args.world, real_time_factor=args.rtf, laser_noise=args.laser_noise,
                extra_args=args.launch_arg)
    print('   launch log: %s' % h.log_path, flush=True)
    try:
        try:
            h.connect(timeout=90.0)
        except HarnessError as e:
            print('demo: error: %s' % e)
            return 1
        print('   everything is up; starting the mission', flush=True)
        code, state, result, wall = h.mission(args.x, args.y, args.yaw, args.corridor,
                                              out=lambda s: print(s, flush=True))
        final = h.pose()
        scan_xy = h.scan_points_map()
        obstacles = result.obstacles if result else []
        found = [(o.center.x, o.center.y) for o in obstacles]
        truth = visible_truth(world, final, h.laser_model) if final else []
        print()
        lines, s = truth_table(truth, found)
        print('\n'.join(lines))
        collisions = h.collisions
        print('mission wall time %.1f s (target <= 20 s), collisions %s' % (wall, collisions))
        loc = h.localisation_summary()
        if loc:
            print('localisation error over the mission (%d samples): p95 %.1f cm / %.2f deg, '
                  'max %.1f cm / %.2f deg (bar: p95 <= 5 cm / 2 deg)'
                  % (loc['samples'], 100 * loc['p95_m'], loc['p95_deg'], 100 * loc['max_m'],
                     loc['max_deg']))
        os.makedirs(os.path.dirname(os.path.abspath(args.png)), exist_ok=True)
        with h.lock:
            path = [p[:2] for p in h.path]
        plot_run(args.png, h.grid, world, path, scan_xy, truth, found,
                 goal=(args.x, args.y, math.radians(args.yaw)),
                 title='%s: pose B (%.1f, %.1f, %.0f deg), %s, %.1f s wall, recall %d/%d'
                 % (world.name, args.x, args.y, args.yaw, 'SUCCEEDED' if code == 0 else 'FAILED',
                    wall, s['matched'], s['true']))
        print('picture of the run: %s' % os.path.relpath(args.png))
        summary = {'world': world.name, 'goal': [args.x, args.y, args.yaw],
                   'use_corridor_law': args.corridor, 'real_time_factor': args.rtf,
                   'succeeded': code == 0, 'wall_time_s': wall, 'collisions': collisions,
                   'final_pose': list(final) if final else None,
                   'obstacles': [{'center': [o.center.x, o.center.y], 'radius': o.radius,
                                  'num_points': o.num_points} for o in obstacles],
                   'recall': s['recall'], 'false_positives': s['false_positives'],
                   'rms_error_m': s['rms_error'], 'max_error_m': s['max_error'],
                   'localisation_error': loc}
        laser, odometry = launch_models(args.launch_arg)
        summary['meta'] = meta(vars(args), real_time_factor=args.rtf, laser_model=laser,
                               odometry_model=odometry)
        with open(os.path.splitext(args.png)[0] + '.json', 'w') as f:
            json.dump(summary, f, indent=2)
        ok = code == 0 and not collisions
        print('== demo %s' % ('succeeded' if ok else 'FAILED'))
        return 0 if ok else 1
    except KeyboardInterrupt:
        print('demo: interrupted')
        return 1
    finally:
        h.close()


def isolated(argv):
    """This script again with ``argv``, in a network namespace of its own (loopback only)."""
    import subprocess
    from tiago_nav_tools.evaluate.isolation import IsolationError, command, resolve
    try:
        cmd = command(resolve('netns'), [sys.executable, os.path.abspath(__file__)] + argv)
    except IsolationError as e:
        print('demo: --isolated: %s' % e)
        return 2
    print('== demo in a network namespace of its own (only loopback up)', flush=True)
    return subprocess.call(cmd)


if __name__ == '__main__':
    sys.exit(main())
