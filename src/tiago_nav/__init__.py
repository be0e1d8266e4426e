"""tiago_nav: a pybullet mock TIAGo, navigation, corridor law and obstacle detection.

The library under this package is plain Python (numpy/scipy/pybullet) and imports no ROS
client code, except :mod:`tiago_nav.rosutil`, which converts between ROS messages and the
library's arrays. Units are SI (REP 103): metres, radians, seconds.
"""
