"""Reading a node's parameter dataclass from the ROS parameter server (see
:mod:`tiago_nav.params` for how parameters are declared)."""
import rospy

from tiago_nav.params import read_params


def read(cls):
    """Every ``~name`` parameter of the dataclass ``cls``, validated; :class:`ParamError`
    naming the parameter otherwise."""
    return read_params(cls, rospy.get_param, rospy.resolve_name)

