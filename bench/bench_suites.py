#!/usr/bin/python3
"""Shipped suites benchmark: every run of ``suites/course.yaml`` (204 runs: the course world and
twelve generated worlds of its class) and ``suites/robustness.yaml`` (96 runs: a start inside a
corridor, a 20 m corridor, bends of 30 to 90 deg, a cluttered room) through ``rosrun tiago_nav
evaluate`` as a user runs it, both sensing profiles, corridor law on and off, three seeds.
Reports per suite the success rate (with its Wilson 95 % interval) against the target of at
least 99 %, per world group, profile, corridor setting and candidate the successes, the least
clearance, the worst localisation p95 and centre RMS, and every run that did not succeed with
its reason.
Writes bench/results/suites.json.

``--from SUITE=DIR`` reads an evaluate output folder of that suite instead of running it: each
run is judged again from its raw record (``runs/ID/raw.json``) with the current metrics
(``tiago_nav_tools.evaluate.run.judge``), as the evaluator would judge it now (the wall time is
the one the evaluator wrote in the folder's summary.json).

``--suites suites/people.yaml --out bench/results/suites_people.json``: the people suite (204
runs among walkers and furniture, two detections); its JSON adds per profile and candidate the
people figures (``people``: tiago_nav_tools.evaluate.report.people_summary).

``--suites suites/people_move_base.yaml --requires move_base --out
bench/results/suites_people_move_base.json``: ROS's move_base among the walkers beside the own
navigation (48 runs at real time); it needs move_base built (bench/move_base/build.sh) and its
workspace sourced on top of the package's, else it says so and exits 0.

Every suite is judged under two rules of "in view" (tiago_nav_tools.evaluate.inview): the evaluator's
(at least MIN_BEAMS = 7 usable beams of the noise-free cast hit the obstacle) and a plain one
(at least PLAIN_BEAMS = 5, detection's smallest cluster). Each rule's success rate, detection
totals (in view, glimpsed, found, missed, false positives, centre errors of every matched
obstacle) and not-succeeded runs land in the JSON (``rules``); the runs whose outcome differs
between the two are listed apart (``rules_differ``).

Usage: bench/bench_suites.py [--suites suites/course.yaml suites/robustness.yaml] [--workers 2]
                             [--from SUITE=DIR ...] [--keep DIR] [--requires PACKAGE ...]
"""
import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, 'bench', 'results')
SUITES = ('suites/course.yaml', 'suites/robustness.yaml')
TARGET = 0.99           # success rate per suite

sys.path.insert(0, os.path.join(ROOT, 'src'))
from tiago_nav_tools.benchmarks import meta  # noqa: E402
from tiago_nav_tools.evaluate import metrics as M  # noqa: E402
from tiago_nav_tools.evaluate.report import detection_totals, people_summary  # noqa: E402
from tiago_nav_tools.evaluate.run import judge, read_json  # noqa: E402
from tiago_nav_tools.evaluate.inview import MIN_BEAMS, PLAIN_BEAMS  # noqa: E402
from tiago_nav_tools.evaluate.suite import DEFAULTS, load  # noqa: E402

RULES = (('evaluator', MIN_BEAMS), ('plain', PLAIN_BEAMS))   # name, usable beams for "in view"


def run_suite(suite, out, workers):
    """``rosrun tiago_nav evaluate SUITE --out OUT --workers N``: wall seconds (raises when the
    evaluator says a run has no result)."""
    t0 = time.monotonic()
    cmd = ['rosrun', 'tiago_nav', 'evaluate', suite, '--out', out, '--workers', str(workers)]
    p = subprocess.Popen(cmd, cwd=ROOT)
    try:
        rc = p.wait()
    finally:    # this benchmark stopped (Ctrl-C, SIGTERM): the evaluator and its runs stop too
        if p.poll() is None:
            p.terminate()
            try:
                p.wait(60.0)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
    if rc:
        raise subprocess.CalledProcessError(rc, cmd)
    return time.monotonic() - t0


def judged(out, min_beams=None):
    """Every run of an evaluate output folder, judged from its spec and raw record with the
    current metrics, "in view" meaning at least ``min_beams`` usable beams (None: the
    evaluator's rule) (its ``result.json`` where there is no raw record: an infrastructure
    error)."""
    runs = os.path.join(out, 'runs')
    res = []
    for rid in sorted(os.listdir(runs)):
        d = os.path.join(runs, rid)
        try:
            with open(os.path.join(d, 'spec.json')) as f:
                spec = json.load(f)
            with open(os.path.join(d, 'raw.json')) as f:
                raw = json.load(f)
            res.append(judge(spec, raw, min_beams))
        except (OSError, ValueError):
            with open(os.path.join(d, 'result.json')) as f:
                res.append(json.load(f))
    return res


def _worst(values, fn):
    v = [x for x in values if x is not None]
    return round(float(fn(v)), 4) if v else None


def summarise(results):
    """The figures of one suite's results (result dicts)."""
    n = len(results)
    ok = sum(1 for r in results if r['outcome'] == 'succeeded')
    lo, hi = M.wilson(ok, n)
    groups = {}
    for r in results:
        key = (r.get('world_group') or r['world'], r['profile'], bool(r['use_corridor_law']),
               r.get('candidate') or 'own')
        groups.setdefault(key, []).append(r)
    rows = []
    for (group, profile, law, cand), rs in sorted(groups.items()):
        rows.append({'group': group, 'profile': profile, 'corridor_law': law, 'candidate': cand,
                     'runs': len(rs),
                     'succeeded': sum(1 for r in rs if r['outcome'] == 'succeeded'),
                     'collisions': sum(int(r.get('collisions') or 0) for r in rs),
                     'min_clearance_m': _worst([r.get('min_clearance_m') for r in rs], min),
                     'loc_error_p95_m_max': _worst([r.get('loc_error_p95_m') for r in rs], max),
                     'rms_error_m_max': _worst([r.get('rms_error') for r in rs], max)})
    failures = [{k: r.get(k) for k in ('run_id', 'world', 'world_group', 'profile',
                                        'use_corridor_law', 'seed', 'candidate', 'goal',
                                        'outcome', 'reason')}
                for r in results if r['outcome'] != 'succeeded']
    return {'runs': n, 'succeeded': ok, 'rate': round(ok / n, 4) if n else None,
            'wilson_95': [round(lo, 4), round(hi, 4)],
            'collisions': sum(int(r.get('collisions') or 0) for r in results),
            'groups': rows, 'people': people_summary(results), 'not_succeeded': failures}


def rule_figures(results, min_beams):
    """One rule's figures: success rate with its Wilson interval, the detection totals
    (:func:`tiago_nav_tools.evaluate.report.detection_totals`, per profile) and the runs that did not
    succeed."""
    s = summarise(results)
    det = detection_totals(results)
    for t in det.values():
        for k in ('rms_error', 'max_error', 'rms_error_glimpsed', 'max_error_glimpsed'):
            t[k] = round(t[k], 4) if t[k] is not None else None
    return {'min_usable_beams': min_beams, 'runs': s['runs'], 'succeeded': s['succeeded'],
            'rate': s['rate'], 'wilson_95': s['wilson_95'], 'detection': det,
            'not_succeeded': s['not_succeeded']}


def differ(by_rule):
    """The runs whose outcome differs between the rules: ``{'run_id', rule: [outcome,
    reason]}``."""
    names = [name for name, _ in RULES]
    outs = {name: {r['run_id']: r for r in by_rule[name]} for name in names}
    rows = []
    for rid in sorted(outs[names[0]]):
        got = [outs[name].get(rid) or {} for name in names]
        if len({g.get('outcome') for g in got}) > 1:
            d = {'run_id': rid}
            d.update({name: [g.get('outcome'), g.get('reason')] for name, g in zip(names, got)})
            rows.append(d)
    return rows


def suite_rtf(path):
    """The real-time factor a suite file's runs use (its defaults, else the evaluator's)."""
    data, _ = load(path)
    return (data.get('defaults') or {}).get('real_time_factor', DEFAULTS['real_time_factor'])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--suites', nargs='+', default=list(SUITES))
    ap.add_argument('--workers', type=int, default=2)
    ap.add_argument('--from', dest='sources', nargs='+', default=[], metavar='SUITE=DIR',
                    help='judge an existing evaluate output folder of SUITE instead of running it')
    ap.add_argument('--keep', help='write the evaluate output folders here (default: a temporary '
                                   'folder, removed)')
    ap.add_argument('--out', default=os.path.join(RESULTS, 'suites.json'))
    ap.add_argument('--requires', nargs='+', default=[], metavar='PACKAGE',
                    help='ROS packages a candidate runs (not this package\'s dependencies): '
                         'when one is not found, say so and exit 0, leaving --out as it is')
    args = ap.parse_args()
    missing = [p for p in args.requires
               if subprocess.call(['rospack', 'find', p], stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL)]
    if missing:
        print('skipped %s: ROS package(s) %s not found (bench/move_base/build.sh builds move_base; '
              'source its workspace); %s left as it is'
              % (' '.join(args.suites), ', '.join(missing), args.out))
        return 0
    signal.signal(signal.SIGTERM, lambda signum, _frame: sys.exit(128 + signum))
    sources = dict(s.split('=', 1) for s in args.sources)
    tmp = args.keep or tempfile.mkdtemp(prefix='bench_suites_')
    out = {'target_rate': TARGET, 'suites': {}}
    try:
        for suite in args.suites:
            name = os.path.splitext(os.path.basename(suite))[0]
            folder = sources.get(suite)
            wall = None
            if folder is None:
                folder = os.path.join(tmp, name)
                wall = run_suite(suite, folder, args.workers)
            else:       # the evaluator's own wall time of that folder's batch, if it says
                wall = ((read_json(os.path.join(folder, 'summary.json')) or {}).get('meta')
                        or {}).get('wall_s')
            by_rule = {rule: judged(folder, beams) for rule, beams in RULES}
            s = summarise(by_rule[RULES[0][0]])
            s['rules'] = {rule: rule_figures(by_rule[rule], beams) for rule, beams in RULES}
            s['rules_differ'] = differ(by_rule)
            s['suite'] = suite
            s['wall_s'] = round(wall, 1) if wall is not None else None
            s['missions_per_minute'] = round(60.0 * s['runs'] / wall, 2) if wall else None
            out['suites'][name] = s
            print('%s: %d runs, %d succeeded (%.1f %%, Wilson %.1f-%.1f %%), %d collisions'
                  % (suite, s['runs'], s['succeeded'], 100 * s['rate'], 100 * s['wilson_95'][0],
                     100 * s['wilson_95'][1], s['collisions']), flush=True)
            for f in s['not_succeeded']:
                print('  %s %s %s law %s seed %s: %s: %s' % (
                    f['run_id'], f['world'], f['profile'], f['use_corridor_law'], f['seed'],
                    f['outcome'], f['reason']), flush=True)
            for rule, fig in s['rules'].items():
                print('  rule %s (>= %d usable beams): %d/%d succeeded (%.1f %%)' % (
                    rule, fig['min_usable_beams'], fig['succeeded'], fig['runs'],
                    100 * (fig['rate'] or 0)), flush=True)
            for d in s['rules_differ']:
                print('  differs: %s: %s' % (d['run_id'], '; '.join(
                    '%s %s (%s)' % (rule, d[rule][0], d[rule][1]) for rule, _ in RULES)))
    finally:
        if not args.keep:
            shutil.rmtree(tmp, ignore_errors=True)
    out['met'] = {name: s['rate'] is not None and s['rate'] >= TARGET
                  for name, s in out['suites'].items()}
    out['met_plain'] = {name: s['rules']['plain']['rate'] is not None
                        and s['rules']['plain']['rate'] >= TARGET
                        for name, s in out['suites'].items()}
    rtf = sorted({suite_rtf(path) for path in args.suites})
    out['meta'] = meta(vars(args), real_time_factor=rtf[0] if len(rtf) == 1 else rtf,
                       laser_model='tiago and ideal', odometry_model='drift and ideal')
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, 'w') as f:
        json.dump(out, f, indent=1)
    print('wrote %s; target (>= %.0f %% per suite) met: %s; under the plain rule: %s'
          % (args.out, 100 * TARGET, out['met'], out['met_plain']))
    return 0 if all(out['met'].values()) and all(out['met_plain'].values()) else 1


if __name__ == '__main__':
    sys.exit(main())
