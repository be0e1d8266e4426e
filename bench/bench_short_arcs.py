#!/usr/bin/python3
"""Short arcs: how well detection places a cylinder that few usable beams hit, against the
count of usable beams that "in view" asks for (tiago_nav_tools.evaluate.inview: the evaluator's 7, the
plain rule's 5). A 0.12 m cylinder 3.6 m from the laser, in a 10 m x 8 m mapped room, its arc cut
three ways: (1) behind a nearer cylinder (2 m away) of another radius (0.183 m) or (2) of the
same radius, the bearing stepped across its silhouette edge; (3) at the end of the usable fan,
the bearing stepped from 101 to 111 deg (the tiago profile loses the beams beyond 103.5 deg, its
self-hits; the ideal profile's fan ends at 110 deg). Both laser profiles; each scan the per-beam
median of 5 scans at rest as the service combines them at a stop, placed with its exact pose.

Per cut, profile and count of usable beams (of the noise-free cast): trials, found (matched
within 0.3 m), within the evaluator's 5 cm tolerance, and the worst centre error. Writes
bench/results/short_arcs.json.

Usage: bench/bench_short_arcs.py [--seeds 8]
"""
import argparse
import json
import math
import os
import sys

import numpy as np
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, 'src'))
from tiago_nav_tools.benchmarks import meta  # noqa: E402
from tiago_nav.detection.pipeline import DetectionParams, ObstacleDetector  # noqa: E402
from tiago_nav_tools.evaluate.suite import DEFAULTS  # noqa: E402
from tiago_nav.geometry import compose, inverse  # noqa: E402
from tiago_nav.scan import median_ranges  # noqa: E402
from tiago_nav_tools.evaluate.inview import MIN_BEAMS, PLAIN_BEAMS, judge_view  # noqa: E402
from tiago_nav.sim.laser import LaserModel  # noqa: E402
from tiago_nav.sim.raster import rasterise_world  # noqa: E402
from tiago_nav.sim.scene import LaserConfig, Scene  # noqa: E402
from tiago_nav.sim.world import World  # noqa: E402
from tiago_nav_tools.evaluate.matching import MATCH_GATE  # noqa: E402

NOISE = 0.01                          # [m] range noise std (the simulator's default)
with open(os.path.join(ROOT, 'config', 'detection.yaml')) as _f:
    REST_SCANS = int(yaml.safe_load(_f)['rest_scans'])   # the service's median of scans at rest
TOL = DEFAULTS['detection_tolerance']  # [m] the evaluator's centre tolerance
RADIUS, RANGE = 0.12, 3.6             # [m] the cylinder, and its distance from the laser
OFFSET = LaserConfig().offset


def room(movable):
    """The room, in the world-file format (docs/simulator.md), with ``movable`` cylinders
    ``(x, y, radius)``."""
    return World.from_dict({
        'name': 'short_arcs', 'resolution': 0.05, 'bounds': [-0.5, -0.5, 10.5, 8.5],
        'robot_start': [1.0, 4.0, 0.0],
        'walls': [{'x': 5.0, 'y': 0.0, 'length': 10.0, 'width': 0.2},
                  {'x': 5.0, 'y': 8.0, 'length': 10.0, 'width': 0.2},
                  {'x': 0.0, 'y': 4.0, 'length': 8.2, 'width': 0.2, 'yaw_deg': 90},
                  {'x': 10.0, 'y': 4.0, 'length': 8.2, 'width': 0.2, 'yaw_deg': 90}],
        'movable_obstacles': [{'x': x, 'y': y, 'radius': r} for x, y, r in movable]})


def at(pose, bearing_deg, rng):
    """The point ``rng`` [m] from the laser of the base ``pose`` at ``bearing_deg``."""
    a = pose[2] + math.radians(bearing_deg)
    lx, ly = pose[0] + OFFSET * math.cos(pose[2]), pose[1] + OFFSET * math.sin(pose[2])
    return lx + rng * math.cos(a), ly + rng * math.sin(a)


def scenes():
    """``(cut, base pose, [movable cylinders])``: the target is always the first cylinder."""
    out = []
    pose = (1.0, 4.0, 0.0)
    for cut, occluder in (('behind a cylinder of another radius', 0.183),
                          ('behind a cylinder of the same radius', RADIUS)):
        ox, oy = at(pose, 0.0, 2.0)
        edge = math.degrees(math.asin(occluder / 2.0)) - math.degrees(math.asin(RADIUS / RANGE))
        for k in range(2, 16):
            out.append((cut, pose, [at(pose, edge + 0.33 * k, RANGE) + (RADIUS,),
                                    (ox, oy, occluder)]))
    pose = (5.0, 1.0, 0.0)
    for b in np.arange(101.0, 111.01, 0.5):
        out.append(('at the end of the usable fan', pose, [at(pose, float(b), RANGE) + (RADIUS,)]))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--seeds', type=int, default=8)
    ap.add_argument('--out', default=os.path.join(ROOT, 'bench', 'results', 'short_arcs.json'))
    args = ap.parse_args()
    cells = {}
    for cut, pose, movable in scenes():
        w = room(movable)
        det = ObstacleDetector(rasterise_world(w), DetectionParams())
        with Scene(w) as sc:
            cfg = sc.laser
            clean, ids = sc.cast(pose)
            laser = sc.laser_pose(pose)
            lib = compose(inverse(pose), laser)
            movable_ids = sc.movable_ids
        t = w.movable_obstacles[0]
        for prof in ('tiago', 'ideal'):
            usable = judge_view(clean, ids, cfg.angles(), movable_ids, prof).usable_beams.get(0, 0)
            if not usable:
                continue
            model = LaserModel(laser_model=prof)
            c = cells.setdefault((cut, prof, usable), {'trials': 0, 'found': 0, 'within': 0,
                                                      'errors': []})
            for seed in range(args.seeds):
                rng = np.random.default_rng(seed)
                r = median_ranges([model.apply(clean, cfg, NOISE, rng).ranges
                                   for _ in range(REST_SCANS)], cfg.range_min, cfg.range_max)
                found = det.detect(r, cfg.angle_min, cfg.angle_increment, cfg.range_min,
                                   cfg.range_max, laser, 'circle_fit', laser_in_base=lib)
                e = min([math.hypot(d.center[0] - t.x, d.center[1] - t.y) for d in found]
                        or [math.inf])
                c['trials'] += 1
                if e <= MATCH_GATE:
                    c['found'] += 1
                    c['within'] += e <= TOL
                    c['errors'].append(e)
    rows = []
    for (cut, prof, usable), c in sorted(cells.items()):
        rows.append({'cut': cut, 'profile': prof, 'usable_beams': usable,
                     'in_view': usable >= MIN_BEAMS, 'in_view_plain': usable >= PLAIN_BEAMS,
                     'trials': c['trials'], 'found': c['found'], 'within_tolerance': c['within'],
                     'max_error_m': round(max(c['errors']), 4) if c['errors'] else None})
        print('%-38s %-5s usable %2d: found %2d/%2d, within %.0f cm %2d, worst %s' % (
            cut, prof, usable, c['found'], c['trials'], 100 * TOL, c['within'],
            '%.3f m' % max(c['errors']) if c['errors'] else '-'))
    out = {'radius_m': RADIUS, 'range_m': RANGE, 'noise_std_m': NOISE, 'rest_scans': REST_SCANS,
           'tolerance_m': TOL, 'min_beams': MIN_BEAMS, 'plain_beams': PLAIN_BEAMS, 'rows': rows}
    for name, k in (('evaluator', MIN_BEAMS), ('plain', PLAIN_BEAMS)):
        sel = [r for r in rows if r['usable_beams'] >= k]
        out[name] = {'trials': sum(r['trials'] for r in sel),
                     'within_tolerance': sum(r['within_tolerance'] for r in sel)}
        print('rule %s (>= %d usable beams): %d of %d placed within %.0f cm' % (
            name, k, out[name]['within_tolerance'], out[name]['trials'], 100 * TOL))
    out['meta'] = meta(vars(args), real_time_factor='library (no ROS)', laser_model='tiago and ideal')
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, 'w') as f:
        json.dump(out, f, indent=1)
    print('wrote %s' % args.out)
    return 0


if __name__ == '__main__':
    sys.exit(main())
