"""Does a corridor lead from here toward pose B? The proxy's decision whether to run the
corridor law (no ROS here).

The law drives a corridor only; where the robot does not stand at a corridor entrance leading
toward pose B (a start in a room, a second run from pose B, an open hall), the proxy goes
straight to move_base instead of letting the law abort with "no corridor ahead".
"""
from tiago_nav.corridor.law import CorridorParams, corridor_toward
from tiago_nav.geometry import inverse, transform_points


def corridor_ahead(points, laser_pose, robot_pose, target, params=None):
    """True when a corridor ahead of the robot leads toward ``target``
    (:func:`tiago_nav.corridor.law.corridor_toward`).

    Args:
        points: ``(N, 2)`` scan points [m] in the laser frame (valid beams only).
        laser_pose: ``(x, y, yaw)`` of the laser frame in base_footprint [m, m, rad].
        robot_pose: ``(x, y, yaw)`` of base_footprint in ``map`` at the scan's time.
        target: pose B ``(x, y, ...)`` [m] in ``map``.
        params: the law's :class:`~tiago_nav.corridor.law.CorridorParams` (default: its defaults).
    """
    robot_points = transform_points(laser_pose, points)
    goal = transform_points(inverse(robot_pose), [target[:2]])[0]
    return corridor_toward(robot_points, goal, params or CorridorParams()) is not None
