"""The evaluator's verdicts and reports: judging a raw record, infrastructure errors apart and
out of the rates, paired comparisons, junit.xml, results.csv."""
import csv
import os
import xml.etree.ElementTree as ET

import pytest

from conftest import ROOT
from tiago_nav_tools.evaluate import report, run

COURSE = os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml')
SPEC = {'id': 'abc', 'pair': 'p1', 'world': {'name': 'ias_lab_room_full', 'group': 'course'},
        'world_path': COURSE, 'goal': [11.0, 0.0, -45.0], 'profile': 'tiago', 'use_corridor_law': True,
        'seed': 1, 'candidate': 'own', 'launch_args': {},
        'limits': {'detection_tolerance': 0.05, 'sim_time_limit': 100.0}}
TRUTH = [(10.736, -1.665), (11.455, -3.794), (12.74, -2.717), (12.391, -0.607)]   # in view from B


def raw(**kw):
    r = {'state': 3, 'state_name': 'SUCCEEDED', 'status_text': '', 'message': 'arrived',
         'obstacles': [[x + 0.01, y, 0.18] for x, y in TRUTH], 'sim_s': 40.0, 'wall_s': 10.0,
         'collisions': 0, 'final_pose': [11.0, 0.0, -0.785], 'timed_out': False,
         'path': [[0.0, 0.0, 0.0], [5.0, 0.0, 0.0], [11.0, 0.0, -0.785]], 'loc_errors': [[0.01, 0.01]]}
    r.update(kw)
    return r


def test_judge_outcomes():
    r = run.judge(SPEC, raw())
    assert r['outcome'] == 'succeeded' and r['recall'] == 1.0 and r['false_positives'] == 0
    assert r['rms_error'] == pytest.approx(0.01, abs=1e-6)
    assert r['path_length_m'] == pytest.approx(11.0)
    assert r['sim_wall_ratio'] == pytest.approx(4.0)
    assert 0 < r['spl'] <= 1 and r['shortest_m'] > 10.0
    assert run.judge(SPEC, raw(obstacles=[[x, y, 0.18] for x, y in TRUTH[:3]]))['outcome'] == 'detection_failure'
    assert run.judge(SPEC, raw(obstacles=[[x, y, .18] for x, y in TRUTH] + [[8, -3, .2]]))['outcome'] \
        == 'detection_failure'
    far = run.judge(SPEC, raw(obstacles=[[x + 0.06, y, 0.18] for x, y in TRUTH]))
    assert far['outcome'] == 'detection_failure' and 'centre error' in far['reason']
    ab = run.judge(SPEC, raw(state=4, state_name='ABORTED', status_text='navigation: no path'))
    assert ab['outcome'] == 'aborted' and 'no path' in ab['reason'] and ab['spl'] == 0.0
    assert run.judge(SPEC, raw(collisions=2))['outcome'] == 'collision'
    assert run.judge(SPEC, raw(timed_out=True, state=2))['outcome'] == 'timeout'
    inf = run.judge(SPEC, {'infra': 'INFRA_CONTRACT', 'reason': 'candidate x: no service'})
    assert inf['outcome'] == 'INFRA_CONTRACT' and 'no service' in inf['reason']


def res(rid, outcome, cand='own', pair='p', **kw):
    d = {'run_id': rid, 'outcome': outcome, 'reason': outcome + ' reason', 'candidate': cand, 'pair': pair,
         'world': 'w', 'world_group': 'w', 'profile': 'tiago', 'seed': 1, 'goal': [1, 2, 3],
         'time_s': 10.0, 'run_wall_s': 2.0}
    d.update(kw)
    return d


def test_infra_errors_are_out_of_the_rates():
    rs = [res('a', 'succeeded', pair='1'), res('b', 'aborted', pair='2'), res('c', 'INFRA_LAUNCH', pair='3')]
    (g,) = report.summarise(rs)
    assert (g['runs'], g['n'], g['successes'], g['infra_errors']) == (3, 2, 1, 1)
    assert g['rate'] == 0.5


def test_paired_comparison():
    own = [res('o%d' % i, 'succeeded' if i < 6 else 'aborted', pair=str(i), time_s=10.0) for i in range(8)]
    cand = [res('c%d' % i, 'succeeded' if i in (0, 6) else 'aborted', 'x', pair=str(i), time_s=12.0)
            for i in range(8)]
    (c,) = report.compare(own + cand)
    # only the candidate: pair 6; only own: pairs 1-5
    assert (c['pairs'], c['only_candidate'], c['only_own']) == (8, 1, 5)
    assert c['mcnemar_p'] == pytest.approx(14 / 64)
    assert c['time_s_difference']['mean'] == pytest.approx(2.0)


def test_junit_and_csv(tmp_path):
    rs = [res('a', 'succeeded'), res('b', 'timeout'), res('c', 'INFRA_SCENARIO')]
    root = ET.fromstring(report.junit(rs))
    cases = root.findall('testcase')
    assert len(cases) == 3 and root.get('failures') == '1' and root.get('errors') == '1'
    assert cases[1].find('failure').get('message') == 'timeout: timeout reason'
    report.write_csv(str(tmp_path / 'r.csv'), rs)
    rows = list(csv.DictReader(open(tmp_path / 'r.csv')))
    assert [r['outcome'] for r in rows] == ['succeeded', 'timeout', 'INFRA_SCENARIO']
    assert rows[0]['success'] == '1' and rows[2]['success'] == ''
    for col in ('run_id', 'outcome', 'reason', 'world', 'seed', 'candidate', 'spl', 'barn_score'):
        assert col in rows[0]


def test_write_json_is_atomic(tmp_path):
    p = str(tmp_path / 'x.json')
    run.write_json(p, {'a': 1})
    assert run.read_json(p) == {'a': 1} and os.listdir(tmp_path) == ['x.json']
    assert run.read_json(str(tmp_path / 'none.json')) is None


def test_slots_never_shared(tmp_path):
    """Two processes never claim the same slot: the lock file is held for the process's life."""
    import subprocess
    import sys
    code = ('import sys, tempfile; sys.path.insert(0, %r); tempfile.gettempdir = lambda: %r; '
            'from tiago_nav_tools.evaluate import run; print(run.claim_slot())') % (
        os.path.join(ROOT, 'src'), str(tmp_path))
    holder = subprocess.Popen([sys.executable, '-c', code + '; sys.stdout.flush(); sys.stdin.read()'],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    first = int(holder.stdout.readline())
    second = int(subprocess.check_output([sys.executable, '-c', code], text=True))
    holder.communicate('')
    assert first != second
    assert run.port_of(second) == 12000 + 10 * second


def test_a_run_whose_last_records_did_not_come_says_so():
    """The supervisor waits END_WAIT for the mission's last records; what did not come stays in
    the result and summary.md names the run (its logs are short)."""
    assert run.judge(SPEC, raw())['end_missing'] == []
    r = dict(run.judge(SPEC, raw(end_missing=['walkers', 'base_at_rest'])), run_id='abc',
             run_wall_s=1.0)
    assert r['outcome'] == 'succeeded' and r['end_missing'] == ['walkers', 'base_at_rest']
    text = report.markdown(report.summarise([r]), [], [r], {'wall_s': 10.0, 'missions_per_minute': 1.0})
    assert '## Runs whose last records did not all come' in text
    assert '- `abc`: no walkers, base_at_rest within 10 s of the result' in text
    clean = dict(run.judge(SPEC, raw()), run_id='abc', run_wall_s=1.0)
    assert 'did not all come' not in report.markdown(report.summarise([clean]), [], [clean],
                                                     {'wall_s': 10.0, 'missions_per_minute': 1.0})
