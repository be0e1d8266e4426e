"""Subscription: a subscriber that rospy's registration race left without its publisher (no
connection while the master lists one) subscribes again; one that is connected, or whose
topic nobody publishes, or that only hears itself, is left alone. Without a ROS master:
rospy.Subscriber is replaced by a recorder."""
import time

import pytest
import rospy

from tiago_nav.ros import topics
from tiago_nav.ros.topics import Subscription, orphaned

# needs ROS: rospy, tiago_nav.ros.topics
pytestmark = pytest.mark.ros


class FakeConnection:
    """A rospy subscriber connection: ``endpoint_id`` is its publisher's URI."""

    def __init__(self, endpoint_id):
        self.endpoint_id, self.closed = endpoint_id, False

    def close(self):
        self.closed = True


class FakeSubscriberImpl:
    """rospy's ``_SubscriberImpl``: its connections, and ``remove_connection`` closing one."""

    def __init__(self):
        self.connections = []

    def remove_connection(self, c):
        c.close()
        self.connections = [x for x in self.connections if x is not c]


class FakeSubscriber:
    made = []

    def __init__(self, name, data_class, callback, **kwargs):
        self.name, self.callback, self.kwargs = name, callback, kwargs
        self.connections = 0
        self.unregistered = False
        self.impl = FakeSubscriberImpl()
        FakeSubscriber.made.append(self)

    def get_num_connections(self):
        return self.connections

    def unregister(self):
        self.unregistered = True


@pytest.fixture
def fake_rospy(monkeypatch):
    FakeSubscriber.made = []
    monkeypatch.setattr(rospy, 'Subscriber', FakeSubscriber)
    monkeypatch.setattr(rospy, 'get_name', lambda: '/localisation')
    monkeypatch.setattr(rospy, 'get_node_uri', lambda: 'http://host:1001/')
    monkeypatch.setattr(topics, 'listed_publishers', lambda name: [])
    return FakeSubscriber


def test_orphaned_needs_no_connection_and_a_listed_publisher_other_than_itself():
    assert orphaned(0, ['/simulator'], '/localisation')
    assert not orphaned(1, ['/simulator'], '/localisation')
    assert not orphaned(0, [], '/localisation')
    assert not orphaned(0, ['/localisation'], '/localisation')


def test_an_orphaned_subscription_subscribes_again_with_the_same_arguments(fake_rospy):
    def cb(msg):
        return msg
    s = Subscription('/map', object, cb, period=3600, queue_size=1)
    first = s.sub
    assert not s.check(publishers=['/simulator'])       # the connection may still be coming
    assert not s.check(publishers=['/simulator'])
    assert s.check(publishers=['/simulator'])           # the third check in a row: orphaned
    assert first.unregistered and s.sub is not first
    assert (s.sub.name, s.sub.callback, s.sub.kwargs) == ('/map', cb, {'queue_size': 1})
    assert s.resubscribed == 1
    s.unregister()


def test_a_connected_or_unpublished_subscription_is_left_alone(fake_rospy):
    s = Subscription('/map', object, lambda m: None, period=3600)
    first = s.sub
    assert not s.check(publishers=[])                  # nobody publishes it yet
    assert not s.check(publishers=['/simulator'])
    first.connections = 1                              # ... and the connection came
    assert not s.check(publishers=['/simulator'])
    first.connections = 0
    assert not s.check(publishers=['/simulator'])      # the count starts again
    assert not s.check(publishers=['/simulator'])
    first.connections = 1
    assert not s.check(publishers=['/simulator'])      # connected
    assert s.sub is first and not first.unregistered and len(fake_rospy.made) == 1
    s.unregister()


def test_the_watch_thread_repairs_an_orphaned_subscription(fake_rospy, monkeypatch):
    monkeypatch.setattr(topics, 'listed_publishers', lambda name: ['/simulator'])
    s = Subscription('/scan', object, lambda m: None, period=0.01)
    try:
        first = s.sub
        deadline = 200
        while s.sub is first and deadline:
            time.sleep(0.01)
            deadline -= 1
        assert first.unregistered and s.resubscribed >= 1
    finally:
        s.unregister()


def test_reconnect_hands_an_orphaned_subscriber_its_publishers_and_leaves_the_others(
        fake_rospy, monkeypatch):
    """Reconnect (actionlib's subscribers, which it does not own): after three checks in a row
    without a connection while publishers are listed, this node's own publisherUpdate gets
    their URIs; a connected subscriber, or one whose topic nobody publishes, is left alone."""
    announced = []
    monkeypatch.setattr(topics, 'announce', lambda topic, uris: announced.append((topic, uris)))
    orphan, fine, unpublished = (FakeSubscriber(n, object, None) for n in ('/a/status', '/a/result', '/b'))
    for s in (orphan, fine, unpublished):
        s.resolved_name = s.name
    fine.connections = 1
    listed = {'/a/status': ['http://server:1/'], '/a/result': ['http://server:1/'], '/b': []}
    r = topics.Reconnect([orphan, fine, unpublished], watch=False)
    assert r.check(listed.get) == [] and r.check(listed.get) == []   # may still be connecting
    assert r.check(listed.get) == ['/a/status']
    assert announced == [('/a/status', ['http://server:1/'])] and r.reconnected == 1
    orphan.connections = 1                              # rospy connected it
    for _ in range(5):
        assert r.check(listed.get) == []
    assert not any(s.unregistered for s in (orphan, fine, unpublished))


def test_connected_peers_count_only_handshaken_connections():
    from types import SimpleNamespace as NS
    from tiago_nav.ros.connections import connected_publishers, connected_subscribers
    # rospy's subscriber-side transport: header None until the publisher's reply is read
    connecting, done = NS(header=None), NS(header={'callerid': '/simulator'})
    assert connected_publishers(NS(impl=NS(connections=[]))) == set()
    assert connected_publishers(NS(impl=NS(connections=[connecting]))) == set()
    assert connected_publishers(NS(impl=NS(connections=[connecting, done]))) == {'/simulator'}
    assert connected_publishers(NS(impl=None)) == set()          # unregistered
    # publisher side: endpoint_id is the subscriber's callerid
    pub = NS(impl=NS(connections=[NS(endpoint_id='/tiago_controller'), NS(endpoint_id='/simulator')]))
    assert connected_subscribers(pub) == {'/tiago_controller', '/simulator'}


def _tf_bytes(child, callerid):
    """A /tf message from ``callerid`` as rospy.AnyMsg hands it over: undecoded."""
    import io

    from geometry_msgs.msg import TransformStamped
    from tf2_msgs.msg import TFMessage
    t = TransformStamped()
    t.header.frame_id, t.header.stamp, t.child_frame_id = 'odom', rospy.Time(5), child
    t.transform.rotation.w = 1.0
    buf = io.BytesIO()
    TFMessage([t]).serialize(buf)
    raw = rospy.AnyMsg()
    raw.deserialize(buf.getvalue())
    raw._connection_header = {'callerid': callerid}
    return raw


def test_others_transform_listener_stores_others_transforms_but_not_its_own(fake_rospy,
                                                                             monkeypatch):
    import tf2_ros
    monkeypatch.setattr(rospy.Time, 'now', staticmethod(lambda: rospy.Time(5)))
    buf = tf2_ros.Buffer(debug=False)
    listener = topics.OthersTransformListener(buf)
    assert sorted(s.name for s in fake_rospy.made) == ['/tf', '/tf_static']
    tf_sub = next(s for s in fake_rospy.made if s.name == '/tf')
    others, own = FakeConnection('http://host:1002/'), FakeConnection('http://host:1001/')
    tf_sub.impl.connections = [others, own]
    tf_sub.callback(_tf_bytes('base_footprint', '/odometry'))
    assert tf_sub.impl.connections == [others, own]
    tf_sub.callback(_tf_bytes('mine', '/localisation'))
    assert buf.can_transform('odom', 'base_footprint', rospy.Time(5))
    assert not buf.can_transform('odom', 'mine', rospy.Time(5))
    assert listener.own == '/localisation'
    # the connection from its own publisher is closed at its first message; the others stay
    assert own.closed and not others.closed and tf_sub.impl.connections == [others]
    tf_sub.callback(_tf_bytes('base_footprint', '/odometry'))
    assert tf_sub.impl.connections == [others]
