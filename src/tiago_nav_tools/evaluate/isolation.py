"""How an evaluation run is kept apart from the others and from the network (no ROS here).

Two modes (docs/evaluation.md, "Isolation"):

``netns``
    Each run's supervisor, master, nodes and candidate live in a Linux network namespace of
    their own, with only loopback up: nothing of the run is reachable from outside the
    namespace, and no run can reach another's master whatever its port. The supervisor is
    started as ``unshare -n`` (as root) or ``unshare -rn`` (an unprivileged user namespace),
    then ``python3 .../tiago_nav_tools/evaluate/isolation.py -- CMD...`` brings ``lo`` up (an ioctl, no
    iproute2 needed) and execs the supervisor, so its pid is the one the watchdog started.
``loopback``
    The host's network: every node gets ``ROS_IP=127.0.0.1`` and the master listens on
    127.0.0.1 at the worker slot's port (ROS's C++ nodes, ``rosout`` among them, still open
    their server sockets on all interfaces whatever ``ROS_IP`` says).

:func:`resolve` picks one: ``auto`` probes once per process (:func:`probe`) and takes
``netns`` where the machine allows it. Both modes keep the worker's port slot.
"""
import fcntl
import os
import socket
import struct
import subprocess
import sys

MODES = ('auto', 'netns', 'loopback')
MODE_VAR = 'TIAGO_NAV_EVAL_ISOLATION'    # the mode the command line asks for, read by the workers
SIOCGIFFLAGS, SIOCSIFFLAGS, IFF_UP = 0x8913, 0x8914, 0x1
_PROBED = {}                              # {'prefix': [...] or None, 'why': str}
# this file, run as a script (python3 -I, stdlib only): it needs no tiago_nav on the path
SCRIPT = os.path.splitext(os.path.abspath(__file__))[0] + '.py'


class IsolationError(RuntimeError):
    """The isolation asked for is not available here."""


def loopback_up(name='lo'):
    """Set interface ``name`` up in this process's network namespace (SIOCSIFFLAGS; needs
    CAP_NET_ADMIN in the namespace, which ``unshare -n`` as root or ``unshare -rn`` gives)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        req = struct.pack('16sH', name.encode(), 0)
        flags = struct.unpack('16sH', fcntl.ioctl(s.fileno(), SIOCGIFFLAGS, req + b'\0' * 22)[:18])[1]
        fcntl.ioctl(s.fileno(), SIOCSIFFLAGS, struct.pack('16sH', name.encode(), flags | IFF_UP) + b'\0' * 22)


def unshare_prefixes():
    """The commands that could start a process in a new network namespace, best first."""
    return [['unshare', '-n'], ['unshare', '-rn']] if os.geteuid() == 0 else [['unshare', '-rn']]


def probe(timeout=10.0):
    """``(prefix, why)``: the command prefix that starts a process in a network namespace of
    its own in which loopback comes up and a socket can listen on it (``None`` when none does
    here, ``why`` then says what failed). Tried once per process; the answer is kept."""
    if _PROBED:
        return _PROBED['prefix'], _PROBED['why']
    why = []
    check = [sys.executable, '-I', SCRIPT, '--', sys.executable, '-c',
             'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); s.listen(1)']
    for prefix in unshare_prefixes():
        try:
            p = subprocess.run(prefix + check, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               stdin=subprocess.DEVNULL, timeout=timeout)
        except (OSError, subprocess.TimeoutExpired) as e:
            why.append('%s: %s' % (' '.join(prefix), e))
            continue
        if p.returncode == 0:
            _PROBED.update(prefix=prefix, why='')
            return prefix, ''
        why.append('%s: exit %d: %s' % (' '.join(prefix), p.returncode,
                                         p.stdout.decode(errors='replace').strip()[-200:]))
    _PROBED.update(prefix=None, why='; '.join(why))
    return None, _PROBED['why']


def resolve(mode):
    """The isolation a run gets for the asked ``mode`` (:data:`MODES`): ``'netns'`` or
    ``'loopback'``. ``auto`` takes ``netns`` where :func:`probe` succeeds; ``netns`` where it
    does not raises :class:`IsolationError` naming what failed."""
    if mode not in MODES:
        raise IsolationError('isolation %r: one of %s' % (mode, ', '.join(MODES)))
    if mode == 'loopback':
        return 'loopback'
    prefix, why = probe()
    if prefix is not None:
        return 'netns'
    if mode == 'netns':
        raise IsolationError('no network namespace here (%s)' % why)
    return 'loopback'


def command(isolation, cmd):
    """``cmd`` (an argv list) as started for ``isolation``: unchanged for ``loopback``; for
    ``netns``, in a new network namespace whose loopback is brought up before ``cmd`` is
    exec'd (the same pid throughout)."""
    if isolation != 'netns':
        return list(cmd)
    prefix, why = probe()
    if prefix is None:
        raise IsolationError('no network namespace for the run: %s' % why)
    return prefix + [sys.executable, '-I', SCRIPT, '--'] + list(cmd)


# --- what a run's processes hold (the tests' and the curious user's audit) --------------------
def netns_of(pid):
    """The network namespace of process ``pid`` (``'net:[INODE]'``), None when it is gone."""
    try:
        return os.readlink('/proc/%s/ns/net' % pid)
    except OSError:
        return None


def _socket_inodes(pid):
    out = set()
    try:
        fds = os.listdir('/proc/%s/fd' % pid)
    except OSError:
        return out
    for fd in fds:
        try:
            link = os.readlink('/proc/%s/fd/%s' % (pid, fd))
        except OSError:
            continue
        if link.startswith('socket:['):
            out.add(link[8:-1])
    return out


def _addr(hexaddr):
    ip, port = hexaddr.split(':')
    raw = bytes.fromhex(ip)
    if len(raw) == 4:
        return '%s:%d' % (socket.inet_ntop(socket.AF_INET, raw[::-1]), int(port, 16))
    words = b''.join(raw[i:i + 4][::-1] for i in range(0, 16, 4))
    return '[%s]:%d' % (socket.inet_ntop(socket.AF_INET6, words), int(port, 16))


def listening(pid):
    """The TCP sockets process ``pid`` listens on, as ``'ADDR:PORT'`` strings (from
    ``/proc/PID/net/tcp*``, the tables of the process's own network namespace, matched to its
    file descriptors by inode)."""
    inodes = _socket_inodes(pid)
    out = []
    for table in ('tcp', 'tcp6'):
        try:
            with open('/proc/%s/net/%s' % (pid, table)) as f:
                next(f)
                for line in f:
                    cols = line.split()
                    if cols[3] == '0A' and cols[9] in inodes:        # TCP_LISTEN
                        out.append(_addr(cols[1]))
        except (OSError, StopIteration):
            continue
    return sorted(out)


def audit(pids):
    """``{pid: {'netns': ..., 'listening': [...], 'cmd': ...}}`` for the live ones of ``pids``."""
    out = {}
    for pid in pids:
        ns = netns_of(pid)
        if ns is None:
            continue
        try:
            with open('/proc/%s/cmdline' % pid, 'rb') as f:
                cmd = f.read().replace(b'\0', b' ').decode(errors='replace').strip()
        except OSError:
            cmd = ''
        out[pid] = {'netns': ns, 'listening': listening(pid), 'cmd': cmd[:200]}
    return out


def main(argv=None):
    """``python3 isolation.py -- CMD...``: loopback up, then exec CMD."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ['--']:
        argv = argv[1:]
    if not argv:
        sys.stderr.write('usage: python3 isolation.py -- CMD [ARG...]\n')
        return 2
    try:
        loopback_up()
    except OSError as e:
        sys.stderr.write('isolation: cannot bring lo up in this network namespace: %s\n' % e)
        return 3
    os.execvp(argv[0], argv)


if __name__ == '__main__':
    sys.exit(main())
