"""Lockstep wired into the nodes, without a ROS master: the simulator node holds before each
step and applies the answers' commands there (and ignores a participant's cmd_vel); the goal
runner starts a goal at its first cycle, takes in the cycle's sensor data every cycle and
answers each cycle with its command; the corridor server answers every cycle, claims the goal's
cycles and releases them at the end."""
import pytest
import rospy

from tiago_nav.nav.navigator import NavConfig
from tiago_nav.params import ParamError, read_params
from tiago_nav_tools.testing.fakes import FakeClock

from test_nav_runner import Rig
from test_simulator_node import BOX, Log, fake_outputs, make_node, twist

from tiago_nav.nodes.simulator import LOCKSTEP_START as S, Params, SimulatorNode

# needs ROS: rospy, tiago_nav.nodes.simulator, tiago_nav.ros
pytestmark = pytest.mark.ros


class FakeHost:
    """The simulator's side of lockstep: records each hold's stamp and, at the holds where a
    participant's deadline falls (every ``tick_every`` steps while anyone takes part), the
    tick's ``(stamp, scan_stamp, odom_stamp)`` from the node's ``sensors`` as the real host
    does; returns the commands queued for the hold; ``participants``: callerids whose cmd_vel
    must be ignored."""

    def __init__(self, commands=None, participants=('/move_base',), tick_every=1):
        self.commands = dict(commands or {})       # step number -> [(v, w)]
        self.participants = participants
        self.tick_every = tick_every
        self.holds = []
        self.ticks = []
        self.clocks = []                            # /clock stamps sent through the host
        self.schedule = type('Schedule', (), {'drops': 0, 'lag_stats': lambda self: dict(
            count=0, max=0.0, p50=0.0, p95=0.0, p99=0.0), 'wait_summary': lambda self: ''})()

    def hold(self, t, sensors, work=None):
        self.holds.append(t)
        if self.participants and (len(self.holds) - 1) % self.tick_every == 0:
            self.ticks.append((t,) + tuple(sensors(t)))
        return self.commands.get(len(self.holds) - 1, [])

    def from_participant(self, msg):
        return msg._connection_header['callerid'] in self.participants

    def has_participants(self):
        return bool(self.participants)

    def publish_clock(self, t):
        self.clocks.append(t)


def lockstep_node(host):
    p = read_params(Params, lambda n, d: {'~world': BOX, '~laser_noise': 0.0,
                                          '~lockstep': True}.get(n, d))
    return SimulatorNode(p, fake_outputs(), use_sim_time=True, log=Log(), lockstep=host)


def from_node(msg, callerid):
    msg._connection_header = {'callerid': callerid}
    return msg


def test_the_simulator_holds_before_every_step_and_each_tick_has_odometry_at_its_time():
    """A 20 Hz participant (ticks every 3 steps of 60 Hz): each tick names odometry stamped
    exactly at the tick (published for it when due) and the newest scan (15 Hz: every 4
    steps); odometry also goes out with each scan, and at no other step."""
    host = FakeHost(tick_every=3)
    node = lockstep_node(host)
    odom = []
    node.out.odom.publish = lambda msg: odom.append(msg.header.stamp.to_sec())
    try:
        node.start()
        for _ in range(10):
            assert node.hold()
            node.step()
        # (in lockstep simulated time starts at LOCKSTEP_START)
        assert [t.to_sec() - S for t in host.holds] == pytest.approx([k / 60.0 for k in range(10)])
        ticks = [x.to_sec() - S for tick in host.ticks for x in tick]    # (tick, scan, odometry)
        assert ticks == pytest.approx([0, 0, 0, 3 / 60, 0, 3 / 60, 6 / 60, 4 / 60, 6 / 60,
                                       9 / 60, 8 / 60, 9 / 60], abs=1e-8)
        assert [t - S for t in odom] == pytest.approx([k / 60 for k in (0, 3, 4, 6, 8, 9)], abs=1e-8)
        assert len(node.out.tf.messages) == len(odom)       # the tf of each odometry
    finally:
        node.close()


def test_answer_commands_act_from_their_hold_and_participants_cmd_vel_is_ignored():
    host = FakeHost(commands={3: [(0.4, 0.0)]})
    node = lockstep_node(host)
    try:
        node.start()
        for _ in range(3):
            node.on_cmd_vel(from_node(twist(0.5), '/move_base'))    # a participant's copy
            node.hold()
            node.step()
        assert node.sim.velocity[0] == 0.0
        node.hold()                                                  # the answer's command
        for _ in range(30):
            node.step()
        assert node.sim.velocity[0] == pytest.approx(0.4, abs=1e-6)
        node.on_cmd_vel(from_node(twist(0.0), '/student'))          # outside nodes still obeyed
        for _ in range(60):
            node.step()
        assert node.sim.velocity[0] == pytest.approx(0.0, abs=1e-6)
    finally:
        node.close()


def test_a_hold_ended_by_shutdown_ends_the_run():
    class Stop(FakeHost):
        def hold(self, *a):
            super().hold(*a)
            return None
    host = Stop()
    node = lockstep_node(host)
    try:
        clock = FakeClock()
        node.run(clock)                 # returns: the host said "shutting down"
        assert len(host.holds) == 1 and node.sim.time == pytest.approx(S)   # no step after it
    finally:
        node.close()


def test_lockstep_needs_sim_time_and_is_refused_naming_it():
    with pytest.raises(ParamError) as e:
        make_node(use_sim_time=False, lockstep=True)
    assert 'lockstep' in str(e.value)


class Participant:
    """A lockstep participant double: cycles every ``period`` of the rig's clock, each
    answered at most once; records the answers ``(stamp, (v, w))``."""

    def __init__(self, clock, period=0.1):
        self.clock, self.period = clock, period
        self.stamp = None
        self.answers = []
        self.ticks = 0

    def tick(self):
        self.clock.sleep(self.period)
        self.stamp = self.clock.now()
        self.ticks += 1
        return True

    def now(self):
        return rospy.Time.from_sec(self.clock.now())

    def answer(self, cmd=None):
        if self.answers and self.answers[-1][0] == self.stamp:
            return None
        self.answers.append((self.stamp, None if cmd is None else (cmd.linear.x, cmd.angular.z)))
        return self.answers[-1]


def test_goal_runner_starts_at_its_first_cycle_and_answers_every_cycle_with_its_command():
    rig = Rig(config=NavConfig())
    part = Participant(rig.clock)
    sensed = []
    rig.runner.ticker = part
    rig.runner.io.participant = part
    rig.runner.io._sense = lambda: sensed.append(rig.clock.now())
    out = rig.run(4.0, 2.0)
    assert out.status == 'succeeded', out.text
    assert len(sensed) == part.ticks          # the cycle's data taken in at every cycle
    stamps = [s for s, _ in part.answers]
    assert stamps == sorted(set(stamps)) and len(stamps) == part.ticks
    assert stamps[0] == pytest.approx(0.1)    # no command before the first cycle
    assert part.answers[-1][1] == (0.0, 0.0)  # the stop answers the last cycle
    assert max(v for _, (v, _) in part.answers) > 0.1


class CorridorParticipant(Participant):
    def __init__(self, clock, period=0.05):
        super().__init__(clock, period)
        self.enabled = True
        self.claims, self.releases = [], 0

    def claim(self, since=None):
        self.claims.append(since)

    def release(self):
        self.releases += 1

    def wait_until_still(self, pose, stop, monitor, timeout):
        # as LockstepParticipant's: stops on cycles; the cycle that judges still stays open
        for i in range(3):
            self.tick()
            if i == 2:
                return True
            stop()


def test_corridor_server_claims_the_goal_answers_each_cycle_and_releases():
    from test_corridor_node import msg, node, wired
    from tiago_nav.sim.worlds import corridor_world
    io, _, clock = wired(corridor_world(1.07, 4.0, start=(-0.8, 0.05, 5.0)))
    part = CorridorParticipant(clock)
    io.participant = part
    io.corridor = node.CorridorServer(node.Params(), clock, io, part)
    goal_id = type('GoalId', (), {'stamp': rospy.Time(0)})()
    io.server.current_goal = type('Handle', (), {'get_goal_id': lambda self: goal_id})()
    reported = []
    succeed = io.server.set_succeeded
    io.server.set_succeeded = lambda *a: reported.append((part.stamp, part.answers[-1][0])) or succeed(*a)
    io.execute(msg.CorridorGoal())
    assert io.server.state == 'succeeded', io.server.text
    # the result goes out while its cycle is still open (simulated time holds at its stamp)
    assert len(reported) == 1 and reported[0][1] < reported[0][0]
    assert part.claims == [None] and part.releases == 1
    stamps = [s for s, _ in part.answers]
    assert len(stamps) == part.ticks and stamps == sorted(set(stamps))   # every cycle, once
    assert part.answers[-1][1] == (0.0, 0.0)
    assert max(v for _, (v, _) in part.answers) > 0.1


@pytest.mark.parametrize('participants, clocks, odoms',
                         [((), [0, 4 / 60, 8 / 60], [0, 2 / 60, 4 / 60, 6 / 60, 8 / 60]),
                          (('/move_base',), [0], [0, 4 / 60, 6 / 60, 8 / 60])])
def test_in_lockstep_clock_goes_out_with_the_scans_only_while_nobody_takes_part(participants,
                                                                                 clocks, odoms):
    """/clock to every node at every physics step was half of a mission's messages: in
    lockstep the simulator sends it through the host, which sends it before each tick (not
    faked here); with the scans (15 Hz of 60) only while nobody takes part, so that ROS time
    still moves with no ticks. Odometry goes out without it: at 30 Hz while nobody takes
    part, else with the scans and for the ticks (here one every 6 steps, 10 Hz)."""
    host = FakeHost(participants=participants, tick_every=6)
    node = lockstep_node(host)
    odom = []
    node.out.odom.publish = lambda msg: odom.append(msg.header.stamp.to_sec())
    try:
        node.start()
        for _ in range(8):
            node.hold()
            node.step()
        assert [t.to_sec() - S for t in host.clocks] == pytest.approx(clocks, abs=1e-8)
        assert [t - S for t in odom] == pytest.approx(odoms, abs=1e-8)
    finally:
        node.close()


def test_the_host_sends_clock_before_a_tick_unless_it_was_the_last_sent_and_again_on_a_retick(
        monkeypatch):
    """The host's wall clock is a fake one here: the answers come from inside the tick's
    publication, and a late answer is made late by moving that clock past the retick, so the
    ticks sent are the same however loaded the machine is."""
    from tiago_nav.msg import LockstepAck
    from tiago_nav.ros import lockstep as roslockstep

    sent = []
    on_tick = []                # what the participant does when a tick reaches it

    class Pub:
        def __init__(self, kind):
            self.kind = kind

        def publish(self, msg):
            sent.append((self.kind, msg.clock.to_sec() if self.kind == 'clock' else msg.stamp.to_sec()))
            if self.kind == 'tick' and on_tick:
                on_tick.pop(0)(msg.stamp.to_sec())

    monkeypatch.setattr(roslockstep, 'direct_publisher', lambda topic, cls, **kw: Pub('tick'))
    monkeypatch.setattr(rospy, 'Subscriber', lambda *a, **kw: None)
    host = roslockstep.LockstepHost(60.0, timeout=5.0, clock_pub=Pub('clock'))
    now = [100.0]
    host.gate.wall = lambda: now[0]
    retick = host.gate.retick
    host.on_ack(LockstepAck(node='/move_base', stamp=rospy.Time(0), period=rospy.Duration(0.1)))

    def answer(t):
        host.on_ack(LockstepAck(node='/move_base', stamp=rospy.Time.from_sec(t),
                                period=rospy.Duration(0.1)))

    def late(t):                # no answer to this tick within the retick
        now[0] += 1.5 * retick

    # 0.1 s: /clock for it already went out with the odometry, so the first tick goes alone
    host.publish_clock(rospy.Time.from_sec(0.1))
    del sent[:]
    on_tick[:] = [answer]
    assert host.hold(rospy.Time.from_sec(0.1), lambda t: (None, None)) == []
    assert sent == [('tick', pytest.approx(0.1))]
    # 0.2 s without /clock for it: /clock first; the answer is late, so tick and /clock again;
    # before each tick the simulator's sensors(t) publishes what is due, and the tick names
    # the stamps it returns
    del sent[:]
    ticks = []
    real_publish = host.pub.publish

    def publish_tick(msg):
        ticks.append((msg.scan_stamp.to_sec(), msg.odom_stamp.to_sec()))
        real_publish(msg)
    host.pub.publish = publish_tick

    def sensors(t):
        sent.append(('sensors', t.to_sec()))
        return rospy.Time.from_sec(0.15), t

    on_tick[:] = [late, answer]
    assert host.hold(rospy.Time.from_sec(0.2), sensors) == []
    assert sent == [('sensors', pytest.approx(0.2)), ('clock', pytest.approx(0.2)),
                    ('tick', pytest.approx(0.2))] * 2
    assert ticks == [(pytest.approx(0.15), pytest.approx(0.2))] * 2
    assert host.schedule.drops == 0 and host.schedule.waited == pytest.approx(1.5 * retick)


def test_peers_tell_what_a_server_did_up_to_a_cycle(monkeypatch):
    """The mission proxy's view of its servers (Peers): inside its cycle at t it needs each
    server's answer for that server's last deadline at or before t; an idle 20 Hz server's
    answer covering past t counts; a node that never answered, or left, is no participant."""
    import threading

    from tiago_nav.msg import LockstepAck
    from tiago_nav.ros import lockstep as roslockstep

    monkeypatch.setattr(rospy, 'Subscriber', lambda *a, **kw: None)
    peers = roslockstep.Peers()

    def ack(node, stamp, period, command=False, leave=False):
        peers.on_ack(LockstepAck(node=node, stamp=rospy.Time.from_sec(stamp),
                                 period=rospy.Duration.from_sec(period), has_command=command,
                                 leave=leave))

    t = rospy.Time.from_sec(1.0)
    assert peers.covering('/move_base', t, 0.0) is None             # never answered
    ack('/move_base', 0.9, 0.1, command=True)
    assert peers.covering('/move_base', t, 0.05) is None            # its 1.0 answer is missing
    threading.Timer(0.02, ack, ('/move_base', 1.0, 0.1, True)).start()
    got = peers.covering('/move_base', t, 2.0)                      # waits for it
    assert got.stamp.to_sec() == pytest.approx(1.0) and got.has_command
    ack('/move_base', 0.9, 0.1)                                     # a stale answer: ignored
    assert peers.covering('/move_base', t, 0.0).has_command
    ack('/corridor_controller', 1.05, 0.05)                         # idle, covering 1.05
    assert not peers.covering('/corridor_controller', t, 0.0).has_command
    ack('/move_base', 1.0, 0.1, leave=True)
    assert peers.covering('/move_base', t, 0.0) is None             # left


def test_lookup_at_does_not_wait_for_data_tf_no_longer_holds():
    """A backlog of scans whose transforms had left tf's buffer waited the whole timeout each
    (move_base at start-up then never caught up with the simulator); data newer than tf holds
    is still waited for."""
    import time

    from tiago_nav.ros import lockstep as roslockstep

    class Buffer:
        oldest, newest = 10.0, 20.0          # [s] what the buffer holds

        def can_transform(self, target, source, stamp):
            return self.oldest <= stamp.to_sec() <= self.newest

        def lookup_transform(self, target, source, stamp):
            t = stamp.to_sec() or self.newest
            if not self.oldest <= t <= self.newest:
                raise RuntimeError('extrapolation')
            return type('T', (), {'header': type('H', (), {'stamp': rospy.Time.from_sec(t)})()})()

    buf = Buffer()
    assert roslockstep.gone(buf, 'odom', 'base', rospy.Time.from_sec(5.0))
    assert not roslockstep.gone(buf, 'odom', 'base', rospy.Time.from_sec(25.0))
    t0 = time.monotonic()
    with pytest.raises(RuntimeError):
        roslockstep.lookup_at(buf, 'odom', 'base', rospy.Time.from_sec(5.0), 2.0)
    assert time.monotonic() - t0 < 0.5                   # gone: no wait
    t0 = time.monotonic()
    with pytest.raises(RuntimeError):
        roslockstep.lookup_at(buf, 'odom', 'base', rospy.Time.from_sec(25.0), 0.3)
    assert time.monotonic() - t0 >= 0.3                  # may still come: waited


def test_the_clock_source_sets_its_own_time_instead_of_receiving_its_clock(monkeypatch):
    """The simulator drops rospy's /clock subscription (it received its own /clock back),
    latches /clock and sets its ROS time as it publishes it."""
    from rosgraph_msgs.msg import Clock
    from rospy.impl import simtime
    from tiago_nav.ros import lockstep as roslockstep

    dropped, sent = [], []
    monkeypatch.setattr(simtime, '_clock_sub', type('Sub', (), {
        'unregister': lambda self: dropped.append(1)})(), raising=False)
    monkeypatch.setattr(roslockstep, 'direct_publisher', lambda topic, cls, **kw: type('Pub', (), {
        'publish': lambda self, msg: sent.append((topic, msg, kw))})())
    monkeypatch.setattr(rospy.rostime, '_rostime_current', None)
    source = roslockstep.ClockSource()
    assert dropped == [1] and simtime._clock_sub is None
    source.publish(Clock(rospy.Time(12, 5)))
    # latched: a node that starts while simulated time stands still still learns it
    assert sent == [('/clock', Clock(rospy.Time(12, 5)), {'latch': True})]
    assert rospy.rostime._rostime_current == rospy.Time(12, 5)


def test_a_goal_that_overtakes_its_cycles_clock_and_tick_keeps_its_stamp():
    """The proxy sends the corridor goal in its cycle at 60.2, which the simulator holds; the
    goal can reach the 20 Hz corridor server before that cycle's /clock and tick (its ROS time
    still the scan's, 60.133). Its cycles start at 60.3 either way, as when the tick came first;
    the server's clock as the start put the first command at 60.2 in one run in twenty."""
    from tiago_nav.lockstep import ParticipantCore, Tick
    from tiago_nav.ros.lockstep import goal_since
    stamp, clock = rospy.Time.from_sec(60.2), rospy.Time.from_sec(60.1 + 1 / 30)

    def first_cycle(since, tick_first):
        core = ParticipantCore(0.05, now=60.0)
        core.on_tick(Tick(60.1))
        core.answered(core.cover(core.idle_answer()))     # idle: covers 60.15
        if not tick_first:
            core.claim(since.to_sec())
        core.on_tick(Tick(60.2))
        due = core.idle_answer()
        if due is not None:
            core.answered(core.cover(due))
        if tick_first:
            core.claim(since.to_sec())
        return core.deadline()

    since = goal_since(stamp, clock)
    assert since == stamp
    assert first_cycle(since, True) == pytest.approx(60.3)
    assert first_cycle(since, False) == pytest.approx(60.3)
    assert first_cycle(min(stamp, clock), False) == pytest.approx(60.2)     # the old rule
    # late goals keep their stamp; one far ahead is on another clock; zero: from now
    assert goal_since(rospy.Time.from_sec(50.0), stamp) == rospy.Time.from_sec(50.0)
    assert goal_since(rospy.Time(1700000000), stamp) == stamp
    assert goal_since(rospy.Time(0), stamp) is None


def test_a_direct_publishers_write_to_a_frozen_subscriber_times_out():
    """rospy writes with a blocking sendall: without a send timeout, a subscriber that stops
    reading (a frozen process, its socket buffers full) would block the simulator's loop for
    as long as it stays frozen; with one the write fails (rospy then drops that connection)."""
    import socket
    import time as wall
    from tiago_nav.ros.lockstep import _SendTimeout, limit_sends
    ours, theirs = socket.socketpair()
    set_before, other = socket.socketpair()
    set_before.settimeout(5.0)
    conns = [type('Conn', (), {'socket': s})() for s in (ours, set_before)]
    conns.append(type('Conn', (), {'socket': None})())        # a connection not yet open
    pub = type('Pub', (), {'impl': type('Impl', (), {'connections': conns})()})()
    seen = []
    listener = _SendTimeout(0.2, then=type('Then', (), {
        'peer_subscribe': lambda self, *a: seen.append('subscribe'),
        'peer_unsubscribe': lambda self, *a: seen.append('unsubscribe')})())
    listener.peer_subscribe('/scan', None, None)      # before the publisher exists: only passed on
    assert ours.gettimeout() is None
    listener.pub = pub
    listener.peer_subscribe('/scan', None, None)
    listener.peer_unsubscribe('/scan', 0)
    assert seen == ['subscribe', 'subscribe', 'unsubscribe']
    assert ours.gettimeout() == 0.2 and set_before.gettimeout() == 5.0
    limit_sends(pub, 0.5)                              # a timeout once set is kept
    assert ours.gettimeout() == 0.2
    t0 = wall.monotonic()
    with pytest.raises(socket.timeout):
        while True:                                    # `theirs` never reads
            ours.sendall(b'x' * 65536)
    assert wall.monotonic() - t0 < 5.0
    for s in (ours, theirs, set_before, other):
        s.close()


def test_the_host_judges_a_participant_by_the_connection_its_answers_came_on(monkeypatch):
    """A participant lives while the connection that brought its answers is open (nobody is
    asked); once it has closed (rospy keeps it, without its socket, while it tries again) the
    node behind it, named by the connection's callerid and not by the answers' ``node`` field,
    is asked whether its process is there."""
    from tiago_nav.msg import LockstepAck
    from tiago_nav.ros import lockstep as roslockstep

    class Conn:
        def __init__(self, callerid):
            self.header, self.socket = {'callerid': callerid}, object()

    conn = Conn('/tester')
    sub = type('Sub', (), {'impl': type('Impl', (), {'connections': [conn]})()})()
    monkeypatch.setattr(roslockstep, 'direct_publisher', lambda topic, cls, **kw: None)
    monkeypatch.setattr(rospy, 'Subscriber', lambda *a, **kw: sub)
    asked = []
    monkeypatch.setattr(roslockstep, 'node_dead', lambda node: asked.append(node) or
                        'the process of %s is gone' % node)
    host = roslockstep.LockstepHost(60.0)
    ack = LockstepAck(node='/late', stamp=rospy.Time(0), period=rospy.Duration.from_sec(0.1))
    ack._connection_header = {'callerid': '/tester'}
    host.on_ack(ack)
    assert host.schedule.is_participant('/late')
    assert host.dead('/late') == '' and asked == []
    conn.socket = None
    assert host.dead('/late') == 'the process of /tester is gone' and asked == ['/tester']


def test_tf_sources_are_the_broadcasters_of_the_moving_links_of_a_chain():
    """``map → odom`` is the localisation's, ``odom → base_footprint`` the simulator's; a static
    link's publisher need not live on, and a link above the chain's common frame is no part."""
    import tf2_ros
    from geometry_msgs.msg import TransformStamped

    from tiago_nav.ros.clock import tf_sources

    buf = tf2_ros.BufferCore()   # (a Buffer asks the master for its service)
    for parent, child, who, stamp in (('world', 'map', '/map_server', 1), ('map', 'odom', '/localisation', 1),
                                      ('odom', 'base_footprint', '/simulator', 1),
                                      ('base_footprint', 'base_laser_link', '/robot_state_publisher', 0)):
        t = TransformStamped()
        t.header.frame_id, t.child_frame_id, t.header.stamp = parent, child, rospy.Time(stamp)
        t.transform.rotation.w = 1.0
        (buf.set_transform_static if stamp == 0 else buf.set_transform)(t, who)
    assert tf_sources(buf, 'map', 'base_laser_link') == {'/localisation', '/simulator'}
    assert tf_sources(buf, 'odom', 'base_footprint') == {'/simulator'}
    assert tf_sources(buf, '/map', 'map') == set()


def test_a_held_wait_goes_on_while_its_source_lives_and_ends_once_it_is_dead():
    """ScanCache.wait_for_scan with a Patience: a scan that comes after several questions is
    taken while its source lives (a plain timeout of one question's length would have given
    up); a dead source ends the wait at the first question, naming why."""
    import collections
    import threading
    import time

    from tiago_nav.clock import Patience
    from tiago_nav.ros import lockstep as roslockstep

    cache = roslockstep.ScanCache.__new__(roslockstep.ScanCache)      # no subscription
    cache.cond, cache.scans = threading.Condition(), collections.deque(maxlen=8)
    scan = type('Scan', (), {'header': type('H', (), {'stamp': rospy.Time(5)})()})()
    asked = []
    live = Patience(0.1, 10.0, lambda: asked.append('live') or '')
    threading.Timer(0.5, cache.on_scan, (scan,)).start()
    assert cache.wait_for_scan(rospy.Time(5), live) is scan
    assert len(asked) >= 3 and live.reason == ''
    dead = Patience(0.1, 10.0, lambda: 'the process of /simulator is gone')
    t0 = time.monotonic()
    assert cache.wait_for_scan(rospy.Time(6), dead) is None
    assert time.monotonic() - t0 < 1.0 and dead.reason == 'the process of /simulator is gone'
