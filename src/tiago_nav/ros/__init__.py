"""The ROS adapter layer: message conversions, parameter reading, ROS time, markers and action
helpers shared by the nodes (:mod:`tiago_nav.nodes`). Importing it needs rospy but no master."""
