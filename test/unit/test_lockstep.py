"""The lockstep protocol without ROS: the schedule holds simulated time at every unanswered
deadline, applies each command at its cycle's stamp, waits for a slow participant while it
lives, drops a dead one once that is known and a hung one after the wall-clock timeout and
takes it back, and a closed loop through it gives the same poses whatever
the participants' latency."""
import math
import random
import time

import pytest

from tiago_nav.lockstep import Ack, Gate, ParticipantCore, Schedule, Tick, grid_after
from tiago_nav.sim.simulator import SimConfig, Simulator
from tiago_nav.sim.world import World
from tiago_nav_tools.testing.lockstep import ThreadParticipant, run_lockstep

RATE = 60.0
DT = 1.0 / RATE


class Log:
    def __init__(self):
        self.lines = []

    def __call__(self, level, text):
        self.lines.append((level, text))

    def warnings(self):
        return [t for level, t in self.lines if level == 'warn']


def schedule(timeout=1.0):
    log = Log()
    return Schedule(RATE, timeout, log), log


def t_of(step):
    """A step's time as the simulator stamps it: whole nanoseconds, floored."""
    return (step * 10**9 // int(RATE)) / 1e9


def test_grid_after_is_strict_and_absolute():
    assert grid_after(0.0, 0.1) == pytest.approx(0.1)
    assert grid_after(0.1, 0.1) == pytest.approx(0.2)
    assert grid_after(0.1 - 1e-12, 0.1) == pytest.approx(0.2)   # float noise: on the grid
    assert grid_after(0.17, 0.1) == pytest.approx(0.2)


def test_stamps_map_to_their_step_even_when_floored_to_nanoseconds():
    s, _ = schedule()
    assert [s.step_of(t_of(k)) for k in range(200)] == list(range(200))
    assert s.step_of(0.02) == 1          # between steps: the step before


def test_time_never_passes_an_unanswered_deadline():
    """A participant answering at random moments: at every step the schedule says whether the
    simulator may go on, and it never may at a deadline the participant has not answered."""
    s, _ = schedule()
    rng = random.Random(1)
    s.receive(Ack('/a', 0.0, 0.1), wall=0.0)
    answered, step, held = 0.0, 0, 0
    while step < 600:
        t = t_of(step)
        waiting = s.hold(t, wall=0.0)
        deadline = grid_after(answered, 0.1)
        assert bool(waiting) == (t >= deadline - 1e-9)
        if waiting:
            held += 1
            if rng.random() < 0.3:        # not yet: the simulator asks again
                continue
            s.receive(Ack('/a', t, 0.1), wall=0.0)
            answered = t
            continue
        step += 1
    assert held >= 100                      # every 0.1 s over 10 s, several asks each


def test_commands_are_applied_at_their_cycle_stamp_in_stamp_order():
    s, _ = schedule()
    s.receive(Ack('/a', 0.0, 0.1), wall=0.0)
    s.receive(Ack('/b', 0.0, 0.05), wall=0.0)
    # answers for the same instant arrive in any order; later stamps wait for their time
    s.receive(Ack('/a', t_of(6), 0.1, command=(0.3, 0.0)), wall=0.0)
    s.receive(Ack('/b', t_of(3), 0.05, command=(0.1, 0.2)), wall=0.0)
    assert s.commands(t_of(2)) == []
    assert s.commands(t_of(3)) == [(0.1, 0.2)]
    assert s.commands(t_of(5)) == []
    assert s.commands(t_of(6)) == [(0.3, 0.0)]
    assert s.lag_stats()['max'] == 0.0


def test_a_late_command_is_applied_at_once_and_its_lag_measured():
    s, _ = schedule()
    s.receive(Ack('/free', t_of(6), 0.1, command=(0.5, 0.0)), wall=0.0)
    assert s.commands(t_of(10)) == [(0.5, 0.0)]
    stats = s.lag_stats()
    assert stats['count'] == 1 and stats['max'] == pytest.approx(4 * DT)


def test_a_silent_participant_is_dropped_with_a_warning_after_the_timeout_and_can_rejoin():
    s, log = schedule(timeout=1.0)
    s.receive(Ack('/a', 0.0, 0.1), wall=0.0)
    t = t_of(6)
    assert s.hold(t, wall=10.0) == ['/a']
    assert s.hold(t, wall=10.9) == ['/a']
    assert not log.warnings()
    assert s.hold(t, wall=11.1) == []
    assert not s.is_participant('/a') and s.drops == 1
    assert '/a' in log.warnings()[0] and 'going on without it' in log.warnings()[0]
    # the simulator ran on; the late answer comes: it registers again
    assert s.receive(Ack('/a', t, 0.1), wall=12.0)
    assert s.is_participant('/a')
    assert s.hold(t_of(11), wall=12.0) == []
    assert s.hold(t_of(12), wall=12.0) == ['/a']


def test_the_timeout_counts_from_the_start_of_each_wait():
    s, _ = schedule(timeout=1.0)
    s.receive(Ack('/a', 0.0, 0.1), wall=0.0)
    for k in range(1, 6):                   # each answer takes 0.9 s: never dropped
        t = t_of(6 * k)
        assert s.hold(t, wall=k) == ['/a']
        assert s.hold(t, wall=k + 0.9) == ['/a']
        s.receive(Ack('/a', t, 0.1), wall=k + 0.9)
        assert s.hold(t, wall=k + 0.9) == []
    assert s.drops == 0


class Verdicts:
    """The simulator's question, does the participant live? Answered from a table of facts
    (node -> reason it is dead, absent while it lives), each question recorded."""

    def __init__(self):
        self.facts, self.asked = {}, []

    def __call__(self, node):
        self.asked.append(node)
        return self.facts.get(node, '')


def test_a_slow_participant_that_lives_is_waited_for_however_long_it_takes():
    """A starved process answers after 20 s of wall time: the simulator asks every second
    whether it lives, waits on, and takes its answer; no drop, no warning."""
    verdicts = Verdicts()
    log = Log()
    s = Schedule(RATE, 30.0, log, dead=verdicts, ask=1.0)
    s.receive(Ack('/a', 0.0, 0.1), wall=0.0)
    t = t_of(6)
    for k in range(201):                    # 0 to 20 s of wall time, every 0.1 s
        assert s.hold(t, wall=10.0 + 0.1 * k) == ['/a']
    assert 19 <= len(verdicts.asked) <= 20 and set(verdicts.asked) == {'/a'}
    assert s.receive(Ack('/a', t, 0.1), wall=30.1)
    assert s.hold(t, wall=30.1) == []
    assert s.drops == 0 and not log.warnings()


def test_a_dead_participant_is_dropped_at_the_first_question_naming_why():
    verdicts = Verdicts()
    s = Schedule(RATE, 30.0, Log(), dead=verdicts, ask=1.0)
    log = s.log
    s.receive(Ack('/a', 0.0, 0.1), wall=0.0)
    s.receive(Ack('/b', 0.0, 0.1), wall=0.0)
    t = t_of(6)
    assert s.hold(t, wall=10.0) == ['/a', '/b']
    verdicts.facts['/a'] = 'the process of /a is gone'
    assert s.hold(t, wall=10.9) == ['/a', '/b']       # not asked yet
    assert s.hold(t, wall=11.0) == ['/b']
    assert not s.is_participant('/a') and s.is_participant('/b') and s.drops == 1
    [warning] = log.warnings()
    assert '/a' in warning and 'the process of /a is gone' in warning and 'going on without it' in warning


def test_a_live_participant_that_never_answers_is_dropped_as_hung_after_the_timeout():
    verdicts = Verdicts()
    s = Schedule(RATE, 30.0, Log(), dead=verdicts, ask=1.0)
    s.receive(Ack('/a', 0.0, 0.1), wall=0.0)
    t = t_of(6)
    assert s.hold(t, wall=10.0) == ['/a']
    assert s.hold(t, wall=39.9) == ['/a']
    assert s.hold(t, wall=40.1) == []
    assert s.drops == 1 and 'stopped? deadlocked?' in s.log.warnings()[0]


def test_leave_drops_at_once_and_applies_its_last_command():
    s, log = schedule()
    s.receive(Ack('/a', 0.0, 0.1), wall=0.0)
    assert s.hold(t_of(6), wall=0.0) == ['/a']
    s.receive(Ack('/a', t_of(3), 0.1, command=(0.0, 0.0), leave=True), wall=0.0)
    assert s.hold(t_of(6), wall=0.0) == []
    assert not s.is_participant('/a')
    assert s.commands(t_of(6)) == [(0.0, 0.0)]
    assert not log.warnings()


@pytest.mark.parametrize('period', [0.025, 0.07, 0.0, -0.1, 1 / 120.0])
def test_periods_off_the_step_grid_are_refused(period):
    s, log = schedule()
    assert not s.receive(Ack('/a', 0.0, period, command=(1.0, 0.0)), wall=0.0)
    assert not s.is_participant('/a')
    assert s.commands(1.0) == []
    assert 'not a whole number' in log.warnings()[0]


@pytest.mark.parametrize('period', [1 / 60.0, 0.05, 1 / 15.0, 0.1, 0.5])
def test_periods_on_the_step_grid_are_taken(period):
    s, log = schedule()
    assert s.receive(Ack('/a', 0.0, period), wall=0.0)
    assert s.deadline('/a') == pytest.approx(period)
    assert not log.warnings()


def test_cmd_vel_of_participants_is_ignored_and_of_others_not():
    s, _ = schedule()
    gate = Gate(s, wall=lambda: 0.0)
    assert not gate.has_participants()
    gate.receive(Ack('/move_base', 0.0, 0.1))
    assert gate.is_participant('/move_base') and gate.has_participants()
    assert not gate.is_participant('/student_controller')
    gate.receive(Ack('/move_base', 0.1, 0.1, leave=True))
    assert not gate.is_participant('/move_base')      # its cmd_vel counts again
    assert not gate.has_participants()                # (and /clock goes out with the scans)


def test_a_stale_or_repeated_answer_is_ignored():
    s, _ = schedule()
    s.receive(Ack('/a', t_of(6), 0.1), wall=0.0)
    assert not s.receive(Ack('/a', t_of(6), 0.1, command=(1.0, 0.0)), wall=0.0)
    assert not s.receive(Ack('/a', t_of(3), 0.1, command=(1.0, 0.0)), wall=0.0)
    assert s.commands(10.0) == []


def test_two_participants_at_10_and_20_hz_are_held_at_their_own_deadlines():
    s, _ = schedule()
    s.receive(Ack('/slow', 0.0, 0.1), wall=0.0)
    s.receive(Ack('/fast', 0.0, 0.05), wall=0.0)
    holds = []
    for step in range(61):
        t = t_of(step)
        waiting = s.hold(t, wall=0.0)
        if waiting:
            holds.append((step, tuple(waiting)))
            for name in waiting:                 # both answer what they owe
                s.receive(Ack(name, t, 0.1 if name == '/slow' else 0.05), wall=0.0)
            assert s.hold(t, wall=0.0) == []
    expected = [(k, ('/fast', '/slow') if k % 6 == 0 else ('/fast',)) for k in range(3, 61, 3)]
    assert holds == expected


def test_lag_statistics():
    s, _ = schedule()
    for k in range(100):
        s.receive(Ack('/free', t_of(k), 0.1, command=(0.1, 0.0)), wall=0.0)
        s.commands(t_of(k + k % 5))
    stats = s.lag_stats()
    assert stats['count'] == 100
    assert stats['max'] == pytest.approx(4 * DT)
    assert stats['p50'] == pytest.approx(2 * DT)
    assert s.lag_stats() != Schedule(RATE, 1.0).lag_stats()


# --- the participant's side ------------------------------------------------------------------
def test_participant_cycle_in_lockstep_waits_for_the_tick_of_its_deadline():
    core = ParticipantCore(0.1, now=0.0)
    assert core.next_cycle(0.1) is None                  # at the deadline: the tick is coming
    core.on_tick(Tick(0.05))                             # another participant's tick
    assert core.next_cycle(0.1) is None
    core.on_tick(Tick(0.1, scan_stamp=1 / 15.0, odom_stamp=0.1))
    assert core.next_cycle(0.1 - DT) is None             # /clock has not caught up yet
    stamp, tick = core.next_cycle(0.1)
    assert stamp == 0.1 and tick.scan_stamp == 1 / 15.0
    core.answered(stamp)
    assert core.next_cycle(0.1) is None
    assert core.deadline() == pytest.approx(0.2)


def test_participant_runs_free_when_time_passes_its_deadline():
    core = ParticipantCore(0.1, now=0.0)
    assert core.next_cycle(0.1 + DT) == (0.1 + DT, None)
    core.answered(0.1 + DT)
    assert core.deadline() == pytest.approx(0.2)
    assert core.next_cycle(0.73) == (0.73, None)         # skipped cycles are not run back to back
    core.answered(0.73)
    assert core.deadline() == pytest.approx(0.8)


def test_idle_participant_answers_due_ticks_until_claimed():
    core = ParticipantCore(0.1, now=0.0)
    core.on_tick(Tick(0.05))
    assert core.idle_answer() is None                    # not due
    core.on_tick(Tick(0.1))
    assert core.idle_answer() == 0.1
    core.answered(0.1)
    assert core.idle_answer() is None
    core.claim(since=0.2)                                # a goal stamped 0.2
    core.on_tick(Tick(0.2))
    assert core.idle_answer() == 0.2                     # up to the goal's stamp: still idle
    core.answered(0.2)
    core.on_tick(Tick(0.3))
    assert core.idle_answer() is None                    # the control loop's
    assert core.next_cycle(0.3)[0] == 0.3
    core.answered(0.3)
    core.release()
    core.on_tick(Tick(0.4))
    assert core.idle_answer() == 0.4


def test_a_tick_that_names_the_participant_is_answered_though_not_due():
    """Registered at 12.73 s (its next deadline 12.8 s), it is held for at once at the
    simulator's step 12.75 s: that tick names it, and is answered."""
    core = ParticipantCore(0.1, now=12.73)
    core.on_tick(Tick(12.75))
    assert core.idle_answer() is None                    # a tick for someone else
    core.on_tick(Tick(12.75, named=True))                # sent again, naming it
    assert core.idle_answer() == 12.75
    core.answered(12.75)
    assert core.deadline() == pytest.approx(12.8)
    core.claim(since=12.6)                               # a control loop's ticks stay its own
    core.on_tick(Tick(12.8, named=True))
    assert core.idle_answer() is None


def test_a_named_tick_the_control_loop_answered_is_not_answered_again_after_release():
    """The corridor law's last cycle (0.05 s period, idle period 0.1 s) answers the tick for
    67.6 s, which names it, and releases: no second, idle answer to that tick (it would cover
    67.65 s while the simulator still held at 67.6 s, and the mission proxy saw the corridor
    goal end at 67.6 s or not depending on which answer it read first: the course mission
    then took one of two routes). The next tick is answered idle as before."""
    core = ParticipantCore(0.05, now=60.0, idle_period=0.1)
    core.claim(since=60.1)
    core.on_tick(Tick(67.6, named=True))
    assert core.idle_answer() is None                    # the control loop's
    assert core.next_cycle(67.6)[0] == pytest.approx(67.6)
    core.answered(67.6)
    core.release()
    assert core.idle_answer() is None                    # answered already
    core.on_tick(Tick(67.65, named=True))
    assert core.idle_answer() == pytest.approx(67.65)
    assert core.cover(67.65) == pytest.approx(67.65)


def test_a_lost_answer_is_sent_again_when_the_tick_comes_again():
    """A participant registers at 1 s (stamped 0: the simulator holds at once); its answer to
    that tick is lost on its way (rospy closed the connection it went on). The tick comes again
    while the simulator waits, and the participant sends its answer again: time goes on. (It
    answered no tick twice: the simulator held until it dropped the participant, and again
    each time it rejoined.) A tick that does not name it gets nothing more."""
    sched, log = schedule(timeout=1.0)
    core = ParticipantCore(0.1, now=1.0)
    sched.receive(Ack('p', 0.0, 0.1), wall=0.0)              # the registration
    assert sched.hold(1.0, wall=0.0) == ['p']
    core.on_tick(Tick(1.0, named=True))
    assert not core.answer_again()
    core.answered(core.idle_answer())                        # sent, and lost
    for wall in (1.5, 2.0):                                  # the simulator gives up on it, it
        sched.hold(1.0, wall=wall)                           # announces itself again: held
    assert log.warnings() and 'p' not in sched.members
    sched.receive(Ack('p', 0.0, 0.1, busy=True), wall=2.1)
    assert sched.hold(1.0, wall=2.1) == ['p']
    core.on_tick(Tick(1.0, named=True))                      # the tick, again
    assert core.idle_answer() is None and core.answer_again()
    assert sched.receive(Ack('p', 1.0, 0.1, busy=True), wall=2.2)
    assert sched.hold(1.0, wall=2.2) == [] and sched.deadline('p') == pytest.approx(1.1)
    core.on_tick(Tick(1.0))                                  # sent to others: not for it
    assert not core.answer_again()
    core.on_tick(Tick(1.1, named=True))                      # its next deadline: a new answer
    assert not core.answer_again() and core.idle_answer() == pytest.approx(1.1)


def test_claimed_cycle_is_the_first_deadline_after_the_goal_whoever_answered_before():
    """The goal (stamped 0.2) and the tick for 0.2 race: either way the control loop's first
    cycle is 0.3."""
    for tick_first in (True, False):
        core = ParticipantCore(0.1, now=0.1)
        if tick_first:
            core.on_tick(Tick(0.2))
            core.answered(core.idle_answer())
            core.claim(since=0.2)
        else:
            core.claim(since=0.2)
            core.on_tick(Tick(0.2))
            core.answered(core.idle_answer())
        assert core.deadline() == pytest.approx(0.3)


def test_an_idle_20hz_participant_covers_its_deadlines_up_to_the_idle_grid():
    """Idle, a 20 Hz participant's answer to the tick at 0.1 covers 0.15 too (the 0.1 s idle
    grid), so the simulator holds for it at 10 Hz; a goal stamped 0.1 then starts at 0.2,
    whether it arrived before or after that answer; once released it covers again."""
    for tick_first in (True, False):
        core = ParticipantCore(0.05, now=0.0)
        core.on_tick(Tick(0.1))
        if not tick_first:
            core.claim(since=0.1)
        due = core.idle_answer()
        assert due == pytest.approx(0.1) and core.cover(due) == pytest.approx(0.15)
        core.answered(core.cover(due))
        if tick_first:
            core.claim(since=0.1)
        assert core.deadline() == pytest.approx(0.2)
        core.on_tick(Tick(0.2))
        assert core.idle_answer() is None and core.next_cycle(0.2)[0] == pytest.approx(0.2)
        core.answered(0.2)
        core.on_tick(Tick(0.25))
        assert core.next_cycle(0.25)[0] == pytest.approx(0.25)    # claimed: every 0.05 s
        core.answered(0.25)
        core.release()
        core.on_tick(Tick(0.3))
        assert core.cover(core.idle_answer()) == pytest.approx(0.35)
    # a 10 Hz participant's idle answers cover only their own tick
    assert ParticipantCore(0.1, now=0.0).cover(0.3) == 0.3


def test_participant_starts_again_when_time_goes_back():
    core = ParticipantCore(0.1, now=20.0)
    core.claim(since=20.0)
    core.on_tick(Tick(20.1))
    core.answered(core.next_cycle(20.1)[0])
    core.on_tick(Tick(20.05))                  # a late tick of the same run: kept as it was
    assert core.latest.stamp == 20.1
    core.on_tick(Tick(0.5))                    # a restarted simulator holding at 0.5
    assert core.next_cycle(0.5) == (0.5, core.latest)


def test_participant_rejects_a_bad_period():
    with pytest.raises(ValueError):
        ParticipantCore(0.0, now=0.0)
    with pytest.raises(ValueError):
        Schedule(RATE, 0.0)


# --- closed loop through the schedule, in process -------------------------------------------
ROOM = {
    'name': 'room', 'resolution': 0.05, 'bounds': [-1, -3, 6, 3], 'robot_start': [0, 0, 0],
    'walls': [{'x': 5.5, 'y': 0, 'length': 6.0, 'width': 0.2, 'yaw_deg': 90}],
}


def steer(sim):
    """A feedback law on the simulator's state at the cycle's time: drive along y = 0.5."""
    x, y, yaw = sim.pose
    return 0.6, max(-1.5, min(1.5, -2.0 * (y - 0.5) - 2.5 * yaw))


def closed_loop(latency, seed, seconds=3.0, answers=None, timeout=5.0, wall=time.monotonic,
                on_silent=None, log=None):
    sim = Simulator(World.from_dict(ROOM), SimConfig(laser_noise=0.0))
    gate = Gate(Schedule(RATE, timeout, log), wall=wall)
    parts = [ThreadParticipant(gate, sim, '/steer', 0.1, steer, latency, seed, answers,
                               on_silent=on_silent and (lambda tick: on_silent(gate, tick))),
             ThreadParticipant(gate, sim, '/idle', 0.05, lambda s: None, latency, seed + 1)]
    try:
        poses = run_lockstep(sim, gate, parts, seconds)
    finally:
        sim.close()
    return poses, gate.schedule, parts


def test_closed_loop_gives_bit_identical_poses_whatever_the_answer_latency():
    fast, sched_a, parts = closed_loop(latency=(0.0, 0.0), seed=1)
    slow, sched_b, _ = closed_loop(latency=(0.0, 0.004), seed=2)
    assert fast == slow                                   # bit for bit
    assert 0.25 < fast[-1][1] < 0.7                       # the law did steer the robot
    assert fast[-1][0] > 1.0
    assert [round(c, 9) for c in parts[0].cycles[:3]] == [0.1, 0.2, 0.3]
    for sched in (sched_a, sched_b):
        assert sched.lag_stats()['count'] >= 29 and sched.lag_stats()['max'] <= 0.1
        assert sched.drops == 0


def test_applying_a_command_late_changes_the_poses():
    """The comparison above can fail: the same law with each command applied one step after
    its cycle (as when a command arrives while the simulator runs on) ends elsewhere."""
    def late(steps):
        sim = Simulator(World.from_dict(ROOM), SimConfig(laser_noise=0.0))
        queued = []
        try:
            for k in range(180):
                if k % 6 == 0:
                    queued.append((k + steps, steer(sim)))
                while queued and queued[0][0] <= k:
                    sim.command(*queued.pop(0)[1])
                sim.step()
            return sim.pose
        finally:
            sim.close()
    assert late(0) != late(1)


def test_a_participant_that_goes_silent_is_dropped_and_the_simulation_goes_on():
    """/steer answers 3 cycles, then no more. The gate's wall clock is a fake one that passes
    only when /steer leaves a tick unanswered and nobody else is missing: then it jumps past the
    timeout. So the drop does not hang on how fast this machine is, and /idle, however late
    its answers come on a loaded machine, is never waited for past the timeout."""
    now = [0.0]
    log = Log()

    def silent(gate, tick):
        end = time.monotonic() + 10.0          # a bound on the wait, not a timing
        while time.monotonic() < end:
            with gate.cond:
                due = gate.schedule.due(tick.stamp)
                if '/steer' not in due:
                    return                     # dropped already, or not held for it
                if due == {'/steer'}:
                    now[0] += 2 * gate.schedule.timeout
                    gate.cond.notify_all()
                    return
            time.sleep(0.001)
        raise AssertionError('/idle never answered the tick at %g s' % tick.stamp)

    poses, sched, parts = closed_loop(latency=(0.0, 0.0), seed=1, seconds=1.0, answers=3,
                                      timeout=1.0, wall=lambda: now[0], on_silent=silent, log=log)
    assert len(poses) == 60
    assert parts[0].cycles == pytest.approx([0.1, 0.2, 0.3])
    assert not sched.is_participant('/steer') and sched.drops == 1
    assert [w for w in log.warnings() if 'no answer from /steer' in w]
    assert sched.is_participant('/idle')
    assert sched.lag_stats()['max'] <= DT          # its commands were applied on time
    assert math.isfinite(poses[-1][0])


def test_gate_sends_the_tick_again_until_answered_and_names_who_is_missing():
    s, _ = schedule(timeout=10.0)
    gate = Gate(s, wall=time.monotonic, poll=0.005, retick=0.01)
    gate.receive(Ack('/a', 0.0, 0.1))
    gate.receive(Ack('/b', 0.0, 0.1))
    ticks = []

    def tick(t, waiting):       # the first tick is lost; /a answers the second, /b the third
        ticks.append((t, tuple(waiting)))
        if len(ticks) == 2:
            gate.receive(Ack('/a', t, 0.1, command=(0.2, 0.0)))
        if len(ticks) == 3:
            gate.receive(Ack('/b', t, 0.1))
    assert gate.hold(t_of(6), tick) == [(0.2, 0.0)]
    assert ticks == [(t_of(6), ('/a', '/b'))] * 2 + [(t_of(6), ('/b',))]


def test_gate_gives_up_on_shutdown():
    s, _ = schedule(timeout=10.0)
    stop = []
    gate = Gate(s, wall=time.monotonic, shutdown=lambda: bool(stop), poll=0.005)
    gate.receive(Ack('/a', 0.0, 0.1))
    assert gate.hold(t_of(6), lambda t, w: stop.append(1)) is None


def test_gate_records_how_long_it_waited_and_whose_answer_ended_the_wait():
    s, _ = schedule(timeout=10.0)
    now = [100.0]
    gate = Gate(s, wall=lambda: now[0], poll=0.001, retick=0.01)
    gate.receive(Ack('/a', 0.0, 0.1))
    gate.receive(Ack('/b', 0.0, 0.1))
    assert gate.hold(t_of(3), lambda t, w: None) == []      # nobody due: no wait
    assert s.waits == 0

    def tick(t, waiting):       # /a answers 0.3 s of wall time after the first tick, /b 0.2 s later
        if waiting == ['/a', '/b']:
            now[0] += 0.3
            gate.receive(Ack('/a', t, 0.1))
        else:
            now[0] += 0.2
            gate.receive(Ack('/b', t, 0.1))
    gate.hold(t_of(6), tick)
    assert s.waits == 1 and s.waited == pytest.approx(0.5)
    assert s.waited_for == {'/b': pytest.approx(0.5)}
    assert s.wait_summary() == 'waited 0.50 s of wall time at 1 steps; last to answer: /b 0.50 s'


def test_gate_wakes_its_hold_only_for_an_answer_that_ends_the_wait_or_adds_to_it():
    s, _ = schedule(timeout=10.0)
    gate = Gate(s, wall=lambda: 0.0)
    gate.receive(Ack('/a', 0.0, 0.1))
    gate.receive(Ack('/b', 0.0, 0.1))
    assert s.due(t_of(6)) == {'/a', '/b'} and s.due(t_of(5)) == set()
    woken = []
    gate.cond.notify_all = lambda: woken.append(sorted(s.due(gate._held[0])))
    gate._held = (t_of(6), {'/a', '/b'})       # as hold() leaves it while it waits
    gate.receive(Ack('/a', t_of(6), 0.1))
    assert woken == []                          # /b is still missing: nothing to do
    gate.receive(Ack('/b', t_of(6), 0.1))
    assert woken == [[]]                        # nobody is missing: the step may go on
    gate._held = (t_of(12), {'/a'})            # (/b answered ahead: it covers 0.2 s)
    gate.receive(Ack('/b', t_of(12), 0.1))
    gate.receive(Ack('/c', 0.0, 0.1))
    assert woken[1:] == [['/a', '/c']]          # a newcomer due now must be sent the tick


# --- waiting for work and for the expected participants (real_time_factor 0) ---------------
def test_with_wait_for_work_time_goes_on_only_while_someone_is_busy_or_the_base_moves():
    s = Schedule(RATE, 1.0, Log(), wait_for_work=True)
    assert s.wants_time()                       # nobody takes part: an outside node drives
    s.receive(Ack('/a', 0.0, 0.1), 0.0)
    s.receive(Ack('/b', 0.0, 0.1), 0.0)
    assert not s.wants_time()                   # both idle: simulated time stands still
    assert s.wants_time(work=True)              # ... unless the base moves
    s.receive(Ack('/a', 0.0, 0.1, busy=True), 0.0)     # a status (not newer): busy all the same
    assert s.wants_time() and s.deadline('/a') == pytest.approx(0.1)
    s.receive(Ack('/a', 0.1, 0.1, command=(0.1, 0.0), busy=True), 0.0)
    assert s.wants_time()
    s.receive(Ack('/a', 0.2, 0.1), 0.0)          # its goal ended: its answers are idle again
    assert not s.wants_time()
    assert Schedule(RATE, 1.0, Log()).wants_time()     # without wait_for_work: always


def test_time_leaves_its_start_only_once_the_expected_participants_have_joined():
    log = Log()
    s = Schedule(RATE, 1.0, log, expected=['/a', '/b'], expect_timeout=5.0)
    s.receive(Ack('/a', 0.0, 0.1, busy=True), 0.0)
    assert s.missing(100.0) == ['/b'] and not s.wants_time()
    s.receive(Ack('/b', 0.0, 0.1), 0.0)
    assert s.missing(101.0) == [] and s.wants_time()
    assert ('info', 'lockstep: every expected participant has joined') in log.lines


def test_an_expected_participant_that_never_joins_is_given_up_with_a_warning():
    log = Log()
    s = Schedule(RATE, 1.0, log, expected=['/a', '/gone'], expect_timeout=5.0)
    s.receive(Ack('/a', 0.0, 0.1, busy=True), 0.0)
    assert s.missing(10.0) == ['/gone'] and not s.wants_time()
    assert s.missing(15.1) == [] and s.wants_time()
    assert log.warnings() == ['lockstep: /gone did not join within 5 s of wall time: simulated '
                              'time goes on without it']


def test_gate_holds_for_work_and_a_busy_answer_releases_it():
    """The step loop stands still while nobody has work, the commands of the answers at that
    time kept; a claiming participant's status (busy, stamped 0) lets it go on at once."""
    s = Schedule(RATE, 1.0, Log(), wait_for_work=True)
    gate = Gate(s, wall=time.monotonic, poll=0.005)
    gate.receive(Ack('/a', 0.0, 0.1))
    gate.receive(Ack('/a', t_of(6), 0.1, command=(0.0, 0.0)))
    looked = []

    def work(commands):
        looked.append(list(commands))
        if len(looked) == 3:
            gate.receive(Ack('/a', 0.0, 0.1, busy=True))
        return False
    assert gate.hold(t_of(6), lambda t, w: None, work) == [(0.0, 0.0)]
    assert len(looked) == 3 and looked[0] == [(0.0, 0.0)]


def test_gate_goes_on_while_the_base_moves_with_nobody_busy():
    s = Schedule(RATE, 1.0, Log(), wait_for_work=True)
    gate = Gate(s, wall=time.monotonic, poll=0.005)
    gate.receive(Ack('/a', 0.0, 0.1))
    assert gate.hold(t_of(1), lambda t, w: None, lambda commands: True) == []


def test_the_simulator_is_in_motion_while_a_command_is_in_force_or_the_base_moves():
    sim = Simulator(World(name='empty', resolution=0.05, bounds=(-5, -5, 5, 5),
                          robot_start=(0.0, 0.0, 0.0)), SimConfig(laser_model='ideal'))
    try:
        assert not sim.in_motion
        sim.command(0.3, 0.0)
        assert sim.in_motion
        sim.step()
        sim.command(0.0, 0.0)
        assert sim.in_motion                    # still rolling: it brakes at its limits
        for _ in range(60):
            sim.step()
        assert not sim.in_motion and sim.velocity == (0.0, 0.0)
    finally:
        sim.close()


def test_settled_values_are_those_of_the_cycles_before():
    from tiago_nav.lockstep import Settled
    s = Settled(0.1)
    s.add(1.0, 'a')
    s.add(1.1, 'b')
    s.add(1.2, 'c')                             # sent in the cycle at 1.2: maybe not here yet
    assert s.get(1.2) == 'b' and s.get(1.15) == 'a' and s.get(None) == 'c'
    assert s.get(1.05) is None
    s.reset(1.1)
    s.add(1.0, 'old')                           # a message of the goal before, late
    s.add(1.1, 'd')
    assert s.get(1.3) == 'd' and s.get(None) == 'd'
