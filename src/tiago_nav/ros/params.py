"""Reading a node's parameter dataclass from the ROS parameter server (see
:mod:`tiago_nav.params` for how parameters are declared)."""
import sys

import rospy

from tiago_nav.params import ParamError, read_params


def read(cls):
    """Every ``~name`` parameter of the dataclass ``cls``, validated; :class:`ParamError`
    naming the parameter otherwise."""
    return read_params(cls, rospy.get_param, rospy.resolve_name)



def read_or_exit(cls, node):
    """:func:`read`, or, for a bad configuration, a fatal log line naming the parameter
    (``<node>: parameter /<node>/<name>: <why>``) and exit status 2."""
    try:
        return read(cls)
    except ParamError as e:
        rospy.logfatal('%s: %s', node, e)
        sys.exit(2)
