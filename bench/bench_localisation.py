#!/usr/bin/python3
"""Localisation benchmark (library level, no ROS): the in-process simulator drives the course
world's route (start room, corridor, a loop in the big room and back; the nine cylinders present
and unmapped) with drifting odometry (distance x 1.02, rotation x 1.03, 1 % noise per step), and
the localiser (:mod:`tiago_nav.localisation.localiser`) registers each scan it finds due, as the node
does. Its error against the truth, and dead reckoning's, over five seeds, with the ideal laser
and with the default ``tiago`` laser.

Then the corridors, with the ``tiago`` laser and the same drift: worlds/corridor_start.yaml
(a start 1 m inside an 8 m corridor, to the room beyond: the error over the whole run) and
worlds/corridor_long.yaml (through a 20 m featureless corridor: along it, the localised error's
growth against dead reckoning's over the stretch where the scan leaves the axis unobservable,
the steps between consecutive estimates (in that stretch and over the whole run, where the
axis is re-acquired) and how many estimates a re-acquired correction took to converge; :func:`tiago_nav_tools.testing.localisation.corridor_figures`).
Both parts also score the published covariance (/amcl_pose's) against the truth: the NEES of
the position, ``eᵀ Σ⁻¹ e`` with ``Σ`` its x-y block (2 degrees of freedom: mean 2 and 95 % of
the scans within 5.99 when the covariance covers the error as it claims), and of the heading
(``e² / σ²``, mean 1, 95 % within 3.84). The simulator's map is its world's own raster, so the
localiser runs with ``map_sigma`` 0 and ``map_surface_depth`` 0.25 (as sim.launch sets them).

Writes bench/results/localisation.json.

Usage: bench/bench_localisation.py [--seeds 5] [--only course|corridors]
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


CHI2_95 = {1: 3.841, 2: 5.991}      # the 95 % quantiles of chi-square with 1 and 2 degrees


def nees_figures(runs):
    """The NEES of the published covariance over the scans of ``runs``
    (:class:`~tiago_nav_tools.testing.localisation.RouteResult` s): position (2 degrees of
    freedom) mean, p95 and share within the 95 % ellipse; heading (1 degree) mean and share."""
    err = np.concatenate([r.loc_err for r in runs])
    cov = np.concatenate([r.covariance for r in runs])
    xy = np.einsum('ni,nij,nj->n', err[:, :2], np.linalg.inv(cov[:, :2, :2]), err[:, :2])
    yaw = err[:, 2] ** 2 / cov[:, 2, 2]
    return {'nees_mean': float(np.mean(xy)), 'nees_p95': float(np.percentile(xy, 95)),
            'nees_within_95_share': float(np.mean(xy <= CHI2_95[2])),
            'nees_yaw_mean': float(np.mean(yaw)),
            'nees_yaw_within_95_share': float(np.mean(yaw <= CHI2_95[1]))}


def sim_config():
    """The localiser's configuration in the simulator: its map is the world's own raster."""
    from tiago_nav_tools.testing.localisation import raster_config
    return raster_config(map_sigma=0.0)


def summary(runs):
    """Pooled figures of :class:`tiago_nav_tools.testing.localisation.RouteResult` s."""
    cat = {k: np.concatenate([getattr(r, k) for r in runs])
           for k in ('loc_xy', 'loc_yaw', 'odo_xy', 'odo_yaw')}
    secs = [t for r in runs for t in r.seconds]
    return {**nees_figures(runs), 'scans': int(len(cat['loc_xy'])), 'registered': len(secs),
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
    ap.add_argument('--only', choices=('course', 'corridors'),
                    help='run one part; the other keeps its figures from the last JSON')
    args = ap.parse_args()
    if os.path.join(ROOT, 'src') not in sys.path:
        sys.path.append(os.path.join(ROOT, 'src'))
    from tiago_nav_tools.benchmarks import meta
    from tiago_nav.sim.laser import LaserModel
    from tiago_nav.sim.world import load_world
    from tiago_nav_tools.testing.localisation import run_route
    path = os.path.join(RESULTS, 'localisation.json')
    out = {}
    if args.only and os.path.exists(path):
        with open(path) as f:
            out = json.load(f)
    if args.only != 'corridors':
        course(args, out)
    if args.only != 'course':
        corridors(args, out)
    out['meta'] = meta(vars(args), real_time_factor='in process (simulated time)',
                       laser_model='ideal and tiago', odometry_model='drift (injected)')
    os.makedirs(RESULTS, exist_ok=True)
    with open(path, 'w') as f:
        json.dump(out, f, indent=2)
    print('wrote bench/results/localisation.json')


def corridors(args, out):
    """The two corridor worlds (tiago laser), per seed and pooled, into ``out['corridors']``."""
    from tiago_nav.sim.laser import LaserModel
    from tiago_nav.sim.world import load_world
    from tiago_nav_tools.testing.localisation import (CORRIDOR_LONG_ROUTE, CORRIDOR_START_ROUTE,
                                                corridor_figures, run_route)
    res = {}
    print('| world | seed | scans | featureless (m) | localised along growth | dead reckoning '
          'along growth | max step in it | max step, run | pending | converged in | '
          'max error increase | max correction | p95 / max | NEES x-y mean / within 95 % / '
          'yaw mean |')
    print('|---|---|---|---|---|---|---|---|---|---|---|---|---|---|')
    for name, route in (('corridor_start', CORRIDOR_START_ROUTE),
                        ('corridor_long', CORRIDOR_LONG_ROUTE)):
        world = load_world(os.path.join(ROOT, 'worlds', name + '.yaml'))
        runs = []
        for seed in range(args.seeds):
            r = run_route(world, route=route, seed=seed, max_time=200.0,
                          laser=LaserModel(laser_model='tiago'), config=sim_config())
            f = corridor_figures(r)
            f.update(nees_figures([r]))
            f['seed'] = seed
            runs.append(f)
            print('| %s | %d | %d | %.1f | %.3f m | %.3f m | %.3f m | %.3f m | %.3f m | %d | '
                  '%.3f m | %.3f m | %.3f / %.3f m | %.2f / %.0f %% / %.2f |' % (
                      name, seed, f['scans'], f.get('featureless_m', 0.0),
                      f.get('loc_along_growth_m', 0.0), f.get('odo_along_growth_m', 0.0),
                      f.get('max_step_featureless_m', 0.0), f['max_step_m'],
                      f['max_pending_m'], f['converge_estimates'],
                      f['max_error_increase_m'], f['max_correction_m'],
                      f['localised_p95_m'], f['localised_max_m'], f['nees_mean'],
                      100 * f['nees_within_95_share'], f['nees_yaw_mean']), flush=True)
        res[name] = {'route': [list(p) for p in route], 'runs': runs,
                     'worst': {k: max(r.get(k, 0.0) for r in runs)
                               for k in ('localised_p95_m', 'localised_max_m',
                                         'max_step_featureless_m', 'max_step_m',
                                         'max_pending_m', 'converge_estimates',
                                         'max_error_increase_m', 'max_correction_m')}}
    out['corridors'] = {'laser': 'tiago', 'seeds': args.seeds, 'worlds': res}


def course(args, out):
    """The course route with both lasers, into ``out``."""
    from tiago_nav.sim.laser import LaserModel
    from tiago_nav.sim.world import load_world
    from tiago_nav_tools.testing.localisation import run_route
    world = load_world(os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml'))
    out.update({'world': world.name, 'seeds': args.seeds, 'lasers': {}})
    print('| laser | scans | registered | rejected | localised p95 / max | dead reckoning p95 | '
          'update median | NEES x-y mean / p95 / within 95 % | NEES yaw mean / within 95 % |')
    print('|---|---|---|---|---|---|---|---|---|')
    for laser in ('ideal', 'tiago'):
        s = summary([run_route(world, seed=seed, laser=LaserModel(laser_model=laser),
                               config=sim_config()) for seed in range(args.seeds)])
        out['lasers'][laser] = s
        print('| %s | %d | %d | %d | %.1f cm / %.2f deg, max %.1f cm | %.1f cm / %.2f deg | '
              '%.1f ms | %.2f / %.1f / %.1f %% | %.2f / %.1f %% |' % (
                  laser, s['scans'], s['registered'], s['rejected'],
                             100 * s['localised_p95_m'], s['localised_p95_deg'],
                             100 * s['localised_max_m'], 100 * s['dead_reckoning_p95_m'],
                             s['dead_reckoning_p95_deg'], s['update_median_ms'] or 0.0,
                             s['nees_mean'], s['nees_p95'], 100 * s['nees_within_95_share'],
                             s['nees_yaw_mean'], 100 * s['nees_yaw_within_95_share']),
              flush=True)


if __name__ == '__main__':
    main()
