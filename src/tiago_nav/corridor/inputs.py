"""Is the corridor node ready to take a goal? Its inputs (the first scan, the transforms it
needs) through the node's small I/O object (``latest_scan()``, ``lookup(parent, child)``
raising ``LookupError``) and a :mod:`tiago_nav.clock` clock; no ROS here."""


def missing_inputs(params, io):
    """``''`` once a first scan and the tf from ``~odom_frame`` to ``~base_frame`` and to the
    scan's frame exist, else a sentence naming what is missing."""
    scan = io.latest_scan()
    missing = 'no laser scan on %s' % params.scan_topic if scan is None else ''
    for frame in (params.base_frame,) + ((scan.frame_id,) if scan is not None else ()):
        try:
            io.lookup(params.odom_frame, frame)
        except LookupError as e:
            missing = missing or 'no tf %s -> %s (%s)' % (params.odom_frame, frame, e)
    return missing


def wait_ready(params, clock, io, timeout):
    """Wait (at most ``timeout`` wall seconds) for :func:`missing_inputs` to find nothing
    missing.

    Returns ``''`` when ready, else a sentence naming what is missing."""
    end = clock.wall() + timeout
    while True:
        missing = missing_inputs(params, io)
        if not missing:
            return ''
        if clock.wall() >= end or clock.shutdown():
            return '%s within %g s' % (missing, timeout)
        clock.sleep(0.05)
