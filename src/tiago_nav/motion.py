"""Is the robot moving? From successive poses, and waiting until it is still (no ROS here).

Poses are ``(x, y, yaw)`` [m, m, rad] in one fixed frame (map or odom); times [s] are ROS time.
"""
import collections
import math

from tiago_nav.clock import STALL, StallWatch
from tiago_nav.geometry import wrap_angle


class MotionMonitor:
    """MOVING or STOPPED from successive poses.

    The robot counts as moving when, over the last ``window`` seconds (at least half of it
    covered by samples), its position changed faster than ``speed_threshold`` [m/s] or its
    heading faster than ``turn_threshold`` [rad/s]. Below both it is stopped. ``None`` until
    enough samples arrived.
    """

    def __init__(self, window=0.5, speed_threshold=0.05, turn_threshold=0.1):
        if not (window > 0 and speed_threshold > 0 and turn_threshold > 0):
            raise ValueError('window and thresholds must be > 0')
        self.window = float(window)
        self.speed_threshold = float(speed_threshold)
        self.turn_threshold = float(turn_threshold)
        self.samples = collections.deque()

    def reset(self):
        self.samples.clear()

    def update(self, t, pose):
        """Add the pose ``(x, y, yaw)`` seen at time ``t`` [s]; return True (moving), False
        (stopped) or None (not enough history yet)."""
        if pose is not None:
            if self.samples and t < self.samples[-1][0]:
                self.samples.clear()            # time went backwards (simulator restarted)
            self.samples.append((t, pose))
            while len(self.samples) > 2 and t - self.samples[1][0] >= self.window:
                self.samples.popleft()
        return self.moving()

    def speeds(self):
        """``(linear [m/s], angular [rad/s])`` over the window, or None."""
        if len(self.samples) < 2:
            return None
        (t0, p0), (t1, p1) = self.samples[0], self.samples[-1]
        dt = t1 - t0
        if dt < self.window / 2.0:
            return None
        return (math.hypot(p1[0] - p0[0], p1[1] - p0[1]) / dt,
                abs(wrap_angle(p1[2] - p0[2])) / dt)

    def moving(self):
        s = self.speeds()
        if s is None:
            return None
        return bool(s[0] > self.speed_threshold or s[1] > self.turn_threshold)


def wait_until_still(clock, pose, stop, monitor, timeout, period=0.04, stall=STALL):
    """Command a stop and wait until the robot is still.

    Args:
        clock: a :mod:`tiago_nav.clock` clock.
        pose: callable returning the current pose (or None when unknown).
        stop: callable that commands the base to stop; called every ``period``.
        monitor: the :class:`MotionMonitor` that judges stillness (reset here).
        timeout: give up after this long [s of ROS time] ...
        period: polling period [s wall].
        stall: ... or when ROS time has stood still this long [s wall] and its source is dead
            (:class:`tiago_nav.clock.StallWatch`; a live, slow source is waited for).

    Returns True once the monitor says stopped, False on timeout, a dead clock or shutdown.
    """
    monitor.reset()
    t0 = clock.now()
    watch = StallWatch(clock, stall)
    while not clock.shutdown():
        stop()
        now = clock.now()
        if monitor.update(now, pose()) is False:
            return True
        if now - t0 > timeout or watch.check(now):
            return False
        clock.sleep(period)
    return False
