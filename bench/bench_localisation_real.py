#!/usr/bin/python3
"""Localisation on real building logs, run as a user runs it: each log of ``../shared/data/real/``
(Radish, CARMEN format, SLAM-corrected poses as the reference) is turned into a bag (/scan,
/odom, tf ``odom → base_footprint``; the odometry synthesised from the reference's steps: 2 %
scale noise per step, rotation noise of 2 % of the turn plus 0.5° per metre, composed so that
it drifts; seeded) and a map built from the scans at their reference poses (0.05 m); the
localisation node is started (``localisation.launch``, simulated time) and given the map on
/map, and the bag is played with ``rosbag play --clock``. Every /amcl_pose is scored against
the reference at each scan (the last estimate carried by the odometry since):
error RMS, p95, max, yaw p95, the share of time lost (error > 0.3 m), the time to recover,
CPU per scan and the node's peak resident memory. The localisers of a log and scenario play
the bag at the same time, each with its own ROS master, so that they share the machine's load
(CPU per scan falls as it rises) and their figures compare; ``--one-at-a-time`` plays them in
turn.

``synthetic-100m`` (:mod:`tiago_nav_tools.testing.realdata.synthetic`): a generated building of
100 m × 100 m at 0.05 m (4 million cells) and a log through a row of its rooms, ``tracking``
only: what grows with the map (peak memory, the time to take the map in) on a map larger
than the real logs'.

Scenarios: ``tracking`` (started at the reference's first pose), ``offset`` (started 2 m to
its left and turned 90°), ``kidnap`` (carried 3 m in one step at 40 % of the log, the
odometry reporting no motion), ``global`` (``/global_localization`` called before the bag
plays; "not offered" when the node has no such service). Judged: back within 0.2 m for 3
scans in a row within 30 scans of the start or the kidnap, 60 after ``/global_localization``
(counted from the first scan at which the node's ``/diagnostics`` no longer says lost: before,
its estimate is the odometry from the reference's first pose); whether ``/diagnostics`` said
lost meanwhile, and the scans the node says it skipped.

``--amcl-setup PATH/devel/setup.bash``: also ROS's amcl (ros-planning/navigation, built by
the user against the platform's ROS 1) on the same bags, with its defaults and with the tuned
set (:data:`AMCL_TUNED`) (``$AMCL_SETUP`` when the option is not given); only the frames, the initial pose and ``use_map_topic`` are set
besides.

The bag plays at the rate that brings one scan every ``--scan-period`` (0.5 s) of wall time, at
least at real time (a faster one makes a node on a busy machine drop scans, and amcl's tf cache,
10 s of the bag's time, run out).
Without the data (``--data``, default ``../shared/data/real`` beside the repository) it says
so and writes nothing. Writes bench/results/localisation_real.json and .png (``--merge [JSON ...]``:
keeps the runs of the last JSON, or of the files given, that this one does not repeat; each run
carries its date and load; ``--scenarios ''`` runs nothing and only merges).

Usage: bench/bench_localisation_real.py [--logs intel,freiburg-079,aces,synthetic-100m]
    [--scenarios tracking,offset,kidnap,global] [--amcl-setup PATH] [--localisers ...]
    [--scan-period 0.1] [--one-at-a-time] [--merge [JSON ...]] [--data DIR] [--work DIR]
"""
import argparse
import json
import math
import os
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, 'bench', 'results')
DATA = os.path.normpath(os.path.join(ROOT, '..', 'shared', 'data', 'real'))
LOGS = ('intel', 'freiburg-079', 'aces')
SYNTHETIC = 'synthetic-100m'      # tiago_nav_tools.testing.realdata.synthetic.NAME
# the tuned set of issue 48 (chosen on the first 120 scans of the Intel log)
AMCL_TUNED = {'laser_max_beams': 90, 'odom_alpha1': 0.05, 'odom_alpha2': 0.05,
              'odom_alpha3': 0.05, 'odom_alpha4': 0.05, 'min_particles': 500,
              'laser_sigma_hit': 0.1, 'update_min_a': 0.2}
LOCALISERS = {'tiago_nav': ('tiago_nav', None), 'amcl_defaults': ('amcl', {}),
              'amcl_tuned': ('amcl', AMCL_TUNED)}
WITHIN_SCANS = {'offset': 30, 'kidnap': 30, 'global': 60}


def score(prep, run, scenario):
    """The figures of one run (:mod:`tiago_nav_tools.testing.realdata.scoring`)."""
    from tiago_nav_tools.testing.realdata import scoring
    from tiago_nav_tools.testing.realdata.convert import read_reference
    t, ref, odom = read_reference(prep[scenario]['reference'])
    e = np.array(run['estimates'], dtype=float).reshape(-1, 7)
    est = scoring.estimates_at_scans(t, odom, e[:, 0], e[:, 1:4])
    s = scoring.summary(t, ref, est)
    err, _ = scoring.errors(ref, est)
    s['estimates'] = int(len(e))
    s['cpu_ms_per_scan'] = 1000.0 * run['cpu_s'] / len(t)
    for k in ('peak_rss_mb', 'cpu_map_s', 'ready_s', 'wall_s', 'node_alive_at_end',
              'diagnostics_published'):
        s[k] = run.get(k)
    if len(e):
        # the covariance the node claimed: its position sigma at the scans it published
        s['sigma_xy_median_m'] = float(np.median(np.sqrt(np.maximum(e[:, 4] + e[:, 5], 0))))
    start = prep[scenario]['event'] if scenario == 'kidnap' else 0
    d = np.array([r[:2] for r in run.get('diagnostics') or []], dtype=float).reshape(-1, 2)
    if scenario in WITHIN_SCANS:
        first = start
        if scenario == 'global':
            # until the node accepts a place, its estimate is the odometry from where it was
            # started (the reference's first pose): counted from the first scan at which its
            # /diagnostics no longer says lost, as the library replay counts
            ok = d[d[:, 1] < 2, 0]
            first = len(t) if not len(ok) else int(np.searchsorted(t, ok[0] - 1e-6))
        rec = scoring.recovery(np.nan_to_num(err, nan=np.inf), first) \
            if first < len(t) else None
        rec = None if rec is None else rec + first - start
        s['back_within_0_2_m_after_scans'] = rec
        s['back_within_limit'] = rec is not None and rec <= WITHIN_SCANS[scenario]
        s['limit_scans'] = WITHIN_SCANS[scenario]
        # what the node's /diagnostics said from the start or the kidnap until it was back
        t1 = t[min(start + rec, len(t) - 1)] if rec is not None else t[-1]
        during = d[(d[:, 0] >= t[start] - 1e-6) & (d[:, 0] <= t1 + 1e-6), 1]
        s['lost_reported_before_back'] = bool(np.any(during >= 2)) if len(d) else None
    skipped = [r[2] for r in run.get('diagnostics') or [] if r[2] is not None]
    s['skipped_scans'] = skipped[-1] if skipped else None
    return s, est


def plot(path, out, estimates, maps):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from tiago_nav_tools.testing.realdata.convert import read_reference
    from tiago_nav_tools.testing.realdata.mapping import load_map
    names = [n for n in out['logs'] if n in maps]
    if not names:
        return
    fig, axes = plt.subplots(1, len(names), figsize=(7 * len(names), 7), squeeze=False)
    colours = {'tiago_nav': 'tab:red', 'amcl_defaults': 'tab:orange', 'amcl_tuned': 'tab:blue'}
    for ax, name in zip(axes[0], names):
        g = load_map(maps[name]['map'])
        x0, y0, x1, y1 = g.bounds
        ax.imshow(np.where(g.data == 100, 0.0, np.where(g.data == 0, 1.0, 0.8)), cmap='gray',
                  origin='lower', extent=(x0, x1, y0, y1), vmin=0, vmax=1)
        _, ref, _ = read_reference(maps[name]['tracking']['reference'])
        ax.plot(ref[:, 0], ref[:, 1], 'k-', lw=1.0, label='reference')
        for (log, loc), est in estimates.items():
            if log == name:
                ax.plot(est[:, 0], est[:, 1], '-', lw=0.9, color=colours.get(loc, 'tab:green'),
                        label=loc)
        run = next((r for r in out['runs'] if r['log'] == name and r['scenario'] == 'tracking'
                    and r['localiser'] == 'tiago_nav' and 'p95_m' in r), None)
        title = name
        if run:
            title += ': tiago_nav p95 %.2f m, lost %.0f %%' % (run['p95_m'],
                                                              100 * run['lost_time_share'])
        ax.set_title(title)
        ax.set_aspect('equal')
        ax.legend(loc='best', fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=70)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--data', default=DATA, help='folder of the logs (default: %(default)s)')
    ap.add_argument('--logs', default=','.join(LOGS + (SYNTHETIC,)))
    ap.add_argument('--scenarios', default='tracking,offset,kidnap,global')
    ap.add_argument('--localisers', default=None,
                    help='of: %s (default: tiago_nav, and both amcl ones with --amcl-setup)'
                         % ', '.join(LOCALISERS))
    ap.add_argument('--amcl-setup', default=os.environ.get('AMCL_SETUP') or None,
                    help='setup.bash of a catkin workspace where amcl is built (default: '
                         '$AMCL_SETUP)')
    ap.add_argument('--scan-period', type=float, default=0.5,
                    help='[s] wall time between scans: the bag plays at median scan interval / '
                         'this, at least at real time')
    ap.add_argument('--one-at-a-time', dest='side_by_side', action='store_false',
                    help='play the bag into one localiser after the other (default: into all of '
                         'them at once, each with its own ROS master, so that they share the '
                         'machine\'s load and their CPU per scan compares)')
    ap.add_argument('--seed', type=int, default=0, help='of the odometry noise')
    ap.add_argument('--work', default=os.path.join(os.path.expanduser('~'), '.cache', 'tiago_nav',
                                                   'realdata'),
                    help='where the bags and maps are made (kept between runs)')
    ap.add_argument('--out', default=os.path.join(RESULTS, 'localisation_real.json'))
    ap.add_argument('--merge', nargs='*', metavar='JSON',
                    help='keep the runs of these JSON files (none given: --out) that this '
                         'invocation does not make')
    args = ap.parse_args()
    if os.path.join(ROOT, 'src') not in sys.path:
        sys.path.append(os.path.join(ROOT, 'src'))
    from tiago_nav_tools.benchmarks import meta
    from tiago_nav_tools.testing.realdata.convert import SCENARIOS, prepare, read_reference
    from tiago_nav_tools.testing.realdata.odometry import dead_reckoning
    from tiago_nav_tools.testing.realdata.play import run_child
    from tiago_nav_tools.testing.realdata.scoring import summary
    from tiago_nav_tools.testing.realdata import synthetic

    logs = [n for n in args.logs.split(',') if n]
    paths = {n: os.path.join(args.data, '%s-corrected.log.gz' % n) for n in logs
             if n != SYNTHETIC}
    missing = [p for p in paths.values() if not os.path.exists(p)]
    if missing:
        print('bench_localisation_real: skipped: no log at %s (the real data lives in '
              '../shared/data/real beside the repository; --data DIR)' % ', '.join(missing))
        return 0
    scenarios = [s for s in args.scenarios.split(',') if s]
    bad = [s for s in scenarios if s not in SCENARIOS]
    if bad:
        ap.error('unknown scenario(s) %s' % ', '.join(bad))
    names = args.localisers.split(',') if args.localisers else \
        ['tiago_nav'] + (['amcl_defaults', 'amcl_tuned'] if args.amcl_setup else [])
    bad = [n for n in names if n not in LOCALISERS]
    if bad:
        ap.error('unknown localiser(s) %s' % ', '.join(bad))
    if any(LOCALISERS[n][0] == 'amcl' for n in names):
        if not args.amcl_setup or not os.path.exists(args.amcl_setup):
            ap.error('amcl needs --amcl-setup PATH/devel/setup.bash')
        args.amcl_setup = os.path.abspath(args.amcl_setup)

    old = {'logs': {}, 'runs': []}
    merge = ([args.out] if not args.merge else args.merge) if args.merge is not None else []
    for path in merge:
        if os.path.exists(path):
            with open(path) as f:
                d = json.load(f)
            old['logs'].update(d.get('logs', {}))
            old['runs'] += d.get('runs', [])
    out = {'data': 'Radish building logs (CARMEN, SLAM-corrected poses) of the real data '
                   'folder (shared/data/real)',
           'odometry': 'translation x (1 + N(0, 0.02)) per step, rotation + N(0, 1) x (2 %% of '
                       'the turn + 0.5 deg per metre), composed; seed %d' % args.seed,
           'map_resolution_m': 0.05, 'lost_m': 0.3, 'converged_m': 0.2,
           'scan_period_s': args.scan_period, 'amcl_tuned': AMCL_TUNED,
           'logs': dict(old.get('logs', {})), 'runs': []}
    preps, estimates = {}, {}
    done = set()
    for name in logs if scenarios else ():     # no scenario: merge and plot only
        print('== %s: preparing (map, bags) in %s' % (name, args.work), flush=True)
        if name == SYNTHETIC:
            if 'tracking' not in scenarios:
                continue
            prep = synthetic.prepare(os.path.join(args.work, name), ['tracking'], args.seed)
        else:
            prep = prepare(paths[name], os.path.join(args.work, name), scenarios, args.seed)
        preps[name] = prep
        t, ref, odom = read_reference(prep['tracking' if name == SYNTHETIC
                                           else scenarios[0]]['reference'])
        dr = summary(t, ref, dead_reckoning(ref[0], odom))
        dts = np.diff(t)
        rate = max(1.0, float(np.median(dts)) / args.scan_period)
        info = dict(prep['log'])
        info.update({'rate': rate, 'median_scan_interval_s': float(np.median(dts)),
                     'dead_reckoning_p95_m': dr['p95_m'], 'dead_reckoning_max_m': dr['max_m']})
        out['logs'][name] = info
        for scenario in scenarios:
            if scenario not in prep:
                continue
            p = prep[scenario]

            def play(loc):
                kind, params = LOCALISERS[loc]
                cfg = {'localiser': kind, 'bag': p['bag'], 'map': prep['map'],
                       'start': p['start'], 'rate': rate, 'duration': p['duration_s'],
                       'last_stamp': p['last_stamp'], 'global_localization': scenario == 'global',
                       'amcl_setup': args.amcl_setup, 'amcl_params': params,
                       'log': os.path.join(args.work, name, '%s_%s.log' % (scenario, loc))}
                t0 = time.monotonic()
                run = run_child(cfg, timeout=p['duration_s'] / rate * 3 + 900)
                return run, os.getloadavg()[0], time.monotonic() - t0

            side = args.side_by_side and len(names) > 1
            if side:
                print('   %-8s %s at once ...' % (scenario, ', '.join(names)), flush=True)
                with ThreadPoolExecutor(len(names)) as pool:
                    played = list(pool.map(play, names))
            else:
                played = None
            for i, loc in enumerate(names):
                kind, params = LOCALISERS[loc]
                print('   %-8s %-13s ...' % (scenario, loc), end=' ', flush=True)
                run, load, wall = played[i] if played else play(loc)
                rec = {'log': name, 'scenario': scenario, 'localiser': loc,
                       'params': params if kind == 'amcl' else 'defaults (config/localisation.yaml)',
                       'date': time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime()),
                       'loadavg_1min': round(load, 2), 'side_by_side': side}
                if 'error' in run:
                    rec['error'] = run['error']
                    print('ERROR %s' % run['error'], flush=True)
                elif scenario == 'global' and not run.get('global_localization_offered'):
                    rec['global_localization'] = 'not offered'
                    print('/global_localization not offered', flush=True)
                else:
                    s, est = score(prep, run, scenario)
                    rec.update(s)
                    if scenario == 'tracking':
                        np.save(os.path.join(args.work, name, 'tracking_%s_estimates.npy' % loc), est)
                    print('p95 %.3f m, max %.2f m, lost %.1f %%, %.1f ms/scan, %.0f MB, %s '
                          'estimates/%d scans%s (%.0f s)'
                          % (s['p95_m'], s['max_m'], 100 * s['lost_time_share'],
                             s['cpu_ms_per_scan'], s['peak_rss_mb'] or -1, s['estimates'],
                             s['scans'], '' if scenario not in WITHIN_SCANS else
                             ', back within 0.2 m after %s scans' % s['back_within_0_2_m_after_scans'],
                             wall), flush=True)
                out['runs'].append(rec)
                done.add((name, scenario, loc))
    for r in old['runs']:       # the latest of each (log, scenario, localiser) kept
        key = (r['log'], r['scenario'], r['localiser'])
        if key not in done:
            out['runs'] = [x for x in out['runs']
                           if (x['log'], x['scenario'], x['localiser']) != key
                           or x.get('date', '') > r.get('date', '')]
            if not any((x['log'], x['scenario'], x['localiser']) == key for x in out['runs']):
                out['runs'].append(r)
    order = {n: i for i, n in enumerate(LOGS + (SYNTHETIC,))}
    out['runs'].sort(key=lambda r: (order.get(r['log'], 99), SCENARIOS.index(r['scenario']),
                                    list(LOCALISERS).index(r['localiser'])))
    out['meta'] = meta(vars(args), real_time_factor='bag played at each log\'s "rate"',
                       laser_model='real (Radish logs)',
                       odometry_model='synthesised from the reference (see "odometry")')
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, 'w') as f:
        json.dump(out, f, indent=1)
    # the trajectories of every log's tracking runs made so far (this invocation's or earlier)
    for name in out['logs']:
        if 'tracking' not in preps.get(name, {}) and name == SYNTHETIC:
            preps[name] = synthetic.prepare(os.path.join(args.work, name), ['tracking'],
                                            args.seed, bags=False)
        elif 'tracking' not in preps.get(name, {}) and \
                os.path.exists(os.path.join(args.data, '%s-corrected.log.gz' % name)):
            preps[name] = prepare(os.path.join(args.data, '%s-corrected.log.gz' % name),
                                  os.path.join(args.work, name), ['tracking'], args.seed, bags=False)
        for loc in LOCALISERS:
            f = os.path.join(args.work, name, 'tracking_%s_estimates.npy' % loc)
            if name in preps and os.path.exists(f):
                estimates[(name, loc)] = np.load(f)
    plot(os.path.splitext(args.out)[0] + '.png', out, estimates, preps)
    print('wrote %s' % os.path.relpath(args.out, ROOT))
    return 0


if __name__ == '__main__':
    sys.exit(main())
