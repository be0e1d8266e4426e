"""The mission state machine (tiago_nav.mission.runner) against a fake backend: a kinematic robot that
drives toward the goal at a fixed speed in simulated time, fake stages that succeed, abort,
hang, vanish or never come, a corridor check that says yes, no or cannot tell, and a fake
detection service that answers like the real one (``success: false`` with a reason) or cannot
be asked (absent, crashed handler)."""
import math

import pytest

from tiago_nav import mission
from tiago_nav.mission import (ABORTED, ACTIVE, NO_CORRIDOR, PREEMPTED, SUCCEEDED, DetectionError,
                               Goal, GoalError, MissionConfig, MissionRunner, Poll, StageError,
                               validate_goal)
from tiago_nav.mission.client import obstacle_table
from tiago_nav.mission.runner import (Cancelled, no_corridor_scan, no_service, service_failed,
                                      service_verdict)
from tiago_nav.mission.sentences import remaining_path_length
from tiago_nav.motion import MotionMonitor


class FakeBackend:
    """Wall time advances by ``dt`` per sleep, simulated time too unless ``clock_stalls`` (until
    the wall time ``resume_at``: a slow simulator; with ``dead``, the reason, a dead one).
    The robot moves toward the navigation goal at ``speed`` m/s while that stage is active."""

    def __init__(self, corridor='succeed', navigation='succeed', detection='ok', speed=1.0,
                 servers=('corridor', 'navigation', 'detection'), preempt_at=None,
                 clock_stalls=False, vanish_at=None, corridor_ahead=True, dead='',
                 resume_at=None):
        self.t = 0.0
        self.w = 0.0
        self.robot = [0.0, 0.0, 0.0]
        self.v = 0.0
        self.modes = {'corridor': corridor, 'navigation': navigation}
        self.detection = detection
        self.ahead = corridor_ahead          # True, False or 'no scan'
        self.asked_corridor = []
        self.speed = speed
        self.servers = set(servers)
        self.preempt_at = preempt_at
        self.clock_stalls = clock_stalls
        self.dead, self.resume_at, self.asked = dead, resume_at, 0
        self.vanish_at = vanish_at
        self.feedbacks = []
        self.sent = []
        self.cancelled = []
        self.stops = 0
        self.active = None
        self.goal = None
        self.started = None

    # clocks
    def now(self):
        return self.t

    def wall(self):
        return self.w

    def source_dead(self):
        self.asked += 1
        return self.dead

    def sleep(self, dt):
        self.w += dt
        if self.clock_stalls and self.resume_at is not None and self.w >= self.resume_at:
            self.clock_stalls = False
        if not self.clock_stalls:
            self.t += dt
            self._move(dt)
        if self.vanish_at is not None and self.t >= self.vanish_at:
            self.servers.discard(self.active)

    def _move(self, dt):
        if self.active == 'navigation' and self.modes['navigation'] in ('succeed', 'hang'):
            gx, gy, _ = self.goal
            d = math.hypot(gx - self.robot[0], gy - self.robot[1])
            step = min(d, self.speed * dt)
            if d > 1e-9:
                self.robot[0] += step * (gx - self.robot[0]) / d
                self.robot[1] += step * (gy - self.robot[1]) / d
        elif self.active == 'corridor':
            self.robot[0] += self.speed * dt * 0.5

    def shutdown(self):
        return False

    def preempt_requested(self):
        return self.preempt_at is not None and self.t >= self.preempt_at

    def pose(self):
        return tuple(self.robot)

    def path(self):
        return None

    def server_ready(self, stage):
        return stage in self.servers

    def send_goal(self, stage, goal):
        self.sent.append(stage)
        self.active, self.goal, self.started = stage, goal, self.t

    def poll(self, stage):
        mode = self.modes[stage]
        if stage == 'navigation' and mode == 'succeed':
            gx, gy, yaw = self.goal
            if math.hypot(gx - self.robot[0], gy - self.robot[1]) < 1e-6:
                self.robot[2] = yaw
                self.active = None
                return Poll(SUCCEEDED, 'goal reached', result=object())
            return Poll(ACTIVE)
        if stage == 'corridor' and mode == 'succeed':
            if self.t - self.started > 2.0:
                self.active = None
                result = type('R', (), {'distance': 1.0, 'reason': 'corridor end'})()
                return Poll(SUCCEEDED, '', result=result)
            return Poll(ACTIVE, feedback=type('F', (), {'distance': self.t - self.started,
                                                        'lateral_offset': 0.01,
                                                        'left_distance': 0.5,
                                                        'right_distance': 0.52})())
        if mode == 'abort':
            self.active = None
            return Poll(mission.ABORTED, 'goal is inside an obstacle')
        return Poll(ACTIVE)           # 'hang'

    def cancel(self, stage):
        self.cancelled.append(stage)
        self.active = None

    def corridor_ahead(self, goal):
        self.asked_corridor.append((goal.x, goal.y))
        if self.ahead == 'no scan':         # the node waits server_timeout [wall] for one
            self._wait_wall(CFG.server_timeout)
            raise StageError('corridor', no_corridor_scan('/scan', CFG.server_timeout))
        return self.ahead

    def _wait_wall(self, seconds):
        w0 = self.w
        while self.w - w0 <= seconds:
            self.sleep(CFG.poll_period)

    def detect(self, timeout):
        """The real backend's contract: the service's answer ``(success, obstacles, message)``;
        DetectionError only when it cannot be asked."""
        if 'detection' not in self.servers:    # the node waits server_timeout [wall] for it
            self._wait_wall(CFG.server_timeout)
            raise DetectionError(no_service('/obstacle_detection', CFG.server_timeout))
        if self.detection == 'crash':          # the handler raised: the call itself fails
            raise DetectionError(service_failed('obstacle_detection', 'service cannot process '
                                                'request: handler returned an error'))
        if self.detection == 'fail':           # what the node answers when it cannot look
            return False, [], 'no /scan received within 2 s'
        if self.detection == 'fail_silently':
            return False, [], ''
        if self.detection == 'none':
            return True, [], ''
        if self.detection == 'cancelled':      # cancelled while the call waited on a slow node
            raise Cancelled()
        return True, ['o1', 'o2'], ''

    def stop_robot(self):
        self.stops += 1

    def publish_feedback(self, state, status, pose):
        self.feedbacks.append((self.t, state, status, pose))

    def states(self):
        out = []
        for _, s, _, _ in self.feedbacks:
            if not out or out[-1] != s:
                out.append(s)
        return out


ALL = ('corridor', 'navigation', 'detection')
CFG = MissionConfig(server_timeout=2.0, corridor_timeout=20.0, navigation_timeout=30.0,
                    poll_period=0.05, clock_timeout=3.0)


def run(backend, goal=Goal(5.0, 0.0, -45.0, True), cfg=CFG):
    return MissionRunner(backend, cfg).run(goal)


def test_success_runs_the_stages_in_order_with_feedback():
    b = FakeBackend()
    out = run(b)
    assert out.status == SUCCEEDED, out.message
    assert b.sent == ['corridor', 'navigation']
    assert out.obstacles == ['o1', 'o2']
    assert 'found 2 obstacles' in out.message
    assert out.final_pose[0] == pytest.approx(5.0)
    assert out.final_pose[2] == pytest.approx(math.radians(-45))
    st = b.states()
    assert st[0] == mission.GOAL_RECEIVED and st[1] == mission.CORRIDOR
    assert st[2] == mission.NAVIGATING and st[3] == mission.MOVING
    assert st[-3:] == [mission.ARRIVED, mission.DETECTING, mission.DETECTION_DONE]
    # "moving, X m to go" sentences count down toward the goal
    to_go = [float(s.split(', ')[1].split(' ')[0]) for _, st_, s, _ in b.feedbacks
             if st_ == mission.MOVING and 'to go' in s]
    assert len(to_go) >= 2 and to_go == sorted(to_go, reverse=True)
    assert to_go[0] <= 4.0
    assert b.stops >= 1                          # the robot is told to stop at the end


def test_without_corridor_law_skips_the_corridor():
    b = FakeBackend()
    out = run(b, Goal(2.0, 1.0, 90.0, False))
    assert out.status == SUCCEEDED
    assert b.sent == ['navigation']
    assert mission.CORRIDOR not in b.states()


@pytest.mark.parametrize('x, y, yaw', [(float('nan'), 0, 0), (0, float('inf'), 0), (0, 0, 720)])
def test_bad_goal_aborts_before_any_stage(x, y, yaw):
    b = FakeBackend()
    out = run(b, Goal(x, y, yaw, True))
    assert out.status == ABORTED
    assert 'goal validation' in out.message
    assert b.sent == []


def test_navigation_aborted_names_navigation_and_the_reason():
    b = FakeBackend(navigation='abort')
    out = run(b)
    assert out.status == ABORTED
    assert out.stage == 'navigation'
    assert out.message.startswith('navigation failed') and 'inside an obstacle' in out.message
    assert b.stops >= 1


def test_absent_server_aborts_after_the_server_timeout():
    b = FakeBackend(servers=('navigation', 'detection'))
    out = run(b)
    assert out.status == ABORTED and out.stage == 'corridor'
    assert 'no corridor_controller server' in out.message
    assert b.sent == []
    assert b.w == pytest.approx(CFG.server_timeout, abs=0.5)


def test_stage_timeout_cancels_the_goal():
    b = FakeBackend(corridor='hang')
    out = run(b)
    assert out.status == ABORTED and out.stage == 'corridor'
    assert 'timed out after 20 s' in out.message
    assert b.cancelled == ['corridor']


def test_dead_clock_does_not_hang():
    dead = 'the process of /simulator, which published /clock, is gone'
    b = FakeBackend(navigation='hang', clock_stalls=True, dead=dead)
    out = run(b, Goal(3, 0, 0, False))
    assert out.status == ABORTED and out.stage == 'navigation'
    assert out.message.startswith('navigation failed: ROS time stopped advancing')
    assert out.message.endswith(dead)
    assert b.cancelled == ['navigation']
    assert b.w < 2 * CFG.clock_timeout


def test_slow_clock_is_waited_for():
    """ROS time stands still for 10 clock_timeouts of wall time while its source lives: the
    mission goes on and succeeds."""
    b = FakeBackend(clock_stalls=True, resume_at=10 * CFG.clock_timeout)
    out = run(b, Goal(3, 0, 0, False))
    assert out.status == SUCCEEDED, out.message
    assert b.asked >= 5 and b.w - b.t >= 10 * CFG.clock_timeout - 1.0


def test_server_that_goes_away_mid_stage_aborts_within_the_lost_timeout():
    b = FakeBackend(navigation='hang', vanish_at=1.0)
    out = run(b, Goal(30, 0, 0, False))
    assert out.status == ABORTED and out.stage == 'navigation'
    assert out.message.startswith('navigation failed: the move_base server went away')
    assert b.cancelled == ['navigation']
    assert b.w - 1.0 == pytest.approx(CFG.server_lost_timeout, abs=2 * CFG.poll_period)


@pytest.mark.parametrize('servers, mode, message', [
    (('corridor', 'navigation'), 'ok',       # (the node's words, with the resolved name)
     'detection failed: no /obstacle_detection service after 2 s (is it running?)'),
    (ALL, 'fail', 'detection failed: no /scan received within 2 s'),
    (ALL, 'fail_silently', 'detection failed: the service failed without a reason'),
    (ALL, 'crash', 'detection failed: the obstacle_detection service failed: service cannot '
                   'process request: handler returned an error')])
def test_detection_failure_aborts_naming_detection(servers, mode, message):
    b = FakeBackend(servers=servers, detection=mode)
    out = run(b)
    assert out.status == ABORTED and out.stage == 'detection'
    assert out.message == message
    assert out.obstacles == []
    if 'detection' not in servers:             # after the node's wait for the service
        assert b.w >= CFG.server_timeout
    assert mission.DETECTING in b.states() and mission.DETECTION_DONE not in b.states()
    assert b.stops >= 1


def test_detection_that_looked_and_found_nothing_succeeds():
    b = FakeBackend(detection='none')
    out = run(b)
    assert out.status == SUCCEEDED and 'found 0 obstacles' in out.message


# --- the corridor stage only where a corridor leads toward pose B ----------------------------
def test_no_corridor_ahead_says_so_and_navigates_directly():
    b = FakeBackend(corridor_ahead=False)
    out = run(b, Goal(5.0, 0.0, -45.0, True))
    assert out.status == SUCCEEDED, out.message
    assert b.asked_corridor == [(5.0, 0.0)]
    assert b.sent == ['navigation']                      # the law never ran
    st = b.states()
    assert st[:3] == [mission.GOAL_RECEIVED, mission.CORRIDOR, mission.NAVIGATING]
    corridor_lines = [s for _, st_, s, _ in b.feedbacks if st_ == mission.CORRIDOR]
    assert corridor_lines[-1] == NO_CORRIDOR == 'no corridor ahead, navigating directly'


def test_corridor_ahead_runs_the_law():
    b = FakeBackend(corridor_ahead=True)
    run(b)
    assert b.sent == ['corridor', 'navigation']
    assert NO_CORRIDOR not in [s for _, _, s, _ in b.feedbacks]
    assert any('in the corridor' in s for _, _, s, _ in b.feedbacks)


def test_corridor_not_asked_without_the_law():
    b = FakeBackend(corridor_ahead='no scan')
    assert run(b, Goal(2.0, 1.0, 0.0, False)).status == SUCCEEDED
    assert b.asked_corridor == []


def test_no_scan_to_judge_the_corridor_aborts_naming_the_corridor():
    b = FakeBackend(corridor_ahead='no scan')
    out = run(b)
    assert out.status == ABORTED and out.stage == 'corridor'
    assert out.message == ('corridor failed: no laser scan on /scan within 2 s: cannot tell '
                           'whether a corridor leads toward pose B')
    assert b.sent == []
    assert b.w >= CFG.server_timeout          # after the node's wait for a scan


# --- unexpected errors -----------------------------------------------------------------------
def test_unexpected_exception_aborts_with_its_text_and_stops():
    b = FakeBackend()

    def boom(stage):
        raise RuntimeError('boom in poll')
    b.poll = boom
    out = run(b, Goal(2.0, 0.0, 0.0, False))
    assert out.status == ABORTED and out.stage == 'navigation'
    assert out.message == 'navigation failed: unexpected error: RuntimeError: boom in poll'
    assert b.stops >= 1


def test_cancel_preempts_the_running_stage_and_stops_the_robot():
    b = FakeBackend(preempt_at=2.0)
    out = run(b, Goal(10, 0, 0, False))
    assert out.status == PREEMPTED and out.stage == 'navigation'
    assert b.cancelled == ['navigation']
    assert b.stops >= 1
    assert 'cancelled during navigation' in out.message and 'stopped' in out.message
    assert 1.0 < out.final_pose[0] < 3.0       # it stopped where it was, not at the goal


def test_feedback_is_rate_limited():
    b = FakeBackend(speed=0.5)
    run(b, Goal(10, 0, 0, False))
    moving = [t for t, s, _, _ in b.feedbacks if s == mission.MOVING]
    assert len(moving) >= 10
    gaps = [b_ - a for a, b_ in zip(moving, moving[1:])]
    assert min(gaps) >= CFG.feedback_period - 1e-9


# --- pieces ----------------------------------------------------------------------------------
def test_validate_goal():
    assert validate_goal('11', ' 0 ', '-45') == (11.0, 0.0, -45.0)
    for bad in [('a', 0, 0), (0, 'nan', 0), (0, 0, 'inf'), (0, 0, 400), (True, 0, 0)]:
        with pytest.raises(GoalError):
            validate_goal(*bad)


def test_motion_monitor_thresholds():
    m = MotionMonitor(window=0.5, speed_threshold=0.05, turn_threshold=0.1)
    assert m.update(0.0, (0, 0, 0)) is None
    assert m.update(0.1, (0.001, 0, 0)) is None         # less than half a window
    for i in range(2, 12):
        res = m.update(0.1 * i, (0.01 * i, 0, 0))        # 0.1 m/s
    assert res is True
    m.reset()
    for i in range(12):
        res = m.update(0.1 * i, (1.0 + 0.002 * i, 0, 0))  # 0.02 m/s: creeping counts as stopped
    assert res is False
    m.reset()
    for i in range(12):
        res = m.update(0.1 * i, (0, 0, 0.03 * i))         # turning in place at 0.3 rad/s
    assert res is True


def test_remaining_path_length():
    path = [(0, 0), (2, 0), (2, 2)]
    assert remaining_path_length(path, (0, 0)) == pytest.approx(4.0)
    assert remaining_path_length(path, (1, 0.5)) == pytest.approx(0.5 + 1 + 2)
    assert remaining_path_length(path, (2, 2)) == pytest.approx(0.0)
    assert remaining_path_length([], (0, 0)) is None


def test_config_rejects_bad_values():
    with pytest.raises(ValueError):
        MissionConfig(server_timeout=0)
    with pytest.raises(ValueError):
        MissionConfig(navigation_timeout=float('nan'))
    with pytest.raises(ValueError):
        MissionConfig(corridor_max_speed=-1)
    MissionConfig(corridor_max_speed=0)


def test_obstacle_table():
    lines = obstacle_table([(10.736, -1.665, 1.2, -0.5, 0.183, 42)])
    assert len(lines) == 3
    assert '10.74' in lines[2] and '-1.67' in lines[2] and '0.183' in lines[2] and '42' in lines[2]
    assert 'no obstacles' in obstacle_table([])[-1]


# --- the corridor decision on simulated scans ------------------------------------------------
def _scan_from(world_file, base_pose):
    """Laser-frame points of a noise-free scan from ``base_pose`` and the laser's pose in
    base_footprint, as the node gets them from /scan and tf."""
    import os
    from conftest import WORLDS
    from tiago_nav.scan import scan_to_points
    from tiago_nav.sim.scene import Scene
    from tiago_nav.sim.world import load_world
    with Scene(load_world(os.path.join(WORLDS, world_file))) as scene:
        r, _ = scene.cast(base_pose)
        L = scene.laser
        pts, _ = scan_to_points(r, L.angle_min, L.angle_increment, L.range_min, L.range_max)
    return pts, (L.offset, 0.0, 0.0)


@pytest.mark.parametrize('world, pose, target, ahead', [
    ('ias_lab_room_full.yaml', (0.0, 0.0, 0.0), (11.0, 0.0), True),      # the course mission
    ('ias_lab_room_full.yaml', (0.0, 0.0, 0.0), (-3.0, 0.0), False),     # the corridor leads away
    ('ias_lab_room_full.yaml', (11.0, 0.0, -0.785), (9.0, -2.0), False),  # 2nd run from pose B
    ('ias_lab_room_full.yaml', (11.0, 0.0, -0.785), (0.0, 0.0), False),  # back: corridor behind
    ('open_hall.yaml', (1.0, 1.0, 0.0), (6.0, 2.6), False),             # no corridor at all
])
def test_corridor_ahead_only_at_an_entrance_leading_to_pose_b(world, pose, target, ahead):
    from tiago_nav.mission.entrance import corridor_ahead
    points, laser = _scan_from(world, pose)
    assert corridor_ahead(points, laser, pose, target) is ahead


def test_corridor_ahead_uses_the_robot_pose():
    """The same scan judged as if the robot stood elsewhere in map: pose B is then off the
    corridor's direction and the answer changes (pose B is transformed into the robot frame)."""
    from tiago_nav.mission.entrance import corridor_ahead
    points, laser = _scan_from('ias_lab_room_full.yaml', (0.0, 0.0, 0.0))
    assert corridor_ahead(points, laser, (0.0, 0.0, 0.0), (11.0, 0.0, 0.0))
    assert not corridor_ahead(points, laser, (0.0, 0.0, math.pi / 2), (11.0, 0.0, 0.0))


def test_a_cancel_while_detection_waits_preempts_in_detection():
    b = FakeBackend(detection='cancelled')
    out = run(b)
    assert out.status == PREEMPTED and out.stage == 'detection', out.message
    assert out.message.startswith('cancelled during detection')


@pytest.mark.parametrize('registered, exited, words', [
    (True, False, ''), (True, None, ''),        # alive, or busy/frozen (cannot tell): wait on
    (True, True, "registered, but its node's process is gone"),
    (False, None, 'no longer registered')])
def test_service_verdict_rests_on_facts(registered, exited, words):
    verdict = service_verdict('/obstacle_detection', registered, exited)
    assert (words in verdict) if words else verdict == ''
    if words:
        assert verdict.startswith('the /obstacle_detection service went away: ')
