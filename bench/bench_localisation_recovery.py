#!/usr/bin/python3
"""Lost detection and relocalisation on real building logs, in process (the library, no ROS):
each log of ``../shared/data/real/`` (the same scenarios, odometry and map as
``bench_localisation_real.py``: :mod:`tiago_nav_tools.testing.realdata`) is replayed scan by scan into
:class:`tiago_nav.localisation.recovery.RecoveringLocaliser`; every scan is taken in (no
timing, no dropped scans), so the figures are the algorithm's, apart from what ROS adds.

Per log and scenario (``tracking``: started at the reference; ``offset``: 2 m to the left and
turned 90°; ``kidnap``: carried 3 m at 40 % of the log, the odometry silent; ``global``:
``global_localization()`` before the first scan): the scans until the estimate is back within
0.2 m of the reference for 3 scans in a row (from the start or the kidnap; targets 30, and 60
for ``global``), how many of the scans before it the status said lost / degraded / OK, the scans
the status said lost while the estimate was right (after convergence), the error p95 / max and
the share of scans lost (> 0.3 m) after convergence, the NEES of the published covariance
after convergence (position ``eᵀ Σ⁻¹ e`` with ``Σ`` its x-y block, 2 degrees of freedom: mean 2
and 95 % of the scans within 5.99 when the covariance covers the error as it claims; heading
``e² / σ²``, 1 degree: mean 1, 95 % within 3.84), the CPU per scan.
For ``global`` the convergence counts from the first scan at which the relocalisation was
accepted (before it the estimate is the odometry's from the reference's first pose).

Writes bench/results/localisation_recovery.json. Without the data it says so and writes
nothing.

Usage: bench/bench_localisation_recovery.py [--logs intel,freiburg-079,aces]
    [--scenarios tracking,offset,kidnap,global] [--data DIR] [--out JSON]
"""
import argparse
import json
import math
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if os.path.join(ROOT, 'src') not in sys.path:
    sys.path.insert(0, os.path.join(ROOT, 'src'))
# before numpy: one BLAS thread, as the nodes run. OpenBLAS's workers spin after every tiny
# inverse, and their CPU would count in the figures (2.5 times the node's own on Freiburg)
import tiago_nav.nodes  # noqa: E402,F401

import numpy as np  # noqa: E402
RESULTS = os.path.join(ROOT, 'bench', 'results')
DATA = os.path.normpath(os.path.join(ROOT, '..', 'shared', 'data', 'real'))
LOGS = ('intel', 'freiburg-079', 'aces')
SCENARIOS = ('tracking', 'offset', 'kidnap', 'global')
WITHIN = {'offset': 30, 'kidnap': 30, 'global': 60}
BACK_M, LOST_M, IN_A_ROW = 0.2, 0.3, 3
CHI2_95 = {1: 3.841, 2: 5.991}      # the 95 % quantiles of chi-square with 1 and 2 degrees


def replay(grid, field, pyr, sc, name):
    """Errors [m], NEES ``(N, 2)`` (position, heading), status levels and relocalising flags
    per scan, CPU [s]."""
    from tiago_nav.geometry import wrap_angle
    from tiago_nav.localisation.recovery import RecoveringLocaliser
    loc = RecoveringLocaliser(grid, sc.start, odom=tuple(sc.odom[0]), field=field, pyramid=pyr)
    if name == 'global':
        loc.global_localization()
    ang = sc.log.angles()
    errs, nees, levels, reloc = [], [], [], []
    t0 = time.process_time()
    for i in range(len(sc.log)):
        od = tuple(sc.odom[i])
        if loc.due(od):
            pts = loc.scan_points(sc.log.ranges[i], ang[0], ang[1] - ang[0], 0.02, 49.99,
                                  (0.0, 0.0, 0.0))
            up = loc.update(od, pts, (0.0, 0.0))
            pose, cov = up.pose, up.covariance
        else:
            pose, cov = loc.follow(od)
        e = np.array(pose[:2]) - sc.log.poses[i, :2]
        errs.append(float(np.hypot(*e)))
        eyaw = wrap_angle(pose[2] - sc.log.poses[i, 2])
        try:
            nees.append((float(e @ np.linalg.solve(cov[:2, :2], e)),
                         eyaw ** 2 / cov[2, 2] if cov[2, 2] > 0 else float('inf')))
        except np.linalg.LinAlgError:
            nees.append((float('inf'), float('inf')))
        levels.append(loc.health.level)
        reloc.append(loc.relocalising)
    return np.array(errs), np.array(nees).reshape(-1, 2), np.array(levels), np.array(reloc), \
        time.process_time() - t0


def figures(name, sc, errs, nees, levels, reloc, cpu):
    start = sc.event if name == 'kidnap' else 0
    if name == 'global':
        done = np.nonzero(~reloc)[0]
        start_ok = int(done[0]) if len(done) else len(errs)
    else:
        start_ok = start
    back = None
    for k in range(start_ok, len(errs) - IN_A_ROW + 1):
        if np.all(errs[k:k + IN_A_ROW] < BACK_M):
            back = k - start
            break
    conv = len(errs) if back is None else start + back
    before = levels[start:conv]
    after = errs[conv:]
    out = {'scans': int(len(errs)), 'event_scan': int(start),
           'back_within_0_2_m_after_scans': back,
           'limit_scans': WITHIN.get(name),
           'back_within_limit': None if name not in WITHIN else
           (back is not None and back <= WITHIN[name]),
           'status_before_back': {'ok': int(np.sum(before == 0)),
                                  'degraded': int(np.sum(before == 1)),
                                  'lost': int(np.sum(before == 2))},
           'lost_reported_before_back': bool(np.any(before == 2)) if len(before) else None,
           'lost_reported_after_back_scans': int(np.sum(levels[conv:] == 2)),
           'cpu_ms_per_scan': 1000.0 * cpu / len(errs)}
    if len(after):
        out.update({'p95_after_m': float(np.percentile(after, 95)),
                    'max_after_m': float(after.max()),
                    'lost_share_after': float(np.mean(after > LOST_M)),
                    'nees_xy_mean_after': float(np.mean(nees[conv:, 0])),
                    'nees_xy_p95_after': float(np.percentile(nees[conv:, 0], 95)),
                    'nees_xy_within_95_share': float(np.mean(nees[conv:, 0] <= CHI2_95[2])),
                    'nees_yaw_mean_after': float(np.mean(nees[conv:, 1])),
                    'nees_yaw_within_95_share': float(np.mean(nees[conv:, 1] <= CHI2_95[1]))})
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--data', default=DATA)
    ap.add_argument('--logs', default=','.join(LOGS))
    ap.add_argument('--scenarios', default=','.join(SCENARIOS))
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--work', default=os.path.join(os.path.expanduser('~'), '.cache', 'tiago_nav',
                                                   'realdata'))
    ap.add_argument('--out', default=os.path.join(RESULTS, 'localisation_recovery.json'))
    args = ap.parse_args()
    from tiago_nav_tools.benchmarks import meta
    from tiago_nav.localisation.global_search import LikelihoodPyramid
    from tiago_nav.gridmap import SCAN_MAP_DEPTH, DistanceField
    from tiago_nav_tools.testing.realdata.carmen import read_log
    from tiago_nav_tools.testing.realdata.convert import prepare, scenario
    from tiago_nav_tools.testing.realdata.mapping import load_map

    logs = [n for n in args.logs.split(',') if n]
    scenarios = [s for s in args.scenarios.split(',') if s]
    bad = [s for s in scenarios if s not in SCENARIOS]
    if bad:
        ap.error('unknown scenario(s) %s' % ', '.join(bad))
    paths = {n: os.path.join(args.data, '%s-corrected.log.gz' % n) for n in logs}
    missing = [p for p in paths.values() if not os.path.exists(p)]
    if missing:
        print('bench_localisation_recovery: skipped: no log at %s (--data DIR)'
              % ', '.join(missing))
        return 0
    out = {'what': __doc__.split('\n\n')[0], 'back_m': BACK_M, 'lost_m': LOST_M,
           'in_a_row': IN_A_ROW, 'runs': []}
    if os.path.exists(args.out):        # the runs of other logs / scenarios kept
        with open(args.out) as f:
            old = json.load(f).get('runs', [])
        out['runs'] = [r for r in old if (r['log'], r['scenario']) not in
                       {(n, s) for n in logs for s in scenarios}]
    for name in logs:
        prep = prepare(paths[name], os.path.join(args.work, name), ['tracking'], args.seed,
                       bags=False)
        grid = load_map(prep['map'])
        # the log's map is built from its scans (the node's default map_surface_depth)
        field, pyr = DistanceField(grid, SCAN_MAP_DEPTH), LikelihoodPyramid(grid)
        log = read_log(paths[name])
        for sn in scenarios:
            sc = scenario(log, sn, args.seed)
            f = figures(sn, sc, *replay(grid, field, pyr, sc, sn))
            f.update({'log': name, 'scenario': sn,
                      'date': time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime()),
                      'loadavg_1min': round(os.getloadavg()[0], 2)})
            out['runs'].append(f)
            write(out, args, meta)        # after every run: a long one keeps what is done
            print('%-13s %-8s back within 0.2 m after %s scans (limit %s); status before: %s; '
                  'after: p95 %s m, lost %s, NEES %s (2) / yaw %s (1); %.1f ms/scan'
                  % (name, sn, f['back_within_0_2_m_after_scans'], f['limit_scans'],
                     f['status_before_back'], '%.3f' % f['p95_after_m'] if 'p95_after_m' in f
                     else '-', '%.1f %%' % (100 * f['lost_share_after'])
                     if 'lost_share_after' in f else '-',
                     '%.2f' % f['nees_xy_mean_after'] if 'nees_xy_mean_after' in f else '-',
                     '%.2f' % f['nees_yaw_mean_after'] if 'nees_yaw_mean_after' in f else '-',
                     f['cpu_ms_per_scan']), flush=True)
    write(out, args, meta)
    print('wrote %s' % os.path.relpath(args.out, ROOT))
    return 0


def write(out, args, meta):
    order = {n: i for i, n in enumerate(LOGS)}
    out['runs'].sort(key=lambda r: (order.get(r['log'], 99), SCENARIOS.index(r['scenario'])))
    out['meta'] = meta(vars(args), real_time_factor='in process (every scan taken in)',
                       laser_model='real (Radish logs)',
                       odometry_model='synthesised from the reference (bench_localisation_real)')
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out + '.part', 'w') as f:
        json.dump(out, f, indent=1)
    os.replace(args.out + '.part', args.out)


if __name__ == '__main__':
    sys.exit(main())
