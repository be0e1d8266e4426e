"""Reading a node's parameter dataclass from the ROS parameter server (see
:mod:`tiago_nav.params` for how parameters are declared)."""
import numpy as np
import rospy

from tiago_nav.params import ParamError, read_params  # noqa: F401  (re-exported for the nodes)


def read(cls):
    """Every ``~name`` parameter of the dataclass ``cls``, validated; :class:`ParamError`
    naming the parameter otherwise."""
    return read_params(cls, rospy.get_param, rospy.resolve_name)


def param(name, default, kind=float, check=None, why=''):
    # TRANSITIONAL: the nodes move to read(); this goes when the last caller does.
    """Read the parameter ``name`` (e.g. ``'~rate'``) as ``kind`` (float, int, bool, str).

    Raises :class:`ParamError` naming the parameter when the value has the wrong type or
    ``check(value)`` is false (``why`` says what is expected).
    """
    value = rospy.get_param(name, default)
    try:
        if kind is bool:
            if not isinstance(value, bool):
                raise TypeError
        elif kind in (int, float):
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError
            if kind is int and float(value) != int(value):
                raise TypeError
            value = kind(value)
            if not np.isfinite(value):
                raise TypeError
        elif kind is str:
            if not isinstance(value, str):
                raise TypeError
        else:
            value = kind(value)
    except (TypeError, ValueError):
        raise ParamError('parameter %s: expected %s, got %r' % (rospy.resolve_name(name),
                                                                  kind.__name__, value)) from None
    if check is not None and not check(value):
        raise ParamError('parameter %s: %r is not allowed%s'
                         % (rospy.resolve_name(name), value, ' (%s)' % why if why else ''))
    return value
