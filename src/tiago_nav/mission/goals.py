"""Validating pose B, the mission's goal (no ROS here): used by the proxy before any stage and
by the client before anything is sent."""
import math

from tiago_nav.goal import GoalError

YAW_LIMIT_DEG = 360.0      # |yaw| accepted by goal validation [deg]


def parse_number(value, name):
    """``value`` (a string or a number) as a finite float; :class:`GoalError` naming ``name``
    otherwise."""
    if isinstance(value, bool):
        raise GoalError('%s: expected a number, got %r' % (name, value))
    try:
        f = float(value.strip() if isinstance(value, str) else value)
    except (TypeError, ValueError):
        raise GoalError('%s: %r is not a number' % (name, value)) from None
    if not math.isfinite(f):
        raise GoalError('%s: %r is not a finite number' % (name, value))
    return f


def validate_goal(x, y, yaw_deg):
    """Check pose B: ``x``, ``y`` [m] in ``map`` and ``yaw_deg`` [deg], strings or numbers.

    Returns ``(x, y, yaw_deg)`` as floats; raises :class:`GoalError` with a sentence naming the
    bad value. The yaw is in degrees and must lie within ±360.
    """
    x = parse_number(x, 'x')
    y = parse_number(y, 'y')
    yaw = parse_number(yaw_deg, 'yaw')
    if abs(yaw) > YAW_LIMIT_DEG:
        raise GoalError('yaw: %g is out of range; give the yaw in degrees, between -%g and %g'
                        % (yaw, YAW_LIMIT_DEG, YAW_LIMIT_DEG))
    return x, y, yaw
