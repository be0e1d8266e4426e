#!/usr/bin/python3
"""Navigation benchmark: the move_base node's goal runner and navigator (tiago_nav.nav, the exact
code the node runs, through tiago_nav_tools.testing.navigation.ClosedLoop) drives the simulator (tiago_nav.sim.Simulator: pybullet scene, diff-drive
base with TIAGo's limits, 0.01 m laser noise) to N seeded random reachable goals in each shipped
world, one after the other from robot_start, in simulated time at 10 Hz control / 15 Hz scans.

Ground truth (from the world file, not from the navigator): a goal is reachable when it lies in
the robot's connected component of free configuration space (static walls and every movable
obstacle, a table's or chair's legs too, grown by the robot radius); the shortest
collision-free path length L is an 8-connected shortest path on that space shortened by line
of sight (close to the any-angle optimum).
Per goal: success (SUCCEEDED within 0.15 m / 0.1 rad, checked on the true pose), collisions
(simulator contact events), time ratio = time to goal / (L / 1.0 m/s), path length ratio =
driven length / L, wall time. Writes bench/results/navigation.json and navigation.png.

``--people``: the same among walkers (worlds/office_walkers.yaml, worlds/lab_mixed.yaml), with
the ideal laser and TIAGo's (tiago_nav.sim.laser), scored also on the people: the smallest gap
between the base's footprint and a walker's leg, the time the base stood waiting, and the
oldest ghost (a cell the laser marked that stayed marked after a scan saw it free;
tiago_nav_tools.testing.navigation.ghost_ages). Writes navigation_people.json and .png.
Usage: bench/bench_navigation.py [--quick] [--goals N] [--seed S] [--people] [--set NAME=VALUE]
[--out JSON]
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np
from scipy import ndimage

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, 'src'))
RESULTS = os.path.join(ROOT, 'bench', 'results')

from tiago_nav_tools.benchmarks import meta  # noqa: E402
from tiago_nav.nav.costmap import MapScan  # noqa: E402
from tiago_nav.nav.navigator import SUCCEEDED, NavConfig, Navigator  # noqa: E402
from tiago_nav.nav.planner import grid_path, path_length, shortcut  # noqa: E402
from tiago_nav.params import build  # noqa: E402
from tiago_nav.robot import ROBOT_RADIUS  # noqa: E402
from tiago_nav.sim.laser import LaserModel  # noqa: E402
from tiago_nav.sim.raster import rasterise_world  # noqa: E402
from tiago_nav.sim.simulator import SimConfig, Simulator  # noqa: E402
from tiago_nav.sim.world import load_world  # noqa: E402
from tiago_nav_tools.evaluate.metrics import obstacle_distance_field  # noqa: E402
from tiago_nav_tools.testing.navigation import ClosedLoop  # noqa: E402

WORLDS = ['ias_lab_room_full.yaml', 'open_hall.yaml']
PEOPLE_WORLDS = ['office_walkers.yaml', 'lab_mixed.yaml']
SPEED = 1.0
CONTROL_DT = 0.1


def shortest_length(grid, dist, a, b):
    free = dist > ROBOT_RADIUS
    rc = grid.world_to_cell([a, b])
    cells = grid_path(np.zeros(dist.shape, np.uint8), rc[0], rc[1], 0.0, passable=free)
    block = np.where(free, 0, 255).astype(np.uint8)
    cells = shortcut(cells, block, tolerance=0)
    pts = grid.cell_to_world(cells)
    pts[0], pts[-1] = a, b
    return path_length(pts), pts


def profile_time(d, vmax, acc):
    """Least time [s] to cover ``d`` from rest to rest with speed ``vmax`` and accel ``acc``."""
    d = abs(d)
    if d <= vmax * vmax / acc:
        return 2.0 * math.sqrt(d / acc)
    return d / vmax + vmax / acc


def heading(a, b):
    return math.atan2(b[1] - a[1], b[0] - a[0])


def lower_bound_time(pose, goal, ref):
    """A kinematic reference time [s] (turn, drive, turn; not a strict bound, since the base
    may turn while it drives): turn on the spot to the reference path's
    first heading, drive its length L rest-to-rest (1.0 m/s, 1.0 m/s^2), turn to the goal yaw
    (1.5 rad/s, 2.0 rad/s^2). The curves in between are counted as free."""
    ref = np.asarray(ref)
    wrap = lambda a: math.atan2(math.sin(a), math.cos(a))
    t0 = profile_time(wrap(heading(ref[0], ref[1]) - pose[2]), 1.5, 2.0) if len(ref) > 1 else 0.0
    t1 = profile_time(wrap(goal[2] - heading(ref[-2], ref[-1])), 1.5, 2.0) if len(ref) > 1 else 0.0
    return t0 + profile_time(path_length(ref), SPEED, 1.0) + t1


def run_world(name, n_goals, rng, config=None, laser=None):
    world = load_world(os.path.join(ROOT, 'worlds', name))
    # exact distances to the movables: a chair's leg (1.5 cm) is thinner than a cell
    grid, dist = obstacle_distance_field(world)
    start = world.start_pose
    labels, _ = ndimage.label(dist > ROBOT_RADIUS + 0.02)
    src = grid.world_to_cell([start[:2]])[0]
    candidates = np.argwhere((labels == labels[src[0], src[1]]) & (dist > ROBOT_RADIUS + 0.2))
    loop = ClosedLoop(world, config, seed=int(rng.integers(1 << 30)),
                      laser=None if laser is None else LaserModel(laser_model=laser))
    sim = loop.sim
    runs = []
    for k in range(n_goals):
        while True:
            g = grid.cell_to_world(candidates[rng.integers(len(candidates))][None])[0]
            if math.hypot(g[0] - sim.pose[0], g[1] - sim.pose[1]) > 1.0:
                break
        goal = (float(g[0]), float(g[1]), float(rng.uniform(-math.pi, math.pi)))
        L, ref = shortest_length(grid, dist, sim.pose[:2], goal[:2])
        tmin = lower_bound_time(sim.pose, goal, ref)
        w0 = time.perf_counter()
        r = loop.run_goal(goal, limit=3.0 * L / SPEED + 30.0)
        state, reason, t_xy, trail = r['state'], r['reason'], r['t_xy'], r['trail']
        loop.settle()                # let the base come to rest
        elapsed = r['time']         # simulated time [s] from the goal to its end
        x, y, yaw = sim.pose
        ok = (state == SUCCEEDED and math.hypot(x - goal[0], y - goal[1]) <= 0.15 + 0.01
              and abs(math.atan2(math.sin(yaw - goal[2]), math.cos(yaw - goal[2]))) <= 0.1 + 0.01)
        runs.append(dict(goal=goal, state=state, reason=reason, success=bool(ok),
                         collisions=int(r['collisions']), shortest=L,
                         time=float(elapsed), time_ratio=float(elapsed / (L / SPEED)),
                         xy_time_ratio=float(t_xy / (L / SPEED)) if t_xy else float('nan'),
                         lower_bound_ratio=float(elapsed / tmin),
                         length_ratio=float(path_length(trail) / L), wall=time.perf_counter() - w0,
                         closest_walker=float(r['closest_walker']), waiting=float(r['waiting']),
                         ghost_age=float(r['ghost_age']),
                         trail=trail.tolist(), reference=ref.tolist()))
        people = ('  walker gap %.2f m  waited %.1f s' % (r['closest_walker'], r['waiting'])
                  if world.walkers else '')
        print('  %-18s goal %2d (%5.2f, %5.2f) L=%5.2f m  %-9s t/(L/v)=%.2f  xy t/(L/v)=%.2f  t/t_ref=%.2f  len=%.2f  coll=%d%s  %s'
              % (name[:-5], k, goal[0], goal[1], L, state, runs[-1]['time_ratio'], runs[-1]['xy_time_ratio'], runs[-1]['lower_bound_ratio'],
                 runs[-1]['length_ratio'], runs[-1]['collisions'], people, '' if ok else reason))
    loop.close()
    return world, grid, runs


def summary(runs):
    out = _summary(runs)
    if any(math.isfinite(r['closest_walker']) for r in runs):    # a world with walkers
        out.update(closest_walker=float(min(r['closest_walker'] for r in runs)),
                   walker_gap_under_0_3=int(sum(r['closest_walker'] < 0.3 for r in runs)),
                   waiting_mean=float(np.mean([r['waiting'] for r in runs])),
                   waiting_max=float(max(r['waiting'] for r in runs)),
                   ghost_age_max=float(max(r['ghost_age'] for r in runs)))
    return out


def _summary(runs):
    ok = [r for r in runs if r['success']]
    tr = np.array([r['time_ratio'] for r in ok]) if ok else np.array([np.nan])
    lr = np.array([r['length_ratio'] for r in ok]) if ok else np.array([np.nan])
    return dict(goals=len(runs), success_rate=len(ok) / max(1, len(runs)),
                collisions=int(sum(r['collisions'] for r in runs)),
                time_ratio_mean=float(np.mean(tr)), time_ratio_median=float(np.median(tr)),
                time_ratio_p90=float(np.percentile(tr, 90)), time_ratio_max=float(np.max(tr)),
                time_ratio_le_1_3=float(np.mean(tr <= 1.3)),
                time_ratio_long_paths_mean=float(np.mean([r['time_ratio'] for r in ok if r['shortest'] >= 4.0]))
                if any(r['shortest'] >= 4.0 for r in ok) else float('nan'),
                xy_time_ratio_mean=float(np.mean([r['xy_time_ratio'] for r in ok])) if ok else float('nan'),
                xy_time_ratio_long_paths_mean=float(np.mean([r['xy_time_ratio'] for r in ok if r['shortest'] >= 4.0]))
                if any(r['shortest'] >= 4.0 for r in ok) else float('nan'),
                lower_bound_ratio_mean=float(np.mean([r['lower_bound_ratio'] for r in ok])) if ok else float('nan'),
                lower_bound_ratio_max=float(np.max([r['lower_bound_ratio'] for r in ok])) if ok else float('nan'),
                long_paths=int(sum(r['shortest'] >= 4.0 for r in ok)),
                length_ratio_mean=float(np.mean(lr)), length_ratio_max=float(np.max(lr)),
                wall_per_goal_s=float(np.mean([r['wall'] for r in runs])))


def timing(name, repeats=20):
    """Median wall time [ms] of one global plan (robot_start -> the farthest reachable free cell)
    and of one costmap update with a scan (mark + clear + re-inflate)."""
    world = load_world(os.path.join(ROOT, 'worlds', name))
    grid = rasterise_world(world)
    nav = Navigator(grid, NavConfig())
    dist = grid.distance_field()
    start = world.start_pose
    labels, _ = ndimage.label(dist > ROBOT_RADIUS + 0.1)
    rc = grid.world_to_cell([start[:2]])[0]
    cx, cy = grid.cell_centres()
    far = np.where(labels == labels[rc[0], rc[1]], np.hypot(cx - start[0], cy - start[1]), -1)
    goal = grid.cell_to_world([np.unravel_index(np.argmax(far), far.shape)])[0]
    tp, tc = [], []
    scene_sim = Simulator(world, SimConfig(seed=0))
    laser = scene_sim.config.laser
    scan = MapScan(scene_sim.scene.laser_pose(), scene_sim.scan(), laser.angle_min,
                   laser.angle_increment, laser.range_min, laser.range_max)
    for _ in range(repeats):
        t = time.perf_counter()
        nav.make_plan(start[:2], goal)
        tp.append(time.perf_counter() - t)
        t = time.perf_counter()
        nav.scan_stamp = None
        nav.add_scan(scan)
        tc.append(time.perf_counter() - t)
    scene_sim.close()
    return dict(map_cells='%dx%d' % (grid.width, grid.height), plan_ms=1e3 * float(np.median(tp)),
                costmap_update_ms=1e3 * float(np.median(tc)), plan_goal=[float(goal[0]), float(goal[1])])


def plot(results, path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(results), figsize=(8 * len(results), 6))
    for ax, (name, (world, grid, runs)) in zip(np.atleast_1d(axes), results.items()):
        x0, y0, x1, y1 = grid.bounds
        ax.imshow(grid.occupied(), origin='lower', extent=(x0, x1, y0, y1), cmap='Greys')
        for c in world.movable_obstacles:
            if c.shape == 'cylinder':
                ax.add_patch(plt.Circle((c.x, c.y), c.radius, color='tab:orange'))
            else:
                ax.add_patch(plt.Polygon(c.outline(), closed=True, fill=False, ec='tab:orange'))
        for wk in world.walkers:
            wp = np.array(wk.path + ((wk.path[0],) if wk.loop else ()))
            ax.plot(wp[:, 0], wp[:, 1], '--', color='tab:brown', lw=0.8)
        for r in runs:
            t = np.array(r['trail'])
            ax.plot(t[:, 0], t[:, 1], '-', lw=1, color='tab:blue' if r['success'] else 'tab:red')
            ax.plot(r['goal'][0], r['goal'][1], 'g.', ms=5)
        s = summary(runs)
        ax.set_title('%s: %d goals, success %.0f %%, collisions %d, time ratio median %.2f%s'
                     % (name, s['goals'], 100 * s['success_rate'], s['collisions'], s['time_ratio_median'],
                        '\nclosest to a walker %.2f m, waiting mean %.1f s, oldest ghost %.2f s'
                        % (s['closest_walker'], s['waiting_mean'], s['ghost_age_max'])
                        if world.walkers else ''), fontsize=9)
        ax.set_aspect('equal')
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--quick', action='store_true', help='5 goals per world')
    ap.add_argument('--goals', type=int, default=30)
    ap.add_argument('--seed', type=int, default=1)
    ap.add_argument('--people', action='store_true',
                    help='among walkers, with the ideal and the TIAGo laser (module docstring)')
    ap.add_argument('--set', action='append', default=[], metavar='NAME=VALUE',
                    help='override a NavConfig / ControllerConfig field (tuning)')
    ap.add_argument('--out', help='the JSON to write, its plot beside it with .png (default '
                    'bench/results/navigation.json, or navigation_people.json with --people)')
    args = ap.parse_args()
    config = build(NavConfig, {k: float(v) for k, v in (kv.split('=') for kv in args.set)})
    n = 5 if args.quick else args.goals
    rng = np.random.default_rng(args.seed)
    worlds = PEOPLE_WORLDS if args.people else WORLDS
    lasers = ('ideal', 'tiago') if args.people else (None,)
    out_json = args.out or os.path.join(RESULTS, 'navigation_people.json' if args.people
                                        else 'navigation.json')
    results, out = {}, {'command': 'bench/bench_navigation.py' + (' --quick' if args.quick else '')
                        + (' --people' if args.people else '')
                        + ''.join(' --set ' + kv for kv in args.set)
                        + (' --out ' + args.out if args.out else ''),
                        'seed': args.seed, 'goals_per_world': n, 'overrides': args.set, 'worlds': {}}
    for laser in lasers:
        for name in worlds:
            key = name[:-5] if laser is None else '%s (%s laser)' % (name[:-5], laser)
            results[key] = run_world(name, n, rng, config, laser)
            out['worlds'][key] = summary(results[key][2])
    if not args.people:
        out['timing'] = {name[:-5]: timing(name) for name in worlds}
        for k, v in out['timing'].items():
            print('%-18s map %s: global plan %.1f ms, costmap update with one scan %.1f ms (median)'
                  % (k, v['map_cells'], v['plan_ms'], v['costmap_update_ms']))
    allruns = [r for v in results.values() for r in v[2]]
    out['overall'] = summary(allruns)
    out['runs'] = {k: [{kk: vv for kk, vv in r.items() if kk not in ('trail', 'reference')} for r in v[2]]
                   for k, v in results.items()}
    print()
    for k, s in list(out['worlds'].items()) + [('overall', out['overall'])]:
        print('%-18s goals %3d  success %5.1f %%  collisions %d  time ratio mean %.2f median %.2f '
              'p90 %.2f max %.2f (<=1.3: %.0f %%; paths >= 4 m: mean %.2f over %d)  xy-only mean %.2f (>= 4 m: %.2f)  t/t_ref mean %.2f max %.2f  '
              'length ratio mean %.2f  wall/goal %.2f s'
              % (k, s['goals'], 100 * s['success_rate'], s['collisions'], s['time_ratio_mean'],
                 s['time_ratio_median'], s['time_ratio_p90'], s['time_ratio_max'],
                 100 * s['time_ratio_le_1_3'], s['time_ratio_long_paths_mean'], s['long_paths'],
                 s['xy_time_ratio_mean'], s['xy_time_ratio_long_paths_mean'],
                 s['lower_bound_ratio_mean'], s['lower_bound_ratio_max'],
                 s['length_ratio_mean'], s['wall_per_goal_s']))
        if args.people:
            print('%-18s closest to a walker %.2f m (%d goals under 0.3 m)  waiting mean %.1f s '
                  'max %.1f s  oldest ghost %.2f s' % ('', s['closest_walker'],
                                                       s['walker_gap_under_0_3'], s['waiting_mean'],
                                                       s['waiting_max'], s['ghost_age_max']))
    os.makedirs(os.path.dirname(os.path.abspath(out_json)), exist_ok=True)
    out['meta'] = meta(vars(args), quick=args.quick, real_time_factor='in process (simulated time)',
                       laser_model='ideal, tiago' if args.people else 'ideal',
                       odometry_model='ideal')
    with open(out_json, 'w') as f:
        json.dump(out, f, indent=1)
    out_png = os.path.splitext(out_json)[0] + '.png'
    plot(results, out_png)
    print('wrote %s, %s' % (out_json, out_png))


if __name__ == '__main__':
    main()
