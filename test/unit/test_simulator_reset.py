"""The simulator's reset (``~reset``): after a drive with noise, drift, a bump and a laser
fault, a reset with a row's parameters (another seed) publishes exactly what a fresh
simulator with those parameters publishes, message for message, stamps included (time goes
back to the start); a reset that would change the world is refused and keeps the state."""
import os
from dataclasses import fields, replace

import pytest
from geometry_msgs.msg import Twist
from std_msgs.msg import String

from conftest import ROOT
from tiago_nav.params import ParamError, read_params
from tiago_nav_tools.testing.fakes import FakePublisher

from tiago_nav.nodes.simulator import Outputs, Params, SimulatorNode
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
