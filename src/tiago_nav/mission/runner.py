"""The mission as a ROS-free state machine: :class:`MissionRunner` runs one :class:`Goal`
through a *backend* and returns an :class:`Outcome`.

Units: metres, radians (degrees only where a name says ``_deg``), seconds. Poses are
``(x, y, yaw)`` of base_footprint in the ``map`` frame. The backend's ``now()`` is ROS time
(simulated under /use_sim_time); stage timeouts count in it. ``wall()`` is a monotonic wall
clock; waits for servers count in it, and so does the "simulated clock stopped" guard, which
abandons a stage only when the backend's ``source_dead()`` names a reason (a slow simulator is
waited for), so nothing hangs if /clock stops.
"""
import math
from dataclasses import dataclass
from typing import Any

from tiago_nav.clock import StallWatch
from tiago_nav.geometry import wrap_angle
from tiago_nav.goal import (ABORTED, ACTIVE, LOST, PREEMPTED, REJECTED,  # noqa: F401
                            SUCCEEDED, GoalError, Outcome)
from tiago_nav.mission.goals import validate_goal
from tiago_nav.mission.sentences import (corridor_done_sentence, corridor_sentence, fmt_pose,
                                         goal_sentence, handoff_sentence, motion_sentence,
                                         plural, remaining_path_length)
from tiago_nav.motion import MotionMonitor, wait_until_still
from tiago_nav.params import param, validate

# --- feedback states (the TiagoTask.action constants: a contract) ----------------------------
GOAL_RECEIVED, CORRIDOR, NAVIGATING, MOVING, STOPPED, ARRIVED, DETECTING, DETECTION_DONE = range(8)
STATE_NAMES = ('GOAL_RECEIVED', 'CORRIDOR', 'NAVIGATING', 'MOVING', 'STOPPED', 'ARRIVED',
               'DETECTING', 'DETECTION_DONE')



@dataclass(frozen=True)
class MissionConfig:
    """Timeouts and thresholds of the mission.

    ``*_timeout`` of a stage: ROS (simulated) seconds from its start; ``server_timeout`` and
    ``detection_timeout``: wall seconds (waiting for a server, one service call);
    ``clock_timeout``: wall seconds without ROS time advancing before the source of ROS time
    is judged (dead: the stage is abandoned; alive, however slow: waited for).
    """
    server_timeout: float = param(30.0, '[s wall] wait this long for each action server / the '
                                  'service, and for a fresh scan to judge the corridor, before a '
                                  'stage fails; in lockstep, at start-up, for the node\'s '
                                  'registration', gt=0)
    server_lost_timeout: float = param(3.0, '[s wall] a stage whose server has been gone (node '
                                       'died: its connections closed) this long aborts', gt=0)
    corridor_timeout: float = param(120.0, '[s] the corridor_controller stage', gt=0)
    navigation_timeout: float = param(240.0, '[s] the move_base stage', gt=0)
    detection_timeout: float = param(10.0, '[s wall] an obstacle_detection call unanswered this '
                                     'long: ask whether its node is dead (fail if so, wait on '
                                     'while it lives)', gt=0)
    settle_timeout: float = param(3.0, '[s] after arrival, wait at most this for the base to be '
                                  'still before scanning', gt=0)
    stop_timeout: float = param(5.0, '[s] on cancel, wait at most this for the base to stop',
                                gt=0)
    clock_timeout: float = param(10.0, '[s wall] when ROS time stands still this long, ask '
                                 'whether its source (the simulator) is dead: abandon the stage '
                                 'if so, wait on if it lives', gt=0)
    feedback_period: float = param(1.0, '[s] at most one progress feedback per period while a '
                                   'state lasts', gt=0)
    poll_period: float = param(0.02, '[s wall] how often stages are polled', gt=0)
    moving_speed: float = param(0.05, '[m/s] MOVING when faster than this over motion_window '
                                '(tf map -> base_footprint)', gt=0)
    moving_turn_rate: float = param(0.1, '[rad/s] ... or turning faster than this', gt=0)
    motion_window: float = param(0.5, '[s] window of poses judging MOVING vs STOPPED', gt=0)
    corridor_max_speed: float = param(0.0, '[m/s] goal of corridor_controller, 0: its default',
                                      ge=0)
    corridor_max_distance: float = param(0.0, '[m] goal of corridor_controller, 0: no limit',
                                         ge=0)

    def __post_init__(self):
        validate(self)


@dataclass
class Goal:
    """Pose B: ``x``, ``y`` [m] in ``map``, ``yaw_deg`` [deg]; whether to try the corridor law."""
    x: float
    y: float
    yaw_deg: float
    use_corridor_law: bool = True

    @property
    def pose(self):
        """``(x, y, yaw)`` [m, m, rad]."""
        return (self.x, self.y, math.radians(self.yaw_deg))


@dataclass
class Poll:
    """What a backend reports about a running action stage."""
    status: str = ACTIVE             # ACTIVE or a terminal outcome
    text: str = ''                   # the server's status text (reason)
    result: Any = None
    feedback: Any = None


class StageError(Exception):
    """A stage failed; ``str()`` names the stage and the reason."""

    def __init__(self, stage, reason):
        super().__init__('%s failed: %s' % (stage, reason))
        self.stage, self.reason = stage, reason


class DetectionError(Exception):
    """Raised by a backend's ``detect`` when the service cannot be asked: absent, its handler
    raised (a crashed node), or no answer within the timeout. A service that answers
    ``success: false`` is not an error of the call: ``detect`` returns that answer."""


NO_CORRIDOR = 'no corridor ahead, navigating directly'


# What the node (tiago_controller) says when the detection service cannot be asked, or no scan
# comes to judge the corridor: one wording for the node and the test doubles that stand for it.
def no_service(name, timeout):
    """The service ``name`` was not registered within ``timeout`` [s wall]."""
    return 'no %s service after %g s (is it running?)' % (name, timeout)


def service_failed(name, error):
    """The call of the service ``name`` raised ``error`` (e.g. its handler raised)."""
    return 'the %s service failed: %s' % (name, error)


def service_silent(name, timeout):
    """The service ``name`` did not answer within ``timeout`` [s wall]."""
    return 'the %s service did not answer within %g s' % (name, timeout)


def service_verdict(name, registered, exited):
    """Is the provider of the service ``name`` dead? Judged from facts, never from time alone:
    ``registered``, the master lists the service; ``exited``, its node's process is gone (True:
    its XML-RPC port refuses connections), there (False) or cannot be told now (None: a busy
    or frozen process). ``''`` while it may live (a slow node is waited for), else the
    reason."""
    if not registered:
        return 'the %s service went away: no longer registered (its node shut down)' % name
    if exited:
        return ('the %s service went away: registered, but its node\'s process is gone (did '
                'it die?)' % name)
    return ''


class Cancelled(Exception):
    """Raised by a backend's wait (e.g. ``detect``) when the goal is cancelled meanwhile: the
    mission ends PREEMPTED in the stage that waited."""


def no_corridor_scan(topic, timeout):
    """No scan on ``topic`` within ``timeout`` [s wall] to judge whether a corridor is ahead."""
    return ('no laser scan on %s within %g s: cannot tell whether a corridor leads toward '
            'pose B' % (topic, timeout))


class _ServerAborted(StageError):
    """The stage's action server ended the goal ABORTED (its own verdict, ``reason`` its status
    text), as opposed to the mission giving up on it (no server, server gone, timeout)."""

    def __init__(self, stage, what, status, reason):
        super().__init__(stage, '%s %s: %s' % (what, status, reason))
        self.server_reason = reason


class _Preempted(Exception):
    def __init__(self, stage):
        super().__init__(stage)
        self.stage = stage


class MissionRunner:
    """Runs one goal after another through a backend.

    The backend is a :mod:`tiago_nav.clock` clock (``now()``, ``wall()``, ``sleep(wall
    seconds)``, ``shutdown()``, ``source_dead()``) and provides ``preempt_requested()``,
    ``pose()`` (``(x, y,
    yaw)`` in map or None), ``path()`` (the current plan as ``[(x, y), ...]`` or None),
    ``server_ready(stage)``, ``send_goal(stage, goal)`` (corridor: ``(max_speed,
    max_distance)``; navigation: ``(x, y, yaw)``), ``poll(stage) -> Poll``, ``cancel(stage)``,
    ``corridor_ahead(goal) -> bool`` (does a corridor lead from here toward the
    :class:`Goal`? may raise :class:`StageError` when it cannot tell, e.g. no scan),
    ``detect(timeout) -> (success, obstacles, message)`` (the obstacle_detection service's
    answer; :class:`DetectionError` when it could not be asked, :class:`Cancelled` when the
    goal was cancelled while it waited), ``stop_robot()`` and
    ``publish_feedback(state, status, pose)``.

    Every failure ends the goal ABORTED with ``'<stage> failed: <reason>'`` (but corridor_controller's
    own abort hands over to move_base: :meth:`_corridor`); an unexpected
    exception too, with its type and text. Cancelling ends it PREEMPTED. The robot is told to
    stop in every case.
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
                self._corridor(goal)
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
        result. Cancels the goal on preemption, timeout (ROS time) or a dead clock (ROS time
        standing still while its source is dead: :class:`tiago_nav.clock.StallWatch`)."""
        self._wait_server(stage, what)
        self.b.send_goal(stage, goal)
        t0 = self.b.now()
        clock = StallWatch(self.b, self.cfg.clock_timeout)
        last_seen = self.b.wall()
        while True:
            if self.b.preempt_requested():
                self.b.cancel(stage)
                raise _Preempted(stage)
            p = self.b.poll(stage)
            if p.status == SUCCEEDED:
                return p
            if p.status == ABORTED:
                raise _ServerAborted(stage, what, p.status, p.text or 'no reason given')
            if p.status != ACTIVE:
                reason = p.text or 'no reason given'
                raise StageError(stage, '%s %s: %s' % (what, p.status, reason))
            t, w = self.b.now(), self.b.wall()
            if self.b.server_ready(stage):
                last_seen = w
            elif w - last_seen > self.cfg.server_lost_timeout:
                self.b.cancel(stage)
                raise StageError(stage, 'the %s server went away (gone for %g s)'
                                 % (what, self.cfg.server_lost_timeout))
            dead = clock.check(t)
            if dead:
                self.b.cancel(stage)
                raise StageError(stage, dead)
            if t - t0 > timeout:
                self.b.cancel(stage)
                raise StageError(stage, 'timed out after %g s' % timeout)
            on_tick(p)
            self.b.sleep(self.cfg.poll_period)

    def _corridor(self, goal):
        """The corridor stage: the law runs only where a corridor leads toward pose B; otherwise
        the stage ends at once with the CORRIDOR feedback :data:`NO_CORRIDOR` (the state stays
        CORRIDOR: the stage decided, and NAVIGATING follows as always).

        When corridor_controller itself aborts the goal (blocked ahead, walls lost...), the
        mission does not end: the NAVIGATING feedback :func:`handoff_sentence` gives its reason
        and move_base drives the rest of the way (it plans around what stopped the law, or
        fails with its own reason). A corridor stage the mission could not run (no server, the
        server gone, a timeout, no scan to judge the corridor) still aborts the mission."""
        self.feedback(CORRIDOR, 'looking for a corridor toward pose B')
        if self.b.preempt_requested():
            raise _Preempted('corridor')
        if not self.b.corridor_ahead(goal):
            self.feedback(CORRIDOR, NO_CORRIDOR)
            return
        self.feedback(CORRIDOR, corridor_sentence())

        def tick(p):
            f = p.feedback
            if f is not None:
                self.feedback(CORRIDOR, corridor_sentence(
                    getattr(f, 'distance', None), getattr(f, 'lateral_offset', None),
                    getattr(f, 'left_distance', None), getattr(f, 'right_distance', None)),
                    force=False)
        try:
            p = self._run_action('corridor', 'corridor_controller',
                                 (self.cfg.corridor_max_speed, self.cfg.corridor_max_distance),
                                 self.cfg.corridor_timeout, tick)
        except _ServerAborted as e:
            self.log('corridor_controller aborted: %s; handing over to move_base' % e.server_reason)
            self.feedback(NAVIGATING, handoff_sentence(e.server_reason))
            return
        r = p.result
        dist = getattr(r, 'distance', None)
        self.log('corridor done%s%s' % (' after %.1f m' % dist if dist is not None else '',
                                         ': %s' % r.reason if getattr(r, 'reason', '') else ''))
        self.feedback(CORRIDOR, corridor_done_sentence(dist, getattr(r, 'reason', '')))

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
        """Tell the robot to stop and wait until it is still (``timeout`` [s] of ROS time; a
        dead clock ends the wait: ``clock_timeout``); True when it stopped."""
        return wait_until_still(self.b, self.b.pose, self.b.stop_robot, self.motion, timeout,
                                period=self.cfg.poll_period * 2, stall=self.cfg.clock_timeout)

    def _detect(self):
        self.feedback(DETECTING, 'looking for obstacles in the laser scan')
        if self.b.preempt_requested():
            raise _Preempted('detection')
        try:
            success, obstacles, message = self.b.detect(self.cfg.detection_timeout)
        except Cancelled:
            raise _Preempted('detection') from None
        except DetectionError as e:
            raise StageError('detection', str(e)) from None
        if not success:
            raise StageError('detection', message or 'the service failed without a reason')
        self.feedback(DETECTION_DONE, 'found %s' % plural(len(obstacles), 'obstacle'))
        return obstacles, message
