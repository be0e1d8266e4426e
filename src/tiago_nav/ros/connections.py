"""Which peers a rospy Publisher or Subscriber has completed its handshake with (read from
rospy's transports; no master call). Used by the subscriptions (:mod:`tiago_nav.ros.topics`),
the resets (:mod:`tiago_nav.ros.reset`) and the lockstep (:mod:`tiago_nav.ros.lockstep`)."""


def _connections(topic):
    impl = getattr(topic, 'impl', None)
    return list(getattr(impl, 'connections', None) or ())


def connected_publishers(subscriber):
    """The node names of the publishers a ``rospy.Subscriber`` has completed its handshake with.
    rospy counts a connection (``get_num_connections``) as soon as it starts connecting, which
    on a loaded machine can be a second before messages flow; the subscriber's transport keeps
    the publisher's reply header (with its ``callerid``) once the handshake is done."""
    return {c.header.get('callerid') for c in _connections(subscriber)
            if getattr(c, 'header', None) is not None}


def connected_subscribers(publisher):
    """The node names of the subscribers connected to a ``rospy.Publisher`` (a connection is
    added once its handshake is done; its ``endpoint_id`` is the subscriber's callerid)."""
    return {getattr(c, 'endpoint_id', None) for c in _connections(publisher)}
