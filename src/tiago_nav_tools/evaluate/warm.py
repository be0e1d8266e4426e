"""Warm stacks: one worker runs the rows that share a stack key on one stack, reset between
rows (no ROS in this process).

A stack is a :mod:`tiago_nav_tools.evaluate.warm_supervisor` supervisor (roscore, demo.launch) on the
worker's slot, in a session of its own, tagged with a token as a run's processes are
(:mod:`tiago_nav_tools.evaluate.run`), isolated as a fresh run is (:mod:`tiago_nav_tools.evaluate.isolation`:
in ``netns`` mode the stack's supervisor, master and nodes live in a network namespace of their
own with only loopback, for all the rows the stack runs; the result's ``isolation`` says
which). :func:`stack_key` says which rows may share one: the same world, sensing profile,
candidate and launch arguments. The corridor law is not part of it: it is a field of the
mission's goal, the stack is the same with it on or off, and a reset rebuilds every node's
state whichever the last row used. Rows of the package's own nodes only: a candidate's outside
nodes offer no reset, so their rows get a fresh stack each
(:func:`tiago_nav_tools.evaluate.run.execute`), and so do rows recorded with ``--record`` (a bag per
run). A different key, a failed reset, an infrastructure error or a dead stack ends the stack;
a row whose reset failed is run again on a fresh stack, and its result says so
(``reset_failed``).

``verify_reset`` k: the k-th, 2k-th ... reset of each stack is checked (:func:`verify`): its row
runs again on a fresh stack of its own (``DIR/verify/runs/ID/``, on the worker's second slot,
while the warm stack waits for its next row) and the two results are compared
(:func:`tiago_nav_tools.evaluate.run.differences`, every field but the wall-clock ones). Equal: the
row says ``verified: true``. Different: the reset *diverged*, which is the evaluator's fault,
not the row's outcome: the row's outcome and figures become the fresh stack's (the reference: a
fresh stack is what the rates mean), it says ``verified: false``, ``diverged`` (the fields) and
``reset_result`` (the warm run's outcome and reason; the whole warm result is kept in
``runs/ID/reset_result.json``), it is not retried, and the summary counts it and the command
exits non-zero (:mod:`tiago_nav_tools.evaluate.cli`).

Each row's ``phases`` (:mod:`tiago_nav_tools.evaluate.timing`) are those of a fresh run, measured on
the stack: ``startup`` from handing the row to the stack to the goal about to be sent (a new
stack's start, or the reset, and the scenario check), ``mission``, ``teardown`` (the mission
client unsubscribing, the answer; for the last row a stack answered, also the stack's end) and
``judging``; CPU is the stack's processes' during the row.
"""
import json
import os
import select
import shutil
import signal
import socket
import subprocess
import sys
import time

from tiago_nav_tools.evaluate import isolation as iso
from tiago_nav_tools.evaluate import run as R
from tiago_nav_tools.evaluate import timing

_WORKER = {'stack': None, 'count': 0}   # this worker process's stack


def stack_key(spec):
    """The rows that may share a stack: those with equal keys (world file or generated world,
    sensing profile, candidate, launch arguments, time limits; not the corridor law, a field of
    the goal). None for rows that always get a fresh stack (a candidate's, recorded ones)."""
    if spec.get('candidate', 'own') != 'own' or spec.get('record'):
        return None
    return json.dumps([spec['world'], spec.get('world_file'), spec['profile'],
                       spec['candidate'], spec['launch_args'],
                       spec['limits']], sort_keys=True)


def tree_cpu(token):
    """[s] CPU time of the live processes carrying ``token`` and of their reaped children."""
    tck = os.sysconf('SC_CLK_TCK')
    total = 0
    for pid in R.tagged_pids(token):
        try:
            with open('/proc/%d/stat' % pid) as f:
                fields = f.read().rsplit(')', 1)[1].split()
        except OSError:
            continue
        total += sum(int(v) for v in fields[11:15])     # utime stime cutime cstime
    return total / tck


class Stack:
    """One warm stack on this worker's slot: its supervisor process, fed run folders."""

    def __init__(self, key, out_dir, first_spec):
        self.key = key
        self.slot = R.claim_slot()
        self.port = R.port_of(self.slot)
        _WORKER['count'] += 1
        self.dir = os.path.join(out_dir, 'stacks', 'slot%02d-%d-%d' % (self.slot, os.getpid(),
                                                                          _WORKER['count']))
        shutil.rmtree(self.dir, ignore_errors=True)
        os.makedirs(os.path.join(self.dir, 'logs'))
        os.makedirs(os.path.join(self.dir, 'ros_home'))
        R.write_json(os.path.join(self.dir, 'spec.json'), first_spec)
        self.token = 'stack.%d.%d' % (os.getpid(), _WORKER['count'])
        env = R.run_env(self.dir, self.port, self.token)
        # the stack's isolation, as a fresh run's (its spec's, else the command line's)
        self.isolation = iso.resolve(first_spec.get('isolation')
                                     or os.environ.get(iso.MODE_VAR, 'auto'))
        cmd = iso.command(self.isolation,
                          [sys.executable, '-m', 'tiago_nav_tools.evaluate.warm_supervisor', self.dir])
        self.log = open(os.path.join(self.dir, 'supervisor.log'), 'w')
        self.proc = subprocess.Popen(cmd, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=self.log, start_new_session=True)
        self.runs = 0
        self.resets = 0         # rows run after a reset
        self.last = None        # (result, path) of the last row the stack answered

    def alive(self):
        return self.proc.poll() is None

    def send(self, run_dir, timeout):
        """Hands ``run_dir`` to the supervisor; its answer (dict), or None when none came
        within ``timeout`` [s wall] or the supervisor ended."""
        try:
            self.proc.stdin.write((run_dir + '\n').encode())
            self.proc.stdin.flush()
        except OSError:
            return None
        end = time.monotonic() + timeout
        fd = self.proc.stdout
        while True:
            left = end - time.monotonic()
            if left <= 0:
                return None
            ready, _, _ = select.select([fd], [], [], min(left, 1.0))
            if ready:
                line = fd.readline()
                if not line:
                    return None
                try:
                    return json.loads(line.decode())
                except ValueError:
                    continue
            elif not self.alive():
                return None

    def close(self):
        """Stops the stack at once: every row's results are written when it answered, so its
        processes are killed (the supervisor's group and everything carrying the stack's token)
        rather than shut down one by one, which takes roslaunch seconds. Returns how many
        processes were killed after the group."""
        try:
            self.proc.stdin.close()
        except OSError:
            pass
        left = R.kill_tree(self.proc.pid, self.token)
        self.proc.wait()
        self.log.close()
        return left


def close_stack():
    """Ends this worker's stack, if any; its end's wall time is counted in the ``teardown`` of
    the last row it answered (whose ``result.json`` is written again)."""
    stack, _WORKER['stack'] = _WORKER['stack'], None
    if stack is None:
        return
    t0 = time.monotonic()
    stack.close()
    dt = time.monotonic() - t0
    if stack.last is not None:
        result, path = stack.last
        down = (result.get('phases') or {}).get('teardown')
        if down is not None:
            down['wall_s'] = (down.get('wall_s') or 0.0) + dt
            R.write_json(path, result)


def execute_warm(spec, out_dir, record=False, attempt=1, verify_reset=0):
    """:func:`tiago_nav_tools.evaluate.run.execute` on this worker's warm stack (a fresh stack when
    the row's key differs from the stack's, or when the row gets one always: see
    :func:`stack_key`). Returns the judged result (also written to ``runs/ID/result.json``)."""
    key = stack_key(dict(spec, record=record))
    if key is None:
        close_stack()
        return R.execute(spec, out_dir, record, attempt)
    stack = _WORKER['stack']
    if stack is not None and (stack.key != key or not stack.alive()):
        close_stack()
        stack = None
    run_dir = os.path.join(out_dir, 'runs', spec['id'])
    shutil.rmtree(run_dir, ignore_errors=True)
    os.makedirs(run_dir)
    full = dict(spec, record=record, world_path=R.world_path(spec, out_dir))
    R.write_json(os.path.join(run_dir, 'spec.json'), full)
    lim = spec['limits']
    wall_limit = lim['startup_timeout'] + lim['wall_time_limit'] + 30.0
    w0 = time.monotonic()
    if stack is None:
        stack = _WORKER['stack'] = Stack(key, out_dir, full)
        cpu0 = 0.0
    else:
        cpu0 = tree_cpu(stack.token)
    answer = stack.send(run_dir, wall_limit)
    wall = time.monotonic() - w0
    cpu = tree_cpu(stack.token) - cpu0
    stack.runs += 1
    if answer is None or answer.get('failed') == 'reset':
        # no answer (the watchdog, or a dead stack) or a failed reset: the stack is done
        close_stack()
        if answer is not None or not os.path.exists(os.path.join(run_dir, 'raw.json')):
            stage = _read(os.path.join(run_dir, 'stage'))
            if answer is None and stage == 'mission':
                raw = {'timed_out': True, 'watchdog': True,
                       'reason': 'wall-clock watchdog: no result within %.0f s' % wall_limit}
                # (the row's stack was started for it, or reset for it: it ran before)
                result = _finish(spec, full, raw, out_dir, attempt, stack, wall, cpu,
                                 'reset' if stack.runs > 1 else 'fresh', (w0, cpu0))
                return _verify_due(spec, out_dir, result, record, stack, verify_reset)
            # the reset failed, or the stack died before the mission: a fresh stack runs the row
            why = answer.get('reason') if answer else 'the warm stack stopped (stage %s)' % stage
            result = R.execute(spec, out_dir, record, attempt)
            result.update(reset_failed=why, stack='fresh')
            # the failed reset was part of the row's start-up
            up = (result.get('phases') or {}).get('startup')
            if up is not None:
                up['wall_s'] = (up.get('wall_s') or 0.0) + wall
            R.write_json(os.path.join(run_dir, 'result.json'), result)
            return result
    if answer is not None and answer.get('failed'):
        close_stack()
    raw = R.read_json(os.path.join(run_dir, 'raw.json')) or {
        'infra': 'INFRA_LAUNCH', 'reason': 'no result from the warm stack (see %s)' % stack.dir}
    result = _finish(spec, full, raw, out_dir, attempt, stack, wall, cpu,
                     answer.get('reset', 'fresh') if answer else 'fresh', (w0, cpu0))
    return _verify_due(spec, out_dir, result, record, stack, verify_reset)


def _verify_due(spec, out_dir, result, record, stack, verify_reset):
    """``result``, verified (:func:`verify`) when it is the k-th, 2k-th ... reset of ``stack``
    (k = ``verify_reset``, 0: none) and not an infrastructure error (that is retried)."""
    if result.get('stack') != 'reset':
        return result
    stack.resets += 1
    if verify_reset and stack.resets % verify_reset == 0 and result['outcome'] not in R.INFRA:
        result = verify(spec, out_dir, result, record)
        if stack.last is not None:      # (the stack's end is counted in the row's teardown)
            stack.last = (result, stack.last[1])
    return result


def _read(path):
    try:
        with open(path) as f:
            return f.read().strip()
    except OSError:
        return 'none'


def row_marks(run_dir, cpu0):
    """:func:`tiago_nav_tools.evaluate.timing.read_marks` of a row run on a stack, its CPU counted
    from ``cpu0`` (the stack's processes' CPU when the row was handed over)."""
    return {k: (t, c - cpu0 if c >= 0 else c) for k, (t, c) in timing.read_marks(run_dir).items()}


def _finish(spec, full, raw, out_dir, attempt, stack, wall, cpu, how, began):
    w0, cpu0 = began
    run_dir = os.path.join(out_dir, 'runs', spec['id'])
    j0, jc0 = time.monotonic(), time.process_time()
    result = R.judge(full, raw)
    result.update(attempt=attempt, slot=stack.slot, port=stack.port, run_wall_s=wall, cpu_s=cpu,
                  leftover_processes=0, host=socket.gethostname(), stack=how,
                  isolation=stack.isolation,
                  phases=timing.phases(row_marks(run_dir, cpu0), w0, w0 + wall, cpu,
                                       time.monotonic() - j0, time.process_time() - jc0))
    path = os.path.join(run_dir, 'result.json')
    R.write_json(path, result)
    stack.last = (result, path)
    return result


def verify(spec, out_dir, warm, record=False):
    """Runs ``spec`` again on a fresh stack of its own (under ``DIR/verify``, on this worker's
    ``verify`` slot: the warm stack stays up for its next row) and compares it with ``warm``,
    the row's result after a reset (:func:`checked`). A fresh run that ends in an
    infrastructure error is run once more; when that one does too, the row keeps ``warm`` with
    ``verified: null`` and the reason in ``verify_error``. Returns the row's result (also
    written to ``runs/ID/result.json``)."""
    vdir = os.path.join(out_dir, 'verify')
    os.makedirs(vdir, exist_ok=True)
    wdir = os.path.join(out_dir, 'worlds')
    if os.path.isdir(wdir) and not os.path.exists(os.path.join(vdir, 'worlds')):
        os.symlink(wdir, os.path.join(vdir, 'worlds'))
    fresh = R.execute(spec, vdir, record, role='verify')
    if fresh['outcome'] in R.INFRA:
        fresh = R.execute(spec, vdir, record, attempt=2, role='verify')
    row_dir = os.path.join(out_dir, 'runs', spec['id'])
    if fresh['outcome'] in R.INFRA:
        row = dict(warm, verified=None,
                   verify_error='the fresh run ended in %s twice: %s (DIR/verify/runs/%s)'
                                % (fresh['outcome'], fresh.get('reason'), spec['id']))
    else:
        row = checked(warm, fresh)
        if row.get('diverged'):
            R.write_json(os.path.join(row_dir, 'reset_result.json'), warm)
    R.write_json(os.path.join(row_dir, 'result.json'), row)
    return row


def checked(warm, fresh):
    """The row's result from ``warm`` (its result after a reset) and ``fresh`` (its result on a
    fresh stack). Equal (:func:`tiago_nav_tools.evaluate.run.differences`, every field but
    :data:`~tiago_nav_tools.evaluate.run.WALL_CLOCK_FIELDS`): ``warm`` with ``verified: true``.
    Different, the reset diverged: the fresh result's outcome and figures (what a fresh stack,
    the reference, gives the row) with the warm run's wall-clock fields (its time is the one
    the batch spent on the row), ``verified: false``, ``diverged`` (the fields that differ) and
    ``reset_result`` (the warm run's outcome and reason)."""
    diff = R.differences(warm, fresh)
    if not diff:
        return dict(warm, verified=True)
    row = {k: v for k, v in fresh.items() if k not in R.WALL_CLOCK_FIELDS}
    row.update((k, v) for k, v in warm.items() if k in R.WALL_CLOCK_FIELDS)
    row.update(verified=False, diverged=diff,
               reset_result={'outcome': warm.get('outcome'), 'reason': warm.get('reason')})
    return row


def group_by_stack(specs):
    """``specs`` in chunks that one worker runs on one stack, in order: consecutive rows with
    the same :func:`stack_key` (rows without one alone)."""
    groups, index = [], {}
    for s in specs:
        k = stack_key(s)
        if k is None:
            groups.append([s])
        elif k in index:
            groups[index[k]].append(s)
        else:
            index[k] = len(groups)
            groups.append([s])
    return groups


def run_group(specs, out_dir, record=False, verify_reset=0):
    """Runs ``specs`` (one :func:`group_by_stack` chunk) in order on this worker's warm stack,
    each retried once after an infrastructure error (on a fresh stack: the error ended the
    stack), as :func:`tiago_nav_tools.evaluate.run.execute_with_retry`; a row whose reset diverged
    (:func:`verify`) is not an infrastructure error and is never retried. Returns their
    results."""
    results = []
    try:
        for s in specs:
            r = execute_warm(s, out_dir, record, 1, verify_reset)
            if r['outcome'] in R.INFRA and not r.get('diverged'):
                first = {'outcome': r['outcome'], 'reason': r['reason']}
                close_stack()
                r = execute_warm(s, out_dir, record, 2, verify_reset)
                r['first_attempt'] = first
                R.write_json(os.path.join(out_dir, 'runs', s['id'], 'result.json'), r)
            results.append(r)
    finally:
        close_stack()
    return results


def terminate(*_):
    """A worker that is told to stop ends its stack first."""
    close_stack()
    sys.exit(1)


def install_handlers():
    signal.signal(signal.SIGTERM, terminate)
