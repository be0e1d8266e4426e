"""A log as a robot's bag (needs rosbag and the ROS message packages).

Topics, stamped with the log's (repaired) scan times so that ``rosbag play --clock`` gives a
``/clock`` a node with ``/use_sim_time`` follows:

- ``/scan`` (sensor_msgs/LaserScan) in ``base_laser_link``: the log's ranges, ``+inf`` for no
  return (REP 117), ``range_max`` :data:`RANGE_MAX`;
- ``/odom`` (nav_msgs/Odometry, ``odom`` → ``base_footprint``) and the same transform on
  ``/tf``, at each scan's time, written just before the scan so a node finds the odometry at
  the scan's stamp;
- ``/tf_static`` (latched): ``base_footprint`` → ``base_laser_link``, the identity (the logs
  give the laser's pose; it is taken as the robot's).
"""
import math

import rosbag
import rospy
from geometry_msgs.msg import TransformStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import LaserScan
from tf2_msgs.msg import TFMessage

from tiago_nav.geometry import yaw_to_quaternion

BASE, LASER, ODOM = 'base_footprint', 'base_laser_link', 'odom'
RANGE_MIN, RANGE_MAX = 0.02, 49.99      # [m] (a reading at or above 50 m is no return)
TF_LEAD = 1e-3          # [s] odometry written this long before its scan


def _transform(parent, child, stamp, pose):
    t = TransformStamped()
    t.header.frame_id, t.header.stamp, t.child_frame_id = parent, stamp, child
    t.transform.translation.x, t.transform.translation.y = pose[0], pose[1]
    q = yaw_to_quaternion(pose[2])
    (t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z,
     t.transform.rotation.w) = q
    return t


def write_bag(path, log, odom, compression='bz2'):
    """Write the bag of ``log`` (:class:`tiago_nav_tools.testing.realdata.carmen.CarmenLog`) with the
    odometry ``odom`` (``(N, 3)`` poses in odom at its scans) to ``path``; returns ``path``."""
    if len(odom) != len(log):
        raise ValueError('%d odometry poses for %d scans' % (len(odom), len(log)))
    if log.times[0] <= TF_LEAD + 0.01:
        raise ValueError('the log\'s first scan time %g s leaves no room before it' % log.times[0])
    angles = log.angles()
    inc = float(angles[1] - angles[0])
    with rosbag.Bag(path, 'w', compression=compression) as bag:
        t0 = rospy.Time.from_sec(log.times[0] - 0.01)
        static = TFMessage([_transform(BASE, LASER, t0, (0.0, 0.0, 0.0))])
        bag.write('/tf_static', static, t0, connection_header={
            'topic': '/tf_static', 'type': static._type, 'md5sum': static._md5sum,
            'message_definition': static._full_text, 'latching': '1'})
        prev = None
        for k in range(len(log)):
            stamp = rospy.Time.from_sec(float(log.times[k]))
            lead = rospy.Time.from_sec(float(log.times[k]) - TF_LEAD)
            o = Odometry()
            o.header.frame_id, o.header.stamp, o.child_frame_id = ODOM, stamp, BASE
            o.pose.pose.position.x, o.pose.pose.position.y = odom[k][0], odom[k][1]
            q = yaw_to_quaternion(odom[k][2])
            (o.pose.pose.orientation.x, o.pose.pose.orientation.y, o.pose.pose.orientation.z,
             o.pose.pose.orientation.w) = q
            if prev is not None:
                dt = log.times[k] - log.times[k - 1]
                dx, dy = odom[k][0] - prev[0], odom[k][1] - prev[1]
                c, s = math.cos(prev[2]), math.sin(prev[2])
                o.twist.twist.linear.x = (c * dx + s * dy) / dt
                o.twist.twist.angular.z = math.remainder(odom[k][2] - prev[2], 2 * math.pi) / dt
            prev = odom[k]
            bag.write('/tf', TFMessage([_transform(ODOM, BASE, stamp, odom[k])]), lead)
            bag.write('/odom', o, lead)
            s = LaserScan()
            s.header.frame_id, s.header.stamp = LASER, stamp
            s.angle_min, s.angle_increment = float(angles[0]), inc
            s.angle_max = float(angles[-1])
            dt_next = (log.times[k + 1] - log.times[k]) if k + 1 < len(log) else 0.0
            s.scan_time = float(dt_next)
            s.range_min, s.range_max = RANGE_MIN, RANGE_MAX
            s.ranges = [float(r) for r in log.ranges[k]]
            bag.write('/scan', s, stamp)
    return path
