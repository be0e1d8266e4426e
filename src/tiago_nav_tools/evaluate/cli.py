"""``rosrun tiago_nav evaluate SUITE.yaml --out DIR [--workers N] [--scheduler ADDR] [--resume]
[--dry-run] [--only ID ...] [--record] [--isolation auto|netns|loopback] [--warm [--verify-reset K]]``:
the batch evaluator (docs/evaluation.md).

Exit 0 when every run ended (whatever its outcome), 1 when a run has no result, 2 for a bad
suite file or argument (the message names the file, the field and the reason), 3 when a row
checked by ``--verify-reset`` diverged from its fresh run, or could not be checked (every
run has a result otherwise).
"""
import argparse
import os
import sys
import time

EXIT_OK, EXIT_MISSING, EXIT_USAGE, EXIT_DIVERGED = 0, 1, 2, 3


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        self.print_usage(sys.stderr)
        sys.stderr.write('evaluate: error: %s\n' % message)
        sys.exit(EXIT_USAGE)


def parse_args(argv):
    ap = _Parser(prog='evaluate', description=__doc__.split('\n\n')[0],
                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('suite', help='suite file (YAML, docs/evaluation.md)')
    ap.add_argument('--out', required=True, help='output folder')
    ap.add_argument('--workers', type=int, default=None,
                    help='local Dask workers (default: the number of cores)')
    ap.add_argument('--scheduler', help='address of an existing Dask scheduler, tcp://HOST:8786')
    ap.add_argument('--resume', action='store_true', help='skip runs that already have a result')
    ap.add_argument('--dry-run', action='store_true', help='list the runs and exit')
    ap.add_argument('--only', nargs='+', metavar='RUN_ID', help='only these runs (ids or unique prefixes)')
    ap.add_argument('--record', action='store_true', help='record a bag per run (rosbag)')
    ap.add_argument('--isolation', choices=('auto', 'netns', 'loopback'), default='auto',
                    help='netns: each run in a network namespace of its own with only loopback; '
                         'loopback: the host network, loopback addresses and a port per worker; '
                         'auto (default): netns where the machine allows it')
    ap.add_argument('--warm', action='store_true',
                    help='run the rows that share world, profile and candidate on '
                         'one stack per worker, reset between rows')
    ap.add_argument('--verify-reset', type=int, default=0, metavar='K',
                    help='with --warm: run the K-th, 2K-th ... reset row of each stack again on a '
                         'fresh stack and compare; a difference (a diverged reset) is counted in '
                         'the summary and makes the exit status 3')
    a = ap.parse_args(argv)
    if a.workers is not None and a.workers < 1:
        ap.error('--workers: must be >= 1, got %d' % a.workers)
    if a.verify_reset < 0:
        ap.error('--verify-reset: must be >= 0, got %d' % a.verify_reset)
    if a.verify_reset and not a.warm:
        ap.error('--verify-reset needs --warm')
    if a.scheduler and a.workers is not None:
        ap.error('--workers and --scheduler exclude each other (the cluster has its workers)')
    return a


def describe(r):
    return '%s  %-22s B=(%6.2f, %6.2f, %6.1f)  %-7s law=%-5s seed=%-3d %s' % (
        r['id'], r['world']['name'][:22], r['goal'][0], r['goal'][1], r['goal'][2], r['profile'],
        'on' if r['use_corridor_law'] else 'off', r['seed'], r['candidate'])


def select(runs, only, path):
    from tiago_nav_tools.evaluate.suite import SuiteError
    out = []
    for o in only:
        hits = [r for r in runs if r['id'].startswith(o)]
        if len(hits) != 1:
            raise SuiteError(path, '--only', '%r matches %d runs' % (o, len(hits)))
        out += hits
    return out


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    a = parse_args(argv)
    from tiago_nav_tools.evaluate import report
    from tiago_nav_tools.evaluate.run import read_json
    from tiago_nav_tools.evaluate.suite import SuiteError, expand, load
    try:
        data, base = load(a.suite)
        runs, generated = expand(data, a.suite, base)
        if a.only:
            runs = select(runs, a.only, a.suite)
    except SuiteError as e:
        sys.stderr.write('evaluate: %s\n' % e)
        return EXIT_USAGE
    if a.dry_run:
        for r in runs:
            print(describe(r))
        print('%d runs' % len(runs))
        return EXIT_OK
    from tiago_nav_tools.evaluate.isolation import IsolationError, resolve
    try:        # on a cluster of its own, each worker resolves 'auto' for its machine
        isolation = a.isolation if a.scheduler and a.isolation == 'auto' else resolve(a.isolation)
    except IsolationError as e:
        sys.stderr.write('evaluate: --isolation %s: %s; use --isolation loopback or auto\n'
                         % (a.isolation, e))
        return EXIT_USAGE
    out = os.path.abspath(a.out)
    os.makedirs(os.path.join(out, 'worlds'), exist_ok=True)
    import yaml
    for name, d in generated.items():
        with open(os.path.join(out, 'worlds', name + '.yaml'), 'w') as f:
            yaml.safe_dump(d, f, sort_keys=False)
    todo, done = [], []
    for r in runs:
        old = read_json(os.path.join(out, 'runs', r['id'], 'result.json')) if a.resume else None
        (done if old is not None and old.get('outcome') else todo).append(r)
    report.write_manifest(out, a.suite, data, runs, vars(a))
    print('evaluate: %d runs (%d to do, %d done before), isolation %s -> %s'
          % (len(runs), len(todo), len(done), isolation, out), flush=True)
    state = {'done': 0, 'failed': 0, 't0': time.monotonic()}

    def progress(res):
        state['done'] += 1
        if res.get('outcome') != 'succeeded':
            state['failed'] += 1
        n = state['done']
        el = time.monotonic() - state['t0']
        eta = el / n * (len(todo) - n)
        print('[%d/%d] done %d, not succeeded %d, remaining %d, ETA %.0f s | %s %s%s %s' % (
            n, len(todo), n, state['failed'], len(todo) - n, eta, res.get('run_id'),
            res.get('outcome'), ' (reset diverged)' if res.get('diverged') else '',
            (res.get('reason') or '')[:100]), flush=True)
    if todo:
        from tiago_nav_tools.evaluate.engine import run_all
        run_all([dict(r, isolation=isolation) for r in todo], out, workers=a.workers,
                scheduler=a.scheduler, record=a.record, progress=progress, warm=a.warm,
                verify_reset=a.verify_reset)
    results, missing = [], []
    for r in runs:
        res = read_json(os.path.join(out, 'runs', r['id'], 'result.json'))
        if res is None or not res.get('outcome'):
            missing.append(r['id'])
            res = {'run_id': r['id'], 'outcome': 'NO_RESULT', 'reason': 'the run has no result file',
                   'world': r['world']['name'], 'world_group': r['world'].get('group'),
                   'profile': r['profile'], 'candidate': r['candidate'], 'seed': r['seed'],
                   'goal': r['goal'], 'use_corridor_law': r['use_corridor_law'], 'pair': r['pair']}
        results.append(res)
    summary = report.write_all(out, runs, results, wall_s=time.monotonic() - state['t0'],
                               workers=a.workers, scheduler=a.scheduler)
    print(summary)
    refreshed = [r['run_id'] for r in results if r.get('reset_failed')]
    if refreshed:
        print('evaluate: %d run(s) ran on a fresh stack after their warm stack\'s reset failed: %s'
              % (len(refreshed), ' '.join(refreshed)))
    diverged = [r for r in results if r.get('diverged')]
    for r in diverged:
        print('evaluate: run %s: its result after a reset (%s) differs from a fresh stack\'s (%s) in '
              '%s; the row has the fresh result' % (r['run_id'], (r.get('reset_result') or {}).get('outcome'),
                                                    r.get('outcome'), ', '.join(r['diverged'])))
    unchecked = [r for r in results if r.get('verify_error')]
    for r in unchecked:
        print('evaluate: run %s: not verified: %s' % (r['run_id'], r['verify_error']))
    if missing:
        print('evaluate: %d run(s) without a result: %s' % (len(missing), ' '.join(missing)))
        return EXIT_MISSING
    if diverged or unchecked:
        print('evaluate: %d reset(s) diverged from a fresh stack, %d could not be verified'
              % (len(diverged), len(unchecked)))
        return EXIT_DIVERGED
    return EXIT_OK
