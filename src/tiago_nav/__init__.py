"""tiago_nav: a pybullet mock TIAGo, navigation, corridor law and obstacle detection.

Layering (checked by test/unit/test_layout.py):

* the library (every module here except the three subpackages below) is plain Python
  (numpy/scipy/pybullet): it imports no rospy, actionlib, tf2_ros or message package, and is
  unit-tested without a ROS master;
* :mod:`tiago_nav.ros` (message conversions, parameter reading, ROS time, markers, actionlib
  helpers) and :mod:`tiago_nav.nodes` (one module per node: ROS wiring around decisions that
  take plain values) are the ROS adapter layer;
* :mod:`tiago_nav.testing` holds test doubles and test/benchmark support; product modules
  never import it.

Units are SI (REP 103): metres, radians, seconds; frames follow REP 105.
"""
