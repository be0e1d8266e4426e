"""Which peers a rospy Publisher or Subscriber has completed its handshake with (read from
rospy's transports; no master call). Used by the subscriptions (:mod:`tiago_nav.ros.topics`),
the resets (:mod:`tiago_nav.ros.reset`) and the lockstep (:mod:`tiago_nav.ros.lockstep`)."""


def _connections(topic):
    """A rospy Publisher's or Subscriber's connections (or those of its ``impl``, given)."""
    impl = getattr(topic, 'impl', topic)
    return list(getattr(impl, 'connections', None) or ())


def connected_publishers(subscriber):
    """The node names of the publishers a ``rospy.Subscriber`` has completed its handshake with.
    rospy counts a connection (``get_num_connections``) as soon as it starts connecting, which
    on a loaded machine can be a second before messages flow; the subscriber's transport keeps
    the publisher's reply header (with its ``callerid``) once the handshake is done."""
    return {c.header.get('callerid') for c in _connections(subscriber)
            if getattr(c, 'header', None) is not None}


def live_publishers(subscriber):
    """:func:`connected_publishers` whose connection is open: rospy keeps a dropped connection
    (a publisher that died) in its list, without its socket, while it tries to connect again."""
    return {c.header.get('callerid') for c in _connections(subscriber)
            if getattr(c, 'header', None) is not None and getattr(c, 'socket', None) is not None}


def connected_subscribers(publisher):
    """The node names of the subscribers connected to a ``rospy.Publisher`` (a connection is
    added once its handshake is done; its ``endpoint_id`` is the subscriber's callerid)."""
    return {getattr(c, 'endpoint_id', None) for c in _connections(publisher)}
