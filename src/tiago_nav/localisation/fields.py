"""One :class:`tiago_nav.localisation.localiser.DistanceField` per map, kept across the
localisation node's resets (no ROS here)."""
from tiago_nav.localisation.localiser import DistanceField

_FIELD = []     # [(map key, DistanceField)]: the last map's field


def distance_field(grid):
    """``grid``'s :class:`tiago_nav.localisation.localiser.DistanceField`, built once per map: a reset
    builds the node's state again for the same map, and the field (read only; 23 MB and a
    fifth of a second for the course world) is the same."""
    key = (grid.data.tobytes(), grid.resolution, tuple(grid.origin))
    if not _FIELD or _FIELD[0][0] != key:
        _FIELD[:] = [(key, DistanceField(grid))]
    return _FIELD[0][1]
