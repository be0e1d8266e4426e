"""The evaluator's start-up verdict, judged by what died (tiago_nav_tools.evaluate.supervisor):
a real roslaunch on a private master, with a node that lives and one that exits with an error;
skipped without ROS."""
import json
import os
import re
import signal
import socket
import time

import pytest

from conftest import NO_WORKSPACE, WORKSPACE_REASON
from tiago_nav_tools.evaluate.supervisor import Infra, Supervisor, died_nodes

pytestmark = [pytest.mark.ros, pytest.mark.skipif(NO_WORKSPACE, reason=WORKSPACE_REASON)]

# a node run as a shell command in place of the package's executable (roslaunch prepends the
# launch prefix to the executable's path, which ``bash -c`` takes as $0)
LAUNCH = """<launch>
  <node pkg="tiago_nav" type="client" name="lives" output="screen" launch-prefix="bash -c 'echo lives $$; exec sleep 600'"/>
  %s
</launch>
"""
DIES = """<node pkg="tiago_nav" type="client" name="dies" launch-prefix="bash -c 'exit 3'"/>"""


def free_port():
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def until(pred, timeout, what):
    t0 = time.monotonic()
    while not pred():
        assert time.monotonic() - t0 < timeout, 'no %s within %g s' % (what, timeout)
        time.sleep(0.05)


def verdict(sup, timeout=0.1):
    with pytest.raises(Infra) as e:
        sup.wait('move_base action server', lambda: False, timeout)
    return e.value


@pytest.fixture
def supervisor(tmp_path, monkeypatch):
    port = free_port()
    monkeypatch.setenv('ROS_MASTER_URI', 'http://127.0.0.1:%d' % port)
    monkeypatch.setenv('ROS_HOME', str(tmp_path))
    monkeypatch.setenv('ROS_LOG_DIR', str(tmp_path / 'log'))
    (tmp_path / 'spec.json').write_text(json.dumps({'limits': {}}))
    sup = Supervisor(str(tmp_path))

    def start(body):
        path = tmp_path / 'run.launch'
        path.write_text(LAUNCH % body)
        sup.start('roslaunch', ['roslaunch', '-p', str(port), str(path)])
        return sup
    yield start
    sup.stop()


def log(sup):
    with open(os.path.join(sup.dir, 'roslaunch.log')) as f:
        return f.read()


def lives_pid(sup):
    for line in log(sup).splitlines():
        if line.startswith('lives '):
            return int(line.split()[1])
    return None


def test_nothing_died_is_a_launch_that_did_not_come_up_in_time(supervisor):
    sup = supervisor('')
    until(lambda: lives_pid(sup) is not None, 60.0, 'node started')
    e = verdict(sup)
    assert e.code == 'INFRA_LAUNCH', e
    assert 'every process alive and no node dead' in str(e)
    # then the node dies (killed as the kernel would kill it): the same wait names it
    os.kill(lives_pid(sup), signal.SIGKILL)
    until(lambda: died_nodes(log(sup)), 60.0, 'roslaunch reporting the death')
    e = verdict(sup)
    assert e.code == 'INFRA_NODE_DIED', e
    assert re.search(r'; lives-\d+ died with exit code -9 \(see roslaunch.log\)$', str(e)), e


def test_a_node_that_exits_with_an_error_is_named(supervisor):
    sup = supervisor(DIES)
    until(lambda: died_nodes(log(sup)), 60.0, 'roslaunch reporting the death')
    e = verdict(sup)
    assert e.code == 'INFRA_NODE_DIED', e
    assert re.search(r'^no move_base action server within 0.1 s; dies-\d+ died with exit code 3 '
                     r'\(see roslaunch.log\)$', str(e)), e
    assert 'lives' not in str(e)
