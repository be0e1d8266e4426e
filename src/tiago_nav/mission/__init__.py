"""The mission of ``tiago_controller`` (the TiagoTask proxy) as a ROS-free state machine.

One goal runs three stages in order, each with its own timeout:

1. ``corridor`` (only with ``use_corridor_law``): the corridor_controller action;
2. ``navigation``: pose B sent to move_base;
3. ``detection``: one call of the obstacle_detection service.

The runner talks to the outside world through a *backend* (``nodes/tiago_controller`` wires
it to actionlib/rospy; the unit tests use a fake), so every path (success, server absent,
aborted, timed out, clock stopped, cancelled) is testable without a ROS master.

Units: metres, radians (degrees only where a name says ``_deg``), seconds. Poses are
``(x, y, yaw)`` of base_footprint in the ``map`` frame. ``now()`` is ROS time (simulated time
under /use_sim_time); stage timeouts count in it. ``wall()`` is a monotonic wall clock; waits for
servers and the "simulated clock stopped" guard count in it, so nothing hangs if /clock stops.
"""
import math
from dataclasses import dataclass, field
from typing import Any, List, Optional, Tuple

from tiago_nav.geometry import wrap_angle
from tiago_nav.motion import MotionMonitor  # noqa: F401  (TRANSITIONAL re-export)

# --- feedback states (the TiagoTask.action constants) ----------------------------------------
GOAL_RECEIVED, CORRIDOR, NAVIGATING, MOVING, STOPPED, ARRIVED, DETECTING, DETECTION_DONE = range(8)
STATE_NAMES = ('GOAL_RECEIVED', 'CORRIDOR', 'NAVIGATING', 'MOVING', 'STOPPED', 'ARRIVED',
               'DETECTING', 'DETECTION_DONE')

STAGES = ('corridor', 'navigation', 'detection')

# Outcomes of an action stage as seen by the runner (from actionlib's terminal states).
ACTIVE, SUCCEEDED, ABORTED, PREEMPTED, REJECTED, LOST = ('active', 'succeeded', 'aborted',
                                                         'preempted', 'rejected', 'lost')

YAW_LIMIT_DEG = 360.0      # |yaw| accepted by goal validation [deg]


# --- goal validation -------------------------------------------------------------------------
class GoalError(ValueError):
    """A goal value that cannot be used (not a number, not finite, out of range)."""


def parse_number(value, name):
    """``value`` (a string or a number) as a finite float; :class:`GoalError` naming ``name``
    otherwise."""
    if isinstance(value, bool):
        raise GoalError('%s: expected a number, got %r' % (name, value))
    try:
        f = float(value.strip() if isinstance(value, str) else value)
    except (TypeError, ValueError):
        raise GoalError('%s: %r is not a number' % (name, value)) from None
    if not math.isfinite(f):
        raise GoalError('%s: %r is not a finite number' % (name, value))
    return f


def validate_goal(x, y, yaw_deg):
    """Check pose B: ``x``, ``y`` [m] in ``map`` and ``yaw_deg`` [deg], strings or numbers.

    Returns ``(x, y, yaw_deg)`` as floats; raises :class:`GoalError` with a sentence naming the
    bad value. The yaw is in degrees and must lie within ±360.
    """
    x = parse_number(x, 'x')
    y = parse_number(y, 'y')
    yaw = parse_number(yaw_deg, 'yaw')
    if abs(yaw) > YAW_LIMIT_DEG:
        raise GoalError('yaw: %g is out of range; give the yaw in degrees, between -%g and %g'
                        % (yaw, YAW_LIMIT_DEG, YAW_LIMIT_DEG))
    return x, y, yaw


# --- motion and progress ---------------------------------------------------------------------
def remaining_path_length(path, position):
    """Length [m] of ``path`` (a sequence of ``(x, y)``, map frame) from the point nearest to
    ``position`` to its end, plus the distance from ``position`` to that point. None if the path
    is empty."""
    if path is None or len(path) == 0:
        return None
    px, py = position[0], position[1]
    best, best_i, best_pt = math.inf, 0, tuple(path[0][:2])
    for i in range(len(path) - 1):
        ax, ay = path[i][0], path[i][1]
        bx, by = path[i + 1][0], path[i + 1][1]
        dx, dy = bx - ax, by - ay
        L2 = dx * dx + dy * dy
        u = 0.0 if L2 == 0 else max(0.0, min(1.0, ((px - ax) * dx + (py - ay) * dy) / L2))
        qx, qy = ax + u * dx, ay + u * dy
        d = math.hypot(px - qx, py - qy)
        if d < best:
            best, best_i, best_pt = d, i, (qx, qy)
    if len(path) == 1:
        return math.hypot(px - path[0][0], py - path[0][1])
    rest = math.hypot(path[best_i + 1][0] - best_pt[0], path[best_i + 1][1] - best_pt[1])
    for i in range(best_i + 1, len(path) - 1):
        rest += math.hypot(path[i + 1][0] - path[i][0], path[i + 1][1] - path[i][1])
    return best + rest


# --- sentences -------------------------------------------------------------------------------
def fmt_pose(pose):
    """``(x, y, yaw)`` → ``'(1.00, 2.00, -45 deg)'``."""
    return '(%.2f, %.2f, %.0f deg)' % (pose[0], pose[1], math.degrees(pose[2]))


def goal_sentence(x, y, yaw_deg, use_corridor_law):
    return 'goal received: go to (%.2f, %.2f, %.0f deg)%s' % (
        x, y, yaw_deg, ', through the corridor with the laser-only law first' if use_corridor_law
        else '')


def corridor_sentence(distance=None, lateral_offset=None, left=None, right=None):
    """A sentence about the corridor law's progress (feedback of corridor_controller)."""
    if distance is None:
        return 'driving the corridor with the laser-only law'
    s = 'in the corridor, %.1f m driven' % distance
    if lateral_offset is not None and math.isfinite(lateral_offset):
        side = 'left' if lateral_offset >= 0 else 'right'
        s += ', %.2f m %s of the centre line' % (abs(lateral_offset), side)
    if left is not None and right is not None and math.isfinite(left) and math.isfinite(right):
        s += ' (walls %.2f m left, %.2f m right)' % (left, right)
    return s


def motion_sentence(moving, to_go):
    """``'moving, 3.2 m to go'`` / ``'stopped, 0.4 m to go'``."""
    word = 'moving' if moving else 'stopped'
    return word if to_go is None else '%s, %.1f m to go' % (word, to_go)


def plural(n, word):
    return '%d %s%s' % (n, word, '' if n == 1 else 's')


# --- the runner ------------------------------------------------------------------------------
@dataclass
class MissionConfig:
    """Timeouts and thresholds of the mission (parameters of nodes/tiago_controller).

    ``*_timeout`` of a stage: ROS (simulated) seconds from its start; ``server_timeout`` and
    ``detection_timeout``: wall seconds (waiting for a server, one service call);
    ``clock_timeout``: wall seconds without ROS time advancing before a stage is abandoned.
    """
    server_timeout: float = 10.0
    corridor_timeout: float = 120.0
    navigation_timeout: float = 240.0
    detection_timeout: float = 10.0
    settle_timeout: float = 3.0
    stop_timeout: float = 5.0
    clock_timeout: float = 10.0
    feedback_period: float = 1.0
    poll_period: float = 0.02
    moving_speed: float = 0.05
    moving_turn_rate: float = 0.1
    motion_window: float = 0.5
    corridor_max_speed: float = 0.0
    corridor_max_distance: float = 0.0

    def __post_init__(self):
        for k, v in self.__dict__.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError('%s must be a finite number, got %r' % (k, v))
            if k.startswith('corridor_max'):
                if v < 0:
                    raise ValueError('%s must be >= 0 (0: the server default), got %r' % (k, v))
            elif v <= 0:
                raise ValueError('%s must be > 0, got %r' % (k, v))


@dataclass
class Goal:
    x: float
    y: float
    yaw_deg: float
    use_corridor_law: bool = True

    @property
    def pose(self):
        return (self.x, self.y, math.radians(self.yaw_deg))


@dataclass
class Poll:
    """What a backend reports about a running action stage."""
    status: str = ACTIVE             # ACTIVE or a terminal outcome
    text: str = ''                   # the server's status text (reason)
    result: Any = None
    feedback: Any = None


@dataclass
class Outcome:
    status: str                      # SUCCEEDED, ABORTED or PREEMPTED
    message: str
    obstacles: List[Any] = field(default_factory=list)
    final_pose: Optional[Tuple[float, float, float]] = None
    stage: Optional[str] = None      # the stage that failed or was cancelled


class StageError(Exception):
    """A stage failed; ``str()`` names the stage and the reason."""

    def __init__(self, stage, reason):
        super().__init__('%s failed: %s' % (stage, reason))
        self.stage, self.reason = stage, reason


class DetectionError(Exception):
    """Raised by a backend's ``detect`` when the service is absent, errs or times out."""


class _Preempted(Exception):
    def __init__(self, stage):
        super().__init__(stage)
        self.stage = stage


class MissionRunner:
    """Runs one goal after another through a backend.

    The backend provides: ``now()``, ``wall()``, ``sleep(wall_seconds)``,
    ``preempt_requested()``, ``pose()`` (``(x, y, yaw)`` in map or None), ``path()`` (the
    current plan as ``[(x, y), ...]`` or None), ``server_ready(stage)``, ``send_goal(stage,
    goal)`` (corridor: ``(max_speed, max_distance)``; navigation: ``(x, y, yaw)``),
    ``poll(stage) -> Poll``, ``cancel(stage)``, ``detect(timeout) -> (obstacles, message)``
    raising :class:`DetectionError`, ``stop_robot()`` and ``publish_feedback(state, status,
    pose)``.
    """

    def __init__(self, backend, config=None, log=None):
        self.b = backend
        self.cfg = config or MissionConfig()
        self.log = log or (lambda msg: None)
        self.motion = MotionMonitor(self.cfg.motion_window, self.cfg.moving_speed,
                                    self.cfg.moving_turn_rate)
        self.state = None
        self.status = ''
        self._last_feedback = -math.inf

    # --- feedback --------------------------------------------------------------------------
    def feedback(self, state, status, force=True):
        """Publish feedback now if the state or sentence changed (or ``force``), else at most
        once per ``feedback_period``."""
        t = self.b.now()
        changed = state != self.state
        if changed or force or (status != self.status
                                and t - self._last_feedback >= self.cfg.feedback_period):
            self.state, self.status, self._last_feedback = state, status, t
            self.b.publish_feedback(state, status, self.b.pose())
            if changed:
                self.log('%s: %s' % (STATE_NAMES[state], status))

    # --- one goal --------------------------------------------------------------------------
    def run(self, goal):
        """Run ``goal`` (:class:`Goal`); return an :class:`Outcome`. The robot is told to stop
        whatever the outcome."""
        self.state, self.status = None, ''
        self.motion.reset()
        stage = None
        try:
            try:
                x, y, yaw = validate_goal(goal.x, goal.y, goal.yaw_deg)
            except GoalError as e:
                raise StageError('goal validation', str(e)) from None
            goal = Goal(x, y, yaw, bool(goal.use_corridor_law))
            self.feedback(GOAL_RECEIVED, goal_sentence(x, y, yaw, goal.use_corridor_law))
            if goal.use_corridor_law:
                stage = 'corridor'
                self._corridor()
            stage = 'navigation'
            self._navigate(goal)
            stage = 'detection'
            obstacles, message = self._detect()
        except _Preempted as e:
            self.b.stop_robot()
            stopped = self._wait_stopped(self.cfg.stop_timeout)
            pose = self.b.pose()
            msg = 'cancelled during %s; robot %s%s' % (
                e.stage, 'stopped' if stopped else 'told to stop (still moving after %g s)'
                % self.cfg.stop_timeout, ' at %s' % fmt_pose(pose) if pose else '')
            return Outcome(PREEMPTED, msg, final_pose=pose, stage=e.stage)
        except StageError as e:
            self.b.stop_robot()
            return Outcome(ABORTED, str(e), final_pose=self.b.pose(), stage=e.stage)
        except Exception as e:        # a bug or an unexpected backend error: still abort cleanly
            self.b.stop_robot()
            return Outcome(ABORTED, '%s failed: unexpected error: %s: %s'
                           % (stage or 'mission', type(e).__name__, e),
                           final_pose=self.b.pose(), stage=stage)
        self.b.stop_robot()
        pose = self.b.pose()
        msg = 'arrived at %s and found %s' % (fmt_pose(pose) if pose else 'pose B',
                                            plural(len(obstacles), 'obstacle'))
        if message:
            msg += ' (%s)' % message
        return Outcome(SUCCEEDED, msg, obstacles=list(obstacles), final_pose=pose)

    # --- stages ----------------------------------------------------------------------------
    def _wait_server(self, stage, what):
        t0 = self.b.wall()
        while not self.b.server_ready(stage):
            if self.b.preempt_requested():
                raise _Preempted(stage)
            if self.b.wall() - t0 > self.cfg.server_timeout:
                raise StageError(stage, 'no %s server after %g s (is it running?)'
                                 % (what, self.cfg.server_timeout))
            self.b.sleep(self.cfg.poll_period * 5)

    def _run_action(self, stage, what, goal, timeout, on_tick):
        """Send ``goal`` to the stage's action server and poll it until it ends; return its
        result. Cancels the goal on preemption, timeout or a stopped clock."""
        self._wait_server(stage, what)
        self.b.send_goal(stage, goal)
        t0 = self.b.now()
        last_t, last_change = t0, self.b.wall()
        last_seen = last_change
        while True:
            if self.b.preempt_requested():
                self.b.cancel(stage)
                raise _Preempted(stage)
            p = self.b.poll(stage)
            if p.status == SUCCEEDED:
                return p
            if p.status != ACTIVE:
                reason = p.text or 'no reason given'
                raise StageError(stage, '%s %s: %s' % (what, p.status, reason))
            t, w = self.b.now(), self.b.wall()
            if self.b.server_ready(stage):
                last_seen = w
            elif w - last_seen > self.cfg.server_timeout:
                self.b.cancel(stage)
                raise StageError(stage, 'the %s server went away' % what)
            if t != last_t:
                last_t, last_change = t, w
            elif w - last_change > self.cfg.clock_timeout:
                self.b.cancel(stage)
                raise StageError(stage, 'ROS time stopped advancing for %g s (is the simulator '
                                 'running?)' % self.cfg.clock_timeout)
            if t - t0 > timeout:
                self.b.cancel(stage)
                raise StageError(stage, 'timed out after %g s' % timeout)
            on_tick(p)
            self.b.sleep(self.cfg.poll_period)

    def _corridor(self):
        self.feedback(CORRIDOR, corridor_sentence())

        def tick(p):
            f = p.feedback
            if f is not None:
                self.feedback(CORRIDOR, corridor_sentence(
                    getattr(f, 'distance', None), getattr(f, 'lateral_offset', None),
                    getattr(f, 'left_distance', None), getattr(f, 'right_distance', None)),
                    force=False)
        p = self._run_action('corridor', 'corridor_controller',
                             (self.cfg.corridor_max_speed, self.cfg.corridor_max_distance),
                             self.cfg.corridor_timeout, tick)
        r = p.result
        dist = getattr(r, 'distance', None)
        self.log('corridor done%s%s' % (' after %.1f m' % dist if dist is not None else '',
                                         ': %s' % r.reason if getattr(r, 'reason', '') else ''))

    def _to_go(self, goal, pose):
        if pose is None:
            return None
        d = remaining_path_length(self.b.path(), pose)
        straight = math.hypot(goal.x - pose[0], goal.y - pose[1])
        return straight if d is None else max(d, straight)

    def _navigate(self, goal):
        pose = self.b.pose()
        to_go = self._to_go(goal, pose)
        self.feedback(NAVIGATING, 'navigating to (%.2f, %.2f, %.0f deg)%s'
                      % (goal.x, goal.y, goal.yaw_deg,
                         ', %.1f m away' % to_go if to_go is not None else ''))

        def tick(_p):
            t, pose = self.b.now(), self.b.pose()
            moving = self.motion.update(t, pose)
            if moving is None:
                return
            self.feedback(MOVING if moving else STOPPED,
                          motion_sentence(moving, self._to_go(goal, pose)), force=False)
        self._run_action('navigation', 'move_base', goal.pose, self.cfg.navigation_timeout, tick)
        # move_base stops the base at the goal; let it come to rest before scanning
        stopped = self._wait_stopped(self.cfg.settle_timeout)
        pose = self.b.pose()
        if pose is None:
            self.feedback(ARRIVED, 'arrived')
        else:
            err = math.hypot(goal.x - pose[0], goal.y - pose[1])
            yaw_err = math.degrees(abs(wrap_angle(goal.pose[2] - pose[2])))
            self.feedback(ARRIVED, 'arrived at %s, %.2f m and %.0f deg from the goal%s'
                          % (fmt_pose(pose), err, yaw_err, '' if stopped else ' (still settling)'))

    def _wait_stopped(self, timeout):
        """Tell the robot to stop and wait until it is still (ROS time, with a wall-clock
        guard); True when it stopped."""
        self.motion.reset()
        t0, w0 = self.b.now(), self.b.wall()
        while True:
            self.b.stop_robot()
            if getattr(self.b, 'shutting_down', lambda: False)():
                return False
            if self.motion.update(self.b.now(), self.b.pose()) is False:
                return True
            if self.b.now() - t0 > timeout or self.b.wall() - w0 > max(timeout, self.cfg.clock_timeout):
                return False
            self.b.sleep(self.cfg.poll_period * 2)

    def _detect(self):
        self.feedback(DETECTING, 'looking for obstacles in one laser scan')
        if self.b.preempt_requested():
            raise _Preempted('detection')
        try:
            obstacles, message = self.b.detect(self.cfg.detection_timeout)
        except DetectionError as e:
            raise StageError('detection', str(e)) from None
        self.feedback(DETECTION_DONE, 'found %s' % plural(len(obstacles), 'obstacle'))
        return obstacles, message


# --- the client's table ----------------------------------------------------------------------
def obstacle_table(rows):
    """Format obstacles as a text table.

    ``rows``: sequence of ``(x, y, x_robot, y_robot, radius, num_points)`` [m, m, m, m, m, -]
    (map frame, then base_footprint at scan time). Returns the lines (header first).
    """
    lines = [' #   x [m]   y [m]  x_robot  y_robot  radius [m]  points',
             '--  ------  ------  -------  -------  ----------  ------']
    for i, (x, y, xr, yr, r, n) in enumerate(rows, 1):
        lines.append('%2d  %6.2f  %6.2f  %7.2f  %7.2f  %10.3f  %6d' % (i, x, y, xr, yr, r, n))
    if not rows:
        lines.append('    (no obstacles)')
    return lines
