"""Lockstep between the simulator and its controllers (no ROS here).

Participants (control loops) answer each control cycle with a :class:`Ack` that carries the
cycle's base command. The simulator keeps a :class:`Schedule` of them and, before each physics
step, asks it who is missing: simulated time never passes a participant's deadline until its
answer is held. Deadlines lie on a fixed grid: the multiples of the participant's period counted
from time 0, so two runs hold at the same instants whenever the participant joined.

:class:`Gate` adds the waiting (a condition variable) for the simulator's step loop;
:class:`ParticipantCore` is the cycle arithmetic of one participant, used by
:class:`tiago_nav.ros.lockstep.LockstepParticipant`. Times are ROS times in seconds; a stamp is
mapped to the physics step grid (``rate`` Hz) by :meth:`Schedule.step_of`.
"""
import heapq
import math
import threading
from dataclasses import dataclass

EPS = 1e-6          # [s] two times closer than this are the same instant (steps are >= 1 ms)
GRID_SLACK = 1e-3   # [steps] a stamp this close to a step is on it (ns stamps are floored)
RESTART = 1.0       # [s] a tick this long before a participant's last answer: time went back


IDLE_PERIOD = 0.1   # [s] an idle participant answers for all its deadlines up to the next
#                     multiple of this (a 20 Hz controller holds the simulator at 10 Hz while
#                     idle; the mission proxy, move_base and the localisation run at 10 Hz)


def grid_after(t, period):
    """The first multiple of ``period`` [s] strictly after time ``t`` [s]."""
    return (math.floor(t / period + EPS) + 1) * period


@dataclass(frozen=True)
class Ack:
    """One participant's answer. ``stamp`` [s]: the cycle's time (sensor data up to it is
    covered); ``period`` [s]; ``command``: ``(v, w)`` [m/s, rad/s] in base_footprint, applied from
    ``stamp`` on, or None; ``leave``: drop me (after applying ``command``); ``busy``: I have
    work, simulated time must go on (see :meth:`Schedule.wants_time`)."""
    node: str
    stamp: float
    period: float
    command: tuple = None
    leave: bool = False
    busy: bool = False


@dataclass
class _Member:
    period: int                 # [steps]
    answered: int               # [step] stamp of the last answer held
    waiting_since: float = None  # [s wall] when the simulator began to wait for it
    asked: float = None         # [s wall] when it last asked whether it lives
    busy: bool = False          # its newest answer says it has work

    @property
    def deadline(self):
        """[step] the next multiple of the period after the last answer."""
        return (self.answered // self.period + 1) * self.period


def _percentile(ordered, q):
    """Nearest-rank percentile ``q`` in [0, 100] of a sorted non-empty list."""
    return ordered[min(len(ordered) - 1, max(0, math.ceil(q / 100.0 * len(ordered)) - 1))]


class Schedule:
    """The simulator's side: who takes part, their deadlines, their commands.

    Args:
        rate: physics rate [Hz]; periods must be whole numbers of steps.
        timeout: [s wall] how long the simulator waits for a missing answer from a participant
            that lives before it drops that participant as hung (it rejoins with its next
            answer).
        dead: ``dead(node)`` is ``''`` while the participant ``node`` lives (its process is
            there: it may be slow), else why it is dead; asked once an answer has been missing
            for ``ask`` [s wall], and again as often: a dead one is dropped at once. None:
            everyone lives (only ``timeout`` drops).
        log: ``log(level, text)`` with level ``'info'`` or ``'warn'``; silent by default.
        wait_for_work: simulated time stands still while participants take part and none of
            them is busy (and the simulator's own ``work()`` says nothing moves): every goal
            then starts at the simulated instant the last one left, whenever it is sent.
        expected: names of participants that must have joined before simulated time leaves
            its start (the launch files name the controllers they start), so that nobody joins
            at an instant that depends on the machine's speed.
        expect_timeout: [s wall] after this long without one of them, time goes on (a warning
            names the missing ones).
    """

    def __init__(self, rate, timeout, log=None, wait_for_work=False, expected=(),
                 expect_timeout=60.0, dead=None, ask=1.0):
        if not (rate > 0 and timeout > 0 and expect_timeout > 0 and ask > 0):
            raise ValueError('rate, timeout, expect_timeout and ask must be > 0, got %r, %r, %r, '
                             '%r' % (rate, timeout, expect_timeout, ask))
        self.rate, self.timeout = float(rate), float(timeout)
        self.dead, self.ask = dead, float(ask)
        self.log = log or (lambda level, text: None)
        self.wait_for_work = bool(wait_for_work)
        self.expected = set(expected)
        self.expect_timeout = float(expect_timeout)
        self._expect_since = None   # [s wall] when the simulator began to wait for them
        self.members = {}
        self._pending = []      # heap of (stamp step, sequence, node, v, w)
        self._seq = 0
        self.lags = []          # [s sim] application time - stamp, per applied command
        self.drops = 0
        self.waits = 0          # steps at which the simulator waited for answers
        self.waited = 0.0       # [s wall] how long, in all
        self.waited_for = {}    # node -> [s wall] of the waits its answer ended

    # --- time grid ------------------------------------------------------------------------
    def step_of(self, t):
        """The step index of time ``t`` [s]: the nearest step when ``t`` is on the grid (ROS
        stamps are whole nanoseconds, floored), else the step before."""
        x = t * self.rate
        k = round(x)
        return int(k) if abs(x - k) < GRID_SLACK else math.floor(x)

    def period_steps(self, period):
        """The period [s] in steps, or None when it is not a positive whole number of steps."""
        x = period * self.rate
        k = round(x)
        return int(k) if k >= 1 and abs(x - k) < GRID_SLACK else None

    # --- answers --------------------------------------------------------------------------
    def is_participant(self, node):
        """True while ``node`` takes part: its velocity commands come in its answers, so its
        ``cmd_vel`` messages must be ignored."""
        return node in self.members

    def deadline(self, node):
        """The participant's next deadline [s]."""
        return self.members[node].deadline / self.rate

    def receive(self, ack, wall):
        """Takes one answer, received at wall time ``wall`` [s]. The first answer registers the
        participant; a period off the step grid is refused (with a warning) and the answer
        ignored; an answer not newer than the last one held is ignored. Returns True when the
        answer was taken."""
        member = self.members.get(ack.node)
        if member is not None and not ack.leave:
            member.busy = bool(ack.busy)    # every answer says it: the newest one counts
        period = self.period_steps(ack.period)
        if period is None and not ack.leave:
            self.log('warn', 'lockstep: %s asks for a period of %g s, not a whole number of '
                     '%g s physics steps: ignored (it runs free)' % (ack.node, ack.period, 1 / self.rate))
            return False
        stamp = self.step_of(ack.stamp)
        if member is not None and stamp <= member.answered and not ack.leave:
            return False
        if ack.command is not None:
            v, w = ack.command
            heapq.heappush(self._pending, (stamp, self._seq, ack.node, float(v), float(w)))
            self._seq += 1
        if ack.leave:
            if self.members.pop(ack.node, None) is not None:
                self.log('info', 'lockstep: %s left' % ack.node)
            return True
        if member is None:
            self.members[ack.node] = _Member(period, stamp, busy=bool(ack.busy))
            self.log('info', 'lockstep: %s joined, period %g s' % (ack.node, period / self.rate))
            if self.expected and ack.node in self.expected and self.expected <= set(self.members):
                self.log('info', 'lockstep: every expected participant has joined')
                self.expected = set()
        else:
            member.period, member.answered, member.waiting_since = period, stamp, None
        return True

    # --- the simulator's questions ------------------------------------------------------------
    def due(self, t):
        """The names of the participants whose deadline is at or before ``t`` [s] (what
        :meth:`hold` asks, without its timeouts)."""
        step = self.step_of(t)
        return {name for name, m in self.members.items() if m.deadline <= step}

    def hold(self, t, wall):
        """Who must answer before simulated time may step past ``t`` [s]: the sorted names of
        participants whose deadline is at or before ``t``. One that is dead (``dead``, asked
        every ``ask`` seconds of the wait) or, though alive, waited for longer than ``timeout``
        (wall time ``wall`` [s]) is dropped with a warning instead."""
        waiting = []
        for name in sorted(self.due(t)):
            m = self.members[name]
            if m.waiting_since is None:
                m.waiting_since = m.asked = wall
            why = ''
            if wall - m.waiting_since > self.timeout:
                why = 'none within %.1f s of wall time, though it lives as far as can be told ' \
                    '(stopped? deadlocked?)' % (wall - m.waiting_since)
            elif self.dead is not None and wall - m.asked >= self.ask:
                m.asked = wall
                why = self.dead(name)
            if why:
                del self.members[name]
                self.drops += 1
                self.log('warn', 'lockstep: no answer from %s for its deadline %.3f s: %s; going '
                         'on without it until it answers again' % (name, m.deadline / self.rate, why))
            else:
                waiting.append(name)
        return waiting

    def missing(self, wall):
        """The sorted names of expected participants that have not joined yet, while the wait
        for them lasts (``wall`` [s]: now); after ``expect_timeout`` a warning names them and
        the simulator stops waiting for them."""
        if not self.expected:
            return []
        if self._expect_since is None:
            self._expect_since = wall
        names = sorted(self.expected - set(self.members))
        if names and wall - self._expect_since > self.expect_timeout:
            self.log('warn', 'lockstep: %s did not join within %g s of wall time: simulated '
                     'time goes on without %s' % (', '.join(names), self.expect_timeout,
                                                  'it' if len(names) == 1 else 'them'))
            self.expected, names = set(), []
        return names

    def busy(self):
        """True while a participant's newest answer says it has work."""
        return any(m.busy for m in self.members.values())

    def wants_time(self, work=False):
        """Whether simulated time may go on (nobody being due): not while an expected
        participant is still missing (see :meth:`missing`), and with ``wait_for_work`` only
        while someone is busy or ``work`` (the simulator's own: the base moves) holds. Without
        participants time always goes on (an outside controller drives the base)."""
        if self.expected and set(self.expected) - set(self.members):
            return False
        if not self.wait_for_work or not self.members:
            return True
        return bool(work) or self.busy()

    def commands(self, t):
        """The commands ``(v, w)`` due at time ``t`` [s] (stamped at or before it), in the order
        of their stamps; the last one is the one in force. Records each one's lag."""
        step = self.step_of(t)
        out = []
        while self._pending and self._pending[0][0] <= step:
            stamp, _, _, v, w = heapq.heappop(self._pending)
            self.lags.append((step - stamp) / self.rate)
            out.append((v, w))
        return out

    def record_wait(self, seconds, last):
        """The simulator waited ``seconds`` [s wall] at one step, until the answers of the
        participants ``last`` (usually one) came; the time is theirs, shared."""
        self.waits += 1
        self.waited += seconds
        for name in last:
            self.waited_for[name] = self.waited_for.get(name, 0.0) + seconds / len(last)

    def wait_summary(self):
        """One line: how long the simulator waited for answers, and whose answers it waited for
        longest (where lockstep's wall time goes)."""
        who = sorted(self.waited_for.items(), key=lambda kv: -kv[1])
        return 'waited %.2f s of wall time at %d steps%s' % (
            self.waited, self.waits, ('; last to answer: ' + ', '.join(
                '%s %.2f s' % kv for kv in who)) if who else '')

    def lag_stats(self):
        """Lag [s of simulated time] between a command's stamp and its application: ``count``,
        ``max``, ``p50``, ``p95``, ``p99`` (zeros when no command was applied)."""
        ordered = sorted(self.lags)
        if not ordered:
            return dict(count=0, max=0.0, p50=0.0, p95=0.0, p99=0.0)
        return dict(count=len(ordered), max=ordered[-1], p50=_percentile(ordered, 50),
                    p95=_percentile(ordered, 95), p99=_percentile(ordered, 99))


class Gate:
    """A :class:`Schedule` shared between the simulator's step loop and the threads that
    receive answers.

    Args:
        schedule: the :class:`Schedule`.
        wall: a function returning monotonic wall time [s].
        shutdown: a function returning True once the process is stopping.
        poll: [s wall] longest wait between two looks at the missing ones and shutdown.
        retick: [s wall] the tick is sent again after this long without an answer (one sent
            before a participant's subscription was connected is lost).
    """

    def __init__(self, schedule, wall, shutdown=lambda: False, poll=0.05, retick=0.2):
        self.schedule, self.wall, self.shutdown, self.poll = schedule, wall, shutdown, poll
        self.retick = retick
        self.cond = threading.Condition()
        self._held = None       # (t, names waited for) while :meth:`hold` waits

    def receive(self, ack):
        """From a subscriber thread: hands one :class:`Ack` to the schedule, and wakes a
        waiting :meth:`hold` only when that answer can end its wait or adds someone to it (an
        answer that leaves others still missing would only wake the step loop for nothing:
        three of the four answers at a typical hold)."""
        with self.cond:
            self.schedule.receive(ack, self.wall())
            if self._held is not None:
                t, waiting = self._held
                due = self.schedule.due(t)
                if due and due <= waiting:
                    return
            self.cond.notify_all()

    def is_participant(self, node):
        with self.cond:
            return self.schedule.is_participant(node)

    def has_participants(self):
        """True while anyone takes part."""
        with self.cond:
            return bool(self.schedule.members)

    def hold(self, t, tick, work=None):
        """Before stepping past simulated time ``t`` [s]: waits until every participant whose
        deadline is at or before ``t`` has answered or has been dropped, and then, while
        :meth:`Schedule.wants_time` says no, for work (a busy answer, ``work`` or a
        participant joining). ``tick(t, waiting)`` is called (to publish the tick) when a wait
        for answers begins and again whenever a participant is added to it, or ``retick`` has
        passed. ``work(commands)``: True when the simulator itself has work once ``commands``
        are applied (the base moves). Returns the commands ``(v, w)`` to apply at ``t`` in
        order, or None on shutdown."""
        told, last, start, before = set(), None, None, ()
        commands = []
        with self.cond:
            while not self.shutdown():
                wall = self.wall()
                waiting = self.schedule.hold(t, wall)
                if not waiting:
                    if start is not None:
                        self.schedule.record_wait(wall - start, before)
                        start = None
                    commands += self.schedule.commands(t)
                    self.schedule.missing(wall)
                    if self.schedule.wants_time(work is not None and work(commands)):
                        return commands
                    self.cond.wait(self.poll)       # every answer wakes it (no _held)
                    continue
                if start is None:
                    start = wall
                before = waiting
                if not told.issuperset(waiting) or wall - last > self.retick:
                    told.update(waiting)
                    last = wall
                    tick(t, waiting)
                self._held = (t, set(waiting))
                try:
                    self.cond.wait(self.poll)
                finally:
                    self._held = None
        return None


@dataclass(frozen=True)
class Tick:
    """What a participant reads from the simulator's tick: the held time and the stamps [s] of
    the newest scan and odometry at or before it; ``named``: the simulator waits for this
    participant's answer (its ``waiting_for`` names it)."""
    stamp: float
    scan_stamp: float = None
    odom_stamp: float = None
    named: bool = False


class ParticipantCore:
    """The cycle arithmetic of one participant (thread-safety is the caller's).

    A cycle begins at the participant's next deadline (the next multiple of ``period`` [s]
    after its last answer, or after the time it was claimed ``since``): in lockstep when the
    simulator's tick for that time has arrived; running free when ROS time has gone past the
    deadline without one (the simulator is not holding for this participant: no lockstep, or
    not registered yet). While not claimed by a control loop the participant is *idle*: every
    tick due to it is answered at once with no command (:meth:`idle_answer`), and the answer
    covers its deadlines up to the next multiple of ``idle_period`` [s] (:meth:`cover`). A
    goal's first cycle is the first deadline after both its ``since`` and that coverage: the
    same instant whether the goal arrived before or after the idle answer, as long as goals
    start on the ``idle_period`` grid (the mission proxy sends them in its 0.1 s cycles)."""

    def __init__(self, period, now, idle_period=IDLE_PERIOD):
        if not (period > 0 and math.isfinite(period)):
            raise ValueError('period must be > 0 s, got %r' % (period,))
        self.period = float(period)
        self.idle_period = float(idle_period or period)
        self.last = float(now)    # [s] stamp of the last answer (or the start)
        self.answered_upto = -math.inf   # [s] stamp of the last answer actually sent
        self.since = -math.inf    # [s] the control loop owns cycles after this time
        self.claimed = False
        self.latest = None        # the newest Tick received

    def deadline(self):
        """[s] the next cycle's time."""
        return grid_after(max(self.last, self.since), self.period)

    def on_tick(self, tick):
        """Keeps the newest tick. One from more than :data:`RESTART` before the last answer
        means ROS time went back (a restarted simulator): the cycles start again from 0."""
        if tick.stamp < self.last - RESTART:
            self.last, self.since, self.latest = 0.0, min(self.since, 0.0), tick
            self.answered_upto = -math.inf
        elif self.latest is None or tick.stamp >= self.latest.stamp - EPS:
            self.latest = tick      # (a tick sent again may name this participant now)

    def next_cycle(self, now):
        """The cycle that has begun at ROS time ``now`` [s], as ``(stamp, tick)`` (``tick``
        None when running free: the stamp is then ``now``), or None to keep waiting. A tick
        counts once ROS time has reached it (``/clock`` and the tick travel apart), so that
        ``now`` equals the cycle's stamp while the simulator holds."""
        d = self.deadline()
        if self.latest is not None and self.latest.stamp >= d - EPS:
            return (self.latest.stamp, self.latest) if now >= self.latest.stamp - EPS else None
        if now > d + EPS:
            return now, None
        return None

    def answered(self, stamp):
        """Records an answer sent for ``stamp`` [s]."""
        self.last = max(self.last, stamp)
        self.answered_upto = max(self.answered_upto, stamp)

    def claim(self, since):
        """A control loop takes the cycles after time ``since`` [s] (e.g. its goal's stamp);
        earlier ones are still answered idle."""
        self.claimed, self.since = True, float(since)

    def release(self):
        """The control loop is done: cycles are answered idle again."""
        self.claimed, self.since = False, -math.inf

    def idle_answer(self):
        """The stamp [s] to answer at once with no command, or None: the newest tick when it is
        due, or names this participant, and no control loop owns it. (A registration makes the
        simulator hold at once, at its current step, which need not be on this participant's
        grid: that tick names it though its next deadline is later. Answering it places the
        participant; not answering it held the simulator until its timeout. A named tick that
        was answered already, e.g. by the control loop's last cycle before it released, is
        not answered again: that second, idle answer would cover the next deadline too, and
        the mission proxy, reading the answers while the simulator still held at that tick,
        saw the stage end one cycle early or not, as the two answers raced it.)"""
        t = self.latest
        if t is None or (t.stamp < grid_after(self.last, self.period) - EPS
                         and not (t.named and t.stamp > self.answered_upto + EPS)):
            return None
        if self.claimed and t.stamp > self.since + EPS:
            return None
        return t.stamp

    def answer_again(self):
        """True when the newest tick names this participant for a time its last answer sent
        covers: that answer was lost on its way, for the simulator still waits for it (it sends
        the tick again while an answer is missing) and takes a repeated answer once. (rospy
        closes a subscriber's older connection to a publisher when a second one comes up, with
        what was still in it: the answer to a registration's tick was lost so, and, no tick
        being answered twice, the simulator held until it dropped the participant, and again
        each time it rejoined, for good.)"""
        t = self.latest
        return t is not None and t.named and t.stamp <= self.answered_upto + EPS

    def cover(self, stamp):
        """The stamp [s] an idle answer to the tick at ``stamp`` carries: its last deadline
        before the next multiple of ``idle_period`` (``stamp`` itself when the period is not
        shorter), so that the simulator does not hold for an idle participant in between."""
        if self.idle_period <= self.period + EPS:
            return stamp
        k = round((grid_after(stamp, self.idle_period) - stamp) / self.period - 1)
        return stamp + max(k, 0) * self.period


class Settled:
    """The newest of a stream of stamped values (another node's messages) as a participant's
    cycle may use them: only values stamped up to ``lag`` [s] before the cycle, so that
    whether one has arrived does not depend on timing (ROS orders nothing across topics: a
    message sent in the cycle being held can still be on its way, while those of earlier
    cycles were sent before the answers that let the simulator reach this one). Values
    stamped before the last :meth:`reset` are ignored.

    Args:
        lag: [s] the participant's period (values of the cycle before are the newest used).
        size: how many values are kept.
    """

    def __init__(self, lag, size=64):
        self.lag = float(lag)
        self.items = []
        self.size = int(size)
        self.since = -math.inf
        self.lock = threading.Lock()

    def reset(self, since):
        """Forget everything; from now on only values stamped at or after ``since`` [s]."""
        with self.lock:
            self.items, self.since = [], float(since)

    def add(self, stamp, value):
        """A value stamped ``stamp`` [s] (in arrival order)."""
        with self.lock:
            if stamp >= self.since - EPS:
                self.items.append((float(stamp), value))
                del self.items[:-self.size]

    def get(self, cycle=None):
        """The newest value stamped at or before ``cycle - lag`` (``cycle`` [s]), or the
        newest of all when ``cycle`` is None (running free); None when there is none."""
        with self.lock:
            if cycle is None:
                return self.items[-1][1] if self.items else None
            limit = cycle - self.lag + EPS
            best = None
            for stamp, value in self.items:
                if stamp <= limit and (best is None or stamp >= best[0]):
                    best = (stamp, value)
            return best[1] if best else None
