"""Waiting in ROS time (tiago_nav.clock): a stalled clock is a verdict only with a dead source.

:func:`source_verdict` judges the facts the ROS side gathers (the master's publishers of /clock,
this process's live connections, processes known gone); :class:`StallWatch` and the waits built
on it give up only when ROS time stands still *and* the source is dead, and wait on (asking
again) while it lives, however long it lags."""
import pytest

from tiago_nav.clock import Patience, StallWatch, Ticker, source_verdict, sleep_until, wait_until
from tiago_nav.motion import MotionMonitor, wait_until_still
from tiago_nav_tools.testing.fakes import FakeClock


# --- the verdict from facts -------------------------------------------------------------------
def test_a_connected_publisher_lives():
    assert source_verdict('/clock', ['/simulator'], {'/simulator'}) == ''
    # another, dead publisher beside it changes nothing: time can still come
    assert source_verdict('/clock', ['/old', '/simulator'], {'/simulator'}, {'/old'}) == ''


@pytest.mark.parametrize('listed, connected, exited, words', [
    (None, set(), set(), 'the ROS master cannot be reached'),
    ([], set(), set(), 'nothing publishes /clock any more'),
    (['/simulator'], set(), {'/simulator'}, 'the process of /simulator, which published /clock, '
                                            'is gone'),
    (['/simulator'], set(), set(), 'the connection to /simulator, which publishes /clock, is '
                                   'closed'),
    # a connection from a node the master no longer lists: it unregistered (shut down)
    ([], {'/simulator'}, set(), 'nothing publishes /clock'),
])
def test_dead_sources_are_named(listed, connected, exited, words):
    assert words in source_verdict('/clock', listed, connected, exited)


def test_a_connected_publisher_whose_process_is_gone_is_dead():
    # (a pid seen gone outweighs a connection rospy has not noticed closing yet)
    assert 'is gone' in source_verdict('/clock', ['/simulator'], {'/simulator'}, {'/simulator'})


# --- waits ----------------------------------------------------------------------------------------
def test_moving_time_never_asks_the_source():
    clock = FakeClock()
    assert sleep_until(clock, 5.0)
    assert clock.asked == 0


def test_a_slow_source_is_waited_for_however_long():
    clock = FakeClock()
    clock.stalled, clock.resume_at = True, 100.0        # 100 s wall behind, alive
    assert wait_until(clock, 1.0, stall=2.0) == ''
    assert clock.now() >= 1.0 and clock.wall() >= 100.0
    assert 40 <= clock.asked <= 51                      # asked about every stall seconds


def test_a_dead_source_ends_the_wait_after_one_stall_naming_it():
    clock = FakeClock(t=3.0)
    clock.stalled, clock.dead = True, 'nothing publishes /clock any more'
    reason = wait_until(clock, 5.0, stall=2.0)
    assert reason == ('ROS time stopped advancing at 3.000 s (for 2.0 s of wall time): '
                      'nothing publishes /clock any more')
    assert 2.0 < clock.wall() < 2.1 and clock.asked == 1


def test_a_source_that_dies_while_slow_is_found_at_the_next_question():
    clock = FakeClock()
    clock.stalled = True

    watch = StallWatch(clock, stall=2.0)
    while clock.wall() < 7.0:
        assert watch.check() == ''
        clock.sleep(0.01)
    clock.dead = 'the connection to /simulator, which publishes /clock, is closed (did it die?)'
    while not watch.check():
        clock.sleep(0.01)
    assert clock.wall() < 8.1
    assert watch.reason.startswith('ROS time stopped advancing at 0.000 s (for 8.')


# --- a wall-clock wait for what a source promised -------------------------------------------
class Wall:
    """A wall clock the test moves, and a source whose verdict it sets."""

    def __init__(self):
        self.t, self.verdict, self.asked = 0.0, '', 0

    def __call__(self):
        return self.t

    def dead(self):
        self.asked += 1
        return self.verdict


def waited(patience, wall, until=1000.0, step=0.05):
    """Wall seconds until ``patience`` is over (None: not within ``until``)."""
    while wall.t <= until:
        if patience.over():
            return wall.t
        wall.t += step
    return None


def test_patience_waits_for_a_live_source_until_it_is_hung():
    wall = Wall()
    p = Patience(2.0, 30.0, wall.dead, wall)
    assert waited(p, wall) == pytest.approx(30.0, abs=0.06)
    assert 'though its source lives' in p.reason
    assert 14 <= wall.asked <= 15           # every 2 s, never before the first 2


def test_patience_ends_at_the_first_question_after_its_source_died():
    wall = Wall()
    p = Patience(2.0, 30.0, wall.dead, wall)
    assert waited(p, wall, until=6.9) is None
    wall.verdict = 'the process of /simulator is gone'
    assert waited(p, wall) == pytest.approx(8.0, abs=0.06)
    assert p.reason == 'the process of /simulator is gone' and p.over()


def test_patience_of_a_number_is_a_plain_timeout_that_asks_nobody():
    wall = Wall()
    p = Patience.of(2.0)
    p.wall = wall
    assert waited(p, wall) == pytest.approx(2.0, abs=0.06) and wall.asked == 0
    assert Patience.of(p) is p
    with pytest.raises(ValueError):
        Patience(2.0, 1.0)


def test_patience_sleeps_no_longer_than_its_next_question():
    wall = Wall()
    p = Patience(2.0, 30.0, wall.dead, wall)
    assert p.left(0.1) == 0.1               # not begun
    p.over()
    wall.t = 1.95
    assert p.left(0.1) == pytest.approx(0.05)


def test_ticker_says_why_it_stopped():
    clock = FakeClock()
    ticker = Ticker(clock, 0.1)
    assert ticker.tick() and ticker.reason == ''
    clock.stalled, clock.dead = True, 'the ROS master cannot be reached'
    assert not ticker.tick()
    assert ticker.reason.endswith('the ROS master cannot be reached')
    clock.shutdown_at = 0.0
    assert not ticker.tick() and ticker.reason == 'node shutting down'


def test_wait_until_still_waits_for_a_slow_clock_and_gives_up_on_a_dead_one():
    poses = {'p': (0.0, 0.0, 0.0)}
    for dead, expect in (('', True), ('nothing publishes /clock any more', False)):
        clock = FakeClock()
        clock.stalled, clock.dead = True, dead
        clock.resume_at = None if dead else 50.0
        still = wait_until_still(clock, lambda: poses['p'], lambda: None, MotionMonitor(), 1.0,
                                 period=0.04, stall=2.0)
        assert still is expect
        assert (clock.wall() >= 50.0) if not dead else (clock.wall() < 2.2)


def test_ticker_sleeps_for_the_time_left_at_the_rate_ros_time_keeps():
    """With ``longest``, a tick of 0.1 s wakes a few times instead of 50 (nap 2 ms), lands
    within about ``nap`` of its time while the rate holds (bags played at 1, 4 and 0.5 times
    real time), and follows a change of rate within a tick."""
    for rate in (1.0, 4.0, 0.5):
        clock = FakeClock()
        clock.rate = rate
        sleeps = []
        sleep = clock.sleep
        clock.sleep = lambda dt: (sleeps.append(dt), sleep(dt))
        ticker = Ticker(clock, 0.1, nap=0.005, longest=0.1)
        late = []
        for i in range(1, 21):
            del sleeps[:]
            assert ticker.tick()
            late.append(clock.now() - ticker.next)
            if i > 1:       # the first tick has no rate yet: it polls every nap
                assert len(sleeps) <= 3, (rate, i, sleeps)
        assert 0.0 <= max(late) <= 0.005 * rate + 1e-9, (rate, late)
    clock = FakeClock()
    ticker = Ticker(clock, 0.1, nap=0.005, longest=0.1)
    for _ in range(5):
        ticker.tick()
    clock.rate = 10.0       # played ten times faster: at most ``longest`` late, once
    ticker.tick()
    assert clock.now() - ticker.next <= 0.1 * 10.0 + 1e-9
    ticker.tick()           # (falls behind by more than a period: runs at once)
    ticker.tick()
    assert clock.now() - ticker.next <= 0.005 * 10.0 + 1e-9


def test_ticker_without_longest_polls_every_nap():
    clock = FakeClock()
    sleeps = []
    sleep = clock.sleep
    clock.sleep = lambda dt: (sleeps.append(dt), sleep(dt))
    ticker = Ticker(clock, 0.1, nap=0.002)
    ticker.tick()
    ticker.tick()
    assert set(round(s, 9) for s in sleeps) == {0.002}
