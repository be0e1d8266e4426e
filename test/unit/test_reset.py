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
