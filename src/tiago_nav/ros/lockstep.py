"""Lockstep over ROS topics (the protocol: :mod:`tiago_nav.lockstep` and docs/lockstep.md).

:class:`LockstepHost` is the simulator's side (answers in, ticks out, cmd_vel of participants
told apart); :class:`LockstepParticipant` a control loop's side, used in place of
:class:`tiago_nav.clock.Ticker`; :class:`ScanCache` and :func:`lookup_at` wait in wall time for
the exact scan and transform of a cycle (ROS time stands still while the simulator holds).
"""
import collections
import copy
import math
import threading
import time
import warnings

import actionlib

import rospy
from geometry_msgs.msg import Twist
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan

from tiago_nav import motion
from tiago_nav.clock import HUNG, NAP, STALL, Patience, StallWatch, Ticker
from tiago_nav.lockstep import EPS, Ack, Gate, ParticipantCore, Schedule, Tick
from tiago_nav.msg import LockstepAck, LockstepTick
from tiago_nav.ros.clock import RosClock, node_dead, nodes_dead, tf_sources
from tiago_nav.ros.reset import keep_status_timer, on_shutdown, persistent, track
from tiago_nav.ros.connections import connected_publishers, connected_subscribers, live_publishers
from tiago_nav.ros.topics import Subscription

ACK_TOPIC = '/sim/lockstep/ack'
TICK_TOPIC = '/sim/lockstep/tick'
USE_LOCKSTEP = '/use_lockstep'      # bool: the participants take part (set by sim.launch)
TIMEOUT = HUNG    # [s wall] the simulator's default wait for a missing answer from a participant
                  # whose process lives (it then drops the participant, which may rejoin; no
                  # goal fails for it); one that died is dropped once that is known
ASK = 1.0         # [s wall] a missing answer: after this long the simulator asks whether its
                  # participant lives, and again as often while it waits
CYCLE_WAIT = 2.0  # [s wall] in a held cycle, a wait for its scan, tf, pose or a peer's answer
                  # asks after this long whether their source lives, and waits on while it
                  # does (up to HUNG): the source has published them, so only a starved
                  # process waits at all (:func:`held`)
STARTUP_WAIT = 30.0  # [s wall] before a node has joined, the longest wait for the data it needs
                    # (simulated time stands still at its start until the expected have joined)
GOAL_LEAD = 1.0  # [s] a goal stamped up to this far ahead of a server's ROS time is on its clock
SEND_TIMEOUT = 1.0  # [s wall] the longest write of a direct publisher to one subscriber
JOIN_POLL = 0.01  # [s wall] how often a participant not registered yet looks at its inputs
WAKE = 0.05       # [s wall] the longest a waiting cycle sleeps between looks at its clock: ticks
                  # and /clock wake it at once (it used to look every 2 ms, 500 wake-ups per wall
                  # second in each waiting loop)


def direct_publisher(topic, msg_class, subscriber_listener=None, send_timeout=SEND_TIMEOUT,
                     **kwargs):
    """A rospy.Publisher that writes in the caller's thread (``queue_size=None``): no queue
    thread per subscriber, whose hand-over (rospy yields the processor after queueing) adds a
    thread switch to every message. For the messages of a lockstep round trip (ticks, answers,
    and in lockstep the simulator's sensor data), where each hop's latency holds the whole
    simulation. A write to one subscriber that takes longer than ``send_timeout`` [s wall] (a
    frozen process whose socket buffers are full) drops that subscriber's connection, as
    rospy does on any write error, instead of blocking the publisher; the subscriber
    connects again once it runs."""
    listener = _SendTimeout(send_timeout, subscriber_listener)
    with warnings.catch_warnings():     # rospy warns about a missing queue_size: it is meant
        warnings.simplefilter('ignore')
        pub = rospy.Publisher(topic, msg_class, queue_size=None, subscriber_listener=listener,
                              **kwargs)
    listener.pub = pub
    limit_sends(pub, send_timeout)
    return pub


def limit_sends(pub, timeout):
    """Puts a send timeout of ``timeout`` [s] on the sockets of ``pub``'s subscriber
    connections that have none (rospy writes with a blocking ``sendall``)."""
    for c in list(pub.impl.connections):
        sock = getattr(c, 'socket', None)
        if sock is not None and sock.gettimeout() is None:
            sock.settimeout(timeout)


class _SendTimeout(rospy.SubscribeListener):
    """:func:`limit_sends` on each new subscriber of ``pub``; then ``then``'s callbacks."""

    def __init__(self, timeout, then=None):
        super().__init__()
        self.timeout, self.then, self.pub = timeout, then, None

    def peer_subscribe(self, topic_name, topic_publish, peer_publish):
        if self.pub is not None:
            limit_sends(self.pub, self.timeout)
        if self.then is not None:
            self.then.peer_subscribe(topic_name, topic_publish, peer_publish)

    def peer_unsubscribe(self, topic_name, num_peers):
        if self.then is not None:
            self.then.peer_unsubscribe(topic_name, num_peers)


class ClockSource:
    """The /clock publisher of the process that makes simulated time (the simulator): a
    :func:`direct_publisher` that also sets this process's own ROS time. rospy subscribes every
    node to /clock under /use_sim_time, the simulator too, which then received each of its
    own /clock messages back (a thread wake-up and a deserialisation, in the process every
    lockstep hold waits on): that subscription is dropped here. /clock is latched: a node
    that starts while simulated time stands still (the simulator waits for work) still learns
    the time."""

    def __init__(self):
        from rospy.impl import simtime
        sub = getattr(simtime, '_clock_sub', None)     # set by rospy.init_node
        if sub is not None:
            sub.unregister()
            simtime._clock_sub = None
        self.pub = direct_publisher('/clock', Clock, latch=True)

    def publish(self, msg):
        self.pub.publish(msg)
        rospy.rostime._set_rostime(msg.clock)


def held(dead=None):
    """A :class:`tiago_nav.clock.Patience` for data a held cycle waits for: :data:`CYCLE_WAIT`
    wall seconds, then on while ``dead()`` says its source lives, up to :data:`HUNG`.
    ``dead`` defaults to the simulator's verdict (``/clock``'s publisher: the scans and the
    odometry are its)."""
    return Patience(CYCLE_WAIT, HUNG, dead or RosClock().source_dead)


def held_tf(buffer, target, source):
    """:func:`held` for the transform ``target`` <- ``source`` of a ``tf2_ros.Buffer``: on while
    the simulator and the broadcasters of that chain (the localisation's ``map → odom``) live."""
    return held(lambda: RosClock().source_dead()
                or nodes_dead(sorted(tf_sources(buffer, target, source))))


def held_by(node):
    """:func:`held` for what the node named ``node`` must send (its answer, its goal's
    result): on while its process lives."""
    return held(lambda: node_dead(node))


def _on_grid(stamp, seconds):
    """``stamp`` (rospy.Time) + ``seconds`` rounded to whole nanoseconds (a stamp on the
    physics grid stays on it)."""
    return rospy.Time(nsecs=stamp.to_nsec() + int(round(seconds * 1e9)))


def _log(level, text):
    (rospy.logwarn if level == 'warn' else rospy.loginfo)(text)


def ack_from_msg(msg):
    """LockstepAck -> :class:`tiago_nav.lockstep.Ack`."""
    cmd = (msg.cmd.linear.x, msg.cmd.angular.z) if msg.has_command else None
    return Ack(msg.node, msg.stamp.to_sec(), msg.period.to_sec(), cmd, msg.leave, msg.busy)


class LockstepHost:
    """The simulator's side.

    Args:
        rate: physics rate [Hz].
        timeout: [s wall] wait for a missing answer from a participant whose process lives
            before dropping it as hung; one that died (its answers' connection closed and its
            process gone, or unregistered) is dropped once that is known (asked every
            :data:`ASK` seconds of the wait: :meth:`dead`).
        clock_pub: the simulator's /clock publisher: a tick is preceded by /clock for the
            held time when that was not the last /clock sent, and a repeated tick by /clock
            again, so that a participant whose /clock subscription connected after that time
            was published still sees ROS time reach its cycle.
        wait_for_work, expected, expect_timeout: see :class:`tiago_nav.lockstep.Schedule`.
    """

    def __init__(self, rate, timeout=TIMEOUT, clock_pub=None, wait_for_work=False, expected=(),
                 expect_timeout=60.0):
        self.clock_pub = clock_pub
        self.clock_stamp = None     # the newest /clock sent (rospy.Time)
        self.callers = {}           # participant -> the node whose connection brought its answers
        self._settings = (rate, timeout, _log, wait_for_work, tuple(expected), expect_timeout,
                          self.dead, ASK)
        self.interrupted = threading.Event()    # makes a waiting :meth:`hold` return None
        self.gate = Gate(Schedule(*self._settings), time.monotonic,
                         lambda: rospy.is_shutdown() or self.interrupted.is_set())
        self.pub = direct_publisher(TICK_TOPIC, LockstepTick)
        self.sub = rospy.Subscriber(ACK_TOPIC, LockstepAck, self.on_ack, queue_size=None,
                                    tcp_nodelay=True)

    @property
    def schedule(self):
        return self.gate.schedule

    def interrupt(self):
        """Makes :meth:`hold` return None now (and at once until :meth:`reset`): the
        simulator's step loop then takes a reset."""
        self.interrupted.set()
        with self.gate.cond:
            self.gate.cond.notify_all()

    def reset(self):
        """As at a fresh start: no participant, the expected ones awaited again, no pending
        command, no statistics; the next /clock is sent whatever its stamp. Participants that
        took part before must join again (each node's reset makes a new participant)."""
        with self.gate.cond:
            self.gate.schedule = Schedule(*self._settings)
            self.gate._held = None
            self.interrupted.clear()
        self.clock_stamp = None

    def on_ack(self, msg):
        header = getattr(msg, '_connection_header', None) or {}
        self.callers[msg.node] = header.get('callerid', msg.node)
        self.gate.receive(ack_from_msg(msg))

    def dead(self, node):
        """``''`` while the participant ``node`` lives: the connection its answers came on is
        open (a process that dies closes it), or else its node's process is there
        (:func:`tiago_nav.ros.clock.node_dead`); else why it is dead."""
        caller = self.callers.get(node, node)
        if caller in live_publishers(self.sub):
            return ''
        return node_dead(caller)

    def has_participants(self):
        """True while anyone takes part (the ticks then carry time forward)."""
        return self.gate.has_participants()

    def from_participant(self, msg):
        """True for a message (e.g. a cmd_vel Twist) published by a current participant: its
        commands come in its answers, so this copy must not be applied."""
        header = getattr(msg, '_connection_header', None) or {}
        return self.gate.is_participant(header.get('callerid', ''))

    def hold(self, t, sensors, work=None):
        """Before stepping past simulated time ``t`` (rospy.Time): waits for the missing
        answers (ticks published as needed), then for work (:meth:`Gate.hold`, ``work``).
        Returns the commands ``(v, w)`` to apply now, in order, or None on shutdown.
        ``sensors(t)``, called before each tick, publishes what the tick needs and returns the
        rospy.Time ``(scan_stamp, odom_stamp)`` of the newest scan and odometry published at
        or before ``t`` (None: none yet)."""
        ticks = []

        def tick(_, waiting):
            scan_stamp, odom_stamp = sensors(t)
            if ticks or self.clock_stamp != t:
                self.publish_clock(t)
            ticks.append(t)
            self.pub.publish(LockstepTick(stamp=t, scan_stamp=scan_stamp or rospy.Time(),
                                          odom_stamp=odom_stamp or rospy.Time(),
                                          waiting_for=waiting))
        return self.gate.hold(t.to_sec(), tick, work)

    def publish_clock(self, t):
        """/clock for ``t`` (rospy.Time), the simulator's only way to send it in lockstep."""
        if self.clock_pub is not None:
            self.clock_pub.publish(Clock(t))
            self.clock_stamp = t


class ScanCache:
    """The last few scans of ``topic``, found by stamp."""

    def __init__(self, topic='/scan', size=8):
        self.cond = threading.Condition()
        self.scans = collections.deque(maxlen=size)
        self.sub = Subscription(topic, LaserScan, self.on_scan, queue_size=size,
                                tcp_nodelay=True)

    def on_scan(self, msg):
        with self.cond:
            self.scans.append(msg)
            self.cond.notify_all()

    def latest(self):
        with self.cond:
            return self.scans[-1] if self.scans else None

    def scans_after(self, after, upto, timeout):
        """Every cached scan stamped in (``after``, ``upto``] (rospy.Time; ``after`` None: no
        lower bound), oldest first, once the one stamped ``upto`` has arrived (waiting as
        :meth:`wait_for_scan` does); None if it does not come."""
        if self.wait_for_scan(upto, timeout) is None:
            return None
        with self.cond:
            return [s for s in self.scans
                    if (after is None or s.header.stamp > after) and s.header.stamp <= upto]

    def wait_for_scan(self, stamp, timeout):
        """The scan stamped exactly ``stamp`` (rospy.Time), waiting for it up to ``timeout``
        [s wall] or as a :class:`~tiago_nav.clock.Patience` allows (:func:`held`); None if it
        does not come (or has left the cache)."""
        patience = Patience.of(timeout)
        with self.cond:
            while True:
                for s in self.scans:
                    if s.header.stamp == stamp:
                        return s
                if patience.over() or rospy.is_shutdown():
                    return None
                self.cond.wait(patience.left(0.1))


def goal_since(goal_stamp, now):
    """The time after which a goal's cycles are its own (rospy.Time, for
    :meth:`LockstepParticipant.claim`): its stamp, however late the goal arrived, and however
    early: a goal sent inside a cycle the simulator holds can reach a server before that
    cycle's /clock and tick do, its stamp then a little ahead of the server's ``now``
    (:meth:`LockstepParticipant.now`). (Taking ``now`` then made the goal's first cycle one
    earlier than in other runs: a corridor run in twenty with both cores busy.) A stamp more
    than :data:`GOAL_LEAD` ahead is a client on another clock: ``now``. None (claim from now)
    for a zero stamp."""
    if goal_stamp.is_zero():
        return None
    return goal_stamp if goal_stamp <= now + rospy.Duration.from_sec(GOAL_LEAD) else now


def gone(buffer, target, source, stamp):
    """True when tf will never give ``target`` <- ``source`` at ``stamp`` (rospy.Time): it
    already holds newer data for that chain but cannot transform at ``stamp`` (the data was
    older than the buffer keeps). Waiting for it would only delay the next message."""
    try:
        newest = buffer.lookup_transform(target, source, rospy.Time(0)).header.stamp
    except Exception:               # noqa: BLE001 - no data at all yet: it may still come
        return False
    return stamp < newest and not buffer.can_transform(target, source, stamp)


def wait_for_transform(buffer, target, source, stamp, timeout):
    """Wait up to ``timeout`` [s wall], or as a :class:`~tiago_nav.clock.Patience` allows
    (:func:`held_tf`), until tf can give ``target`` <- ``source`` at exactly ``stamp`` (tf2's
    own timeout runs in ROS time, which stands still while the simulator holds); not at all
    when it is :func:`gone`. True when it can."""
    patience = Patience.of(timeout)
    while not buffer.can_transform(target, source, stamp):
        if patience.over() or rospy.is_shutdown() or gone(buffer, target, source, stamp):
            return False
        time.sleep(NAP)
    return True


def lookup_at(buffer, target, source, stamp, timeout):
    """tf ``target`` <- ``source`` at exactly ``stamp`` (no extrapolation), after
    :func:`wait_for_transform`. Raises tf2_ros.TransformException when it does not come."""
    wait_for_transform(buffer, target, source, stamp, timeout)
    return buffer.lookup_transform(target, source, stamp)


class LockstepParticipant:
    """A control loop in lockstep with the simulator, used in place of
    :class:`tiago_nav.clock.Ticker`.

    Idle (not claimed) it answers every tick due to it at once, with no command, from the tick
    subscriber's thread. A control loop calls :meth:`claim` when its goal starts, then per
    cycle :meth:`tick` and :meth:`answer`, and :meth:`release` when the goal ends.

    Args:
        period: control period [s], a whole number of the simulator's physics steps.
        clock: a :mod:`tiago_nav.clock` clock (default :class:`RosClock`).
        name: the participant's name; default the node's name (which is the callerid of its
            cmd_vel messages, so that the simulator ignores those).
        enabled: take part; default the ``/use_lockstep`` parameter. When False this is a
            plain :class:`Ticker` and publishes nothing.
        stall: [s wall] when ROS time stands still this long without a tick for it,
            :meth:`tick` asks whether the simulator is dead (then it gives up), and again
            every ``stall`` seconds while it lives.
        ready: ``ready(tick)`` (a LockstepTick) returns once the node has taken in the sensor
            data the tick names (e.g. its costmap holds every scan up to ``tick.scan_stamp``);
            called before each idle answer, from the tick subscriber's thread. None: idle
            answers are immediate.
        inputs: ``inputs()`` is True once the node's sensor data flows (e.g. it has received a
            scan and the odometry tf); None: nothing to wait for. May be set as the attribute
            ``inputs`` after construction. The participant registers with the simulator only
            once ticks and answers are connected both ways and ``inputs()`` holds (looked at
            every :data:`JOIN_POLL` wall seconds), and answers nothing before: a participant that
            registered sooner would hold the simulator while it waited for a scan or
            transform published before its subscription connected, which never comes (the
            simulator then drops it after its timeout and goes on without it, a start that
            differs from run to run).
    """

    def __init__(self, period, clock=None, name=None, enabled=None, stall=STALL, ready=None,
                 inputs=None):
        self.clock = clock or RosClock()
        self.period = float(period)
        self.name = name or rospy.get_name()
        self.enabled = rospy.get_param(USE_LOCKSTEP, False) if enabled is None else enabled
        self.stall, self.ready, self.inputs = stall, ready, inputs
        self.stamp = None        # rospy.Time of the current cycle
        self.reason = ''         # why the last tick() gave up
        self.tick_msg = None     # its LockstepTick, None when running free
        self.ticker = None if self.enabled else Ticker(self.clock, self.period, stall)
        if not self.enabled:
            return
        self.cond = threading.Condition()
        self.core = ParticipantCore(self.period, self.clock.now())
        self._msgs = {}          # tick stamp [s] -> LockstepTick, for the newest tick
        self._answered = True
        self._left = False
        self._busy = False       # what the last answer sent said of work (Ack.busy)
        self._last_ack = None    # the last answer sent (sent again when it was lost)
        self.joined = threading.Event()     # registered: the inputs flow (see ``inputs``)
        self._join = _Join(self)
        self.pub = direct_publisher(ACK_TOPIC, LockstepAck, subscriber_listener=self._join)
        self.sub = Subscription(TICK_TOPIC, LockstepTick, self.on_tick, queue_size=10,
                                tcp_nodelay=True)
        # a cycle waits for ROS time too (a tick counts once its /clock has come; running free,
        # ROS time passes the deadline): each /clock wakes it (this callback shares rospy's own
        # /clock connection, after rospy has set the time)
        self.clock_sub = rospy.Subscriber('/clock', Clock, self._on_clock, queue_size=None) \
            if rospy.get_param('/use_sim_time', False) else None
        self._closed = False
        on_shutdown(self.leave)
        threading.Thread(target=self._join_when_ready, name='lockstep join', daemon=True).start()
        track(self)     # a node's reset closes it (tiago_nav.ros.reset)

    def inputs_ready(self):
        """True once the simulator's ticks reach this participant, the simulator has subscribed
        to its answers (an answer published before would be lost, though counted as given; other
        nodes subscribe to the answers too, e.g. the mission proxy) and ``inputs()`` holds."""
        simulators = connected_publishers(self.sub.sub) - {None}
        if not simulators & connected_subscribers(self.pub):
            return False
        try:
            return self.inputs is None or bool(self.inputs())
        except Exception as e:      # noqa: BLE001 - the join thread must not die
            rospy.logwarn_throttle(10.0, '%s: lockstep: checking its inputs: %s' % (self.name, e))
            return False

    def wait_joined(self, timeout):
        """Wait up to ``timeout`` wall seconds until registered with the simulator (at once when
        not taking part), and until this node's ROS time runs (its first /clock has come, under
        /use_sim_time); False, with a warning, if either did not happen. A node should serve
        goals only then: a goal that began before would run free, and at the simulator's full
        speed a free control loop falls behind it (a corridor law drove into the obstacle it
        should have stopped before); and what it stamped before its first /clock would say 0
        (a mission's first feedback did, in one run of two: /clock travels on a connection of its
        own, which may come up after the scans and tf that let the node register)."""
        deadline = time.monotonic() + timeout
        if self.ticker is None and not self.joined.wait(timeout):
            rospy.logwarn('%s: not registered in lockstep within %g s (is the simulator holding? '
                          'do its inputs flow?): serving anyway, running free until it registers',
                          self.name, timeout)
            return False
        while self.clock.now() <= 0.0 and not rospy.is_shutdown():
            if time.monotonic() > deadline:
                rospy.logwarn('%s: no /clock within %g s: serving anyway, with ROS time 0 until '
                              'it comes', self.name, timeout)
                return False
            time.sleep(JOIN_POLL)
        return True

    def _join_when_ready(self):
        while not rospy.is_shutdown() and not self._closed:
            if self.inputs_ready():
                self.joined.set()
                self.pub.publish(self.join_msg())
                return
            time.sleep(JOIN_POLL)

    def now(self):
        """rospy.Time: ROS time as far as this participant knows, its clock or the newest
        tick's stamp if later (/clock and the ticks travel apart)."""
        t = self.clock.now()
        if self.ticker is None:
            with self.cond:
                if self.core.latest is not None:
                    t = max(t, self.core.latest.stamp)
        return rospy.Time.from_sec(t)

    # --- what the cycle saw -------------------------------------------------------------------
    @property
    def lockstep(self):
        """True when the current cycle is held by the simulator (its stamps are exact)."""
        return self.tick_msg is not None

    @property
    def scan_stamp(self):
        """rospy.Time of the newest scan at or before the cycle, None when running free."""
        return self.tick_msg.scan_stamp if self.tick_msg else None

    @property
    def odom_stamp(self):
        """rospy.Time of the newest odometry and tf at or before the cycle, None when free."""
        return self.tick_msg.odom_stamp if self.tick_msg else None

    # --- the protocol ---------------------------------------------------------------------------
    def _ack(self, stamp, cmd=None, leave=False, busy=False):
        msg = LockstepAck(node=self.name, stamp=stamp, period=rospy.Duration.from_sec(self.period),
                          has_command=cmd is not None, cmd=cmd or Twist(), leave=leave,
                          busy=busy)
        self._busy = busy
        self._last_ack = msg
        self.pub.publish(msg)
        return msg

    def join_msg(self):
        """The registration: stamped 0, so that the simulator holds at once at its current time
        and the participant's answer to that tick sets its place (a simulator that already
        knows the participant only takes its ``busy``: whether a control loop owns it)."""
        return LockstepAck(node=self.name, stamp=rospy.Time(0),
                           period=rospy.Duration.from_sec(self.period), busy=self.core.claimed)

    def _on_clock(self, _):
        with self.cond:     # (rospy has set the time: this callback comes after its own)
            if self.core.claimed and self.core.next_cycle(self.clock.now()) is not None:
                self.cond.notify_all()      # a cycle begins: wake tick()

    def _nap(self, now):
        """How long [s wall] :meth:`tick` may sleep at ROS time ``now`` [s]: until the next
        deadline (ROS time without /use_sim_time is wall time; with it, /clock wakes the loop),
        within [:data:`NAP`, :data:`WAKE`]."""
        return min(max(self.core.deadline() - now, NAP), WAKE)

    def on_tick(self, msg):
        with self.cond:
            tick = Tick(msg.stamp.to_sec(), named=self.name in msg.waiting_for)
            self.core.on_tick(tick)
            if self.core.latest is tick:
                self._msgs = {tick.stamp: msg}
            self.cond.notify_all()
            last = self._last_ack
            if last is not None and not self._left and self.core.answer_again() and \
                    last.stamp.to_sec() >= tick.stamp - EPS:
                # the same answer (the simulator ignores it if it has it), saying what this
                # participant says now of work
                again = copy.copy(last)
                again.busy = self._busy
                self.pub.publish(again)
        self._idle_answer()

    def _idle_answer(self):
        """Answers the newest tick with no command when it is due and no control loop owns it
        (after ``ready``)."""
        with self.cond:
            due = None if self._left or not self.joined.is_set() else self.core.idle_answer()
            msg = self._msgs.get(due)
        if due is None:
            return
        if self.ready is not None:
            self.ready(msg)
        with self.cond:
            if self.core.idle_answer() == due:
                upto = self.core.cover(due)
                self._ack(msg.stamp if upto == due else _on_grid(msg.stamp, upto - due))
                self.core.answered(upto)

    def claim(self, since=None):
        """A control loop takes the cycles after ``since`` (rospy.Time, default now; give the
        goal's stamp so that the first cycle does not depend on when the goal arrived)."""
        if self.enabled:
            with self.cond:
                self._left = False
                self.core.claim((since or rospy.Time.from_sec(self.clock.now())).to_sec())

    def release(self):
        """Back to idle (answer the last cycle first, with the stop command)."""
        if self.enabled:
            with self.cond:
                self.core.release()
            self._idle_answer()

    def tick(self):
        """Waits for the next cycle: the simulator's tick for this participant's next deadline
        (lockstep), or ROS time past it (running free). False on shutdown, or when ROS time
        stands still and its source is dead (:class:`tiago_nav.clock.StallWatch`: a live
        simulator, however slow, is waited for); ``reason`` then says which."""
        if self.ticker is not None:
            ok = self.ticker.tick()
            self.reason = self.ticker.reason
            return ok
        clock = self.clock
        watch = StallWatch(clock, self.stall)
        self.reason = ''
        with self.cond:
            if not self.core.claimed:       # a loop without claim(): it owns every later cycle
                self._left = False
                self.core.claim(self.core.last)
            if not self._busy and self.joined.is_set():
                # a simulator that waits for work stands still until a participant says it has
                # some: say so once, in a registration (stamped 0: it moves no deadline)
                self.pub.publish(self.join_msg())
                self._busy = True
            while not clock.shutdown():
                now = clock.now()
                cycle = self.core.next_cycle(now)
                if cycle is not None:
                    stamp, tick = cycle
                    self.tick_msg = self._msgs[stamp] if tick is not None else None
                    self.stamp = self.tick_msg.stamp if tick is not None else rospy.Time.from_sec(stamp)
                    self._answered = False
                    return True
                asked = watch.asked
                self.reason = watch.check(now)
                if self.reason:
                    return False
                if watch.asked != asked and self.joined.is_set():
                    # ROS time has stood still for `stall` wall seconds and the simulator
                    # lives: it may have dropped this participant (no answer within its
                    # lockstep timeout, on a starved machine) and, waiting for work, be
                    # waiting for it. Announce it again so that it rejoins; a simulator that
                    # still holds it only takes the announcement's busy flag.
                    self.pub.publish(self.join_msg())
                self.cond.wait(self._nap(now))
        self.reason = 'node shutting down'
        return False

    def answer(self, cmd=None, busy=True):
        """Answers the current cycle; ``cmd`` (geometry_msgs/Twist) is its base command, which
        the simulator applies from the cycle's stamp on; ``busy`` False: this loop needs no
        more simulated time for now (a simulator that waits for work may stand still at this
        cycle, e.g. while the mission proxy asks for detection). Returns the LockstepAck sent
        (None when not taking part or already answered)."""
        if self.ticker is not None:
            return None
        with self.cond:
            if self._answered or self.stamp is None:
                return None
            self._answered = True
            self.core.answered(self.stamp.to_sec())
            if not self.joined.is_set():
                return None     # not registered: the simulator does not wait for this cycle
            return self._ack(self.stamp, cmd, busy=busy)

    def wait_until_still(self, pose, stop, monitor, timeout):
        """:func:`tiago_nav.motion.wait_until_still` for a claimed control loop: each cycle
        calls ``stop()`` (the node's stop, for observers) and answers with a zero command
        (the simulator ignores a participant's cmd_vel), until ``monitor`` judges the poses
        ``pose()`` still (True) or ``timeout`` [s ROS] has passed (False). The cycle of that
        judgement is left unanswered: simulated time holds at its stamp while the caller reports
        the end (a result stamped then is the same in every run), and the caller's next answer
        (its stop, or :meth:`release`) lets time go on."""
        if self.ticker is not None:
            return motion.wait_until_still(self.clock, pose, stop, monitor, timeout, stall=self.stall)
        monitor.reset()
        t0 = None
        while self.tick():
            now = self.stamp.to_sec()
            t0 = now if t0 is None else t0
            if monitor.update(now, pose()) is False:
                return True
            if now - t0 > timeout:
                return False
            stop()
            self.answer(Twist())
        return False

    def leave(self, cmd=None):
        """Stop taking part (the simulator no longer waits; ``cmd``: a last command) until the
        next :meth:`claim` or :meth:`tick`."""
        if self.ticker is None:
            with self.cond:
                self._left = True
                self.core.release()
            try:
                self._ack(rospy.Time.from_sec(self.clock.now()), cmd, leave=True)
            except rospy.ROSException:
                pass        # shutting down (or closed): the simulator's timeout drops it instead

    def close(self):
        """:meth:`leave` for good: also stop taking in the ticks (each costs this process and
        the simulator a message), e.g. a client that took part only to place its goal on a
        cycle. The participant cannot take part again."""
        if self.ticker is None:
            self._closed = True
            self.leave()
            self.sub.unregister()
            if self.clock_sub is not None:
                self.clock_sub.unregister()
            # the answers' publisher stays registered (rospy shares one per topic in a
            # process): a node that takes part again (a reset's new participant) would
            # otherwise register it anew, and a simulator connecting in between fails its
            # handshake; rospy's retries back off, and the node's answers went unheard for
            # longer than the lockstep waits
            listeners = self.pub.impl.subscriber_listeners if self.pub.impl else None
            if listeners is not None:
                listeners[:] = [l for l in listeners if getattr(l, 'then', None) is not self._join]


class Peers:
    """The other participants' answers as they go to the simulator (on ``/sim/lockstep/ack``):
    lets a node that coordinates others (the mission proxy) know, inside its own cycle, what
    each of them did up to that cycle."""

    def __init__(self):
        self.cond = threading.Condition()
        self.newest = {}         # node -> its newest LockstepAck
        self.awaited = set()     # the nodes whose answers :meth:`covering` waits for
        self.sub = rospy.Subscriber(ACK_TOPIC, LockstepAck, self.on_ack, queue_size=None,
                                    tcp_nodelay=True)

    def on_ack(self, msg):
        with self.cond:
            old = self.newest.get(msg.node)
            if msg.leave or old is None or old.leave or msg.stamp >= old.stamp:
                self.newest[msg.node] = msg
            if msg.node in self.awaited:    # (the others' answers wake nobody)
                self.cond.notify_all()

    def covering(self, node, stamp, timeout):
        """``node``'s newest answer once it covers ``node``'s last deadline at or before
        ``stamp`` (rospy.Time; a participant acts only at its deadlines, so that answer says
        what it did up to ``stamp``), waiting for it up to ``timeout`` [s wall] or as a
        :class:`~tiago_nav.clock.Patience` allows (:func:`held_by`). None when ``node`` does
        not take part (never answered, or left) or the answer does not come."""
        t = stamp.to_sec()
        patience = Patience.of(timeout)
        with self.cond:
            self.awaited.add(node)
            try:
                while True:
                    a = self.newest.get(node)
                    if a is None or a.leave:
                        return None
                    period = a.period.to_sec()
                    due = math.floor(t / period + EPS) * period if period > 0 else t
                    if a.stamp.to_sec() >= due - EPS:
                        return a
                    if patience.over() or rospy.is_shutdown():
                        return None
                    self.cond.wait(patience.left(0.1))
            finally:
                self.awaited.discard(node)


def restamp_foreign(goal, now):
    """Gives a goal (an actionlib ServerGoalHandle) stamped more than :data:`GOAL_LEAD` ahead
    of the server's ROS time ``now`` (rospy.Time) that time instead: its client was on another
    clock (one started before ``/use_sim_time`` was set stamps in wall time). actionlib's
    SimpleActionServer orders goals by stamp and recalls a goal stamped before the last one
    ("canceled because another goal was received"): one such goal would make the server recall
    every later goal of every client. (A zero stamp actionlib itself makes ``now``.)"""
    gid = goal.get_goal_id()
    if gid.stamp > now + rospy.Duration.from_sec(GOAL_LEAD):
        rospy.logwarn('%s: goal %s is stamped %.3f s, %.3f s ahead of this node\'s ROS time: '
                      'its client is on another clock; taken as sent now', rospy.get_name(),
                      gid.id, gid.stamp.to_sec(), (gid.stamp - now).to_sec())
        gid.stamp = now


class ClaimingActionServer(actionlib.SimpleActionServer):
    """A SimpleActionServer (started by :meth:`start`) whose lockstep ``participant`` claims
    the cycles after a goal's stamp as soon as the goal arrives, when no goal is running: not
    only once the execute callback starts, after actionlib has accepted the goal. In between,
    the participant would answer the goal's first cycle idle, and a client that sends the goal
    inside its own cycle and waits until it is accepted (the mission proxy) would see it start a
    cycle late in some runs."""

    def __init__(self, name, spec, execute_cb, participant):
        self.participant = participant
        super().__init__(name, spec, execute_cb, auto_start=False)

    def internal_goal_callback(self, goal):
        part = self.participant
        if part is not None and part.enabled and not self.is_active():
            part.claim(goal_since(goal.get_goal_id().stamp, part.now()))
        restamp_foreign(goal, rospy.Time.now())
        super().internal_goal_callback(goal)

    def start(self):
        """Starts the server; each new subscriber of its status then gets the status at once.
        actionlib publishes it on a timer in ROS time, which stands still while the simulator
        waits for work, and a client waits for a status before it sends a goal."""
        with persistent():          # a node's reset keeps its server (tiago_nav.ros.reset)
            super().start()
        self.action_server.status_pub.impl.add_subscriber_listener(_StatusOnConnect(self))
        keep_status_timer(self)     # its status goes on after ROS time went back (a reset)


class _StatusOnConnect(rospy.SubscribeListener):
    """Publishes an action server's status when a client subscribes to it (from a thread of
    its own: the listener runs inside rospy's connection set-up)."""

    def __init__(self, server):
        super().__init__()
        self.server = server

    def peer_subscribe(self, topic_name, topic_publish, peer_publish):
        threading.Thread(target=self._publish, name='status on connect', daemon=True).start()

    def _publish(self):
        try:
            self.server.action_server.publish_status()
        except rospy.ROSException:
            pass            # shutting down


class _Join(rospy.SubscribeListener):
    """Sends the participant's registration to each simulator that connects to its answers
    (a simulator started, or restarted, after the participant)."""

    def __init__(self, participant):
        super().__init__()
        self.participant = participant

    def peer_subscribe(self, topic_name, topic_publish, peer_publish):
        if self.participant.joined.is_set():
            peer_publish(self.participant.join_msg())
