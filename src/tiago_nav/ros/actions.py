"""actionlib helpers: is a server there (without ROS time), wait for it, and a goal client that
loses no feedback."""
import threading
import time

import actionlib
import rospy
from actionlib import CommState
from actionlib_msgs.msg import GoalStatus

from tiago_nav.ros.topics import Reconnect, action_subscribers


FEEDBACK_GRACE = 1.0     # [s wall] after a result, the longest wait for the feedback it names


class TaskClient:
    """A client of one TiagoTask (or any) action with SimpleActionClient's method names, built
    on actionlib.ActionClient so that no feedback is lost: SimpleActionClient drops feedback
    that arrives before ``send_goal`` has returned (the server's first feedback often does), and
    every actionlib client drops feedback that arrives after the result (feedback and result
    travel on separate topics). Here each feedback of the goal is taken from the feedback topic
    itself, and a result that names its last feedback state (TiagoTask's ``state``) counts once
    that feedback has come too (at most :data:`FEEDBACK_GRACE` later)."""

    def __init__(self, action, action_type=None):
        if action_type is None:
            from tiago_nav.msg import TiagoTaskAction as action_type
        self.action_client = actionlib.ActionClient(action, action_type)
        self.gh = None
        self._done = threading.Event()
        self._fed = threading.Event()
        self._goal_id = None
        self._feedback_cb = None
        self._last_state = None
        self._lock = threading.Lock()
        self._feedback_sub = rospy.Subscriber(self.action_client.feedback_sub.name,
                                              self.action_client.ActionFeedback, self._on_feedback,
                                              queue_size=None)

    def wait_for_server(self, timeout):
        """``timeout``: a rospy.Duration or seconds (wall)."""
        return wait_server(self, timeout.to_sec() if hasattr(timeout, 'to_sec') else timeout)

    def _on_feedback(self, msg):
        with self._lock:
            if msg.status.goal_id.id != self._goal_id:
                return
            cb = self._feedback_cb
            self._last_state = getattr(msg.feedback, 'state', None)
        if cb is not None:
            cb(msg.feedback)
        self._check_fed()

    def _check_fed(self):
        """The result has come, and the feedback state it names (if any) too."""
        if not self._done.is_set() or self.gh is None:
            return
        result = self.gh.get_result()
        wanted = getattr(result, 'state', None)
        with self._lock:
            if wanted is None or self._last_state == wanted:
                self._fed.set()

    def send_goal(self, goal, feedback_cb=None):
        done = self._done = threading.Event()
        self._fed = threading.Event()

        def on_transition(gh):
            if gh.get_comm_state() == CommState.DONE:
                done.set()
                self._check_fed()
        with self._lock:
            self._feedback_cb, self._last_state = feedback_cb, None
            self.gh = self.action_client.send_goal(goal, on_transition)
            self._goal_id = self.gh.comm_state_machine.action_goal.goal_id.id

    def wait_for_result(self, timeout):
        """``timeout``: a rospy.Duration or seconds, counted in wall time. True once the result
        has come (and the last feedback it names, or :data:`FEEDBACK_GRACE` has passed)."""
        if not self._done.wait(timeout.to_sec() if hasattr(timeout, 'to_sec') else timeout):
            return False
        self._check_fed()
        self._fed.wait(FEEDBACK_GRACE)
        return True

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
    """Wait up to ``timeout`` wall seconds for a SimpleActionClient's server. A client topic
    that missed the server at start-up (:mod:`tiago_nav.ros.topics`: the status one, without
    which a server never counts as there) is connected again meanwhile."""
    t0 = time.monotonic()
    reconnect = Reconnect(action_subscribers(client), watch=False)
    checked = t0
    while time.monotonic() - t0 < timeout and not rospy.is_shutdown():
        if server_connected(client):
            return True
        if time.monotonic() - checked >= reconnect.period:
            checked = time.monotonic()
            reconnect.check()
        time.sleep(0.05)
    return False
