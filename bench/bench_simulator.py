#!/usr/bin/python3
"""Simulator speed: how much faster than real time the mock TIAGo runs with the full laser
(666 beams at 15 Hz, 60 Hz physics) at real_time_factor:=0.

Two figures: the library alone (tiago_nav.sim.Simulator stepping and scanning, no ROS) and the
ROS node (sim.launch on its own master, measured from /clock), each in the shipped worlds while
the base drives in circles. Writes bench/results/simulator.json and simulator.png.
Usage: bench/bench_simulator.py [--quick]
"""
import argparse
import json
import math
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, 'src'))
RESULTS = os.path.join(ROOT, 'bench', 'results')

from tiago_nav_tools.benchmarks import launch_models, meta  # noqa: E402
from tiago_nav.geometry import transform_points  # noqa: E402
from tiago_nav.scan import scan_to_points  # noqa: E402
from tiago_nav_tools.testing.harness import free_port, stop_process  # noqa: E402
from tiago_nav.sim.raster import rasterise_world  # noqa: E402
from tiago_nav.sim.simulator import SimConfig, Simulator  # noqa: E402
from tiago_nav.sim.world import load_world  # noqa: E402

WORLDS = ['ias_lab_room_full.yaml', 'open_hall.yaml']


def library_factor(world, sim_seconds):
    sim = Simulator(world, SimConfig())
    t0 = time.perf_counter()
    scans = 0
    while sim.time < sim_seconds:
        sim.command(0.3, 0.4)
        scan_due, _ = sim.step()
        if scan_due:
            sim.scan()
            scans += 1
    wall = time.perf_counter() - t0
    sim.close()
    return sim_seconds / wall, scans


def node_factor(world_path, wall_seconds):
    """Run sim.launch at real_time_factor:=0 with a circling base; sim seconds per wall second.
    Measured in a child process, since a rospy process can join only one master."""
    out = subprocess.run([sys.executable, os.path.abspath(__file__), '--node', world_path,
                          str(wall_seconds)], stdout=subprocess.PIPE, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def measure_node(world_path, wall_seconds):
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI='http://localhost:%d' % port)
    launch = subprocess.Popen(['roslaunch', '-p', str(port), 'tiago_nav', 'sim.launch',
                               'world:=' + world_path, 'real_time_factor:=0'],
                              env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              start_new_session=True)
    try:
        os.environ['ROS_MASTER_URI'] = env['ROS_MASTER_URI']
        import rospy
        from geometry_msgs.msg import Twist
        from rosgraph_msgs.msg import Clock
        rospy.init_node('bench_simulator', anonymous=True, disable_signals=True)
        deadline = time.time() + 30
        first = None
        while first is None and time.time() < deadline:
            try:
                first = rospy.wait_for_message('/clock', Clock, timeout=1.0)
            except rospy.ROSException:
                pass
        if first is None:
            raise RuntimeError('no /clock from the simulator within 30 s')
        cmd = rospy.Publisher('/mobile_base_controller/cmd_vel', Twist, queue_size=1)
        twist = Twist()
        twist.linear.x, twist.angular.z = 0.3, 0.4
        t0 = time.time()
        c0 = rospy.wait_for_message('/clock', Clock, timeout=5).clock.to_sec()
        while time.time() - t0 < wall_seconds:
            cmd.publish(twist)
            time.sleep(0.02)
        c1 = rospy.wait_for_message('/clock', Clock, timeout=5).clock.to_sec()
        wall = time.time() - t0
        return (c1 - c0) / wall
    finally:
        stop_process(launch)


def plot(world, path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    grid = rasterise_world(world)
    sim = Simulator(world, SimConfig())
    laser = sim.config.laser
    points, _ = scan_to_points(sim.scan(), laser.angle_min, laser.angle_increment, laser.range_min,
                               laser.range_max)
    points = transform_points(sim.scene.laser_pose(), points)
    fig, ax = plt.subplots(figsize=(10, 5.5))
    x0, y0, x1, y1 = grid.bounds
    ax.imshow(grid.data, origin='lower', extent=(x0, x1, y0, y1), cmap='gray_r', vmin=0, vmax=100)
    ax.plot(points[:, 0], points[:, 1], '.', ms=2,
            color='tab:green', label='scan (666 beams, 0.01 m noise)')
    for i, c in enumerate(world.movable_obstacles):
        ax.add_patch(plt.Circle((c.x, c.y), c.radius, fill=False, color='tab:red',
                                label='movable obstacles (not in the map)' if i == 0 else None))
    x, y, th = sim.pose
    ax.add_patch(plt.Circle((x, y), sim.config.robot_radius, color='tab:blue', alpha=0.5, label='robot'))
    ax.arrow(x, y, 0.4 * math.cos(th), 0.4 * math.sin(th), width=0.03, color='tab:blue')
    ax.set_title('%s: the map (static geometry) and the first scan' % world.name)
    ax.set_xlabel('x [m] (map)')
    ax.set_ylabel('y [m] (map)')
    ax.legend(loc='upper right', fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    sim.close()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--quick', action='store_true', help='shorter runs')
    ap.add_argument('--node', nargs=2, metavar=('WORLD', 'SECONDS'), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.node:
        print(measure_node(args.node[0], float(args.node[1])))
        return
    os.makedirs(RESULTS, exist_ok=True)
    sim_seconds = 20.0 if args.quick else 60.0
    wall_seconds = 4.0 if args.quick else 10.0
    out = {'machine': {'cores': os.cpu_count()}, 'worlds': {}}
    print('%-22s %16s %14s' % ('world', 'library [x RT]', 'node [x RT]'))
    for name in WORLDS:
        path = os.path.join(ROOT, 'worlds', name)
        world = load_world(path)
        lib, _ = library_factor(world, sim_seconds)
        node = node_factor(path, wall_seconds)
        out['worlds'][world.name] = {'library_real_time_factor': round(lib, 1),
                                     'node_real_time_factor': round(node, 1)}
        print('%-22s %16.1f %14.1f' % (world.name, lib, node), flush=True)
    out['target_node_real_time_factor'] = 20.0
    out['node_real_time_factor_min'] = min(v['node_real_time_factor'] for v in out['worlds'].values())
    plot(load_world(os.path.join(ROOT, 'worlds', WORLDS[0])), os.path.join(RESULTS, 'simulator.png'))
    laser, odometry = launch_models()
    out['meta'] = meta({k: v for k, v in vars(args).items() if k != 'node'}, quick=args.quick,
                       real_time_factor=0.0, laser_model='ideal in process; %s in the node' % laser,
                       odometry_model='ideal in process; %s in the node' % odometry)
    with open(os.path.join(RESULTS, 'simulator.json'), 'w') as f:
        json.dump(out, f, indent=2)
    print('node real-time factor (min over worlds): %.1fx (target >= 20x)'
          % out['node_real_time_factor_min'])
    print('wrote bench/results/simulator.json and simulator.png')


if __name__ == '__main__':
    main()
