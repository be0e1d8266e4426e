"""Map rasterisation: known cells occupied or free; movable obstacles never in the map."""
import math

import numpy as np
import pytest

from tiago_nav.gridmap import OCCUPIED, FREE
from tiago_nav.sim.raster import rasterise_world
from tiago_nav.sim.world import World


def world(**kw):
    d = {'name': 'r', 'resolution': 0.05, 'bounds': [0, 0, 5, 4], 'robot_start': [1, 1, 0]}
    d.update(kw)
    return World.from_dict(d)


def value_at(grid, x, y):
    (r, c), = grid.world_to_cell([[x, y]])
    return grid.data[r, c]


def test_size_and_origin_from_bounds():
    g = rasterise_world(world(bounds=[-1.0, -2.0, 4.0, 2.0], robot_start=[0, 0, 0]))
    assert g.shape == (80, 100)
    assert g.origin == (-1.0, -2.0) and g.resolution == 0.05
    assert np.all(g.data == FREE)


def test_axis_aligned_wall_cells():
    g = rasterise_world(world(walls=[{'x': 2.5, 'y': 2.0, 'length': 3.0, 'width': 0.2}]))
    assert value_at(g, 2.5, 2.0) == OCCUPIED
    assert value_at(g, 1.02, 2.09) == OCCUPIED          # inside, near a corner
    assert value_at(g, 2.5, 2.35) == FREE                # 0.25 m from the centre line
    assert value_at(g, 0.8, 2.0) == FREE                 # beyond its end
    # the occupied band is the wall's width, give or take one cell
    col = g.world_to_cell([[2.5, 0]])[0, 1]
    band = np.flatnonzero(g.data[:, col] == OCCUPIED)
    assert 4 <= band.size <= 6
    assert abs(g.cell_to_world([[band.mean(), col]])[0, 1] - 2.0) < 0.03


def test_rotated_wall_is_continuous_and_in_place():
    g = rasterise_world(world(walls=[{'x': 2.5, 'y': 2.0, 'length': 3.0, 'width': 0.05, 'yaw_deg': 30}]))
    for s in np.linspace(-1.4, 1.4, 57):
        x, y = 2.5 + s * math.cos(math.radians(30)), 2.0 + s * math.sin(math.radians(30))
        assert value_at(g, x, y) == OCCUPIED, (x, y)
    # a point 0.2 m off the wall's line is free
    assert value_at(g, 2.5 - 0.2 * math.sin(math.radians(30)), 2.0 + 0.2 * math.cos(math.radians(30))) == FREE


def test_static_cylinder_in_map_movable_not():
    g = rasterise_world(world(static_cylinders=[{'x': 1.5, 'y': 3.0, 'radius': 0.3}],
                              movable_obstacles=[{'x': 3.5, 'y': 1.0, 'radius': 0.3}]))
    assert value_at(g, 1.5, 3.0) == OCCUPIED
    assert value_at(g, 1.5 + 0.25, 3.0) == OCCUPIED
    assert value_at(g, 1.5 + 0.45, 3.0) == FREE
    assert value_at(g, 3.5, 1.0) == FREE
    area = (g.data == OCCUPIED).sum() * 0.05 ** 2
    assert area == pytest.approx(math.pi * 0.3 ** 2, rel=0.3)


def test_geometry_outside_bounds_is_clipped():
    g = rasterise_world(world(walls=[{'x': 10, 'y': 10, 'length': 1, 'width': 1},
                                     {'x': 0.0, 'y': 2.0, 'length': 4.0, 'width': 0.2, 'yaw_deg': 90}]))
    assert value_at(g, 0.02, 2.0) == OCCUPIED
    assert (g.data == OCCUPIED).sum() > 0
