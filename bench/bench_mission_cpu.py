#!/usr/bin/python3
"""The course mission's CPU, per node and per phase, on this tree against an earlier commit.

The course mission (course world, pose B (11, 0, -45 deg), corridor law on, seed 0) at
``real_time_factor:=0`` on this tree ("this tree") and on ``--commit`` (default 07ccd86, the
release before the robustness work), interleaved for ``--pairs`` pairs in ABBA order (this
tree then the commit, the commit then this tree, ...: a load that drifts over the runs favours
neither), each run a fresh demo.launch on a private master. The commit is checked out
into a git worktree (a temporary one unless ``--worktree`` names one to keep and reuse) and its
catkin workspace built with its own ``make setup`` (with this tree's virtualenv when both
Makefiles install the same PyPI packages).

Each run is a child process in the measured tree's workspace (``source .ws/devel/setup.bash``):
it starts roscore and ``roslaunch tiago_nav demo.launch`` (no client, no RViz), waits for every
server of the mission and for the launch's processes to fall quiet (their CPU rate below
``QUIET_CPU`` of a core), sends the goal with a plain actionlib client and reads each process's
CPU time (user + system, with its waited-for children's, ``/proc/<pid>/stat``) at the goal, at
every change of the mission's feedback state and at the result. Phases: *corridor* from the goal
to the first NAVIGATING feedback (GOAL_RECEIVED, CORRIDOR), *navigation* to the first DETECTING
(NAVIGATING, MOVING, STOPPED, ARRIVED), *detection* to the result. The child uses nothing of
the tree's library but its messages, so the same code measures both trees.

Reported per tree: the median, least and largest CPU seconds of each process and each phase
(the stack: every process of the launch, roscore's included), wall and simulated seconds, the
result (succeeded, final pose, obstacles found and matched, centre RMS against the world file:
:mod:`tiago_nav_tools.evaluate.inview` from the true final pose); the ratios this tree / commit of the
medians, and of each pair's runs (median and range), with the load average at each run. The
machine may be busy: the pairs and the medians are there for that; the load says how busy.

Writes bench/results/mission_cpu.json and mission_cpu.png.

Usage: bench/bench_mission_cpu.py [--commit 07ccd86] [--pairs 5] [--worktree DIR]
                                  [--out bench/results/mission_cpu.json]
"""
import argparse
import json
import math
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, 'bench', 'results')
WORLD = 'ias_lab_room_full.yaml'
COURSE = (11.0, 0.0, -45.0)
DEFAULT_COMMIT = '07ccd86'
PHASES = ('corridor', 'navigation', 'detection')
# TiagoTask feedback state -> phase (action/TiagoTask.action)
PHASE_OF = {0: 'corridor', 1: 'corridor', 2: 'navigation', 3: 'navigation', 4: 'navigation',
            5: 'navigation', 6: 'detection', 7: 'detection'}
QUIET_CPU = 0.05        # [CPU s per wall s] the launch counts as settled below this
QUIET_WINDOW = 1.0      # [s wall] ... over this long
SETTLE_TIMEOUT = 60.0   # [s wall] longest wait for it
UP_TIMEOUT = 120.0      # [s wall] longest wait for the servers
MISSION_TIMEOUT = 300.0  # [s wall]
# the environment a sourced workspace sets: cleared before sourcing the measured tree's
WS_VARS = ('ROS_PACKAGE_PATH', 'CMAKE_PREFIX_PATH', 'PYTHONPATH', 'LD_LIBRARY_PATH',
           'PKG_CONFIG_PATH', 'ROSLISP_PACKAGE_DIRECTORIES', 'ROS_ETC_DIR', 'ROS_ROOT',
           'ROS_DISTRO', 'ROS_VERSION', 'ROS_PYTHON_VERSION')


# --- /proc ---------------------------------------------------------------------------------
def _stat(pid):
    """``(ppid, cpu seconds)`` of a process: utime + stime + cutime + cstime (its own and its
    waited-for children's), or None when it is gone."""
    try:
        with open('/proc/%d/stat' % pid) as f:
            fields = f.read().rsplit(')', 1)[1].split()
    except OSError:
        return None
    tick = os.sysconf('SC_CLK_TCK')
    return int(fields[1]), sum(int(v) for v in fields[11:15]) / tick


def descendants(roots):
    """``{pid: name}`` of the live processes ``roots`` and everything under them."""
    # the measured tree's harness (this runs in the child, on that tree's workspace); both
    # this tree and the earlier commits compared with have it
    from tiago_nav_tools.testing.harness import _process_name
    parent = {}
    for d in os.listdir('/proc'):
        if d.isdigit():
            s = _stat(int(d))
            if s is not None:
                parent[int(d)] = s[0]
    roots = set(roots)
    out = {}
    for pid in parent:
        p = pid
        while p not in roots and p in parent:
            p = parent[p]
        if p in roots:
            out[pid] = _process_name(pid)
    return out


def sample(pids):
    """``{pid: cpu seconds}`` of the processes ``pids`` (a gone one is left out)."""
    out = {}
    for pid in pids:
        s = _stat(pid)
        if s is not None:
            out[pid] = s[1]
    return out


# --- one run (child process, in the measured tree's workspace) -----------------------------
def _free_port():
    with socket.socket() as s:
        s.bind(('localhost', 0))
        return s.getsockname()[1]


def run_child(tree, log_path):
    """One course mission on the launch of the sourced workspace; prints ``RESULT <json>``."""
    import tiago_nav       # the measured tree's (the sourced workspace's), so imported here
    from tiago_nav_tools.testing.harness import stop_process
    here = [os.path.realpath(p) for p in tiago_nav.__path__]
    if not any(p.startswith(os.path.realpath(tree) + os.sep) for p in here):
        raise SystemExit('bench_mission_cpu: tiago_nav comes from %s, not from %s'
                         % (here, tree))
    port = _free_port()
    uri = 'http://localhost:%d' % port
    os.environ['ROS_MASTER_URI'] = uri
    log = open(log_path, 'w')
    core = subprocess.Popen(['roscore', '-p', str(port)], stdout=log, stderr=subprocess.STDOUT,
                            start_new_session=True)
    launch = subprocess.Popen(
        ['roslaunch', '-p', str(port), '--wait', 'tiago_nav', 'demo.launch',
         'world:=' + os.path.join(tree, 'worlds', WORLD), 'real_time_factor:=0',
         'client:=false', 'rviz:=false', 'gui:=false'],
        stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        print('RESULT ' + json.dumps(_mission(core, launch, uri)), flush=True)
    finally:
        import rospy
        rospy.signal_shutdown('done')
        stop_process(launch)
        stop_process(core)
        log.close()


def _mission(core, launch, uri):
    import actionlib
    import rosgraph
    import rospy
    from move_base_msgs.msg import MoveBaseAction
    from nav_msgs.msg import Odometry
    from tiago_nav.msg import CorridorAction, TiagoTaskAction, TiagoTaskGoal
    t0 = time.monotonic()

    def left():
        if launch.poll() is not None:
            raise RuntimeError('roslaunch exited with %s' % launch.returncode)
        rest = UP_TIMEOUT - (time.monotonic() - t0)
        if rest <= 0:
            raise RuntimeError('the launch was not up within %g s' % UP_TIMEOUT)
        return rest

    while not rosgraph.is_master_online(uri):
        left()
        time.sleep(0.2)
    while not rosgraph.Master('/mission_cpu').hasParam('/use_sim_time'):
        left()
        time.sleep(0.1)
    rospy.init_node('mission_cpu', anonymous=True, disable_signals=True)
    clients = {}
    for name, kind in (('move_base', MoveBaseAction), ('corridor_controller', CorridorAction),
                       ('tiago_controller', TiagoTaskAction)):
        clients[name] = actionlib.SimpleActionClient(name, kind)
        while not clients[name].wait_for_server(rospy.Duration(1.0)):
            left()
    while True:
        try:
            rospy.wait_for_service('obstacle_detection', 1.0)
            break
        except rospy.ROSException:
            left()
    for name in ('move_base', 'corridor_controller'):
        clients.pop(name).action_client.stop()
    # the launch's start-up work (maps, distance fields) done: its CPU rate falls quiet
    procs = descendants((core.pid, launch.pid))
    before, t_before, t_end = sample(procs), time.monotonic(), time.monotonic() + SETTLE_TIMEOUT
    while True:
        time.sleep(QUIET_WINDOW)
        procs = descendants((core.pid, launch.pid))
        now, t_now = sample(procs), time.monotonic()
        rate = sum(v - before.get(p, 0.0) for p, v in now.items()) / (t_now - t_before)
        if rate < QUIET_CPU or t_now > t_end:
            break
        before, t_before = now, t_now
    settle_rate = rate
    client = clients['tiago_controller']
    marks = []      # (state, wall s, sim s, {pid: cpu s})

    def on_feedback(fb):
        if not marks or fb.state != marks[-1][0]:
            marks.append((fb.state, time.monotonic(), rospy.get_time(), sample(procs)))

    loadavg = list(os.getloadavg())
    marks.append((None, time.monotonic(), rospy.get_time(), sample(procs)))
    client.send_goal(TiagoTaskGoal(x=COURSE[0], y=COURSE[1], yaw_deg=COURSE[2],
                                   use_corridor_law=True), feedback_cb=on_feedback)
    done = client.wait_for_result(rospy.Duration(MISSION_TIMEOUT))
    end = (None, time.monotonic(), rospy.get_time(), sample(procs))
    from actionlib_msgs.msg import GoalStatus
    state = client.get_state()
    result = client.get_result()
    # processes started during the mission (none expected): counted whole
    late = {p: n for p, n in descendants((core.pid, launch.pid)).items() if p not in procs}
    if late:
        extra = sample(late)
        procs.update(late)
        end[3].update(extra)
        for m in marks:
            m[3].update({p: 0.0 for p in late})
    truth = rospy.wait_for_message('/sim/ground_truth', Odometry, 10.0)
    marks.append(end)
    phase_at = []       # (phase, index of the mark that starts it)
    for k, m in enumerate(marks[:-1]):
        ph = 'corridor' if m[0] is None else PHASE_OF.get(m[0], 'detection')
        if not phase_at or phase_at[-1][0] != ph:
            phase_at.append((ph, k))
    phases = {}
    for n, (ph, k) in enumerate(phase_at):
        k1 = phase_at[n + 1][1] if n + 1 < len(phase_at) else len(marks) - 1
        a, b = marks[k], marks[k1]
        by = {}
        for pid, name in procs.items():
            by[name] = by.get(name, 0.0) + b[3].get(pid, 0.0) - a[3].get(pid, 0.0)
        phases[ph] = {'wall_s': b[1] - a[1], 'sim_s': b[2] - a[2], 'cpu_by_process_s': by,
                      'cpu_s': sum(by.values())}
    by = {}
    for pid, name in procs.items():
        by[name] = by.get(name, 0.0) + marks[-1][3].get(pid, 0.0) - marks[0][3].get(pid, 0.0)
    p = truth.pose.pose
    true_pose = [p.position.x, p.position.y, 2.0 * math.atan2(p.orientation.z, p.orientation.w)]
    rec = {'succeeded': bool(done) and state == GoalStatus.SUCCEEDED,
           'status': client.get_goal_status_text(), 'loadavg_at_goal': loadavg,
           'settle_cpu_rate': settle_rate,
           'wall_s': marks[-1][1] - marks[0][1], 'sim_s': marks[-1][2] - marks[0][2],
           'cpu_s': sum(by.values()), 'cpu_by_process_s': by, 'phases': phases,
           'states': [m[0] for m in marks[1:-1]], 'true_final_pose': true_pose}
    if result is not None:
        q = result.final_pose.pose
        rec['result_pose'] = [q.position.x, q.position.y,
                              2.0 * math.atan2(q.orientation.z, q.orientation.w)]
        rec['centres'] = [[o.center.x, o.center.y] for o in result.obstacles]
    client.action_client.stop()
    return rec


# --- the commit's tree ---------------------------------------------------------------------
def git(*args, cwd=ROOT):
    return subprocess.check_output(('git',) + args, cwd=cwd, text=True).strip()


def pip_packages(tree):
    return subprocess.check_output(['make', '-s', '-C', tree, 'print-pip-packages'],
                                   text=True).strip()


def prepare(commit, worktree):
    """The commit checked out in ``worktree`` (made when missing) and its workspace built with
    its own ``make setup``; returns ``(full hash, tree path)``."""
    full = git('rev-parse', '--verify', commit + '^{commit}')
    if os.path.isdir(worktree):
        have = git('rev-parse', 'HEAD', cwd=worktree)
        if have != full:
            raise SystemExit('bench_mission_cpu: %s holds %s, not %s' % (worktree, have, full))
    else:
        git('worktree', 'add', '--detach', worktree, full)
    args = ['make', '-C', worktree, 'setup']
    if pip_packages(worktree) == pip_packages(ROOT) and os.path.exists(
            os.path.join(ROOT, '.venv', '.done')):
        args.append('VENV=' + os.path.join(ROOT, '.venv'))     # the same packages: reused
    print('building %s in %s: %s' % (full[:10], worktree, ' '.join(args[3:]) or 'own venv'),
          flush=True)
    subprocess.check_call(args, stdout=subprocess.DEVNULL)
    return full, worktree


def run_in(tree, log_path):
    """One run in ``tree``'s workspace: its record (or ``{'error': ...}``)."""
    env = {k: v for k, v in os.environ.items() if k not in WS_VARS}
    cmd = 'source %s && exec %s %s --child %s --log %s' % tuple(
        map(_quote, (os.path.join(tree, '.ws', 'devel', 'setup.bash'), sys.executable,
                     os.path.abspath(__file__), tree, log_path)))
    p = subprocess.run(['bash', '-c', cmd], env=env, stdout=subprocess.PIPE, text=True)
    for line in p.stdout.splitlines():
        if line.startswith('RESULT '):
            return json.loads(line[7:])
    return {'error': 'exit %s, no result (see %s)' % (p.returncode, log_path)}


def _quote(s):
    import shlex
    return shlex.quote(s)


# --- judging and summarising ---------------------------------------------------------------
def judge(rec, world):
    """The record's detection figures against the world file, from the true final pose."""
    from tiago_nav_tools.evaluate.metrics import detection_score
    from tiago_nav_tools.evaluate.inview import truth as view_truth
    if 'true_final_pose' not in rec:
        return rec
    in_view, glimpsed = view_truth(world, tuple(rec['true_final_pose']))
    s = detection_score([(x, y) for _, x, y, _ in in_view], rec.get('centres', []),
                        [(x, y) for _, x, y, _ in glimpsed])
    rec.update({'in_view': s['true'], 'found': s['found'], 'matched': s['matched'],
                'false_positives': s['false_positives'], 'rms_error_m': s['rms_error'],
                'goal_error_m': math.hypot(rec['true_final_pose'][0] - COURSE[0],
                                           rec['true_final_pose'][1] - COURSE[1])})
    return rec


def _median(v):
    v = sorted(v)
    n = len(v)
    if not n:
        return None
    return v[n // 2] if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2])


def spread(values):
    """``{'median', 'min', 'max', 'n'}`` of the values (None when there are none)."""
    v = [x for x in values if x is not None]
    return {'median': _median(v), 'min': min(v), 'max': max(v), 'n': len(v)} if v else None


def summarise(runs):
    """Per tree: medians and ranges of CPU per process, per phase (and per process in each),
    wall, simulated time; the results."""
    ok = [r for r in runs if 'cpu_s' in r]
    names = sorted({n for r in ok for n in r['cpu_by_process_s']})
    out = {'runs': len(runs), 'measured': len(ok),
           'succeeded': sum(1 for r in ok if r.get('succeeded')),
           'cpu_s': spread([r['cpu_s'] for r in ok]),
           'wall_s': spread([r['wall_s'] for r in ok]),
           'sim_s': spread([r['sim_s'] for r in ok]),
           'cpu_by_process_s': {n: spread([r['cpu_by_process_s'].get(n, 0.0) for r in ok])
                                for n in names},
           'phases': {}}
    for ph in PHASES:
        have = [r['phases'][ph] for r in ok if ph in r.get('phases', {})]
        out['phases'][ph] = {
            'cpu_s': spread([h['cpu_s'] for h in have]),
            'wall_s': spread([h['wall_s'] for h in have]),
            'sim_s': spread([h['sim_s'] for h in have]),
            'cpu_by_process_s': {n: spread([h['cpu_by_process_s'].get(n, 0.0) for h in have])
                                 for n in names}}
    out['matched'] = spread([r.get('matched') for r in ok])
    out['in_view'] = spread([r.get('in_view') for r in ok])
    out['false_positives'] = spread([r.get('false_positives') for r in ok])
    out['rms_error_m'] = spread([r.get('rms_error_m') for r in ok])
    out['goal_error_m'] = spread([r.get('goal_error_m') for r in ok])
    return out


def _ratio(a, b):
    return None if a is None or b is None or b <= 0 else a / b


def ratios(pairs, this, other):
    """This tree over the commit: of the medians (``median_ratio``) and per pair (``pairs``:
    median, least, largest of each pair's ratio) for the stack, each process and each phase."""
    def both(get):
        done = [(a, b) for a, b in pairs if 'cpu_s' in a and 'cpu_s' in b]
        mine = spread([get(a) for a, _ in done])
        theirs = spread([get(b) for _, b in done])
        return {'median_ratio': _ratio(mine and mine['median'], theirs and theirs['median']),
                'pairs': spread([_ratio(get(a), get(b)) for a, b in done])}
    out = {'cpu_s': both(lambda r: r['cpu_s']), 'wall_s': both(lambda r: r['wall_s']),
           'sim_s': both(lambda r: r['sim_s']), 'cpu_by_process_s': {}, 'phases': {}}
    names = sorted(set(this['cpu_by_process_s']) | set(other['cpu_by_process_s']))
    for n in names:
        out['cpu_by_process_s'][n] = both(lambda r, n=n: r['cpu_by_process_s'].get(n, 0.0))
    for ph in PHASES:
        out['phases'][ph] = both(lambda r, ph=ph: r['phases'].get(ph, {}).get('cpu_s'))
    return out


def plot(report, path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    a, b = report['this']['summary'], report['other']['summary']
    la, lb = report['this']['label'], report['other']['label']
    names = sorted(set(a['cpu_by_process_s']) | set(b['cpu_by_process_s']),
                   key=lambda n: -((a['cpu_by_process_s'].get(n) or {}).get('median') or 0.0))
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 4.5), gridspec_kw={'width_ratios': [3, 1]})

    def bars(ax, keys, get, labels):
        for off, s, lab, col in ((-0.2, a, la, 'tab:blue'), (0.2, b, lb, 'tab:gray')):
            st = [get(s, k) or {'median': 0.0, 'min': 0.0, 'max': 0.0} for k in keys]
            med = [x['median'] for x in st]
            err = [[m - x['min'] for m, x in zip(med, st)], [x['max'] - m for m, x in zip(med, st)]]
            ax.bar([i + off for i in range(len(keys))], med, 0.4, yerr=err, capsize=3,
                   color=col, label=lab)
        ax.set_xticks(range(len(keys)))
        ax.set_xticklabels(labels, rotation=30, ha='right', fontsize=8)
        ax.set_ylabel('CPU [s] (median, bars: least to largest)')
        ax.legend(fontsize=8)

    bars(ax1, names, lambda s, n: s['cpu_by_process_s'].get(n), names)
    ax1.set_title('course mission at real_time_factor 0: CPU per process (%d pairs)'
                  % report['pairs'], fontsize=9)
    keys = list(PHASES) + ['stack']
    bars(ax2, keys, lambda s, k: s['cpu_s'] if k == 'stack' else s['phases'][k]['cpu_s'], keys)
    ax2.set_title('per phase and in all', fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def table(report):
    a, b = report['this']['summary'], report['other']['summary']
    r = report['ratios']
    rows = [('stack', a['cpu_s'], b['cpu_s'], r['cpu_s'])]
    rows += [(n, a['cpu_by_process_s'].get(n), b['cpu_by_process_s'].get(n),
              r['cpu_by_process_s'][n]) for n in sorted(r['cpu_by_process_s'])]
    rows += [('phase ' + ph, a['phases'][ph]['cpu_s'], b['phases'][ph]['cpu_s'], r['phases'][ph])
             for ph in PHASES]
    rows += [('wall', a['wall_s'], b['wall_s'], r['wall_s']),
             ('simulated', a['sim_s'], b['sim_s'], r['sim_s'])]

    def f(s):
        return '-' if not s else '%.3f (%.3f-%.3f)' % (s['median'], s['min'], s['max'])

    def g(x):
        return '-' if x is None else '%.3f' % x
    lines = ['%-22s %-24s %-24s %-8s %s' % ('[s]', report['this']['label'][:24],
                                          report['other']['label'][:24], 'ratio',
                                          'pair ratios')]
    for name, x, y, q in rows:
        p = q['pairs']
        lines.append('%-22s %-24s %-24s %-8s %s' % (name, f(x), f(y), g(q['median_ratio']),
                                                    '-' if not p else '%.3f (%.3f-%.3f)'
                                                    % (p['median'], p['min'], p['max'])))
    return lines


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--commit', default=DEFAULT_COMMIT, help='the earlier commit to compare with')
    ap.add_argument('--pairs', type=int, default=6, help='interleaved pairs of runs (>= 1)')
    ap.add_argument('--worktree', help='where the commit is checked out (kept and reused; '
                                       'default: a temporary directory, removed at the end)')
    ap.add_argument('--out', default=os.path.join(RESULTS, 'mission_cpu.json'))
    ap.add_argument('--child', help=argparse.SUPPRESS)
    ap.add_argument('--log', help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        run_child(args.child, args.log)
        return 0
    if args.pairs < 1:
        ap.error('--pairs must be >= 1')
    if not os.path.exists(os.path.join(ROOT, '.ws', '.done')):
        ap.error('this tree has no workspace: run `make setup` first')
    temp = None
    if args.worktree:
        worktree = os.path.abspath(args.worktree)
    else:
        temp = tempfile.mkdtemp(prefix='tiago_nav_cpu_')
        worktree = os.path.join(temp, 'tree')
    from tiago_nav_tools.benchmarks import commit as this_commit, launch_models, meta
    from tiago_nav.sim.world import load_world
    world = load_world(os.path.join(ROOT, 'worlds', WORLD))
    try:
        full, tree = prepare(args.commit, worktree)
        logs = tempfile.mkdtemp(prefix='tiago_nav_cpu_logs_')
        this = {'label': 'this tree', 'commit': this_commit(ROOT), 'runs': []}
        other = {'label': args.commit, 'commit': full, 'runs': []}
        pairs = []
        for k in range(args.pairs):
            pair = []
            # ABBA: this tree first in even pairs, the commit first in odd ones (a load that
            # rises or falls over the runs favours neither)
            order = ((this, ROOT), (other, tree))
            for side, where in (order if k % 2 == 0 else order[::-1]):
                log = os.path.join(logs, '%s_%d.log' % ('this' if side is this else 'other', k))
                rec = judge(run_in(where, log), world)
                rec['pair'] = k
                side['runs'].append(rec)
                pair.append(rec)
                print('  pair %d %-10s %s' % (k, side['label'][:10], 'error: ' + rec['error']
                      if 'error' in rec else
                      'cpu %.2f s  wall %.2f s  sim %.1f s  %s  %s/%s found  RMS %s  load %.1f  %s'
                      % (rec['cpu_s'], rec['wall_s'], rec['sim_s'],
                         'ok' if rec['succeeded'] else 'FAILED', rec.get('matched'),
                         rec.get('in_view'), '-' if rec.get('rms_error_m') is None else
                         '%.4f m' % rec['rms_error_m'], rec['loadavg_at_goal'][0],
                         ' '.join('%s %.2f' % kv for kv in sorted(rec['cpu_by_process_s'].items())
                                  if kv[1] >= 0.05))), flush=True)
            pairs.append(tuple(pair) if k % 2 == 0 else tuple(pair[::-1]))
        shutil.rmtree(logs, ignore_errors=True)
    finally:
        if temp:
            subprocess.call(['git', 'worktree', 'remove', '--force', worktree], cwd=ROOT)
            shutil.rmtree(temp, ignore_errors=True)
    this['summary'], other['summary'] = summarise(this['runs']), summarise(other['runs'])
    report = {'world': WORLD, 'goal': list(COURSE), 'use_corridor_law': True,
              'real_time_factor': 0.0, 'pairs': args.pairs,
              'order': 'this tree first in even pairs (0, 2, ...), the commit first in odd ones',
              'this': this, 'other': other, 'ratios': ratios(pairs, this['summary'], other['summary'])}
    laser, odometry = launch_models()
    report['meta'] = meta({k: v for k, v in vars(args).items() if k not in ('child', 'log')},
                          real_time_factor=0.0, laser_model=laser, odometry_model=odometry)
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, 'w') as f:
        json.dump(report, f, indent=2)
    png = os.path.splitext(args.out)[0] + '.png'
    plot(report, png)
    print('\n'.join(table(report)))
    print('wrote %s and %s' % (os.path.relpath(args.out), os.path.relpath(png)))
    return 0


if __name__ == '__main__':
    sys.exit(main())
