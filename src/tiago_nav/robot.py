"""The mock TIAGo's fixed geometry: the one place these numbers are written (REP 103 units).

Parameters that depend on the robot (``robot_radius`` of the costmap, the corridor law, the
simulator) take these as their defaults.
"""
ROBOT_RADIUS = 0.27     # [m] base footprint radius (TIAGo's base is about 0.54 m across)
LASER_OFFSET = 0.2      # [m] base_laser_link ahead of base_footprint's origin
BASE_LINK_HEIGHT = 0.0985  # [m] base_link above base_footprint (the floor), as on TIAGo
LASER_HEIGHT = 0.3      # [m] base_laser_link above the floor, above the base body
