"""Subscriptions that find their publisher even when rospy's start-up registration misses it.

rospy (ros_comm 1.16) learns a topic's publishers twice when it subscribes: from the master's
reply to ``registerSubscriber`` and from the master's ``publisherUpdate`` call when a publisher
registers. Its registration thread keeps only the update that reached it *last*
(``rospy.impl.registration.RegManager.run``). When a publisher registers while a subscriber is
registering, the reply (computed before the publisher was known, so without it) can arrive
after the ``publisherUpdate`` (with it), and the subscriber never connects. It is rare, and more
likely on a loaded machine where nodes start together, as in a launch file. A node that waits
for a latched map then waits for ever. :class:`Subscription` notices this state: no connection
while the master lists a publisher. It then subscribes again, and the new registration gets the
current list. Subscribers made by others (actionlib's clients: a proxy that waits for ever for
its action server's status) are watched by :class:`Reconnect`, which hands rospy the master's
list again through the node's own ``publisherUpdate``.
"""
import threading
import time
from xmlrpc.client import ServerProxy

import rosgraph
import rospy
import tf2_ros
from tf2_msgs.msg import TFMessage

from tiago_nav.ros.reset import track

CHECK_PERIOD = 1.0      # [s wall] how often a subscription without a connection asks the master
GRACE = 3               # checks in a row that must find it orphaned: a connection still being made
#                         (slow under load) is not a missed publisher
MAX_BACKOFF = 30.0      # [s wall] the longest wait between two subscriptions again


def listed_publishers(topic, master=None):
    """The nodes the master lists as publishing ``topic`` (a resolved name); [] when the master
    cannot be reached."""
    try:
        pubs, _, _ = (master or rosgraph.Master(rospy.get_name())).getSystemState()
    except (rosgraph.MasterError, OSError):
        return []
    return next((nodes for name, nodes in pubs if name == topic), [])


def orphaned(connections, publishers, own_name):
    """True when a subscriber with ``connections`` connections has missed its publishers: the
    master lists ``publishers`` (node names) other than ``own_name`` (a node that publishes and
    subscribes one topic, e.g. /tf, counts no connection to itself)."""
    return connections == 0 and any(p != own_name for p in publishers)


class Subscription:
    """A ``rospy.Subscriber(name, data_class, callback, **kwargs)`` that subscribes again when
    it has no connection while the master lists a publisher (see the module's docstring).

    A wall-time thread checks every ``period`` seconds. The master is asked only while there
    is no connection; it subscribes again after ``grace`` checks in a row found it orphaned (a
    connection that is still being made, slow on a loaded machine, is left to finish). After subscribing again it waits twice as long before the next try (up
    to 30 s): a publisher killed without unregistering stays listed until it is replaced. This relies on this process having no other Subscriber on ``name``:
    rospy shares one registration between them, so unregistering one would not make a new
    registration."""

    def __init__(self, name, data_class, callback, period=CHECK_PERIOD, grace=GRACE, **kwargs):
        self.name = rospy.resolve_name(name)
        self._make = lambda: rospy.Subscriber(name, data_class, callback, **kwargs)
        self.period, self.grace = period, grace
        self.orphaned_checks = 0
        self.resubscribed = 0
        self.sub = self._make()
        self._stop = threading.Event()
        threading.Thread(target=self._watch, name='subscription ' + self.name, daemon=True).start()
        track(self)     # a node's reset unregisters it (tiago_nav.ros.reset)

    def check(self, publishers=None):
        """Subscribe again if the subscriber has been orphaned for ``grace`` checks in a row.
        ``publishers`` overrides the master's list (tests). True when it subscribed again."""
        if self.sub.get_num_connections() > 0:
            self.orphaned_checks = 0
            return False
        if publishers is None:
            publishers = listed_publishers(self.name)
        if not orphaned(self.sub.get_num_connections(), publishers, rospy.get_name()):
            self.orphaned_checks = 0
            return False
        self.orphaned_checks += 1
        if self.orphaned_checks < self.grace:
            return False
        self.orphaned_checks = 0
        rospy.logwarn('%s: no connection to %s, which the master lists as published by %s: '
                      'subscribing again', rospy.get_name(), self.name, ', '.join(publishers))
        self.sub.unregister()
        self.sub = self._make()
        self.resubscribed += 1
        return True

    def unregister(self):
        self._stop.set()
        self.sub.unregister()

    def _watch(self):
        wait = self.period
        while not self._stop.wait(wait) and not rospy.is_shutdown():
            try:
                # a publisher that was killed stays listed until it is replaced: back off
                wait = min(2 * wait, MAX_BACKOFF) if self.check() else self.period
            except Exception as e:          # noqa: BLE001 - a watchdog must not die
                rospy.logwarn_throttle(10.0, '%s: checking %s: %s', rospy.get_name(), self.name, e)


def publisher_uris(topic, own_name, master=None):
    """The slave API URIs of the nodes the master lists as publishing ``topic`` (a resolved
    name), ``own_name`` left out; [] when the master cannot be reached."""
    master = master or rosgraph.Master(rospy.get_name())
    uris = []
    for node in listed_publishers(topic, master):
        if node == own_name:
            continue
        try:
            uris.append(master.lookupNode(node))
        except (rosgraph.MasterError, OSError):
            continue
    return uris


def announce(topic, uris):
    """Tell this node's own slave API that ``uris`` publish ``topic``, as the master's
    ``publisherUpdate`` does: rospy's registration thread then connects to each one it has no
    connection with (and leaves the others)."""
    ServerProxy(rospy.core.get_node_uri()).publisherUpdate('/master', topic, uris)


def action_subscribers(client):
    """The rospy Subscribers of an actionlib (Simple)ActionClient: status, result, feedback."""
    ac = getattr(client, 'action_client', client)
    return [ac.status_sub, ac.result_sub, ac.feedback_sub]


class Reconnect:
    """Watches rospy Subscribers made elsewhere (:func:`action_subscribers`) for the missed
    publisher of the module's docstring. A wall-time thread checks every ``period`` seconds;
    one with no connection while the master lists a publisher for ``grace`` checks in a row is
    handed the master's list again (:func:`announce`), and rospy connects it. Unlike
    :class:`Subscription` it never unregisters what it watches (actionlib owns it). With
    ``watch`` False there is no thread: the owner calls :meth:`check` every ``period``."""

    def __init__(self, subscribers, period=CHECK_PERIOD, grace=GRACE, watch=True):
        self.subs = list(subscribers)
        self.period, self.grace = period, grace
        self.orphaned_checks = [0] * len(self.subs)
        self.reconnected = 0
        self._stop = threading.Event()
        if watch:
            threading.Thread(target=self._watch, name='reconnect', daemon=True).start()
            track(self)     # a node's reset stops it (tiago_nav.ros.reset)

    def check(self, publishers=None):
        """One check of every subscriber; ``publishers`` (a function of the topic returning
        publisher URIs) overrides the master (tests). The topics handed their publishers."""
        done = []
        for i, sub in enumerate(self.subs):
            if sub.get_num_connections() > 0:
                self.orphaned_checks[i] = 0
                continue
            uris = (publishers(sub.resolved_name) if publishers
                    else publisher_uris(sub.resolved_name, rospy.get_name()))
            if not uris:
                self.orphaned_checks[i] = 0
                continue
            self.orphaned_checks[i] += 1
            if self.orphaned_checks[i] < self.grace:
                continue
            self.orphaned_checks[i] = 0
            rospy.logwarn('%s: no connection to %s, which the master lists as published by %s: '
                          'connecting again', rospy.get_name(), sub.resolved_name, ', '.join(uris))
            announce(sub.resolved_name, uris)
            self.reconnected += 1
            done.append(sub.resolved_name)
        return done

    def close(self):
        self._stop.set()

    def _watch(self):
        while not self._stop.wait(self.period) and not rospy.is_shutdown():
            try:
                self.check()
            except Exception as e:          # noqa: BLE001 - a watchdog must not die
                rospy.logwarn_throttle(10.0, '%s: checking action topics: %s', rospy.get_name(), e)


def wait_for_message(name, data_class, timeout):
    """Like ``rospy.wait_for_message`` with ``timeout`` [s wall], but through a
    :class:`Subscription`: the first message, or ``rospy.ROSException`` after ``timeout``."""
    got = []
    done = threading.Event()

    def on_msg(msg):
        if not got:
            got.append(msg)
            done.set()
    sub = Subscription(name, data_class, on_msg)
    try:
        end = time.monotonic() + timeout
        while not done.wait(min(0.1, max(0.0, end - time.monotonic()))):
            if rospy.is_shutdown():
                raise rospy.ROSInterruptException('shutdown while waiting for %s' % sub.name)
            if time.monotonic() >= end:
                raise rospy.ROSException('timeout exceeded while waiting for a message on %s'
                                         % sub.name)
        return got[0]
    finally:
        sub.unregister()


class OthersTransformListener(tf2_ros.TransformListener):
    """A ``tf2_ros.TransformListener`` that leaves out what this node itself sends on ``/tf``.

    A node that broadcasts a transform it never looks up (localisation's ``map → odom``) would
    otherwise decode each of its own messages again through its loopback connection and store
    it: with a bag played faster than real time that is tens of messages a second of CPU for
    nothing. ``/tf`` is taken in undecoded (``rospy.AnyMsg``); a message whose publisher is this
    node is dropped before decoding, and the connection it came on closed (rospy connects a
    node's subscriber to its own publisher like any other, and connects again only when the
    master announces a change of /tf's publishers: the next own message closes it again); the
    others are decoded and stored as the base class does. ``/tf_static`` is taken in as
    usual."""

    def __init__(self, buffer):
        # the base class subscribes on construction: do its work here with /tf undecoded
        self.buffer = buffer
        self.last_update = rospy.Time.now()
        self.last_update_lock = threading.Lock()
        self.own = rospy.get_name()
        self.tf_sub = rospy.Subscriber('/tf', rospy.AnyMsg, self.raw_callback)
        self.tf_static_sub = rospy.Subscriber('/tf_static', TFMessage, self.static_callback)

    def _drop_own_connection(self):
        """Close the /tf connection from this node's own publisher (a subscriber connection's
        ``endpoint_id`` is its publisher's URI)."""
        own = rospy.get_node_uri()
        impl = self.tf_sub.impl
        for c in list(impl.connections):
            if c.endpoint_id == own:
                impl.remove_connection(c)

    def raw_callback(self, raw):
        who = raw._connection_header.get('callerid', 'default_authority')
        if who == self.own:
            self._drop_own_connection()
            return
        msg = TFMessage().deserialize(raw._buff)
        msg._connection_header = raw._connection_header
        self.callback(msg)
