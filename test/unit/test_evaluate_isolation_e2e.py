"""A real evaluation run in each isolation mode, audited during its mission: in ``netns`` mode
every process of the run is in a network namespace other than the evaluator's and every socket
it listens on is in there; in ``loopback`` mode only ROS's C++ nodes (rosout,
robot_state_publisher) listen beyond loopback. Skipped without a built, sourced workspace."""
import os
import shutil
import threading
import time

import pytest

from conftest import NO_WORKSPACE, ROOT, WORKSPACE_REASON
from tiago_nav_tools.evaluate import isolation, run, suite

pytestmark = [pytest.mark.ros, pytest.mark.skipif(NO_WORKSPACE, reason=WORKSPACE_REASON)]
CPP_NODES = ('rosout', 'robot_state_publisher')


def spec():
    data = {'worlds': [{'file': os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml'),
                        'poses': [[11.0, 0.0, -45.0]]}],
            'profiles': {'ideal': {'laser_model': 'ideal', 'odometry_model': 'ideal',
                                   'localisation': 'ground_truth', 'laser_noise': 0.01}},
            'defaults': {'sim_time_limit': 120, 'wall_time_limit': 120, 'startup_timeout': 60}}
    (s,), _ = suite.expand(data, 'isolation.yaml', ROOT)
    return s


def audited_run(tmp_path, mode):
    """Run the course mission in ``mode``; audit its processes once its mission has begun and
    its master, simulator and the nodes' servers are up. Returns (result, audit)."""
    s = dict(spec(), isolation=mode)
    out = {}
    t = threading.Thread(target=lambda: out.update(r=run.execute(s, str(tmp_path))), daemon=True)
    t.start()
    stage = tmp_path / 'runs' / s['id'] / 'stage'
    token = '%s.%d.1' % (s['id'], os.getpid())
    seen = {}
    deadline = time.monotonic() + 180
    while t.is_alive() and time.monotonic() < deadline:
        if stage.exists() and stage.read_text() == 'mission':
            a = isolation.audit(run.tagged_pids(token))
            if len(a) > len(seen):
                seen = a
        time.sleep(0.1)
    t.join(60)
    assert 'r' in out, 'no result within the time limits'
    return out['r'], seen


def test_netns_run_has_no_socket_outside_its_namespace(tmp_path):
    if isolation.probe()[0] is None:
        pytest.skip('no network namespaces here: %s' % isolation.probe()[1])
    r, audit = audited_run(tmp_path, 'netns')
    assert r['outcome'] == 'succeeded' and r['isolation'] == 'netns', r.get('reason')
    assert len(audit) >= 8, audit        # the supervisor, roscore, rosmaster, rosout, the nodes
    mine = isolation.netns_of(os.getpid())
    namespaces = {a['netns'] for a in audit.values()}
    assert len(namespaces) == 1 and mine not in namespaces, audit
    listening = [addr for a in audit.values() for addr in a['listening']]
    assert '127.0.0.1:%d' % r['port'] in listening        # the master, inside
    # every socket of the run is in its namespace's tables: the master's too, which the
    # evaluator's namespace does not have
    assert '127.0.0.1:%d' % r['port'] not in isolation.listening(os.getpid())
    p = r['phases']
    assert all(p[k]['wall_s'] > 0 for k in ('startup', 'mission', 'teardown', 'judging')), p
    assert p['mission']['cpu_s'] > 0 and p['startup']['cpu_s'] > 0, p
    assert sum(p[k]['wall_s'] for k in ('startup', 'mission', 'teardown')) == pytest.approx(r['run_wall_s'],
                                                                                          abs=0.05)
    assert not run.tagged_pids('%s.%d.1' % (r['run_id'], os.getpid()))


def test_loopback_run_listens_beyond_loopback_only_through_ros_cpp_nodes(tmp_path):
    r, audit = audited_run(tmp_path, 'loopback')
    assert r['outcome'] == 'succeeded' and r['isolation'] == 'loopback', r.get('reason')
    assert len(audit) >= 8, audit
    mine = isolation.netns_of(os.getpid())
    assert {a['netns'] for a in audit.values()} == {mine}
    beyond = {pid: a for pid, a in audit.items()
              if any(not addr.startswith(('127.0.0.1:', '[::1]:')) for addr in a['listening'])}
    assert beyond, 'rosout listens on all interfaces (roscpp): the audit should see it'
    for pid, a in beyond.items():
        assert os.path.basename(a['cmd'].split()[0]) in CPP_NODES, a
