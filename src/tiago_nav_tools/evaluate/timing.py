"""Where a run's time goes (no ROS here): its wall time and CPU in four phases.

``startup``
    from starting the run's supervisor to the goal about to be sent: the supervisor's own
    start, the master, demo.launch and the candidate, readiness and the scenario check;
``mission``
    from there to the mission's end (the result, the base at rest, the last tf samples);
``teardown``
    stopping every process of the run (SIGINT, then harder) until the last one is gone;
``judging``
    turning the supervisor's record into the result (metrics, detection against the truth).

The supervisor marks each stage (:func:`mark`) in ``RUN_DIR/stages``: the stage, the
monotonic clock (system-wide on Linux, so comparable between processes) and the CPU seconds
used so far by every live process carrying the run's token (their own and their reaped
children's: a process that ended was counted in its parent). :func:`phases` turns the marks,
the run's start and end and the judging's own figures into ``{phase: {'wall_s', 'cpu_s'}}``.
"""
import os
import time

PHASES = ('startup', 'mission', 'teardown', 'judging')
STAGES_FILE = 'stages'
_TICK = os.sysconf('SC_CLK_TCK')


def tree_cpu(token, token_var):
    """CPU seconds (user + system, own + reaped children's) of every live process whose
    environment carries ``token_var=token``, this process included."""
    needle = ('%s=%s' % (token_var, token)).encode() + b'\0'
    total = 0
    for pid in os.listdir('/proc'):
        if not pid.isdigit():
            continue
        try:
            with open('/proc/%s/environ' % pid, 'rb') as f:
                if needle not in f.read() + b'\0':
                    continue
            with open('/proc/%s/stat' % pid, 'rb') as f:
                stat = f.read()
        except OSError:
            continue
        fields = stat[stat.rindex(b')') + 2:].split()
        total += sum(int(v) for v in fields[11:15])     # utime stime cutime cstime
    return total / _TICK


def mark(run_dir, stage, token=None, token_var=None):
    """Append ``stage``, the monotonic time and the run's CPU so far to ``RUN_DIR/stages``
    (CPU -1 without a token; nothing when the file cannot be written)."""
    cpu = tree_cpu(token, token_var) if token and token_var else -1.0
    try:        # a mark that cannot be written costs the breakdown, never the run
        with open(os.path.join(run_dir, STAGES_FILE), 'a') as f:
            f.write('%s %.6f %.3f\n' % (stage, time.monotonic(), cpu))
    except OSError:
        pass


def read_marks(run_dir):
    """``{stage: (monotonic, cpu)}`` from ``RUN_DIR/stages`` (the first mark of each stage)."""
    out = {}
    try:
        with open(os.path.join(run_dir, STAGES_FILE)) as f:
            for line in f:
                parts = line.split()
                if len(parts) == 3 and parts[0] not in out:
                    try:
                        out[parts[0]] = (float(parts[1]), float(parts[2]))
                    except ValueError:
                        continue
    except OSError:
        pass
    return out


def phases(marks, start, end, cpu_total, judging_wall, judging_cpu):
    """``{phase: {'wall_s', 'cpu_s'}}`` of one run. ``marks``: :func:`read_marks`; ``start``,
    ``end``: monotonic times of starting the supervisor and of the last process gone;
    ``cpu_total``: the run's processes' CPU seconds; ``judging_*``: the judging's wall and
    CPU seconds. A phase the run never reached (a start-up that failed has no mission) has
    0 s; a phase whose CPU is unknown (no mark) has ``cpu_s`` None."""
    m = marks.get('mission')
    t = marks.get('teardown')
    t_mission = m[0] if m else None
    t_teardown = t[0] if t else end
    startup_end = t_mission if t_mission is not None else t_teardown
    out = {'startup': {'wall_s': max(0.0, startup_end - start)},
           'mission': {'wall_s': max(0.0, t_teardown - t_mission) if t_mission is not None else 0.0},
           'teardown': {'wall_s': max(0.0, end - t_teardown)},
           'judging': {'wall_s': judging_wall, 'cpu_s': judging_cpu}}
    cpu_m = m[1] if m and m[1] >= 0 else None
    cpu_t = t[1] if t and t[1] >= 0 else None
    out['startup']['cpu_s'] = cpu_m if cpu_m is not None else cpu_t
    out['mission']['cpu_s'] = (max(0.0, cpu_t - cpu_m) if cpu_m is not None and cpu_t is not None
                               else 0.0 if m is None and cpu_t is not None else None)
    out['teardown']['cpu_s'] = max(0.0, cpu_total - cpu_t) if cpu_t is not None and cpu_total is not None \
        else None
    return out


def batch(results, wall_s, workers=None):
    """The batch's time by phase, from its results' ``phases``: per phase the total, the
    median and the share of the runs' summed wall time, wall and CPU; and ``mission_share``,
    the share of the batch's worker time (``wall_s`` x ``workers``; the runs' summed wall time
    when the worker count is unknown) spent in missions. None where no run has phases."""
    from tiago_nav_tools.evaluate.metrics import median
    timed = [r['phases'] for r in results if isinstance(r.get('phases'), dict)]
    if not timed:
        return None
    run_wall = sum(sum((p.get(k) or {}).get('wall_s') or 0.0 for k in PHASES) for p in timed)
    out = {'runs': len(timed), 'run_wall_s': run_wall, 'phases': {}}
    for k in PHASES:
        walls = [(p.get(k) or {}).get('wall_s') for p in timed]
        cpus = [(p.get(k) or {}).get('cpu_s') for p in timed]
        w = sum(v for v in walls if v is not None)
        c = [v for v in cpus if v is not None]
        out['phases'][k] = {'wall_s': w, 'median_wall_s': median(walls),
                            'wall_share': w / run_wall if run_wall > 0 else None,
                            'cpu_s': sum(c) if c else None, 'median_cpu_s': median(cpus)}
    worker_time = wall_s * workers if wall_s and workers else run_wall
    mission = out['phases']['mission']['wall_s']
    out['worker_time_s'] = worker_time
    out['mission_share'] = mission / worker_time if worker_time > 0 else None
    return out
