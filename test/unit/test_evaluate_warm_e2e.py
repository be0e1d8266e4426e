"""Two rows on one real warm stack in ``netns`` mode, audited during the second row's mission
(after a reset): every process of the stack is in one network namespace other than the
evaluator's and listens only in there, the results say ``netns`` and carry their time
breakdown (the reset row's start-up is the reset), and nothing of the stack is left after.
Skipped without a built, sourced workspace or without network namespaces."""
import os
import shutil
import threading
import time

import pytest

from conftest import NO_WORKSPACE, ROOT, WORKSPACE_REASON
from tiago_nav_tools.evaluate import isolation, run, suite
from tiago_nav_tools.evaluate import warm as W

pytestmark = [pytest.mark.ros, pytest.mark.skipif(NO_WORKSPACE, reason=WORKSPACE_REASON)]
PHASES = ('startup', 'mission', 'teardown', 'judging')


def specs():
    data = {'worlds': [{'file': os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml'),
                        'poses': [[11.0, 0.0, -45.0], [8.39, -3.77, 128.1]]}],
            'profiles': {'ideal': {'laser_model': 'ideal', 'odometry_model': 'ideal',
                                   'localisation': 'ground_truth', 'laser_noise': 0.01}},
            'seeds': [1, 2],
            'defaults': {'sim_time_limit': 120, 'wall_time_limit': 120, 'startup_timeout': 60}}
    runs, _ = suite.expand(data, 'warm_isolation.yaml', ROOT)
    a, b = runs[0], runs[-1]
    assert W.stack_key(a) == W.stack_key(b) and a['goal'] != b['goal'] and a['seed'] != b['seed']
    return [dict(a, isolation='netns'), dict(b, isolation='netns')]


def test_a_warm_stack_lives_in_a_namespace_of_its_own(tmp_path):
    if isolation.probe()[0] is None:
        pytest.skip('no network namespaces here: %s' % isolation.probe()[1])
    rows = specs()
    out = {}
    t = threading.Thread(target=lambda: out.update(r=W.run_group(rows, str(tmp_path))), daemon=True)
    t.start()
    stage = tmp_path / 'runs' / rows[1]['id'] / 'stage'
    seen, token = {}, None
    deadline = time.monotonic() + 240
    while t.is_alive() and time.monotonic() < deadline:
        stack = W._WORKER['stack']
        if stack is not None and stage.exists() and stage.read_text() == 'mission':
            token = stack.token
            a = isolation.audit(run.tagged_pids(token))
            if len(a) > len(seen):
                seen = a
        time.sleep(0.1)
    t.join(60)
    assert 'r' in out, 'no results within the time limits'
    first, second = out['r']
    assert [r['stack'] for r in (first, second)] == ['fresh', 'reset'], \
        [(r['outcome'], r.get('reason'), r.get('reset_failed')) for r in (first, second)]
    for r in (first, second):
        assert r['outcome'] == 'succeeded' and r['isolation'] == 'netns', r.get('reason')
        assert all(r['phases'][k]['wall_s'] > 0 for k in PHASES), r['phases']
        assert r['phases']['mission']['cpu_s'] > 0 and r['phases']['startup']['cpu_s'] > 0, r['phases']
    # the first row's phases cover its time on the stack; the second's teardown also the stack's end
    p = first['phases']
    assert sum(p[k]['wall_s'] for k in PHASES[:3]) == pytest.approx(first['run_wall_s'], abs=0.05)
    p = second['phases']
    assert sum(p[k]['wall_s'] for k in PHASES[:3]) > second['run_wall_s']
    # the audit during the reset row's mission: one namespace, not the evaluator's, the
    # master listening in it only
    assert token is not None and len(seen) >= 8, seen
    namespaces = {a['netns'] for a in seen.values()}
    assert len(namespaces) == 1 and isolation.netns_of(os.getpid()) not in namespaces, seen
    listening = [addr for a in seen.values() for addr in a['listening']]
    assert '127.0.0.1:%d' % second['port'] in listening
    assert '127.0.0.1:%d' % second['port'] not in isolation.listening(os.getpid())
    assert not run.tagged_pids(token)
