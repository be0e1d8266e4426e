"""The corridor_controller node's wiring (tiago_nav.nodes.corridor_controller.RosIO): a goal
message in, Twist commands, CorridorFeedback and a CorridorResult with a stamped exit pose out,
around the decisions (tiago_nav.corridor.server, tested in test_corridor_server.py). Scans and
tf come from a fake robot instead of a subscription and a tf buffer."""
import pytest

from tiago_nav.sim.worlds import corridor_world
from tiago_nav_tools.testing.corridor import FakeCorridorRobot
from tiago_nav_tools.testing.fakes import FakeActionServer, FakeClock

# needs ROS: the node module imports rospy; its messages need the built workspace
pytestmark = pytest.mark.ros
msg = pytest.importorskip('tiago_nav.msg', reason='needs the built workspace (make setup)')
node = pytest.importorskip('tiago_nav.nodes.corridor_controller')


class TwistToRobot:
    """A publisher of geometry_msgs/Twist that records each message and drives ``robot``."""

    def __init__(self, robot):
        self.robot, self.messages = robot, []

    def publish(self, twist):
        self.messages.append(twist)
        self.robot.command(twist.linear.x, twist.angular.z)


def wired(world, preempt_at=None):
    """A RosIO around the decisions, without its subscription and tf buffer."""
    clock = FakeClock()
    robot = FakeCorridorRobot(world, clock)
    io = node.RosIO.__new__(node.RosIO)         # no rospy subscription, no tf listener
    io.participant, io.latest_scan, io.lookup = None, robot.latest_scan, robot.lookup
    io.server, io.cmd_pub = FakeActionServer(clock, preempt_at), TwistToRobot(robot)
    io.corridor = node.CorridorServer(node.Params(), clock, io)
    return io, robot, clock


@pytest.mark.parametrize('tf_ok', [True, False])
def test_a_goal_through_the_ros_side(tf_ok):
    io, robot, clock = wired(corridor_world(1.07, 3.0, start=(-0.5, 0.0, 0.0)))
    robot.tf_ok = tf_ok
    io.execute(msg.CorridorGoal(max_speed=0.5, max_distance=1.0))
    server = io.server
    assert all(type(m).__name__ == 'Twist' for m in io.cmd_pub.messages)
    assert io.cmd_pub.messages[-1].linear.x == 0.0 == io.cmd_pub.messages[-1].angular.z
    assert isinstance(server.result, msg.CorridorResult) and server.result.reason == server.text
    pose = server.result.exit_pose
    if not tf_ok:
        assert server.state == 'aborted' and 'tf' in server.text, server.text
        assert pose.header.frame_id == '' and not server.feedback         # no pose to report
        return
    assert server.state == 'succeeded', server.text
    assert max(m.linear.x for m in io.cmd_pub.messages) == pytest.approx(0.5, abs=1e-6)
    assert server.feedback and all(isinstance(f, msg.CorridorFeedback) for f in server.feedback)
    last = server.feedback[-1]
    assert last.left_distance > 0.3 and last.right_distance > 0.3     # walls known, 1.07 m apart
    assert pose.header.frame_id == 'map'
    assert pose.header.stamp.to_sec() == pytest.approx(clock.now(), abs=1e-6)
    x, y, _ = robot.pose
    assert (pose.pose.position.x, pose.pose.position.y) == pytest.approx((x, y), abs=1e-6)
    assert server.result.distance == pytest.approx(x + 0.5, abs=0.02) and x + 0.5 > 1.0
