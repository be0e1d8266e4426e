#!/usr/bin/python3
"""laser_filters' LaserScanRangeFilter for the move_base candidate: ranges below
``~lower_threshold`` [m] become NaN (no hit, no clearing), everything else is passed on.

A TIAGo's laser sees its own base at the ends of its fan (20 beams each side, 0.23-0.26 m:
the simulator's ``tiago`` laser model has them too); on the robot a laser filter drops them
before move_base, which would otherwise mark its own footprint as an obstacle and find no valid
command. Debian packages no laser_filters, so the candidate runs this stand-in:
/scan in, /scan_filtered out (move_base_ros.launch)."""
import math

import rospy
from sensor_msgs.msg import LaserScan


def main():
    rospy.init_node('scan_range_filter')
    lower = float(rospy.get_param('~lower_threshold', 0.3))
    pub = rospy.Publisher('scan_filtered', LaserScan, queue_size=5)

    def on_scan(m):
        m.ranges = [math.nan if r < lower else r for r in m.ranges]
        pub.publish(m)

    rospy.Subscriber('scan', LaserScan, on_scan, queue_size=5)
    rospy.spin()


if __name__ == '__main__':
    main()
