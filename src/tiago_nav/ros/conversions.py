"""Conversions between ROS messages and the library's plain types (needs no ROS master).

Poses are ``(x, y, yaw)`` [m, m, rad]; grids are :class:`tiago_nav.gridmap.GridMap`.
"""
import numpy as np
import rospy
from geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion, Transform, TransformStamped
from nav_msgs.msg import MapMetaData, OccupancyGrid

from tiago_nav.geometry import quaternion_to_yaw, yaw_to_quaternion
from tiago_nav.gridmap import GridMap
from tiago_nav.nav.runner import goal_pose
from tiago_nav.scan import Scan
from tiago_nav.scan import scan_to_points


def pose_msg(pose):
    """``(x, y, yaw)`` → geometry_msgs/Pose."""
    x, y, yaw = pose
    return Pose(position=Point(x, y, 0.0), orientation=Quaternion(*yaw_to_quaternion(yaw)))


def pose_stamped(pose, frame_id, stamp=None):
    """``(x, y, yaw)`` → geometry_msgs/PoseStamped in ``frame_id``."""
    msg = PoseStamped(pose=pose_msg(pose))
    msg.header.frame_id = frame_id
    msg.header.stamp = stamp if stamp is not None else rospy.Time()
    return msg


def pose_from_msg(pose):
    """geometry_msgs/Pose → ``(x, y, yaw)``."""
    q = pose.orientation
    return (pose.position.x, pose.position.y, quaternion_to_yaw(q.x, q.y, q.z, q.w))


def transform_msg(pose):
    """``(x, y, yaw)`` → geometry_msgs/Transform."""
    x, y, yaw = pose
    t = Transform()
    t.translation.x, t.translation.y = x, y
    t.rotation = Quaternion(*yaw_to_quaternion(yaw))
    return t


def transform_stamped(pose, parent, child, stamp):
    """A TransformStamped ``parent → child`` whose child frame sits at ``pose`` in ``parent``."""
    msg = TransformStamped(transform=transform_msg(pose))
    msg.header.frame_id = parent
    msg.header.stamp = stamp
    msg.child_frame_id = child
    return msg


def pose_from_transform(transform):
    """geometry_msgs/Transform → ``(x, y, yaw)``."""
    t, q = transform.translation, transform.rotation
    return (t.x, t.y, quaternion_to_yaw(q.x, q.y, q.z, q.w))


def gridmap_to_msg(grid, frame_id='map', stamp=None):
    """:class:`GridMap` → nav_msgs/OccupancyGrid (row-major, row 0 at the origin)."""
    msg = OccupancyGrid()
    msg.header.frame_id = frame_id
    msg.header.stamp = stamp if stamp is not None else rospy.Time()
    msg.info = MapMetaData(map_load_time=msg.header.stamp, resolution=grid.resolution,
                           width=grid.width, height=grid.height,
                           origin=pose_msg((grid.origin[0], grid.origin[1], 0.0)))
    msg.data = grid.data.astype(np.int8).ravel().tolist()
    return msg


def gridmap_from_msg(msg):
    """nav_msgs/OccupancyGrid → :class:`GridMap`. A rotated map origin is refused
    (:func:`gridmap_in_grid_frame` takes it)."""
    grid, frame = gridmap_in_grid_frame(msg)
    if frame[2] != 0.0:
        raise ValueError('maps with a rotated origin are not supported (yaw %.3f rad)' % frame[2])
    return grid


def gridmap_in_grid_frame(msg):
    """nav_msgs/OccupancyGrid → ``(grid, frame)``: a :class:`GridMap` and the pose ``(x, y,
    yaw)`` [m, m, rad] in the map frame of the frame the grid is laid out in. A map whose
    origin is not rotated (|yaw| ≤ 1e-6 rad) is its own frame: ``frame`` is ``(0, 0, 0)`` and
    the grid's origin is the message's; a rotated one (MapMetaData's origin with a yaw) is laid
    out in a frame at that origin pose: the grid's origin is ``(0, 0)`` and a point ``p`` of
    the grid's frame is ``frame ∘ p`` in the map frame. :class:`ValueError` for data of the
    wrong size or a non-positive resolution."""
    info = msg.info
    yaw = pose_from_msg(info.origin)[2]
    if len(msg.data) != info.width * info.height:
        raise ValueError('map data has %d cells, expected %d x %d'
                         % (len(msg.data), info.width, info.height))
    if not info.resolution > 0:
        raise ValueError('map resolution %r is not positive' % info.resolution)
    data = np.asarray(msg.data, dtype=np.int8).reshape(info.height, info.width)
    x, y = float(info.origin.position.x), float(info.origin.position.y)
    if abs(yaw) <= 1e-6:
        return GridMap(data, float(info.resolution), (x, y)), (0.0, 0.0, 0.0)
    return GridMap(data, float(info.resolution), (0.0, 0.0)), (x, y, float(yaw))


def scan_points(scan):
    """sensor_msgs/LaserScan → ``(points, index)`` in the scan's frame (invalid beams dropped,
    see :func:`tiago_nav.scan.scan_to_points`)."""
    return scan_to_points(scan.ranges, scan.angle_min, scan.angle_increment,
                          scan.range_min, scan.range_max)


def known_frames(yaml_text):
    """The frame names in tf2's ``all_frames_as_yaml()``: each child and its parent."""
    names = set()
    for line in yaml_text.splitlines():
        if line and not line[0].isspace() and line.rstrip().endswith(':'):
            names.add(line.rstrip()[:-1].strip('\'"'))
        elif line.strip().startswith('parent:'):
            names.add(line.split(':', 1)[1].strip().strip('\'"'))
    return names - {''}


def scan_from_msg(msg, seconds=True):
    """sensor_msgs/LaserScan → :class:`tiago_nav.scan.Scan`: ranges as a float array and the
    stamp in seconds (``seconds``: the corridor law's), or ranges as the message's tuple and
    the stamp as its rospy.Time (detection's, which looks transforms up at it)."""
    if seconds:
        return Scan(np.asarray(msg.ranges, float), msg.angle_min, msg.angle_increment,
                    msg.range_min, msg.range_max, msg.header.stamp.to_sec(), msg.header.frame_id)
    return Scan(msg.ranges, msg.angle_min, msg.angle_increment, msg.range_min, msg.range_max,
                msg.header.stamp, msg.header.frame_id)


def goal_from_pose(pose):
    """geometry_msgs/Pose → ``(x, y, yaw)`` checked like a goal (raises
    :class:`tiago_nav.goal.GoalError`)."""
    o = pose.orientation
    return goal_pose((pose.position.x, pose.position.y, pose.position.z), (o.x, o.y, o.z, o.w))


COV_INDEX = (0, 1, 5)      # x, y, yaw in a ROS pose covariance's rows and columns


def covariance_6x6(cov3):
    """The 36 row-major values of a ROS pose covariance from a 3 × 3 ``(x, y, yaw)`` one."""
    out = np.zeros((6, 6))
    out[np.ix_(COV_INDEX, COV_INDEX)] = cov3
    return out.ravel().tolist()
