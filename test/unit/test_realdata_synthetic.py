"""The synthetic building of the real-data benchmark (tiago_nav_tools.testing.realdata.synthetic):
rooms joined by doors, a route through them in free space, ranges ray-cast to the walls."""
import math

import numpy as np

from tiago_nav_tools.testing.realdata import synthetic
from tiago_nav_tools.testing.realdata.carmen import beam_angles


def test_rooms_doors_route_and_ranges():
    g = synthetic.building(size=30.0, room=10.0)
    assert g.data.shape == (600, 600) and g.resolution == 0.05
    occ = g.occupied()
    # outer walls closed, an inner wall with a door in the middle of each room's side
    assert occ[:, 0].all() and occ[0, :].all()
    col = int(10.0 / 0.05)
    assert occ[int(2.0 / 0.05), col] and not occ[int(5.0 / 0.05), col]
    # the route (first row of rooms, along y = 5) runs in free space through the doors
    poses = synthetic.route(size=30.0, room=10.0)
    rc = g.world_to_cell(poses[:, :2])
    assert not occ[rc[:, 0], rc[:, 1]].any()
    # from (5, 5) facing +x: straight ahead through both doors to the outer wall at x = 30
    # (its face at 29.9); at 60 deg the wall at y = 10 (face at 9.9) beside the door, unless a
    # box stands in between
    angles = beam_angles(180)
    r = synthetic.cast(g, np.array([[5.0, 5.0, 0.0]]), angles, noise=0.0)[0]
    ahead, slant = r[90], r[int(np.argmin(np.abs(angles - math.radians(60.0))))]
    assert abs(ahead - 24.9) < 0.06, ahead
    wall = 4.9 / math.sin(math.radians(60.0))
    assert abs(slant - wall) < 0.1 or slant < wall, slant
    assert np.isfinite(r).all()                              # a closed building
