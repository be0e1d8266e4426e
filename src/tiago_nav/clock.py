"""Waiting in ROS time without hanging when that time stops (no ROS here).

A *clock* is any object with ``now()`` (ROS time [s]: simulated under ``/use_sim_time``),
``wall()`` (a monotonic wall clock [s]), ``sleep(seconds)`` (wall time) and ``shutdown()``
(True once the process is stopping). :class:`tiago_nav.ros.clock.RosClock` is the ROS one,
:class:`tiago_nav.testing.fakes.FakeClock` a simulated one for unit tests.
"""

NAP = 0.002          # [s wall] polling step of sleep_until
STALL = 2.0          # [s wall] ROS time standing still this long counts as stopped


def sleep_until(clock, target, stall=STALL, nap=NAP):
    """Sleep until ROS time ``target`` [s].

    Returns True once ``clock.now() >= target``; False when the process is shutting down or
    ROS time has not moved for ``stall`` seconds of wall time (a stopped ``/clock``), so that
    no loop built on it can block for ever.
    """
    last, since = clock.now(), clock.wall()
    while not clock.shutdown():
        now = clock.now()
        if now >= target:
            return True
        if now != last:
            last, since = now, clock.wall()
        elif clock.wall() - since > stall:
            return False
        clock.sleep(nap)
    return False


class Ticker:
    """A fixed-rate loop in ROS time: ``tick()`` sleeps until the next period and returns False
    when :func:`sleep_until` gives up. A loop that falls more than one period behind skips the
    missed ticks instead of running them back to back."""

    def __init__(self, clock, period, stall=STALL):
        self.clock, self.period, self.stall = clock, float(period), stall
        self.next = clock.now()

    def tick(self):
        self.next = max(self.next + self.period, self.clock.now() - self.period)
        return sleep_until(self.clock, self.next, self.stall)
