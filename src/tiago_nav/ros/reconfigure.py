"""dynamic_reconfigure for a node's run-time parameters (those declared ``dynamic=(lo, hi)``,
:func:`tiago_nav.params.dynamic_fields`; their ``cfg/*.cfg`` is made from the same table).

:func:`serve` offers the standard server (``~set_parameters``, ``~parameter_descriptions``,
``~parameter_updates``: rqt_reconfigure and ``rosrun dynamic_reconfigure dynparam`` work as with
any node). Each request goes to the node's :class:`tiago_nav.params.ParamChanges`, which checks
it as a start-up value is checked and puts it in force at the next control cycle's boundary; a
refused request is logged and answered with the values in force, so the server, the parameter
server and the node never disagree.
"""
import rospy
from dynamic_reconfigure.server import Server

from tiago_nav.params import ParamError, dynamic_fields, values
from tiago_nav.ros.reset import persistent


def serve(config_type, cls, changes, node):
    """Start a dynamic_reconfigure server of ``config_type`` (a generated ``tiago_nav.cfg``
    class) for the parameter dataclass ``cls``. ``changes()`` returns the node's current
    :class:`~tiago_nav.params.ParamChanges` (None while a reset rebuilds the node, whose new
    state then reads the parameter server, where the server has written each change). Made
    once per process: the server outlives resets (after one, :func:`show` the new state's
    values). Returns the dynamic_reconfigure server."""
    names = [row[0] for row in dynamic_fields(cls)]
    described = {p['name'] for p in config_type.config_description['parameters']}
    if set(names) != described:
        raise RuntimeError('%s: cfg parameters %s differ from the reconfigurable parameters %s: '
                           'rebuild the workspace' % (node, sorted(described), sorted(names)))

    def callback(config, level):
        target = changes()
        if target is None:
            return config
        wanted = {n: config[n] for n in names}
        try:
            new = target.request(wanted)
        except ParamError as e:
            new = target.requested
            rospy.logwarn('%s: dynamic_reconfigure: %s; keeping %s', node, e,
                          ', '.join('%s %g' % (n, values(new)[n]) for n in names
                                    if wanted[n] != values(new)[n]))
        given = values(new)
        changed = [n for n in names if given[n] != wanted[n]]
        for n in names:
            config[n] = given[n]
        if level != ~0 and not changed:
            rospy.loginfo('%s: dynamic_reconfigure: %s', node,
                          ', '.join('%s %g' % (n, given[n]) for n in names))
        return config

    with persistent():
        return Server(config_type, callback)


def show(server, params):
    """Make ``server`` (:func:`serve`'s, None: nothing) hold the run-time values of
    ``params``, a state a reset has just built from the parameter server (where a
    ``rosparam set`` may have changed them since the last request)."""
    if server is None:
        return
    given = values(params)
    server.update_configuration({p['name']: given[p['name']]
                                 for p in server.type.config_description['parameters']})
