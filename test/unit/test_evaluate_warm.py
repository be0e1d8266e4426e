"""Warm stacks without ROS: which rows share a stack (tiago_nav_tools.evaluate.warm.stack_key,
group_by_stack), the engine sending each group to one worker in order (faked runs), a row whose
reset failed run again on a fresh stack and counted, the verdict on a reset row against its
fresh run (every field but the wall-clock ones compared; different: diverged, with the fresh
run's figures) and which resets are verified, and the CPU time of a stack's processes found
by its token. test/warm_reset.test verifies real resets, and reports a planted reset fault."""
import json
import os
import subprocess
import sys

import pytest

from tiago_nav_tools.evaluate import run as R
from tiago_nav_tools.evaluate import warm as W


def spec(run_id, world='w', profile='tiago', law=True, seed=1, goal=(1.0, 0.0, 0.0), candidate='own'):
    return {'id': run_id, 'candidate': candidate, 'pair': None, 'world': {'name': world, 'group': None},
            'goal': list(goal), 'profile': profile, 'use_corridor_law': law, 'seed': seed,
            'launch_args': {'laser_model': profile},
            'limits': {'real_time_factor': 0, 'startup_timeout': 90, 'wall_time_limit': 300},
            'candidate_spec': None if candidate == 'own' else {'replaces': ['detection']}}


def test_rows_share_a_stack_when_only_seed_pose_and_corridor_law_differ():
    a = spec('a', seed=1, goal=(1, 0, 0))
    assert W.stack_key(a) == W.stack_key(spec('b', seed=2, goal=(3, 1, 90)))
    assert W.stack_key(a) == W.stack_key(spec('e', law=False))     # a goal field, not the stack's
    for other in (spec('c', world='v'), spec('d', profile='ideal')):
        assert W.stack_key(other) != W.stack_key(a)
    assert W.stack_key(spec('f', candidate='centroid')) is None     # outside nodes: no reset
    assert W.stack_key(dict(a, record=True)) is None                # a bag per run


def test_groups_keep_the_suite_order_within_a_key():
    specs = [spec('a1'), spec('b1', profile='ideal'), spec('a2', seed=2, law=False),
             spec('c', candidate='x'), spec('b2', profile='ideal', seed=2), spec('a3', seed=3),
             spec('d', candidate='x')]
    groups = [[s['id'] for s in g] for g in W.group_by_stack(specs)]
    assert groups == [['a1', 'a2', 'a3'], ['b1', 'b2'], ['c'], ['d']]


def test_the_engine_sends_each_group_to_one_worker_in_order(tmp_path, monkeypatch):
    pytest.importorskip('distributed')
    from distributed import LocalCluster
    from tiago_nav_tools.evaluate import engine
    calls = []

    def fake_group(specs, out_dir, record=False, verify_reset=0):
        calls.append(([s['id'] for s in specs], verify_reset))
        return [{'run_id': s['id'], 'candidate': s['candidate'], 'outcome': 'succeeded',
                 'stack': 'reset' if i else 'fresh'} for i, s in enumerate(specs)]
    monkeypatch.setattr(W, 'run_group', fake_group)
    cluster = LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                           dashboard_address=None, silence_logs=40)
    try:
        specs = [spec('a1'), spec('b1', profile='ideal'), spec('a2', seed=2),
                 spec('b2', profile='ideal', seed=2)]
        seen = []
        results = engine.run_all(specs, str(tmp_path), scheduler=cluster.scheduler_address,
                                 progress=seen.append, warm=True, verify_reset=3)
    finally:
        cluster.close()
    assert sorted(calls) == [(['a1', 'a2'], 3), (['b1', 'b2'], 3)]
    assert sorted(r['run_id'] for r in results) == ['a1', 'a2', 'b1', 'b2'] == sorted(r['run_id'] for r in seen)


def _result(s, **kw):
    r = {'schema': 1, 'run_id': s['id'], 'outcome': 'succeeded', 'reason': 'ok', 'time_s': 20.0,
         'path': [[0, 0, 0], [1, 0, 0]], 'wall_s': 3.0, 'cpu_s': 5.0, 'stack': 'reset',
         'found_detail': [{'center': {'x': 1.0, 'y': 2.0, 'z': 0.0},
                           'center_robot': {'x': 0.5, 'y': -0.2, 'z': 0.0}, 'radius': 0.2,
                           'num_points': 14, 'center_std': 0.01, 'radius_std': 0.0,
                           'center_covariance': [1e-4, 0.0, 0.0, 1e-4]}],
         'loc_covariance': [[1.1, 1e-4, 0.0, 0.0, 1e-4, 0.0, 1e-5]]}
    r.update(kw)
    return r


def _changed(r, path, value):
    """A deep copy of result ``r`` with the item at ``path`` (keys and indices) set to ``value``."""
    out = json.loads(json.dumps(r))
    d = out
    for k in path[:-1]:
        d = d[k]
    d[path[-1]] = value
    return out


@pytest.mark.parametrize('path, value, field', [
    (('outcome',), 'detection_failure', 'outcome'),
    (('path', 1, 1), 0.01, 'path'),
    (('found_detail', 0, 'center_std'), 0.012, 'found_detail'),
    (('found_detail', 0, 'radius_std'), float('inf'), 'found_detail'),
    (('found_detail', 0, 'center_covariance', 1), 2e-5, 'found_detail'),
    (('found_detail', 0, 'center_robot', 'x'), 0.51, 'found_detail'),
    (('loc_covariance', 0, 6), 2e-5, 'loc_covariance'),
    (('center_nees',), 1.7, 'center_nees'),         # a field the warm result lacks
])
def test_a_reset_row_that_differs_in_any_field_but_the_wall_clock_ones_diverged(path, value, field):
    s = spec('a1')
    warm = _result(s, phases={'mission': {'wall_s': 4.0, 'cpu_s': 6.0}}, attempt=1)
    fresh = _changed(_result(s, stack=None, wall_s=9.0, cpu_s=8.0, attempt=1,
                             phases={'mission': {'wall_s': 7.0, 'cpu_s': 9.0}}), path, value)
    row = W.checked(warm, fresh)
    assert row['diverged'] == [field] and row['verified'] is False
    # the row counts with the fresh run's figures, the warm run's time and its verdict kept
    assert row[field] == fresh[field] != warm.get(field)
    assert (row['wall_s'], row['cpu_s'], row['stack']) == (3.0, 5.0, 'reset')
    assert row['phases'] == {'mission': {'wall_s': 4.0, 'cpu_s': 6.0}}
    assert row['reset_result'] == {'outcome': 'succeeded', 'reason': 'ok'}
    assert row['outcome'] not in R.INFRA


def test_a_reset_row_differing_only_in_wall_clock_fields_is_verified():
    s = spec('a1')
    warm = _result(s)
    fresh = _result(s)
    verdict = ('verified', 'diverged', 'reset_result', 'verify_error')
    for i, k in enumerate(set(R.WALL_CLOCK_FIELDS) - set(verdict)):    # every other one differs
        warm[k], fresh[k] = 'warm %d' % i, {'fresh': i}
    row = W.checked(warm, fresh)
    assert row['verified'] is True and 'diverged' not in row
    assert row['outcome'] == 'succeeded' and row['stack'] == warm['stack']


def test_equal_values_numbers_to_their_last_bits_unknown_ones_too():
    inf, nan = float('inf'), float('nan')
    assert R.same([inf, nan, 1.0], [inf, nan, 1.0 + 1e-12])
    assert not R.same(nan, 0.0) and not R.same(inf, 1e300) and not R.same(1.0, 1.0 + 1e-6)
    assert not R.same({'a': 1}, {'a': 1, 'b': None})


class CountingStack:
    def __init__(self):
        self.resets, self.last = 0, None


def test_the_kth_2kth_reset_of_each_stack_is_verified(monkeypatch):
    checked_ids = []
    monkeypatch.setattr(W, 'verify', lambda sp, out, r, record=False:
                        checked_ids.append(sp['id']) or dict(r, verified=True))
    for stack_rows in (['a0', 'a1', 'a2', 'a3', 'a4', 'a5'], ['b0', 'b1', 'b2']):
        st = CountingStack()
        for i, rid in enumerate(stack_rows):
            r = _result(spec(rid), stack='reset' if i else 'fresh')
            if rid == 'a3':
                r['outcome'] = 'INFRA_NODE_DIED'        # retried on a fresh stack, not verified
            W._verify_due(spec(rid), '/nonexistent', r, False, st, 2)
    # per stack: its 2nd and 4th reset; a3 (the 3rd reset) is counted though not verified
    assert checked_ids == ['a2', 'a4', 'b2']


class FakeStack:
    """Answers like a stack whose reset fails."""

    def __init__(self, key, out_dir, first):
        self.key, self.slot, self.port, self.token, self.runs = key, 0, 12000, 'fake', 0
        self.resets = 0
        self.dir = out_dir
        self.closed = False
        self.isolation, self.last = 'loopback', None

    def alive(self):
        return not self.closed

    def send(self, run_dir, timeout):
        return {'run_dir': run_dir, 'reset': 'reset', 'failed': 'reset',
                'reason': '/move_base/reset/start: start failed: no map'}

    def close(self):
        self.closed = True


def test_a_row_whose_reset_failed_runs_on_a_fresh_stack_and_says_so(tmp_path, monkeypatch):
    monkeypatch.setattr(W, 'Stack', FakeStack)
    monkeypatch.setattr(W, 'tree_cpu', lambda token: 0.0)
    fresh = []

    def execute(sp, out, record=False, attempt=1):
        fresh.append(sp['id'])
        return _result(sp, stack=None)
    monkeypatch.setattr(R, 'execute', execute)
    s = spec('a2', seed=2)
    r = W.execute_warm(s, str(tmp_path))
    assert fresh == ['a2'] and r['outcome'] == 'succeeded'
    assert r['reset_failed'] == '/move_base/reset/start: start failed: no map'
    assert W._WORKER['stack'] is None           # the stack was ended
    assert 'reset_failed' in R.WALL_CLOCK_FIELDS


class AnsweringStack(FakeStack):
    """Answers like a stack that ran the row: its stage marks (the time, the stack's CPU so
    far) and raw.json written, the stack's CPU at 10 s before the row and 16 s after."""

    def send(self, run_dir, timeout):
        import time
        t = time.monotonic()
        with open(os.path.join(run_dir, 'stages'), 'w') as f:
            f.write('reset %.6f 10.5\nmission %.6f 12.0\nteardown %.6f 15.0\ndone %.6f 15.5\n'
                    % (t, t + 0.2, t + 0.9, t + 1.0))
        with open(os.path.join(run_dir, 'raw.json'), 'w') as f:
            json.dump({'schema': 1, 'id': os.path.basename(run_dir)}, f)
        CPU['now'] = 16.0
        return {'run_dir': run_dir, 'reset': 'reset', 'failed': None}


CPU = {'now': 10.0}


def test_a_warm_row_has_its_isolation_and_phases_counted_from_its_start(tmp_path, monkeypatch):
    monkeypatch.setattr(W, 'Stack', AnsweringStack)
    CPU['now'] = 10.0
    monkeypatch.setattr(W, 'tree_cpu', lambda token: CPU['now'])
    monkeypatch.setattr(R, 'judge', lambda full, raw: {'run_id': full['id'], 'outcome': 'succeeded'})
    W._WORKER['stack'] = AnsweringStack(W.stack_key(spec('a1')), str(tmp_path), None)
    W._WORKER['stack'].isolation = 'netns'
    r = W.execute_warm(spec('a2', seed=2), str(tmp_path))
    assert r['isolation'] == 'netns' and r['stack'] == 'reset' and r['cpu_s'] == 6.0
    p = r['phases']
    # CPU from the row's start (10 s): to the mission 2 s, the mission 3 s, after it 1 s
    assert (p['startup']['cpu_s'], p['mission']['cpu_s'], p['teardown']['cpu_s']) == (2.0, 3.0, 1.0)
    assert p['mission']['wall_s'] == pytest.approx(0.7, abs=1e-3)
    assert p['judging']['wall_s'] >= 0
    # ending the stack counts in the teardown of the last row it answered, on disk too
    before = p['teardown']['wall_s']
    clock = FakeClock()
    monkeypatch.setattr(W, 'time', clock)
    monkeypatch.setattr(AnsweringStack, 'close', lambda self: clock.advance(2.5))
    W.close_stack()
    on_disk = json.loads((tmp_path / 'runs' / 'a2' / 'result.json').read_text())
    assert on_disk['phases']['teardown']['wall_s'] == pytest.approx(before + 2.5, abs=1e-9)


class FakeClock:
    """``time`` for :mod:`tiago_nav_tools.evaluate.warm`: its monotonic clock moves when told."""

    def __init__(self):
        self.now = 1000.0

    def monotonic(self):
        return self.now

    def advance(self, dt):
        self.now += dt


def test_a_new_stack_is_isolated_as_a_fresh_run(tmp_path, monkeypatch):
    from tiago_nav_tools.evaluate import isolation as iso
    started = []

    class Proc:
        pid = 1

    monkeypatch.setattr(W.subprocess, 'Popen', lambda cmd, **kw: started.append(cmd) or Proc())
    monkeypatch.setattr(iso, '_PROBED', {'prefix': ['unshare', '-n'], 'why': ''})
    monkeypatch.setattr(R, 'claim_slot', lambda: 3)
    st = W.Stack('k', str(tmp_path), dict(spec('a1'), isolation='netns'))
    assert st.isolation == 'netns' and started[-1][:2] == ['unshare', '-n']
    assert started[-1][-2:] == ['tiago_nav_tools.evaluate.warm_supervisor', st.dir]
    st = W.Stack('k', str(tmp_path), dict(spec('a1'), isolation='loopback'))
    assert st.isolation == 'loopback' and started[-1][0] == sys.executable


def test_the_summary_says_how_the_warm_runs_got_their_stack(tmp_path):
    from tiago_nav_tools.evaluate import report
    ph = {k: {'wall_s': 1.0, 'cpu_s': 1.0} for k in ('startup', 'mission', 'teardown', 'judging')}
    rs = [{'run_id': 'a', 'stack': 'fresh', 'isolation': 'netns', 'phases': dict(ph, startup={'wall_s': 4.0, 'cpu_s': 3.0})},
          {'run_id': 'b', 'stack': 'reset', 'isolation': 'netns', 'phases': ph, 'verified': True},
          {'run_id': 'c', 'stack': 'fresh', 'isolation': 'netns', 'phases': ph, 'reset_failed': 'x'},
          {'run_id': 'd', 'stack': 'reset', 'isolation': 'netns', 'phases': ph, 'verified': False,
           'outcome': 'succeeded', 'diverged': ['loc_covariance', 'path'],
           'reset_result': {'outcome': 'collision', 'reason': '1 contact'}},
          {'run_id': 'e', 'stack': 'reset', 'isolation': 'netns', 'phases': ph, 'verified': None,
           'outcome': 'succeeded', 'verify_error': 'the fresh run ended in INFRA_LAUNCH twice'}]
    w = report.stacks(rs)
    assert (w['fresh'], w['reset'], w['reset_failed']) == (2, 3, 1)
    assert (w['checked'], w['verified'], w['diverged'], w['verify_errors']) == (3, 1, 1, 1)
    assert w['diverged_runs'] == ['d']
    assert w['startup_reset_s'] == 1.0 and w['startup_fresh_s'] == 2.5
    md = report.divergence_lines(rs)
    assert '1 reset run differs from a fresh stack\'s run of the same row, 1 could not be checked' in ' '.join(md)
    assert '- `d`: after the reset collision, fresh succeeded; differs in loc_covariance, path' in md
    assert report.divergence_lines(rs[:3]) == []
    assert report.stacks([{'run_id': 'a'}]) is None
    meta = {'isolation': report.isolations(rs), 'stacks': w,
            'time': __import__('tiago_nav_tools.evaluate.timing', fromlist=['batch']).batch(rs, 10.0, 1)}
    text = '\n'.join(report.isolation_lines(meta) + report.time_lines(rs, meta))
    assert 'each stack (master and nodes) in a network namespace of its own' in text
    assert 'Warm stacks: 3 runs after a reset (median start-up 1.00 s), 2 on a stack' in text
    assert '1 rerun on a fresh stack after a failed reset; 3 reset runs checked against a fresh ' \
           'stack: 1 equal, 1 diverged, 1 not verified' in text


def test_tree_cpu_counts_the_processes_carrying_the_token():
    env = dict(os.environ, **{R.TOKEN_VAR: 'cpu-test'})
    # the child says when it has burnt its 0.3 s of CPU; on a loaded machine that can take
    # any wall time, so the test waits for the child's word, not for a wall-clock deadline
    p = subprocess.Popen([sys.executable, '-c', 'import sys, time\nt = time.process_time()\n'
                          'while time.process_time() - t < 0.3: pass\n'
                          'print("burnt", flush=True)\nsys.stdin.read()'],
                         env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == 'burnt'
        assert W.tree_cpu('cpu-test') >= 0.25
        assert W.tree_cpu('no-such-token') == 0
    finally:
        p.kill()
        p.wait()


def test_benchmarks_page_shows_warm_against_fresh():
    from tiago_nav_tools import benchmarks
    w = {'workers': 2, 'fresh': '2 workers', 'warm': '2 workers, warm',
         'fresh_missions_per_minute': 12.5, 'warm_missions_per_minute': 31.0, 'speedup': 2.48,
         'runs_compared': 4, 'runs_differing': {'x': ['path']}, 'all_equal': False,
         'infrastructure_errors': 0, 'fresh_mission_share': 0.2, 'warm_mission_share': 0.61,
         'stacks': {'reset': 2}}
    text = '\n'.join(benchmarks.render_evaluate({'run_ids': ['a'], 'suite': 's.yaml', 'settings': [],
                                                 'warm': [w]}))
    assert 'Warm stacks (`evaluate --warm`) against fresh ones on the same rows' in text
    assert '| 2 | 12.5 | 31 | 2.48 | 3 of 4 | 0 | 20.0 % | 61.0 % | 2 |' in text, text
    assert 'Warm stacks' not in '\n'.join(benchmarks.render_evaluate({'settings': []}))


def test_benchmarks_page_holds_each_setting_to_the_first():
    """A warm-only run of the benchmark (2 workers fresh, then warm) compares with its first
    setting, not with a 1-worker one it did not run, and claims no best local setting."""
    from tiago_nav_tools import benchmarks
    s = [{'setting': '2 workers', 'results': 3, 'runs': 3},
         {'setting': '2 workers, warm', 'results': 3, 'runs': 3, 'runs_compared': 3,
          'runs_differing_from_2_workers': {'b': ['path']}}]
    text = '\n'.join(benchmarks.render_evaluate({'run_ids': ['a', 'b', 'c'], 'suite': 's.yaml',
                                                 'settings': s}))
    assert '| rows differing from 2 workers |' in text, text
    assert '| 2 workers, warm | 3/3 |' in text and '| 1 of 3 |' in text, text
    assert 'Best local setting' not in text


def test_bench_picks_rows_in_whole_stack_groups():
    import importlib.util
    from conftest import ROOT
    from tiago_nav_tools.evaluate import suite
    path = os.path.join(ROOT, 'bench', 'bench_evaluate.py')
    spec_ = importlib.util.spec_from_file_location('bench_evaluate', path)
    B = importlib.util.module_from_spec(spec_)
    spec_.loader.exec_module(B)
    course = os.path.join(ROOT, 'suites', 'course.yaml')
    data, base = suite.load(course)
    runs, _ = suite.expand(data, course, base)
    key = {r['id']: W.stack_key(r) for r in runs}
    ids = B.pick_stacks(course, 4, 2)
    assert len(set(ids)) == 4 and sorted(collections_count(key[i] for i in ids)) == [2, 2]
    assert B.pick_stacks(course, len(runs)) == [r['id'] for r in runs]
    ids = B.pick_stacks(course, 20, 3)
    assert len(set(ids)) == 20 and len({key[i] for i in ids}) == 7     # 3 rows a key, 7 keys


def collections_count(values):
    import collections
    return list(collections.Counter(values).values())
