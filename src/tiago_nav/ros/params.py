"""Reading a node's parameter dataclass from the ROS parameter server (see
:mod:`tiago_nav.params` for how parameters are declared)."""
import math
import sys

import rospy

from tiago_nav.params import ParamError, read_params
from tiago_nav.sim.world import load_world


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


def start_pose(params):
    """The initial pose ``(x, y, yaw)`` [m, m, rad] of base_footprint in map: ``initial_pose``
    if given, else the world's robot_start (:class:`WorldError` when the file is unusable,
    :class:`ParamError` naming ``initial_pose`` when neither is given)."""
    if not params.initial_pose and not params.world:
        raise ParamError('give initial_pose [x, y, yaw_deg] or a world file', 'initial_pose')
    if params.initial_pose:
        x, y, yaw_deg = params.initial_pose
        return (float(x), float(y), math.radians(yaw_deg))
    return load_world(params.world).start_pose
