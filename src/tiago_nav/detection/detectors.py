"""One :class:`tiago_nav.detection.pipeline.ObstacleDetector` per map and detection
parameters, kept across the detection node's resets (no ROS here)."""
from tiago_nav.detection.pipeline import ObstacleDetector

_DETECTOR = []      # [(map and parameters key, ObstacleDetector)]: the last map's


def detector_for(grid, params):
    """``grid``'s :class:`tiago_nav.detection.pipeline.ObstacleDetector` with the detection
    parameters ``params``, built once per map and parameters: a reset builds the node's state
    again for the same map, and the detector's distance transform and field (read only,
    determined by the map and ``params``) take most of a reset's time to build."""
    key = (grid.data.tobytes(), grid.resolution, tuple(grid.origin), repr(params))
    if not _DETECTOR or _DETECTOR[0][0] != key:
        _DETECTOR[:] = [(key, ObstacleDetector(grid, params))]
    return _DETECTOR[0][1]
