"""One run's process tree, its watchdog and its verdict (no ROS in this process).

:func:`execute` starts the run's supervisor (:mod:`tiago_nav_tools.evaluate.supervisor`: roscore,
demo.launch, the candidate, the mission client) as the leader of a new session, on the
worker slot's port (:func:`claim_slot`), with its own ROS_HOME, ROS_LOG_DIR and folder, and
loopback-only ROS_IP/ROS_HOSTNAME/ROS_MASTER_URI; where network namespaces are available
(:mod:`tiago_nav_tools.evaluate.isolation`), in a network namespace of its own with only loopback
(the run's ``isolation``, from its spec or ``TIAGO_NAV_EVAL_ISOLATION``, ``auto`` by default).
The supervisor marks its stages with their time and CPU (:mod:`tiago_nav_tools.evaluate.timing`),
from which the result's ``phases`` come. A wall-clock watchdog kills the whole
group; afterwards every process still carrying the run's token in its environment (roslaunch
puts each node in a session of its own) is killed too. :func:`judge` turns the supervisor's
``raw.json`` into ``result.json`` (:data:`SCHEMA`), written atomically.
"""
import fcntl
import json
import math
import os
import resource
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

SCHEMA = 1
BASE_PORT = 12000
PORT_STEP = 10
MAX_SLOTS = 100                 # ports 12000..12990
INFRA = ('INFRA_LAUNCH', 'INFRA_NODE_DIED', 'INFRA_SCENARIO', 'INFRA_CONTRACT')
OUTCOMES = ('succeeded', 'aborted', 'collision', 'timeout', 'detection_failure') + INFRA
TOKEN_VAR = 'TIAGO_NAV_EVAL_TOKEN'
# result.json fields that follow the wall clock or the worker, not the run's row (a warm
# stack's verification of its reset among them: tiago_nav_tools.evaluate.warm.verify)
WALL_CLOCK_FIELDS = ('cpu_s', 'wall_s', 'run_wall_s', 'startup_wall_s', 'sim_wall_ratio', 'host',
                     'port', 'slot', 'attempt', 'first_attempt', 'phases', 'isolation',
                     'leftover_processes', 'stack', 'reset_failed', 'verified', 'diverged',
                     'reset_result', 'verify_error')
_SLOTS = {}                     # this process's claimed slots: {role: {'slot', 'fd'}}


def slot_dir():
    return os.path.join(tempfile.gettempdir(), 'tiago_nav_eval_slots')


def _port_free(port):
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(('127.0.0.1', port))
            return True
        except OSError:
            return False


def claim_slot(role='run'):
    """This process's worker slot for ``role`` (claimed once, for its lifetime): the first
    ``k`` whose lock file under :func:`slot_dir` no other live process holds (flock) and whose
    port ``BASE_PORT + PORT_STEP * k`` is free. Two processes never share a slot, nor two roles
    of one process (a worker's warm stack runs on its ``run`` slot while the fresh run that
    verifies one of its rows runs on its ``verify`` slot)."""
    if role in _SLOTS:
        return _SLOTS[role]['slot']
    os.makedirs(slot_dir(), exist_ok=True)
    for k in range(MAX_SLOTS):
        fd = os.open(os.path.join(slot_dir(), 'slot_%02d.lock' % k), os.O_CREAT | os.O_RDWR, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            continue
        if not _port_free(port_of(k)):
            fcntl.flock(fd, fcntl.LOCK_UN)
            os.close(fd)
            continue
        os.ftruncate(fd, 0)
        os.write(fd, str(os.getpid()).encode())
        _SLOTS[role] = {'slot': k, 'fd': fd}
        return k
    raise RuntimeError('no free evaluation slot (ports %d..%d)' % (BASE_PORT, port_of(MAX_SLOTS - 1)))


def port_of(slot):
    return BASE_PORT + PORT_STEP * slot


def run_env(run_dir, port, token):
    env = dict(os.environ)
    env.update(ROS_MASTER_URI='http://127.0.0.1:%d' % port, ROS_IP='127.0.0.1',
               ROS_HOSTNAME='localhost', ROS_HOME=os.path.join(run_dir, 'ros_home'),
               ROS_LOG_DIR=os.path.join(run_dir, 'logs'), PYTHONUNBUFFERED='1')
    env[TOKEN_VAR] = token
    return env


def tagged_pids(token):
    """Pids of live processes whose environment carries ``TOKEN_VAR=token``."""
    needle = ('%s=%s' % (TOKEN_VAR, token)).encode() + b'\0'
    out = []
    for pid in os.listdir('/proc'):
        if not pid.isdigit() or int(pid) in (os.getpid(), os.getppid()):
            continue
        try:
            with open('/proc/%s/environ' % pid, 'rb') as f:
                if needle in f.read() + b'\0':
                    out.append(int(pid))
        except OSError:
            continue
    return out


def kill_tree(leader, token):
    """Kill the run's process group ``leader`` and every process carrying its ``token``
    (each one's own process group too: roslaunch gives every node a session). Returns how many
    processes had to be killed after the group."""
    try:
        os.killpg(leader, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    left = 0
    for _ in range(3):
        pids = tagged_pids(token)
        if not pids:
            break
        left += len(pids)
        for pid in pids:
            for kill in (lambda p: os.killpg(os.getpgid(p), signal.SIGKILL),
                         lambda p: os.kill(p, signal.SIGKILL)):
                try:
                    kill(pid)
                except (ProcessLookupError, PermissionError):
                    pass
        time.sleep(0.2)
    return left


def write_json(path, obj):
    """Write ``obj`` as JSON atomically (a temporary file, then os.replace)."""
    tmp = '%s.tmp.%d' % (path, os.getpid())
    with open(tmp, 'w') as f:
        json.dump(obj, f, indent=1, sort_keys=True)
    os.replace(tmp, path)


def read_json(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def execute(spec, out_dir, record=False, attempt=1, role='run'):
    """Run ``spec`` (a run row) once: its supervisor in its own session, watched, on this
    process's slot for ``role`` (:func:`claim_slot`). Returns the judged result dict (also
    written to ``runs/ID/result.json``)."""
    slot = claim_slot(role)
    port = port_of(slot)
    run_dir = os.path.join(out_dir, 'runs', spec['id'])
    shutil.rmtree(run_dir, ignore_errors=True)
    os.makedirs(os.path.join(run_dir, 'logs'))
    os.makedirs(os.path.join(run_dir, 'ros_home'))
    spec = dict(spec, record=record, world_path=world_path(spec, out_dir))
    write_json(os.path.join(run_dir, 'spec.json'), spec)
    token = '%s.%d.%d' % (spec['id'], os.getpid(), attempt)
    env = run_env(run_dir, port, token)
    lim = spec['limits']
    wall_limit = lim['startup_timeout'] + lim['wall_time_limit'] + 30.0
    from tiago_nav_tools.evaluate import isolation as iso
    mode = iso.resolve(spec.get('isolation') or os.environ.get(iso.MODE_VAR, 'auto'))
    cmd = iso.command(mode, [sys.executable, '-m', 'tiago_nav_tools.evaluate.supervisor', run_dir])
    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    w0 = time.monotonic()
    with open(os.path.join(run_dir, 'supervisor.log'), 'w') as log:
        p = subprocess.Popen(cmd, env=env,
                             stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                             start_new_session=True)
        watchdog = False
        try:
            p.wait(wall_limit)
        except subprocess.TimeoutExpired:
            watchdog = True
        leftovers = kill_tree(p.pid, token)
        p.wait()
    wall = time.monotonic() - w0
    ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
    raw = read_json(os.path.join(run_dir, 'raw.json'))
    try:
        with open(os.path.join(run_dir, 'stage')) as f:
            stage = f.read().strip()
    except OSError:
        stage = 'none'
    if raw is None:
        if watchdog and stage == 'mission':
            raw = {'timed_out': True, 'watchdog': True,
                   'reason': 'wall-clock watchdog: no result within %.0f s' % wall_limit}
        else:
            raw = {'infra': 'INFRA_LAUNCH',
                   'reason': 'no result from the run (stage %s, supervisor exit %s%s; see '
                             'supervisor.log)' % (stage, p.returncode, ', killed by the wall-clock '
                                                  'watchdog' if watchdog else '')}
    j0, jc0 = time.monotonic(), time.process_time()
    result = judge(spec, raw)
    from tiago_nav_tools.evaluate.timing import phases, read_marks
    result.update(attempt=attempt, slot=slot, port=port, run_wall_s=wall, cpu_s=cpu,
                  leftover_processes=leftovers, host=socket.gethostname(), isolation=mode,
                  phases=phases(read_marks(run_dir), w0, w0 + wall, cpu, time.monotonic() - j0,
                                time.process_time() - jc0))
    write_json(os.path.join(run_dir, 'result.json'), result)
    return result


def same(a, b, tol=1e-9):
    """Equal values, numbers to within ``tol`` (absolute; relative for large ones): tf's
    interpolation can round the last bit differently with its cache's history, which is not
    part of a run's row. Lists and dicts element by element."""
    if isinstance(a, bool) or isinstance(b, bool) or a is None or b is None:
        return type(a) is type(b) and a == b
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        if a == b:
            return True         # (infinities too: an unknown std is +inf in both)
        if not (math.isfinite(a) and math.isfinite(b)):
            return math.isnan(a) and math.isnan(b)     # (an infinity equals only itself)
        return abs(a - b) <= tol * max(1.0, abs(a), abs(b))
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(same(x, y, tol) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k], tol) for k in a)
    return a == b


def differences(a, b):
    """The fields of two results of one run (``result.json`` dicts) that differ (:func:`same`),
    leaving out :data:`WALL_CLOCK_FIELDS` and nothing else (uncertainties and covariances,
    ``found_detail`` and ``loc_covariance``, are compared as every other field, and so is any
    field a result gains): at ``real_time_factor`` 0 in lockstep a run's outcome and every
    other figure are a function of its row, wherever and beside whatever it ran."""
    keys = (set(a) | set(b)) - set(WALL_CLOCK_FIELDS)
    return sorted(k for k in keys if not same(a.get(k), b.get(k)))


def world_path(spec, out_dir):
    """The run's world file: the suite's file, or the generated world written under
    ``out_dir/worlds`` (by the command line before any run)."""
    if spec.get('world_file') and os.path.isfile(spec['world_file']):
        return spec['world_file']
    return os.path.join(os.path.abspath(out_dir), 'worlds', spec['world']['name'] + '.yaml')


def execute_with_retry(spec, out_dir, record=False):
    """:func:`execute`, and once more when the first attempt ended in an infrastructure
    error; the result keeps the first attempt's outcome and reason in ``first_attempt``."""
    r = execute(spec, out_dir, record)
    if r['outcome'] in INFRA:
        first = {'outcome': r['outcome'], 'reason': r['reason']}
        r = execute(spec, out_dir, record, attempt=2)
        r['first_attempt'] = first
        write_json(os.path.join(out_dir, 'runs', spec['id'], 'result.json'), r)
    return r


def judge(spec, raw, min_beams=None):
    """The run's result from its spec and the supervisor's raw record: the outcome (infra >
    timeout > collision > aborted > detection failure > succeeded), its reason and the
    metrics (:mod:`tiago_nav_tools.evaluate.metrics`). ``min_beams``: the usable beams that make an
    obstacle in view (None: :data:`tiago_nav_tools.evaluate.inview.MIN_BEAMS`; the rescoring's plain rule
    passes :data:`tiago_nav_tools.evaluate.inview.PLAIN_BEAMS`)."""
    from tiago_nav_tools.evaluate import metrics as M
    base = {'schema': SCHEMA, 'run_id': spec['id'], 'pair': spec.get('pair'),
            'world': spec['world']['name'], 'world_group': spec['world'].get('group'),
            'goal': spec['goal'], 'profile': spec['profile'], 'use_corridor_law': spec['use_corridor_law'],
            'seed': spec['seed'], 'candidate': spec['candidate'],
            'launch_args': spec['launch_args']}
    if raw.get('infra'):
        return dict(base, outcome=raw['infra'], reason=raw.get('reason', ''))
    if 'state' not in raw and not raw.get('watchdog'):
        return dict(base, outcome='INFRA_LAUNCH', reason=raw.get('reason', 'incomplete record'))
    from tiago_nav.sim.world import load_world
    world = load_world(spec['world_path'])
    path = raw.get('path') or []
    start = path[0] if path else world.start_pose
    final = raw.get('final_pose')
    goal = spec['goal']
    shortest = M.shortest_path_length(world, start[:2], goal[:2])
    driven = M.path_length(path)
    sim_t = raw.get('sim_s')
    m = {'time_s': sim_t, 'wall_s': raw.get('wall_s'), 'path_length_m': driven,
         'shortest_m': shortest, 'collisions': raw.get('collisions'),
         'min_clearance_m': M.min_clearance(path, world),
         'sim_wall_ratio': M.ratio(sim_t, raw.get('wall_s')),
         'startup_wall_s': raw.get('startup_wall_s'),
         'final_pose': final, 'goal_error_m': math.hypot(final[0] - goal[0], final[1] - goal[1])
         if final else None}
    loc = raw.get('loc_errors') or []
    m['loc_error_p95_m'] = M.percentile([e[0] for e in loc], 95)
    m['loc_error_max_m'] = M.percentile([e[0] for e in loc], 100)
    m['loc_error_p95_deg'] = (math.degrees(M.percentile([e[1] for e in loc], 95)) if loc else None)
    m['loc_samples'] = len(loc)
    # among walkers: the least gap of the base's body to a walker's legs, the time it stood
    # still away from pose B (metrics.closest_walker, metrics.waiting_time)
    truth_log, walker_log = raw.get('truth_log') or [], raw.get('walkers') or []
    if world.walkers:
        m['closest_walker_m'] = M.closest_walker(truth_log, walker_log)
        m['waiting_s'] = M.waiting_time(truth_log, goal[:2]) if truth_log else None
        # the oldest ghost in the navigation's published costmaps (ghosts.py; None: none came)
        ghosts = raw.get('ghosts') or []
        m['ghost_age_s'] = max(g[1] for g in ghosts) if ghosts else None
    det_ok, det = True, {}
    if raw.get('state') == 3 and final:         # SUCCEEDED: judge what it reported
        from tiago_nav_tools.evaluate import inview
        from tiago_nav_tools.evaluate import shapes as S
        from tiago_nav.sim.scene import Scene
        obs = world.movable_obstacles
        with Scene(world) as scene:
            # the walkers where they stood at the end, the newest of the scans at rest (a
            # walker in front of an obstacle hides it)
            inview.place_walkers(scene, walker_log[-1][1] if walker_log else None)
            v = inview.view_from(scene, tuple(final), spec['profile'],
                                 inview.MIN_BEAMS if min_beams is None else min_beams)
            # what the cast saw of each shape but a cylinder (faces, legs: where targets apply)
            parts = S.parts_in_view(scene, final, spec['profile'],
                                    [i for i in v.in_view + v.glimpsed if obs[i].shape != 'cylinder'])
        found = [(o[0], o[1]) for o in raw.get('obstacles', [])]
        details = raw.get('obstacles_detail') or []
        # the reports that lie where a walker was during the scans at rest (metrics.PERSON_WINDOW)
        walkers = M.walker_reports(found, details, walker_log,
                                   walker_log[-1][0]) if walker_log else None
        # the centres the detection said it could not fix, with the bound it claims
        bounds = {j: d['center_covariance'] for j, d in enumerate(details)
                  if d.get('center_fixed') is False and d.get('center_covariance')}
        det_ok, det = M.detection([(obs[i].x, obs[i].y) for i in v.in_view], found,
                                  spec['limits']['detection_tolerance'],
                                  [(obs[i].x, obs[i].y) for i in v.glimpsed], walkers, bounds)
        det['truth'] = [[obs[i].x, obs[i].y, obs[i].radius] for i in v.in_view]
        # every obstacle a beam reached: its beams and usable beams (a rescoring's input),
        # whether it is in view, and its centre error when matched (None: not found)
        seen = v.in_view + v.glimpsed
        errors = det.pop('errors')
        err = {seen[e['index']]: e['error'] for e in errors}
        det['view'] = [{'index': i, 'x': obs[i].x, 'y': obs[i].y, 'radius': obs[i].radius,
                        'beams': v.beams[i], 'usable_beams': v.usable_beams[i],
                        'in_view': i in v.in_view, 'error': err.get(i)} for i in sorted(seen)]
        # each obstacle in view or matched: its shape, the label reported, the centre, extent
        # and orientation errors (tiago_nav_tools.evaluate.shapes)
        pair = {seen[e['index']]: e['found'] for e in errors}
        det['shapes'] = S.score(obs, [{'index': i, 'in_view': i in v.in_view, 'found': pair.get(i),
                                       'error': err.get(i)}
                                      for i in sorted(seen) if i in v.in_view or i in pair],
                                details, parts)
    m.update({'detection_' + k if k in ('problem', 'truth', 'view', 'shapes') else k: v
              for k, v in det.items()})
    m['found'] = raw.get('obstacles', [])
    # every field of each reported obstacle as the message had it (its uncertainty and its
    # centre in the robot's frame among them), and the localisation's covariance during the
    # mission: :func:`differences` compares them as every other field
    m['found_detail'] = raw.get('obstacles_detail', [])
    m['loc_covariance'] = raw.get('loc_covariance', [])
    m['path'] = path
    m['feedback'] = raw.get('feedback', [])
    # the mission's last records that had not come within the supervisor's END_WAIT: the logs
    # (walkers, true poses, localisation) they would have ended are short by that much
    m['end_missing'] = raw.get('end_missing') or []
    if raw.get('timed_out'):
        outcome = 'timeout'
        reason = raw.get('reason') or 'no result within %g s of simulated time' % spec['limits']['sim_time_limit']
    elif (raw.get('collisions') or 0) > 0:
        outcome, reason = 'collision', '%d contact(s) in the simulator' % raw['collisions']
    elif raw.get('state') != 3:
        outcome = 'aborted'
        reason = '%s: %s' % (raw.get('state_name', raw.get('state')),
                             raw.get('status_text') or raw.get('message') or '(no reason given)')
    elif not det_ok:
        outcome, reason = 'detection_failure', det['problem']
    else:
        outcome, reason = 'succeeded', raw.get('message', '')
    ok = outcome == 'succeeded'
    m['success'] = M.success(outcome)
    m['spl'] = M.spl(ok, shortest, driven) if shortest is not None else None
    ot = shortest / M.MAX_SPEED if shortest is not None else None
    m['optimal_time_s'] = ot
    m['barn_score'] = M.barn_score(ok, ot, sim_t) if ot and sim_t is not None else None
    return dict(base, outcome=outcome, reason=reason, **m)
