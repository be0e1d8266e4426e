"""Resetting a node to a fresh start's state without restarting its process.

A warm evaluation stack (docs/evaluation.md) runs the next row after a reset instead of a
restart. The simulator resets itself (``/simulator/reset``: time goes back to its start).
Every other node of the package offers two std_srvs/Trigger services (docs/interfaces.md):

``~reset/stop``
    takes the node's state down: it leaves the lockstep (its participant closes), stops
    taking in messages (every subscriber, tf listener and service its state made is
    unregistered), forgets its goal bookkeeping and what its latched publishers last sent.
    Called on every node before the simulator's reset, so that no node takes in the reset
    simulator's messages with its old state.
``~reset/start``
    builds the state anew from the node's parameters as they are now, exactly as at start:
    new subscriptions receive the latched topics (the reset simulator's start state, the map,
    the localisation's first ``map → odom``) as a starting node would, a new participant joins
    the lockstep. It answers once the node is as ready as at start (e.g. move_base serves
    goals) and each new subscription is connected to the publishers the master lists
    (:func:`wait_connected`).

:class:`Generation` records what a node's state makes while it is built (``with gen:``), so
that ``stop`` can take it all down without a list kept by hand; :class:`NodeReset` offers the
two services for a node made by a ``build()`` function. Action servers and the node's
publishers outlive resets (their clients stay connected; a latched one forgets its message,
:class:`Latched`); :func:`forget_goals` clears a server's goal bookkeeping as a fresh
server's.
"""
import threading
import time
import weakref

import rosgraph
import rospy

from tiago_nav.ros.connections import connected_publishers

CONNECT_TIMEOUT = 10.0      # [s wall] the longest a reset's start waits for its subscriptions
_local = threading.local()
_patched = []


def _building():
    return getattr(_local, 'generation', None)


class Latched:
    """A latched publisher made by a node's state: a reset's stop forgets its last message, so
    that a new subscriber gets nothing from it until the new state publishes, as from a fresh
    node (the publisher itself stays registered: see :func:`_patch`)."""

    def __init__(self, pub):
        self.pub = pub

    def close(self):
        impl = self.pub.impl
        if impl is not None:
            impl.latch = None


def _patch():
    """Record what a thread that builds a :class:`Generation` makes (installed once; a no-op
    in other threads): each rospy Subscriber and Service (taken down by the stop), and each
    latched Publisher as :class:`Latched`. Publishers are not unregistered: a node that
    unregisters a topic's publisher and registers it again makes a subscriber that connects in
    between fail its handshake, and rospy's retries back off for seconds; a publisher stays
    for the process's life, shared by the states (rospy shares one per topic in a
    process)."""
    if _patched:
        return
    from rospy.impl.tcpros_service import Service

    def tracked(cls, what):
        init = cls.__init__

        def wrapped(self, *args, **kwargs):
            init(self, *args, **kwargs)
            gen = _building()
            obj = what(self) if gen is not None else None
            if obj is not None:
                gen.track(obj)
        cls.__init__ = wrapped
    tracked(rospy.topics.Subscriber, lambda sub: sub)
    tracked(Service, lambda srv: srv)
    tracked(rospy.topics.Publisher, lambda pub: Latched(pub) if pub.impl.is_latch else None)
    _patched.append(True)


class persistent:
    """``with persistent():`` what the current thread makes is not recorded: it outlives
    resets (an action server built with the node's first state)."""

    def __enter__(self):
        self._outer = _building()
        _local.generation = None
        return self

    def __exit__(self, *exc):
        _local.generation = self._outer
        return False


def keep_status_timer(server):
    """actionlib publishes a server's status from a rospy.Timer that dies when ROS time goes
    back (a reset simulator): its clients would then take the server for gone. Replaces it
    with one that starts again from the new time (``reset=True``)."""
    a = server.action_server
    timer = getattr(a, 'status_timer', None)
    if timer is None or getattr(timer, '_reset', False):
        return
    timer.shutdown()
    a.status_timer = rospy.Timer(timer._period, a.publish_status_async, reset=True)


def adopt(server, execute, participant):
    """An action server that outlives resets serves the new state: ``execute`` is its execute
    callback, ``participant`` the lockstep participant that claims its goals
    (:class:`tiago_nav.ros.lockstep.ClaimingActionServer`), and its goal bookkeeping is a
    fresh server's (:func:`forget_goals`)."""
    forget_goals(server)
    keep_status_timer(server)
    server.execute_callback = execute
    if hasattr(server, 'participant'):
        server.participant = participant
    return server


def on_shutdown(method):
    """``rospy.on_shutdown`` for a bound ``method`` of a node's state, holding it weakly: rospy
    keeps its hooks for the process's life, and a reset state's hook would otherwise keep that
    whole state (maps, costmaps) alive after every reset."""
    ref = weakref.WeakMethod(method)

    def hook(*_):
        m = ref()
        if m is not None:
            m()
    rospy.on_shutdown(hook)


def track(obj):
    """Record ``obj`` (anything with ``close()``, ``unregister()`` or ``shutdown()``) in the
    :class:`Generation` being built in this thread, if any: the package's own classes that keep
    threads or re-subscribe (:class:`tiago_nav.ros.topics.Subscription`,
    :class:`tiago_nav.ros.lockstep.LockstepParticipant`) call it."""
    gen = _building()
    if gen is not None:
        gen.track(obj)
    return obj


class Generation:
    """What one build of a node's state made: rospy subscribers and services, and the objects
    :func:`track` was given. ``with gen:`` records what the current thread makes;
    :meth:`close` takes it down (in reverse order)."""

    def __init__(self):
        _patch()
        self.objects = []
        self.closed = False

    def track(self, obj):
        if all(o is not obj for o in self.objects):
            self.objects.append(obj)

    def __enter__(self):
        self._outer = _building()
        _local.generation = self
        return self

    def __exit__(self, *exc):
        _local.generation = self._outer
        return False

    def close(self):
        """Unregister and close everything recorded; idempotent."""
        if self.closed:
            return
        self.closed = True
        for obj in reversed(self.objects):
            for name in ('close', 'unregister', 'shutdown'):
                fn = getattr(obj, name, None)
                if fn is not None:
                    try:
                        fn()        # (a second unregister of a rospy topic does nothing)
                    except Exception as e:      # noqa: BLE001 - take the rest down anyway
                        rospy.logwarn('%s: reset: closing %r: %s', rospy.get_name(), obj, e)
                    break


def forget_goals(server):
    """Give an actionlib SimpleActionServer a fresh server's goal bookkeeping: no goal
    statuses, no current or next goal, no cancel time (a cancel stamped in the last run would
    otherwise cancel every goal stamped before it, and simulated time restarts lower)."""
    import actionlib
    a = server.action_server
    with a.lock:
        a.status_list = []
        a.last_cancel = rospy.Time()
    with server.lock:
        server.current_goal = actionlib.ServerGoalHandle()
        server.next_goal = actionlib.ServerGoalHandle()
        server.new_goal = False
        server.preempt_request = False
        server.new_goal_preempt_request = False


def wait_connected(generation, timeout=CONNECT_TIMEOUT):
    """Waits until each rospy Subscriber ``generation`` recorded has completed its handshake
    with every publisher the master lists for its topic (other than this node). A fresh
    start's subscriptions are connected seconds before the first goal; after a reset the next
    row's goal follows at once, and a message sent before its subscriber's connection is lost
    (move_base's first plan, read by the proxy on its next cycle). Raises RuntimeError naming
    the topics still waiting after ``timeout`` [s wall]."""
    me = rospy.get_name()
    subs = [o for o in generation.objects if isinstance(o, rospy.topics.Subscriber)]
    master = rosgraph.Master(me)
    end = time.monotonic() + timeout
    while True:
        try:
            listed = dict(master.getSystemState()[0])
        except (rosgraph.MasterError, OSError):
            listed = None
        waiting = sorted({s.resolved_name for s in subs if listed is not None and
                          set(listed.get(s.resolved_name, ())) - {me} - connected_publishers(s)})
        if listed is not None and not waiting:
            return
        if time.monotonic() > end or rospy.is_shutdown():
            raise RuntimeError('no connection within %g s to the publishers of %s' % (
                timeout, ', '.join(waiting) if listed is not None else '(the master is gone)'))
        time.sleep(0.02)


class NodeReset:
    """``~reset/stop`` and ``~reset/start`` (std_srvs/Trigger) for a node whose state is made
    by ``build()`` (returns the state; raises to refuse) and taken down by ``stop(state)``
    (optional: beyond what :class:`Generation` recorded, e.g. forgetting goals). ``state`` is
    the current one (None between stop and start)."""

    def __init__(self, build, stop=None, first=None):
        from std_srvs.srv import Trigger
        self.build, self.stop_fn = build, stop
        self.lock = threading.Lock()
        self.generation = Generation()
        if first is None:
            with self.generation:
                first = build()
        self.state = first
        self.stop_srv = rospy.Service('~reset/stop', Trigger, self.on_stop)
        self.start_srv = rospy.Service('~reset/start', Trigger, self.on_start)

    def stop(self):
        with self.lock:
            state, self.state = self.state, None
            if state is not None and self.stop_fn is not None:
                self.stop_fn(state)
            self.generation.close()
            self.generation = Generation()      # (the closed one keeps nothing alive)

    def start(self):
        with self.lock:
            if self.state is not None:
                return self.state
            self.generation = Generation()
            with self.generation:
                self.state = self.build()
            wait_connected(self.generation)
        return self.state

    def on_stop(self, _):
        from std_srvs.srv import TriggerResponse
        try:
            self.stop()
        except Exception as e:      # noqa: BLE001 - the caller starts a fresh stack
            return TriggerResponse(False, 'stop failed: %s: %s' % (type(e).__name__, e))
        return TriggerResponse(True, 'stopped')

    def on_start(self, _):
        from std_srvs.srv import TriggerResponse
        try:
            self.start()
        except Exception as e:      # noqa: BLE001 - the caller starts a fresh stack
            self.generation.close()
            with self.lock:
                self.state = None
            return TriggerResponse(False, 'start failed: %s: %s' % (type(e).__name__, e))
        return TriggerResponse(True, 'started')
