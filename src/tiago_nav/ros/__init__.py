"""The ROS adapter layer: message conversions, parameter reading, ROS time, markers and action
helpers shared by the nodes (:mod:`tiago_nav.nodes`). Importing it needs rospy but no master."""
import threading

# rospy 1.15.9 (Debian 11) calls Thread.isAlive(), which Python 3.9 removed (fixed in rospy 1.15.10,
# ros/ros_comm#2092): there rospy.signal_shutdown() raises AttributeError once init_node has
# registered its thread, so a node or the client ends in a traceback with exit status 1. Every
# node imports this package before init_node; where Thread has isAlive this does nothing.
if not hasattr(threading.Thread, 'isAlive'):
    threading.Thread.isAlive = threading.Thread.is_alive
