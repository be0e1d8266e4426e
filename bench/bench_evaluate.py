#!/usr/bin/python3
"""Batch evaluation benchmark: the same runs of a suite with 1, 2 and 3 local Dask workers and
on a separately started Dask cluster (a ``dask scheduler`` and a ``dask worker`` process with two
worker processes), through ``rosrun tiago_nav evaluate`` as a user runs it. Reports missions per
minute per setting and whether every run's result is the same in every setting (all but the
wall-clock figures, ``tiago_nav_tools.evaluate.run.WALL_CLOCK_FIELDS``: wall and CPU seconds,
simulated/wall ratio, start-up time, the worker's host, slot and port).
Per setting it also reports where the time goes (``tiago_nav_tools.evaluate.timing``): the runs'
start-up, mission, teardown and judging wall time and CPU (totals and medians) and the share
of the setting's worker time (wall time x workers) spent in missions; and the runs' isolation.
``--warm``: each worker count runs the same rows a second time right after, with warm stacks
(``evaluate --warm``: one stack per worker for the rows that share world, profile and candidate,
reset between rows), and the report adds per worker count the warm rate over the
fresh one, whether every row's warm result equals its fresh result (all fields but the
wall-clock ones), the missions' share of the worker time in both, and how many rows ran after a
reset. The rows are then picked in whole stack groups (every row of a key, the keys spread over
the suite; ``--per-stack N``: at most N rows of each), since rows spread one per key would each
start a stack of their own. ``--runs`` at least the suite's size takes every row.
Writes bench/results/evaluate.json and evaluate.png.

Usage: bench/bench_evaluate.py [--suite suites/course.yaml] [--runs 20] [--workers 1 2 3]
                               [--no-cluster] [--keep DIR] [--isolation auto|netns|loopback]
                               [--warm [--per-stack N]] [--quick] [--out JSON]
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, 'bench', 'results')
PORT = 8786


def evaluate(argv):
    """``rosrun tiago_nav evaluate ARGV``: (exit code, wall seconds)."""
    t0 = time.monotonic()
    rc = subprocess.call(['rosrun', 'tiago_nav', 'evaluate'] + argv, cwd=ROOT)
    return rc, time.monotonic() - t0


def pick(suite, n):
    """``n`` run ids spread evenly over the suite's expansion (every k-th of the dry-run list)."""
    out = subprocess.run(['rosrun', 'tiago_nav', 'evaluate', suite, '--out', tempfile.gettempdir(),
                          '--dry-run'], cwd=ROOT, stdout=subprocess.PIPE, text=True, check=True)
    ids = [line.split()[0] for line in out.stdout.splitlines() if line[:1].isalnum()
           and not line.endswith(' runs')]
    step = max(1, len(ids) // n)
    return ids[::step][:n]


def pick_stacks(suite, n, per=None):
    """``n`` run ids in whole stack groups (:func:`tiago_nav_tools.evaluate.warm.group_by_stack` of the
    suite's rows, each cut to its first ``per`` rows when given), the groups taken at an even
    stride over the suite so that the picked rows span its worlds, profiles and corridor
    settings; every row when ``n`` is at least the suite's size."""
    from tiago_nav_tools.evaluate import suite as S
    from tiago_nav_tools.evaluate.warm import group_by_stack
    data, base = S.load(suite)
    runs, _ = S.expand(data, suite, base)
    if n >= len(runs):
        return [r['id'] for r in runs]
    groups = [g[:per] if per else g for g in group_by_stack(runs)]
    mean = sum(len(g) for g in groups) / float(len(groups))
    stride = max(1, int(len(groups) / max(1.0, n / mean)))
    order = groups[::stride] + [g for i, g in enumerate(groups) if i % stride]
    ids = []
    for g in order:
        ids += [r['id'] for r in g][:n - len(ids)]
        if len(ids) >= n:
            break
    return ids


def results(out):
    """``{run_id: result.json}`` of an evaluate output folder."""
    runs = os.path.join(out, 'runs')
    res = {}
    for rid in sorted(os.listdir(runs)) if os.path.isdir(runs) else []:
        try:
            with open(os.path.join(runs, rid, 'result.json')) as f:
                res[rid] = json.load(f)
        except (OSError, ValueError):
            pass
    return res


class Cluster:
    """A ``dask scheduler`` and a ``dask worker --nworkers 2`` as separate processes on
    loopback, stopped with :meth:`close`."""

    def __init__(self, folder, workers=2, timeout=60.0):
        dask = [sys.executable, '-m', 'dask']     # the sourced workspace puts it on the path
        self.address = 'tcp://127.0.0.1:%d' % PORT
        self.logs = [open(os.path.join(folder, n), 'w') for n in ('scheduler.log', 'worker.log')]
        self.procs = [subprocess.Popen(dask + ['scheduler', '--host', '127.0.0.1', '--port', str(PORT),
                                        '--no-dashboard'], stdout=self.logs[0], stderr=subprocess.STDOUT)]
        self.procs.append(subprocess.Popen(dask + ['worker', self.address, '--nthreads', '1',
                                            '--nworkers', str(workers), '--no-dashboard'],
                                           stdout=self.logs[1], stderr=subprocess.STDOUT))
        from distributed import Client     # the evaluator's own dependency
        deadline = time.monotonic() + timeout
        with Client(self.address, timeout=timeout) as c:
            while len(c.scheduler_info()['workers']) < workers:
                if time.monotonic() > deadline:
                    self.close()
                    raise RuntimeError('the Dask cluster has fewer than %d workers after %g s'
                                       % (workers, timeout))
                time.sleep(0.2)

    def close(self):
        for p in reversed(self.procs):
            p.terminate()
            try:
                p.wait(30)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        for f in self.logs:
            f.close()


def plot(settings, path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 3.5))
    names = [s['setting'] for s in settings]
    ax.bar(names, [s['missions_per_minute'] for s in settings], color='tab:blue')
    for i, s in enumerate(settings):
        ax.text(i, s['missions_per_minute'], '%.2f' % s['missions_per_minute'], ha='center',
                va='bottom')
    ax.set_ylabel('missions per minute')
    ax.set_title('%d runs per setting, %d cores' % (settings[0]['runs'], os.cpu_count()))
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--suite', default='suites/course.yaml')
    ap.add_argument('--runs', type=int, default=20, help='run ids, spread over the suite')
    ap.add_argument('--workers', type=int, nargs='+', default=[1, 2, 3])
    ap.add_argument('--no-cluster', dest='cluster', action='store_false',
                    help='skip the separately started Dask cluster')
    ap.add_argument('--keep', help='write the evaluate output folders here (default: a temporary '
                                   'folder, removed)')
    ap.add_argument('--out', default=os.path.join(RESULTS, 'evaluate.json'))
    ap.add_argument('--isolation', choices=('auto', 'netns', 'loopback'), default='auto',
                    help="the evaluator's --isolation")
    ap.add_argument('--quick', action='store_true',
                    help='4 runs, 2 workers, no separate cluster (a quick look; overrides those '
                         'options; with --warm: 2 rows of each of 2 stack keys)')
    ap.add_argument('--warm', action='store_true',
                    help='each worker count also with warm stacks (evaluate --warm), on the same '
                         'rows picked in whole stack groups')
    ap.add_argument('--per-stack', type=int, default=None, metavar='N',
                    help='with --warm: at most N rows of each stack key')
    args = ap.parse_args()
    if args.quick:
        args.runs, args.workers, args.cluster = 4, [2], False
        if args.warm and args.per_stack is None:
            args.per_stack = 2
    if args.per_stack is not None and args.per_stack < 1:
        ap.error('--per-stack: must be >= 1')
    if os.path.join(ROOT, 'src') not in sys.path:
        sys.path.append(os.path.join(ROOT, 'src'))
    from tiago_nav_tools.benchmarks import meta
    from tiago_nav_tools.evaluate.run import WALL_CLOCK_FIELDS, differences
    from tiago_nav_tools.evaluate.report import isolations, stacks
    from tiago_nav_tools.evaluate.timing import PHASES, batch
    for var, value in (('ROS_HOSTNAME', 'localhost'), ('ROS_IP', '127.0.0.1')):
        os.environ.setdefault(var, value)
    base = args.keep or tempfile.mkdtemp(prefix='bench_evaluate_')
    os.makedirs(base, exist_ok=True)
    ids = pick_stacks(args.suite, args.runs, args.per_stack) if args.warm else pick(args.suite, args.runs)
    print('%d runs of %s: %s' % (len(ids), args.suite, ' '.join(ids)), flush=True)
    settings, by_setting = [], {}
    modes, counts, fresh_of = [], {}, {}
    for w in args.workers:      # each worker count fresh, then (--warm) warm in the same hour
        name = '%d worker%s' % (w, '' if w == 1 else 's')
        modes.append((name, ['--workers', str(w)]))
        counts[name] = w
        if args.warm:
            modes.append((name + ', warm', ['--workers', str(w), '--warm']))
            counts[name + ', warm'] = w
            fresh_of[name + ', warm'] = name
    counts['Dask cluster, 2 workers'] = 2
    if args.cluster:
        modes.append(('Dask cluster, 2 workers', None))
    for name, extra in modes:
        out = os.path.join(base, name.replace(' ', '_').replace(',', ''))
        shutil.rmtree(out, ignore_errors=True)
        os.makedirs(out)
        cluster = None
        if extra is None:
            cluster = Cluster(out)
            extra = ['--scheduler', cluster.address]
        try:
            rc, wall = evaluate([args.suite, '--out', out, '--isolation', args.isolation, '--only']
                                + ids + extra)
        finally:
            if cluster:
                cluster.close()
        res = results(out)
        outcomes = {}
        for r in res.values():
            outcomes[r.get('outcome')] = outcomes.get(r.get('outcome'), 0) + 1
        s = {'setting': name, 'exit_code': rc, 'runs': len(ids), 'results': len(res),
             'wall_s': wall, 'missions_per_minute': 60.0 * len(res) / wall, 'outcomes': outcomes,
             'infrastructure_errors': sum(v for k, v in outcomes.items() if str(k).startswith('INFRA')),
             'leftover_processes': sum(r.get('leftover_processes') or 0 for r in res.values()),
             'cpu_s_per_mission': sum(r.get('cpu_s') or 0 for r in res.values()) / max(1, len(res)),
             'isolation': isolations(res.values()),
             'time': batch(list(res.values()), wall, counts[name])}
        if name in fresh_of:
            s['stacks'] = stacks(list(res.values()))
        settings.append(s)
        by_setting[name] = res
        print('%-26s exit %d  %d/%d results  %.0f s  %.2f missions/min  %s  isolation %s' % (
            name, rc, len(res), len(ids), wall, s['missions_per_minute'], outcomes, s['isolation']),
            flush=True)
        t = s['time']
        if t:
            print('%-26s missions %.1f %% of the worker time (%.0f s = %.0f s x %d workers)' % (
                '', 100 * (t['mission_share'] or 0), t['worker_time_s'], wall, counts[name]))
            for k in PHASES:
                p = t['phases'][k]
                print('%-26s   %-9s wall %6.1f s (%4.1f %% of the runs\', median %5.2f s)  CPU %6.1f s '
                      '(median %5.2f s)' % ('', k, p['wall_s'], 100 * (p['wall_share'] or 0),
                                           p['median_wall_s'] or 0, p['cpu_s'] or 0,
                                           p['median_cpu_s'] or 0), flush=True)
    ref_name = settings[0]['setting']
    ref = by_setting[ref_name]
    for s in settings[1:]:
        other = by_setting[s['setting']]
        diff = {rid: differences(ref[rid], other[rid]) for rid in ids if rid in ref and rid in other}
        s['runs_differing_from_' + ref_name.replace(' ', '_')] = {k: v for k, v in diff.items() if v}
        s['runs_compared'] = len(diff)
    warm = []
    for s in settings:      # each warm setting against the fresh one with its worker count
        if s['setting'] not in fresh_of:
            continue
        fresh = next(f for f in settings if f['setting'] == fresh_of[s['setting']])
        a, b = by_setting[fresh['setting']], by_setting[s['setting']]
        diff = {rid: differences(a[rid], b[rid]) for rid in ids if rid in a and rid in b}
        w = {'workers': counts[s['setting']], 'fresh': fresh['setting'], 'warm': s['setting'],
             'fresh_missions_per_minute': fresh['missions_per_minute'],
             'warm_missions_per_minute': s['missions_per_minute'],
             'speedup': s['missions_per_minute'] / fresh['missions_per_minute']
             if fresh['missions_per_minute'] else None,
             'runs_compared': len(diff), 'runs_differing': {k: v for k, v in diff.items() if v},
             'all_equal': len(diff) == len(ids) and not any(diff.values()),
             'infrastructure_errors': s['infrastructure_errors'],
             'fresh_mission_share': (fresh.get('time') or {}).get('mission_share'),
             'warm_mission_share': (s.get('time') or {}).get('mission_share'),
             'stacks': s.get('stacks')}
        warm.append(w)
        print('%s: %.2f x the fresh rate (%.2f vs %.2f missions/min); every row equal to its fresh '
              'result: %s (%d compared); missions %.1f %% of the worker time (fresh %.1f %%); %s' % (
                  s['setting'], w['speedup'] or 0, w['warm_missions_per_minute'],
                  w['fresh_missions_per_minute'], w['all_equal'], w['runs_compared'],
                  100 * (w['warm_mission_share'] or 0), 100 * (w['fresh_mission_share'] or 0),
                  'stacks %s' % w['stacks']), flush=True)
    first = settings[0]['missions_per_minute']
    local = [s for s in settings if s['setting'] != 'Dask cluster, 2 workers'
             and s['setting'] not in fresh_of]
    best = max(local, key=lambda s: s['missions_per_minute'])
    out = {'suite': args.suite, 'run_ids': ids, 'wall_clock_fields': list(WALL_CLOCK_FIELDS),
           'settings': settings, 'best_local': best['setting'],
           'best_speedup_over_1_worker': best['missions_per_minute'] / first if first else None,
           'all_equal': all(not s.get('runs_differing_from_' + ref_name.replace(' ', '_'))
                            and s['results'] == len(ids) for s in settings)}
    if warm:
        out['warm'] = warm
    out['meta'] = meta(vars(args), real_time_factor=0.0, laser_model='per suite profile',
                       odometry_model='per suite profile')
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, 'w') as f:
        json.dump(out, f, indent=2)
    plot(settings, os.path.splitext(args.out)[0] + '.png')
    print('best: %s, %.2f x the %s rate; every run equal in every setting: %s'
          % (best['setting'], out['best_speedup_over_1_worker'] or 0, ref_name, out['all_equal']))
    print('wrote %s' % args.out)
    if not args.keep:
        shutil.rmtree(base, ignore_errors=True)
    return 0 if all(s['results'] == len(ids) for s in settings) else 1


if __name__ == '__main__':
    sys.exit(main())
