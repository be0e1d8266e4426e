"""Waiting in ROS time without hanging when that time stops, and pacing simulated time at a
real-time factor (:class:`Pacer`); no ROS here.

A *clock* is any object with ``now()`` (ROS time [s]: simulated under ``/use_sim_time``),
``wall()`` (a monotonic wall clock [s]), ``sleep(seconds)`` (wall time), ``shutdown()``
(True once the process is stopping) and ``source_dead()``: ``''`` while whatever makes ROS
time (the simulator, through ``/clock``) lives and is connected to this process, else a
sentence saying why it is dead (its publisher unregistered, the connection closed, its process
gone). :class:`tiago_nav.ros.clock.RosClock` is the ROS one (it gathers those facts and
:func:`source_verdict` judges them), :class:`tiago_nav_tools.testing.fakes.FakeClock` a simulated one
for unit tests.

ROS time standing still is not by itself a verdict: on a loaded machine a live simulator can
fall seconds behind. A wait that sees ROS time stand still for ``stall`` wall seconds asks
``source_dead()`` (:class:`StallWatch`): a dead source ends the wait at once, naming the
reason; a live one is waited for, asked again every ``stall`` seconds, the waiter's own
patience counting in ROS time (a goal's timeout). A wait in wall time for something a source
has promised (the scan a lockstep tick names) is judged the same way (:class:`Patience`).
"""
import time

NAP = 0.002          # [s wall] polling step of sleep_until
STALL = 2.0          # [s wall] ROS time standing still this long: ask whether its source is dead
HUNG = 30.0          # [s wall] a source whose process lives but that has kept nothing of its
#                      promise this long is hung (stopped, deadlocked): the wait gives up


class Patience:
    """How long a wait in wall time for something a source has promised may last (the scan or
    transform a lockstep tick names, another participant's answer), judged from facts, never
    from time alone: ``step`` [s wall] at first; then ``dead()`` is asked, and while it says
    the source lives (``''``) the wait goes on, asking again every ``step`` seconds, up to
    ``bound`` [s wall] in all (a live source that has kept nothing of its promise that long is
    hung: stopped, deadlocked). ``dead`` None makes it a plain timeout of ``step``; ``wall``
    is a monotonic clock [s].

    Single use: the wait begins at the first :meth:`over`. ``reason`` says why it ended
    (``''`` while it lasts)."""

    def __init__(self, step, bound=HUNG, dead=None, wall=time.monotonic):
        if not (step >= 0 and bound >= step and (step > 0 or dead is None)):
            raise ValueError('need 0 <= step <= bound (step > 0 with a source to ask), got step '
                             '%r, bound %r' % (step, bound))
        self.step, self.bound, self.dead, self.wall = float(step), float(bound), dead, wall
        self.start = self.next = None
        self.reason = ''

    @classmethod
    def of(cls, timeout):
        """``timeout`` itself when it is a Patience, else a plain timeout of ``timeout`` [s]."""
        return timeout if isinstance(timeout, Patience) else cls(timeout, timeout)

    def over(self):
        """True once the wait must end (``reason`` says why)."""
        now = self.wall()
        if self.start is None:
            self.start, self.next = now, now + self.step
        if self.reason or now < self.next:
            return bool(self.reason)
        waited = now - self.start
        if self.dead is None:
            self.reason = 'not within %g s of wall time' % self.step
        elif waited >= self.bound:
            self.reason = ('not within %.0f s of wall time, though its source lives (stopped? '
                           'deadlocked?)' % waited)
        else:
            self.reason = self.dead()
            while self.next <= now:         # the questions keep to the grid of ``step``
                self.next += self.step
        return bool(self.reason)

    def left(self, longest):
        """[s wall] how long to sleep before the next look: at most ``longest``, and not past the
        next question."""
        if self.next is None:
            return longest
        return min(longest, max(self.next - self.wall(), 0.0))


def source_verdict(topic, listed, connected, exited=(), what='the simulator'):
    """Is the source of a topic (ROS time's ``/clock``; a sensor a cycle names) dead? Judged
    from facts, never from time alone.

    Args:
        topic: the topic's name (``/clock``), for the sentence.
        listed: the nodes the ROS master lists as publishing ``topic``; None when the master
            cannot be reached.
        connected: the nodes this process holds a live connection from on ``topic``.
        exited: the nodes among ``listed`` known to have no process any more (e.g. their
            pid is gone); those whose state is unknown are not in it.
        what: who normally publishes it, for the sentence.

    Returns ``''`` when a listed publisher is connected and its process is not known to have
    exited (it lives; it may be slow), else the reason it is dead:
    the master unreachable, no publisher registered, every publisher's process gone, or no
    connection left to any of them (a killed process's connections close; its registration
    stays behind)."""
    if listed is None:
        return 'the ROS master cannot be reached'
    listed = [n for n in listed if n]
    if not listed:
        return 'nothing publishes %s any more (%s is not running)' % (topic, what)
    living = [n for n in listed if n not in set(exited)]
    if not living:
        return 'the process of %s, which published %s, is gone' % (', '.join(listed), topic)
    if not set(living) & set(connected):
        return 'the connection to %s, which publishes %s, is closed (did it die?)' % (
            ', '.join(living), topic)
    return ''


class StallWatch:
    """Watches ROS time during a wait: :meth:`check` returns ``''`` while time moves, or stands
    still with its source alive; the reason (``clock.source_dead()``'s, with how long time
    stood still) once it stands still and its source is dead. The source is asked only after
    ``stall`` wall seconds without a change of ROS time, then again every ``stall`` seconds.
    ``reason`` keeps the last verdict."""

    def __init__(self, clock, stall=STALL):
        self.clock, self.stall = clock, float(stall)
        self.last, self.since = clock.now(), clock.wall()
        self.asked = self.since
        self.reason = ''

    def check(self, now=None):
        """``''`` to keep waiting, else why ROS time will not move again."""
        now = self.clock.now() if now is None else now
        wall = self.clock.wall()
        if now != self.last:
            self.last, self.since, self.asked = now, wall, wall
            return ''
        if wall - self.asked <= self.stall:
            return ''
        self.asked = wall
        dead = self.clock.source_dead()
        if dead:
            self.reason = 'ROS time stopped advancing at %.3f s (for %.1f s of wall time): %s' % (
                now, wall - self.since, dead)
        return self.reason


def wait_until(clock, target, stall=STALL, nap=NAP, rate=None, longest=None):
    """Sleep until ROS time ``target`` [s]. Returns ``''`` once ``clock.now() >= target``, else
    why not: ``'node shutting down'``, or the :class:`StallWatch` reason when ROS time stopped
    and its source is dead. While the source lives, however slow, it keeps waiting.

    Each sleep is ``nap`` [s wall]; with ``rate`` (ROS seconds per wall second, e.g. measured
    over the last waits) and ``longest`` [s wall], it is the time left at that rate, at least
    ``nap`` and at most ``longest``: a wait of a tenth of a second wakes about twice instead
    of fifty times (each wake costs a thread switch of CPU), and lands up to about ``nap``
    late while the rate holds, up to ``longest`` when ROS time speeds up."""
    watch = StallWatch(clock, stall)
    while not clock.shutdown():
        now = clock.now()
        if now >= target:
            return ''
        dead = watch.check(now)
        if dead:
            return dead
        step = nap
        if rate and longest:
            step = min(max((target - now) / rate, nap), longest)
        clock.sleep(step)
    return 'node shutting down'


def sleep_until(clock, target, stall=STALL, nap=NAP):
    """:func:`wait_until` as a bool: True once ROS time reached ``target``."""
    return not wait_until(clock, target, stall, nap)


class Ticker:
    """A fixed-rate loop in ROS time: ``tick()`` sleeps until the next period and returns False
    when :func:`wait_until` gives up (``reason`` then says why). A loop that falls more than one
    period behind skips the missed ticks instead of running them back to back. ``nap`` [s wall]:
    the polling step (a tick lands up to that late; each poll wakes the thread, about 0.1 ms
    of CPU on a virtual machine); with ``longest`` [s wall], the sleeps are as long as the
    time left at the rate ROS time kept over the tick before, between ``nap`` and
    ``longest``."""

    def __init__(self, clock, period, stall=STALL, nap=NAP, longest=None):
        self.clock, self.period, self.stall, self.nap = clock, float(period), stall, nap
        self.longest = longest
        self.next = clock.now()
        self.reason = ''
        self.rate = None            # ROS seconds per wall second over the last tick
        self._last = (self.next, clock.wall())

    def tick(self):
        """Sleep until the next period. With ``longest`` [s wall], the sleeps follow the rate
        ROS time kept over the tick before (:func:`wait_until`)."""
        self.next = max(self.next + self.period, self.clock.now() - self.period)
        self.reason = wait_until(self.clock, self.next, self.stall, self.nap, self.rate,
                                 self.longest)
        if self.longest:
            now, wall = self.clock.now(), self.clock.wall()
            if now > self._last[0] and wall > self._last[1]:
                self.rate = (now - self._last[0]) / (wall - self._last[1])
            self._last = (now, wall)
        return not self.reason


BEHIND = 0.5            # [s wall] a run this far behind its real_time_factor restarts its pacing


class Pacer:
    """Holds simulated time at ``real_time_factor`` × wall time on a :mod:`tiago_nav.clock`
    clock (its ``wall()`` and ``sleep()``). A run that falls more than :data:`BEHIND` wall
    seconds behind (a slow machine) goes on from where it is instead of catching up;
    ``real_time_factor`` 0 runs as fast as possible, yielding the processor now and then."""

    def __init__(self, clock, dt, real_time_factor, steps=0):
        self.clock, self.dt, self.rtf = clock, float(dt), float(real_time_factor)
        self.restart(steps)

    def restart(self, steps):
        """Pace from now on, ``steps`` steps having been taken."""
        self.t0, self.steps0 = self.clock.wall(), steps

    def pace(self, steps):
        """Wait until ``steps`` steps of ``dt`` [s sim] are due in wall time."""
        if self.rtf > 0:
            ahead = self.t0 + (steps - self.steps0) * self.dt / self.rtf - self.clock.wall()
            if ahead > 0:
                self.clock.sleep(ahead)
            elif ahead < -BEHIND:
                self.restart(steps)
        elif steps % 64 == 0:
            self.clock.sleep(0)                 # let the subscriber threads in
