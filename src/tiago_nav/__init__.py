"""tiago_nav: a pybullet mock TIAGo, navigation, corridor law and obstacle detection.

Layering (checked by test/unit/test_layout.py):

* the library (every module here except the two subpackages below) is plain Python
  (numpy/scipy/pybullet): it imports no rospy, actionlib, tf2_ros or message package, and is
  unit-tested without a ROS master;
* :mod:`tiago_nav.ros` (message conversions, parameter reading, ROS time, markers, actionlib
  helpers) and :mod:`tiago_nav.nodes` (one module per node: ROS wiring around decisions that
  take plain values) are the ROS adapter layer;
* the evaluation and tooling (batch evaluator, benchmark registry, docs generator, test support)
  is the separate package :mod:`tiago_nav_tools`; nothing here imports it.

Units are SI (REP 103): metres, radians, seconds; frames follow REP 105.
"""
from pkgutil import extend_path

# In a catkin workspace the generated message modules (tiago_nav.msg, tiago_nav.srv) are in the
# devel space's tiago_nav: join it however this package was found first (a process that imports
# tiago_nav_tools first finds the source tree's tiago_nav before the devel space's).
__path__ = extend_path(__path__, __name__)
