"""Runs isolated from each other and from the network (tiago_nav_tools.evaluate.isolation): the
probe, forcing a mode, and the audit of what a process in a run's namespace holds. The real
run in a namespace is test_evaluate_e2e.py's."""
import os
import socket
import subprocess
import sys

import pytest

from conftest import ROOT
from tiago_nav_tools.evaluate import isolation

SRC = os.path.join(ROOT, 'src')
DENIED = 'unshare -n: exit 1: Operation not permitted'

NETNS = isolation.probe()[0] is not None
needs_netns = pytest.mark.skipif(not NETNS, reason='no network namespaces here: %s' % isolation.probe()[1])


def test_modes():
    assert isolation.resolve('loopback') == 'loopback'
    assert isolation.resolve('auto') == ('netns' if NETNS else 'loopback')
    assert isolation.command('loopback', ['x', 'y']) == ['x', 'y']
    with pytest.raises(isolation.IsolationError, match='one of auto, netns, loopback'):
        isolation.resolve('bridge')


def test_forced_netns_without_namespaces_is_a_clear_error(monkeypatch):
    monkeypatch.setattr(isolation, '_PROBED', {'prefix': None, 'why': DENIED})
    with pytest.raises(isolation.IsolationError, match='no network namespace here.*Operation not permitted'):
        isolation.resolve('netns')
    assert isolation.resolve('auto') == 'loopback'


def test_listening_sockets_of_this_process():
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        s.listen(1)
        port = s.getsockname()[1]
        assert '127.0.0.1:%d' % port in isolation.listening(os.getpid())
    assert '127.0.0.1:%d' % port not in isolation.listening(os.getpid())


@needs_netns
def test_a_process_in_the_run_namespace_listens_only_there():
    """A listener started as a netns run's processes are: another namespace, loopback up, its
    socket absent from the host's tables and unreachable from here."""
    code = ('import socket, sys, time\ns = socket.socket()\ns.bind(("127.0.0.1", 0))\ns.listen(1)\n'
            'print(s.getsockname()[1], flush=True)\ntime.sleep(60)')
    p = subprocess.Popen(isolation.command('netns', [sys.executable, '-c', code]), stdout=subprocess.PIPE,
                         text=True)
    try:
        port = int(p.stdout.readline())
        a = isolation.audit([p.pid])[p.pid]
        assert a['netns'] != isolation.netns_of(os.getpid())
        assert a['listening'] == ['127.0.0.1:%d' % port]
        assert '127.0.0.1:%d' % port not in isolation.listening(os.getpid())
        with socket.socket() as c:
            c.settimeout(2.0)
            assert c.connect_ex(('127.0.0.1', port)) != 0        # not reachable from outside
        # another run's namespace has the same port free: no run meets another's master
        same = ('import socket\ns = socket.socket()\ns.bind(("127.0.0.1", %d))\ns.listen(1)' % port)
        assert subprocess.call(isolation.command('netns', [sys.executable, '-c', same]), timeout=30) == 0
    finally:
        p.kill()
        p.wait()


@needs_netns
def test_nested_namespaces():
    """Inside a namespace (as CI's chroots run), a run's namespace still comes up."""
    code = ('import subprocess, sys; sys.path.insert(0, %r); from tiago_nav_tools.evaluate import isolation as i; '
            'sys.exit(subprocess.call(i.command(i.resolve("netns"), ["true"])))' % SRC)
    outer = isolation.unshare_prefixes()[0]
    assert subprocess.call(outer + [sys.executable, '-I', isolation.SCRIPT, '--', sys.executable, '-c', code],
                           timeout=60) == 0


def test_evaluator_refuses_a_forced_netns_it_cannot_give(monkeypatch, tmp_path, capsys):
    from tiago_nav_tools.evaluate import cli
    monkeypatch.setattr(isolation, '_PROBED', {'prefix': None, 'why': DENIED})
    rc = cli.main([os.path.join(ROOT, 'suites', 'smoke.yaml'), '--out', str(tmp_path / 'out'),
                   '--isolation', 'netns'])
    err = capsys.readouterr().err
    assert rc == cli.EXIT_USAGE and 'Operation not permitted' in err and '--isolation loopback or auto' in err
    assert not (tmp_path / 'out').exists()          # nothing started
