"""The simulator's reset (``~reset``): after a drive with noise, drift, a bump and a laser
fault, a reset with a row's parameters (another seed) publishes exactly what a fresh
simulator with those parameters publishes, message for message, stamps included (time goes
back to the start); a reset that would change the world is refused and keeps the state."""
import os
import threading
import time
from dataclasses import fields, replace

import pytest
from geometry_msgs.msg import Twist
from std_msgs.msg import String

from conftest import ROOT
from tiago_nav.params import ParamError, read_params
from tiago_nav_tools.testing.fakes import FakePublisher

from tiago_nav.nodes.simulator import Outputs, Params, SimulatorNode
from test_lockstep_wiring import FakeHost
from test_simulator_node import BOX, Log

pytestmark = pytest.mark.ros


def params(**kw):
    kw.setdefault('world', BOX)     # the node's defaults: tiago laser (noisy), drifting odometry
    return read_params(Params, lambda n, d: {'~' + k: v for k, v in kw.items()}.get(n, d))


def outputs():
    return Outputs(**{f.name: FakePublisher() for f in fields(Outputs)})


def twist(v, w=0.0):
    t = Twist()
    t.linear.x, t.angular.z = v, w
    return t


def drive(node, steps, v=0.6, w=0.3):
    for _ in range(steps):
        node.on_cmd_vel(twist(v, w))
        node.step()


def record(node):
    """Everything published so far, topic by topic (messages serialised: exact equality)."""
    out = {}
    for f in fields(Outputs):
        pub = getattr(node.out, f.name)
        out[f.name] = [_bytes(m) for m in pub.messages]
    return out


def _bytes(msg):
    import io
    b = io.BytesIO()
    msg.serialize(b)
    return b.getvalue()


def clear(node):
    for f in fields(Outputs):
        getattr(node.out, f.name).messages.clear()


def test_a_reset_publishes_what_a_fresh_start_publishes():
    warm = SimulatorNode(params(seed=3), outputs(), log=Log())
    fresh = SimulatorNode(params(seed=7), outputs(), log=Log())
    try:
        warm.start()
        drive(warm, 300)                       # 5 s: into the wall at x = 2.5, noise, drift
        warm.on_laser_fault(String('nan 0.5'))
        drive(warm, 30)
        assert warm.sim.collisions > 0 and warm.sim.time > 5
        clear(warm)
        warm.reset(params(seed=7))
        fresh.start()
        assert record(warm) == record(fresh)
        assert warm.sim.time == fresh.sim.time and warm.sim.collisions == 0
        clear(warm)
        clear(fresh)
        drive(warm, 200)
        drive(fresh, 200)
        assert record(warm) == record(fresh)
        assert warm.sim.pose == fresh.sim.pose and warm.sim.odom_pose == fresh.sim.odom_pose
    finally:
        warm.close()
        fresh.close()


def test_a_reset_that_changes_the_world_is_refused_and_keeps_the_state():
    node = SimulatorNode(params(seed=3), outputs(), log=Log())
    try:
        node.start()
        drive(node, 60)
        pose, t = node.sim.pose, node.sim.time
        other = os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml')
        with pytest.raises(ParamError, match='world'):
            node.reset(replace(params(seed=4), world=other))
        assert node.sim.pose == pose and node.sim.time == t
    finally:
        node.close()


class _WallClock:
    """The step loop's clock: wall time, and ``stop()`` ends :meth:`SimulatorNode.run`."""

    def __init__(self):
        self.done = threading.Event()

    def wall(self):
        return time.monotonic()

    def sleep(self, seconds):
        time.sleep(seconds)

    def shutdown(self):
        return self.done.is_set()

    def stop(self):
        self.done.set()


class _Host(FakeHost):
    """A lockstep host without participants (the step loop runs free, as between a reset's stop
    and its start), with a real host's interrupt and reset: an interrupted :meth:`hold` returns
    None until :meth:`reset`. Its ``interrupt()`` comes late: it first gives the step loop the
    time to take a reset already asked for (the reset service's thread losing the processor
    between asking and interrupting), as long as the loop can."""

    def __init__(self):
        super().__init__(participants=())
        self.interrupted = threading.Event()
        self.resets = threading.Event()

    def hold(self, t, sensors, work=None):
        return None if self.interrupted.is_set() else super().hold(t, sensors, work)

    def reset(self):
        self.interrupted.clear()
        self.resets.set()

    def interrupt(self):
        self.resets.wait(LATE)
        self.interrupted.set()


LATE = 1.0      # [s wall] how long the late interrupt gives the step loop


def test_a_reset_asked_for_while_the_step_loop_runs_leaves_it_stepping():
    """The reset service's thread asks for a reset, then interrupts the host's hold; a step
    loop that took the reset in between (it runs free, nobody taking part) must not be left
    with the interrupt, which ended it at its next hold: the node then exited right after its
    reset, and a warm stack's launch with it (the reset failed, the row ran on a fresh stack)."""
    from tiago_nav.nodes.simulator import Params as P
    p = read_params(P, lambda n, d: {'~world': BOX, '~laser_noise': 0.0, '~lockstep': True,
                                     '~real_time_factor': 0.0, '~seed': 3}.get(n, d))
    host, clock = _Host(), _WallClock()
    node = SimulatorNode(p, outputs(), use_sim_time=True, log=Log(), lockstep=host)
    loop = threading.Thread(target=node.run, args=(clock,), daemon=True)
    try:
        loop.start()
        while len(host.holds) < 100 and loop.is_alive():
            time.sleep(0.01)
        assert node.request_reset(replace(p, sim=replace(p.sim, seed=4)), 10.0) is None
        assert host.resets.is_set() and node.sim.time < 1.5
        holds = len(host.holds)
        end = time.monotonic() + 10.0
        while len(host.holds) < holds + 100 and loop.is_alive() and time.monotonic() < end:
            time.sleep(0.01)
        assert loop.is_alive(), 'the step loop ended after the reset'
        assert len(host.holds) >= holds + 100
    finally:
        clock.stop()
        loop.join(10.0)
        node.close()
