"""tiago_nav.ros.reset without a master: a Generation records what the building thread hands
to track() (not other threads, not inside persistent()), closes it in reverse order once, goes
on when one close fails; forget_goals gives an action server a fresh server's bookkeeping;
keep_status_timer swaps a status timer for one that survives ROS time going back."""
import threading

import pytest

from tiago_nav.ros import reset

pytestmark = pytest.mark.ros


class Thing:
    def __init__(self, log, name, method='close', fail=False):
        self.log, self.name, self.fail = log, name, fail
        setattr(self, method, self._closed)

    def _closed(self):
        self.log.append(self.name)
        if self.fail:
            raise RuntimeError('boom')


def test_a_generation_closes_what_its_thread_tracked_in_reverse_order_once():
    log = []
    gen = reset.Generation()
    with gen:
        a = reset.track(Thing(log, 'a'))
        reset.track(Thing(log, 'b', 'unregister'))
        with reset.persistent():
            reset.track(Thing(log, 'kept'))
        reset.track(a)                              # tracked once
        other = threading.Thread(target=lambda: reset.track(Thing(log, 'other thread')))
        other.start()
        other.join()
        reset.track(Thing(log, 'c', 'shutdown'))
    reset.track(Thing(log, 'after'))                # no generation being built: not recorded
    gen.close()
    gen.close()
    assert log == ['c', 'b', 'a']


def test_a_failing_close_does_not_keep_the_others_open(monkeypatch):
    log = []
    monkeypatch.setattr(reset.rospy, 'logwarn', lambda *a: log.append('warned'))
    gen = reset.Generation()
    with gen:
        reset.track(Thing(log, 'a'))
        reset.track(Thing(log, 'b', fail=True))
    gen.close()
    assert log == ['b', 'warned', 'a']


def test_forget_goals_and_the_status_timer():
    import actionlib
    import rospy

    class Server:
        pass
    s = Server()
    s.lock = threading.RLock()
    s.action_server = Server()
    s.action_server.lock = threading.RLock()
    s.action_server.status_list = ['old goal']
    s.action_server.last_cancel = rospy.Time(40)
    s.current_goal = s.next_goal = 'old'
    s.new_goal = s.preempt_request = s.new_goal_preempt_request = True
    reset.forget_goals(s)
    a = s.action_server
    assert a.status_list == [] and a.last_cancel == rospy.Time()
    assert isinstance(s.current_goal, actionlib.ServerGoalHandle)
    assert not (s.new_goal or s.preempt_request or s.new_goal_preempt_request)

    made = []

    class Timer:
        def __init__(self, period, callback, reset=False):
            self._period, self._reset, self.stopped = period, reset, False
            made.append(self)

        def shutdown(self):
            self.stopped = True
    a.publish_status_async = lambda event: None
    old = a.status_timer = Timer(rospy.Duration(0.2), None)
    real = reset.rospy.Timer
    reset.rospy.Timer = Timer
    try:
        reset.keep_status_timer(s)
        reset.keep_status_timer(s)       # already one that survives: kept
    finally:
        reset.rospy.Timer = real
    assert old.stopped and a.status_timer is made[1] and a.status_timer._reset
    assert len(made) == 2 and a.status_timer._period == rospy.Duration(0.2)


def test_a_shutdown_hook_does_not_keep_a_dropped_state_alive(monkeypatch):
    import gc
    import weakref
    hooks, called = [], []
    monkeypatch.setattr(reset.rospy, 'on_shutdown', hooks.append)

    class State:
        def stop(self):
            called.append(self)
    kept, dropped = State(), State()
    reset.on_shutdown(kept.stop)
    reset.on_shutdown(dropped.stop)
    gone = weakref.ref(dropped)
    del dropped
    gc.collect()
    assert gone() is None
    for h in hooks:
        h()
    assert called == [kept]


def test_a_latched_publisher_of_a_state_forgets_its_message_and_stays_registered():
    """A new state's subscriber must not get the last run's latched message (move_base's plan
    was read as the next run's), and the publisher is not unregistered."""
    import rospy
    from std_msgs.msg import String
    gen = reset.Generation()
    with gen:
        latched = rospy.Publisher('/reset_test/latched', String, queue_size=1, latch=True)
        rospy.Publisher('/reset_test/plain', String, queue_size=1)
    latched.impl.latch = String('the last run')     # (as publish() leaves it)
    gen.close()
    assert [type(o).__name__ for o in gen.objects] == ['Latched']
    assert latched.impl is not None and not latched.impl.closed and latched.impl.latch is None


def test_a_reset_start_waits_for_its_subscriptions_connections(monkeypatch):
    """wait_connected returns once every recorded Subscriber is connected to each publisher the
    master lists (its own node aside), and names the topics still waiting at the timeout."""
    import rosgraph
    import rospy
    connected = {'/plan': set(), '/tf': {'/simulator'}}

    class Master:
        def __init__(self, _name):
            pass

        def getSystemState(self):
            return ([['/plan', ['/move_base']], ['/tf', ['/simulator', '/me']]], [], [])
    monkeypatch.setattr(rosgraph, 'Master', Master)
    monkeypatch.setattr(rospy, 'get_name', lambda: '/me')
    monkeypatch.setattr(reset, 'connected_publishers', lambda s: connected[s.resolved_name])
    gen = reset.Generation()
    for name in ('/plan', '/tf'):
        sub = object.__new__(rospy.topics.Subscriber)
        sub.resolved_name = name
        gen.objects.append(sub)
    with pytest.raises(RuntimeError, match=r'publishers of /plan$'):
        reset.wait_connected(gen, timeout=0.05)
    threading.Timer(0.05, lambda: connected['/plan'].add('/move_base')).start()
    reset.wait_connected(gen, timeout=5.0)
