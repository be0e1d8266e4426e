"""actionlib helpers: is a server there (without ROS time), wait for it, and a goal client that
loses no feedback."""
import threading
import time

import actionlib
import rospy
from actionlib import CommState
from actionlib_msgs.msg import GoalStatus


class TaskClient:
    """A client of one TiagoTask (or any) action with SimpleActionClient's method names, built
    on actionlib.ActionClient so that no feedback is lost: SimpleActionClient drops feedback
    that arrives before ``send_goal`` has returned (the server's first feedback often does)."""

    def __init__(self, action, action_type=None):
        if action_type is None:
            from tiago_nav.msg import TiagoTaskAction as action_type
        self.action_client = actionlib.ActionClient(action, action_type)
        self.gh = None
        self._done = threading.Event()

    def wait_for_server(self, timeout):
        """``timeout``: a rospy.Duration or seconds (wall)."""
        return wait_server(self, timeout.to_sec() if hasattr(timeout, 'to_sec') else timeout)

    def send_goal(self, goal, feedback_cb=None):
        done = self._done = threading.Event()

        def on_transition(gh):
            if gh.get_comm_state() == CommState.DONE:
                done.set()

        def on_feedback(gh, fb):
            if feedback_cb is not None:
                feedback_cb(fb)
        self.gh = self.action_client.send_goal(goal, on_transition, on_feedback)

    def wait_for_result(self, timeout):
        """``timeout``: a rospy.Duration or seconds, counted in wall time."""
        return self._done.wait(timeout.to_sec() if hasattr(timeout, 'to_sec') else timeout)

    def get_state(self):
        return self.gh.get_goal_status() if self.gh else GoalStatus.LOST

    def get_result(self):
        return self.gh.get_result() if self.gh else None

    def get_goal_status_text(self):
        return self.gh.get_goal_status_text() if self.gh else ''

    def cancel_goal(self):
        if self.gh:
            self.gh.cancel()


def server_connected(client):
    """True when a SimpleActionClient is connected to a live action server (the check of
    actionlib's wait_for_server, done once and without ROS time, which may stand still or be
    near 0 under /use_sim_time)."""
    ac = getattr(client, 'action_client', client)
    msg = ac.last_status_msg
    if not msg:
        return False
    sid = msg._connection_header.get('callerid')
    return bool(ac.pub_goal.impl.has_connection(sid) and ac.pub_cancel.impl.has_connection(sid)
                and any(c.callerid_pub == sid for c in ac.result_sub.impl.connections)
                and any(c.callerid_pub == sid for c in ac.feedback_sub.impl.connections))


def wait_server(client, timeout):
    """Wait up to ``timeout`` wall seconds for a SimpleActionClient's server."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout and not rospy.is_shutdown():
        if server_connected(client):
            return True
        time.sleep(0.05)
    return False
