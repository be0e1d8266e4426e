#!/usr/bin/python3
"""Localisation benchmark (library level, no ROS): the in-process simulator drives the course
world's route (start room, corridor, a loop in the big room and back; the nine cylinders present
and unmapped) with drifting odometry (distance x 1.02, rotation x 1.03, 1 % noise per step), and
the localiser (:mod:`tiago_nav.localisation`) registers each scan it finds due, as the node
does. Its error against the truth, and dead reckoning's, over five seeds, with the ideal laser
and with the default ``tiago`` laser. Writes bench/results/localisation.json.

Usage: bench/bench_localisation.py [--seeds 5]
"""
import argparse
import json
import math
import os
import statistics
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, 'bench', 'results')


def summary(runs):
    """Pooled figures of :class:`tiago_nav.testing.localisation.RouteResult` s."""
    cat = {k: np.concatenate([getattr(r, k) for r in runs])
           for k in ('loc_xy', 'loc_yaw', 'odo_xy', 'odo_yaw')}
    secs = [t for r in runs for t in r.seconds]
    return {'scans': int(len(cat['loc_xy'])), 'registered': len(secs),
            'rejected': int(sum(r.rejected for r in runs)),
            'localised_p95_m': float(np.percentile(cat['loc_xy'], 95)),
            'localised_max_m': float(cat['loc_xy'].max()),
            'localised_p95_deg': math.degrees(np.percentile(cat['loc_yaw'], 95)),
            'localised_max_deg': math.degrees(cat['loc_yaw'].max()),
            'dead_reckoning_p95_m': float(np.percentile(cat['odo_xy'], 95)),
            'dead_reckoning_p95_deg': math.degrees(np.percentile(cat['odo_yaw'], 95)),
            'update_median_ms': 1000 * statistics.median(secs) if secs else None}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--seeds', type=int, default=5)
    args = ap.parse_args()
    if os.path.join(ROOT, 'src') not in sys.path:
        sys.path.append(os.path.join(ROOT, 'src'))
    from tiago_nav.benchmarks import meta
    from tiago_nav.sim.laser import LaserModel
    from tiago_nav.sim.world import load_world
    from tiago_nav.testing.localisation import run_route
    world = load_world(os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml'))
    out = {'world': world.name, 'seeds': args.seeds, 'lasers': {}}
    print('| laser | scans | registered | rejected | localised p95 / max | dead reckoning p95 | '
          'update median |')
    print('|---|---|---|---|---|---|---|')
    for laser in ('ideal', 'tiago'):
        s = summary([run_route(world, seed=seed, laser=LaserModel(laser_model=laser))
                     for seed in range(args.seeds)])
        out['lasers'][laser] = s
        print('| %s | %d | %d | %d | %.1f cm / %.2f deg, max %.1f cm | %.1f cm / %.2f deg | '
              '%.1f ms |' % (laser, s['scans'], s['registered'], s['rejected'],
                             100 * s['localised_p95_m'], s['localised_p95_deg'],
                             100 * s['localised_max_m'], 100 * s['dead_reckoning_p95_m'],
                             s['dead_reckoning_p95_deg'], s['update_median_ms'] or 0.0), flush=True)
    out['meta'] = meta(vars(args), real_time_factor='in process (simulated time)',
                       laser_model='ideal and tiago', odometry_model='drift (injected)')
    os.makedirs(RESULTS, exist_ok=True)
    with open(os.path.join(RESULTS, 'localisation.json'), 'w') as f:
        json.dump(out, f, indent=2)
    print('wrote bench/results/localisation.json')


if __name__ == '__main__':
    main()
