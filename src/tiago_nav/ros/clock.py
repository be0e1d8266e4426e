"""ROS time for the nodes' loops (:mod:`tiago_nav.clock` explains the clock protocol), and the
facts that tell a dead source of ROS time from a slow one."""
import socket
import time
import xmlrpc.client

import rosgraph
import rospy
import yaml
from rospy.impl.registration import get_topic_manager

from tiago_nav.clock import source_verdict
from tiago_nav.ros.connections import live_publishers

CLOCK_TOPIC = '/clock'
PROBE_TIMEOUT = 1.0     # [s wall] one question to a node's XML-RPC server (is its process there?)


def node_exited(uri, caller_id, timeout=PROBE_TIMEOUT):
    """True when the node whose XML-RPC server is ``uri`` has no process any more: its port
    refuses connections (a process that died takes its listening socket with it). False when
    it answers; None when that cannot be told within ``timeout`` [s wall] (a busy or frozen
    process)."""
    class _Transport(xmlrpc.client.Transport):
        def make_connection(self, host):
            conn = super().make_connection(host)
            conn.timeout = timeout
            return conn
    try:
        xmlrpc.client.ServerProxy(uri, transport=_Transport()).getPid(caller_id)
        return False
    except ConnectionRefusedError:
        return True
    except (OSError, socket.timeout, xmlrpc.client.Error):
        return None


def topic_facts(topic=CLOCK_TOPIC, master=None):
    """``(listed, connected, exited)`` for :func:`tiago_nav.clock.source_verdict` of a topic this
    process subscribes to (``topic``, resolved): the master's
    publishers of ``topic`` (None when it cannot be reached), those this process has a live
    connection from (:func:`~tiago_nav.ros.connections.live_publishers`), and the listed ones
    without a connection whose process is gone."""
    connected = live_publishers(get_topic_manager().get_subscriber_impl(topic))
    caller = rospy.get_name()
    master = master or rosgraph.Master(caller)
    try:
        pubs, _, _ = master.getSystemState()
    except (rosgraph.MasterError, OSError):
        return None, connected, set()
    listed = next((nodes for name, nodes in pubs if name == topic), [])
    exited = set()
    for node in listed:
        if node in connected:
            continue
        try:
            uri = master.lookupNode(node)
        except (rosgraph.MasterError, OSError):
            continue
        if node_exited(uri, caller):
            exited.add(node)
    return listed, connected, exited


class RosClock:
    """``now()`` is ROS time (``/clock`` under ``/use_sim_time``), ``wall()`` monotonic wall
    time; ``sleep`` sleeps in wall time, so it never blocks when ``/clock`` stops;
    ``source_dead()`` judges ``/clock``'s publisher from :func:`topic_facts`."""

    def now(self):
        return rospy.get_time()

    def wall(self):
        return time.monotonic()

    def sleep(self, seconds):
        time.sleep(seconds)

    def shutdown(self):
        return rospy.is_shutdown()

    def source_dead(self):
        """``''`` while ROS time's source lives: wall time (no /use_sim_time), this process's
        own (the simulator publishes /clock and takes no /clock in), or a connected /clock
        publisher whose process is there; else the reason (:func:`source_verdict`)."""
        if rospy.rostime.is_wallclock() or \
                get_topic_manager().get_subscriber_impl(CLOCK_TOPIC) is None:
            return ''
        return source_verdict(CLOCK_TOPIC, *topic_facts())


def topic_dead(topic, what='the simulator'):
    """``''`` while a publisher of ``topic`` (resolved) that this process subscribes to lives and
    is connected, else the reason (:func:`tiago_nav.clock.source_verdict`)."""
    return source_verdict(topic, *topic_facts(topic), what=what)


def node_dead(node, master=None):
    """``''`` while the process of ``node`` (a node name) is there or cannot be told from a busy
    one; else why it is dead: not registered with the ROS master any more (it shut down), or
    its process gone (:func:`node_exited`: a crash leaves its registration behind). A live
    process may still be slow or hung: that is for the waiter's bound (:class:`~tiago_nav.clock.
    Patience`) to judge."""
    caller = rospy.get_name()
    master = master or rosgraph.Master(caller)
    try:
        uri = master.lookupNode(node)
    except rosgraph.MasterError:
        return '%s is not registered with the ROS master any more (it shut down)' % node
    except OSError:
        return ''           # the master is not the source: whether it lives is not known here
    return 'the process of %s is gone' % node if node_exited(uri, caller) else ''


def nodes_dead(nodes, master=None):
    """:func:`node_dead` of each of ``nodes``: the first reason found, ``''`` while all live."""
    for node in nodes:
        why = node_dead(node, master)
        if why:
            return why
    return ''


def tf_sources(buffer, target, source):
    """The nodes whose moving transforms make up the chain ``target`` <- ``source`` in a
    ``tf2_ros.Buffer``, as far as it knows that chain (each frame's broadcaster; static
    transforms, which hold whether their publisher lives on, left out)."""
    try:
        frames = yaml.safe_load(buffer.all_frames_as_yaml()) or {}
    except yaml.YAMLError:
        return set()

    def up(frame):
        path = []
        while frame in frames and frame not in path:
            path.append(frame)
            frame = frames[frame].get('parent')
        return path
    a, b = up(source.lstrip('/')), up(target.lstrip('/'))
    shared = set(a) & set(b)
    return {frames[f].get('broadcaster') for f in a + b
            if f not in shared and frames[f].get('most_recent_transform')
            and frames[f].get('broadcaster') not in (None, 'default_authority')}


def reaches_past(sent, stamp):
    """True when one of the ``map → odom`` stamps ``sent`` (rospy.Time) lies after ``stamp``:
    tf then gives ``map → odom`` at ``stamp`` without a re-send."""
    return any(t > stamp for t in sent)
