"""Warm stacks without ROS: which rows share a stack (tiago_nav.evaluate.warm.stack_key,
group_by_stack), the engine sending each group to one worker in order (faked runs), a row whose
reset failed run again on a fresh stack and counted, the verification of a reset row against a
fresh stack (equal: verified; different: INFRA_RESET naming the fields), and the CPU time of a
stack's processes found by its token."""
import json
import os
import subprocess
import sys

import pytest

from tiago_nav.evaluate import run as R
from tiago_nav.evaluate import warm as W


def spec(run_id, world='w', profile='tiago', law=True, seed=1, goal=(1.0, 0.0, 0.0), candidate='own'):
    return {'id': run_id, 'candidate': candidate, 'pair': None, 'world': {'name': world, 'group': None},
            'goal': list(goal), 'profile': profile, 'use_corridor_law': law, 'seed': seed,
            'launch_args': {'laser_model': profile},
            'limits': {'real_time_factor': 0, 'startup_timeout': 90, 'wall_time_limit': 300},
            'candidate_spec': None if candidate == 'own' else {'replaces': ['detection']}}


def test_rows_share_a_stack_when_only_seed_and_pose_differ():
    a = spec('a', seed=1, goal=(1, 0, 0))
    assert W.stack_key(a) == W.stack_key(spec('b', seed=2, goal=(3, 1, 90)))
    for other in (spec('c', world='v'), spec('d', profile='ideal'), spec('e', law=False)):
        assert W.stack_key(other) != W.stack_key(a)
    assert W.stack_key(spec('f', candidate='centroid')) is None     # outside nodes: no reset
    assert W.stack_key(dict(a, record=True)) is None                # a bag per run


def test_groups_keep_the_suite_order_within_a_key():
    specs = [spec('a1'), spec('b1', law=False), spec('a2', seed=2), spec('c', candidate='x'),
             spec('b2', law=False, seed=2), spec('a3', seed=3), spec('d', candidate='x')]
    groups = [[s['id'] for s in g] for g in W.group_by_stack(specs)]
    assert groups == [['a1', 'a2', 'a3'], ['b1', 'b2'], ['c'], ['d']]


def test_the_engine_sends_each_group_to_one_worker_in_order(tmp_path, monkeypatch):
    pytest.importorskip('distributed')
    from distributed import LocalCluster
    from tiago_nav.evaluate import engine
    calls = []

    def fake_group(specs, out_dir, record=False, verify_reset=0):
        calls.append(([s['id'] for s in specs], verify_reset))
        return [{'run_id': s['id'], 'candidate': s['candidate'], 'outcome': 'succeeded',
                 'stack': 'reset' if i else 'fresh'} for i, s in enumerate(specs)]
    monkeypatch.setattr(W, 'run_group', fake_group)
    cluster = LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                           dashboard_address=None, silence_logs=40)
    try:
        specs = [spec('a1'), spec('b1', law=False), spec('a2', seed=2), spec('b2', law=False, seed=2)]
        seen = []
        results = engine.run_all(specs, str(tmp_path), scheduler=cluster.scheduler_address,
                                 progress=seen.append, warm=True, verify_reset=3)
    finally:
        cluster.close()
    assert sorted(calls) == [(['a1', 'a2'], 3), (['b1', 'b2'], 3)]
    assert sorted(r['run_id'] for r in results) == ['a1', 'a2', 'b1', 'b2'] == sorted(r['run_id'] for r in seen)


def _result(s, **kw):
    r = {'schema': 1, 'run_id': s['id'], 'outcome': 'succeeded', 'reason': 'ok', 'time_s': 20.0,
         'path': [[0, 0, 0], [1, 0, 0]], 'wall_s': 3.0, 'cpu_s': 5.0, 'stack': 'reset'}
    r.update(kw)
    return r


def test_a_verified_reset_row_equal_to_its_fresh_run(tmp_path, monkeypatch):
    s = spec('a1')
    os.makedirs(tmp_path / 'runs' / 'a1')
    monkeypatch.setattr(R, 'execute', lambda sp, out, record=False, attempt=1:
                        _result(sp, stack=None, wall_s=9.0, cpu_s=8.0))
    out = W.verify(s, str(tmp_path), _result(s))
    assert out['outcome'] == 'succeeded' and out['verified'] is True
    assert json.loads((tmp_path / 'runs' / 'a1' / 'result.json').read_text())['verified'] is True


def test_a_reset_row_that_differs_from_its_fresh_run_is_an_infrastructure_error(tmp_path, monkeypatch):
    s = spec('a1')
    os.makedirs(tmp_path / 'runs' / 'a1')
    monkeypatch.setattr(R, 'execute', lambda sp, out, record=False, attempt=1:
                        _result(sp, time_s=20.1, path=[[0, 0, 0], [1, 0.01, 0]]))
    out = W.verify(s, str(tmp_path), _result(s))
    assert out['outcome'] == 'INFRA_RESET' and 'INFRA_RESET' in R.INFRA
    assert 'path, time_s' in out['reason'] and out['reset_outcome'] == 'succeeded'


class FakeStack:
    """Answers like a stack whose reset fails."""

    def __init__(self, key, out_dir, first):
        self.key, self.slot, self.port, self.token, self.runs = key, 0, 12000, 'fake', 0
        self.dir = out_dir
        self.closed = False

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


def test_tree_cpu_counts_the_processes_carrying_the_token():
    env = dict(os.environ, **{R.TOKEN_VAR: 'cpu-test'})
    p = subprocess.Popen([sys.executable, '-c', 'import time\nt = time.process_time()\n'
                          'while time.process_time() - t < 0.3: pass\ntime.sleep(30)'], env=env)
    try:
        import time
        end = time.monotonic() + 10
        while W.tree_cpu('cpu-test') < 0.25 and time.monotonic() < end:
            time.sleep(0.05)
        assert W.tree_cpu('cpu-test') >= 0.25
        assert W.tree_cpu('no-such-token') == 0
    finally:
        p.kill()
        p.wait()
