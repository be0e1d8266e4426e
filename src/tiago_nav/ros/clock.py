"""ROS time for the nodes' loops (:mod:`tiago_nav.clock` explains the clock protocol)."""
import time

import rospy


class RosClock:
    """``now()`` is ROS time (``/clock`` under ``/use_sim_time``), ``wall()`` monotonic wall
    time; ``sleep`` sleeps in wall time, so it never blocks when ``/clock`` stops."""

    def now(self):
        return rospy.get_time()

    def wall(self):
        return time.monotonic()

    def sleep(self, seconds):
        time.sleep(seconds)

    def shutdown(self):
        return rospy.is_shutdown()
