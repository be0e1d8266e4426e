"""Obstacle detection from one laser scan: map subtraction, centroid clustering, centre estimation.

Everything here is plain numpy/scipy; frames are named in each function (``map`` for the static
map and the results, ``base_laser_link`` for raw scan points). Units: metres, radians.
"""
from tiago_nav.detection.pipeline import METHODS, DetectionParams, Detection, ObstacleDetector  # noqa: F401
