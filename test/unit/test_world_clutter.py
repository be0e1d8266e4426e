"""tiago_nav.sim.worlds.cluttered_room and the shipped worlds/clutter_room.yaml made with it:
the gaps it promises, measured on the world (between cylinder surfaces, cylinder to wall face),
the door as the only way in, pose B reachable and every cylinder in view from it."""
import math
import os

import numpy as np
import pytest

from conftest import WORLDS
from tiago_nav.nav.costmap import Costmap
from tiago_nav.nav.planner import PlanError, plan
from tiago_nav.sim.raster import rasterise_world
from tiago_nav.sim.world import World, load_world
from tiago_nav.sim.worlds import cluttered_room, cluttered_room_pose_b
from tiago_nav_tools.evaluate.matching import visible_truth


def wall_gap(c, wall):
    """[m] from cylinder ``c``'s surface to the nearest point of the (rotated) wall box."""
    th = wall.yaw
    dx, dy = c.x - wall.x, c.y - wall.y
    u = dx * math.cos(th) + dy * math.sin(th)            # along the wall
    v = -dx * math.sin(th) + dy * math.cos(th)           # across it
    ex = max(abs(u) - wall.length / 2.0, 0.0)
    ey = max(abs(v) - wall.width / 2.0, 0.0)
    return math.hypot(ex, ey) - c.radius


def gaps(world):
    cs = world.movable_obstacles
    between = sorted(min(math.hypot(a.x - b.x, a.y - b.y) - a.radius - b.radius
                         for b in cs if b is not a) for a in cs)
    to_wall = [min(wall_gap(c, w) for w in world.walls) for c in cs]
    return np.array(between), np.array(to_wall)


@pytest.fixture(scope='module')
def shipped():
    return load_world(os.path.join(WORLDS, 'clutter_room.yaml'))


def test_the_shipped_file_is_the_generator_s_default():
    generated = World.from_dict(cluttered_room())
    shipped = load_world(os.path.join(WORLDS, 'clutter_room.yaml'))
    for key in ('bounds', 'robot_start', 'walls', 'movable_obstacles', 'static_cylinders'):
        a, b = getattr(generated, key), getattr(shipped, key)
        assert np.allclose(np.asarray(a, dtype=float) if key in ('bounds', 'robot_start') else
                           [list(vars(x).values()) for x in a],
                           np.asarray(b, dtype=float) if key in ('bounds', 'robot_start') else
                           [list(vars(x).values()) for x in b], atol=1e-3), key


def test_obstacles_are_close_together_and_close_to_the_walls(shipped):
    between, to_wall = gaps(shipped)
    assert len(between) == 8
    # each cylinder's nearest neighbour: 0.3-0.5 m surface to surface (the robot is 0.54 m)
    assert between.min() == pytest.approx(0.3, abs=1e-3)
    assert between.max() <= 0.5 + 1e-3
    # each cylinder's nearest wall face: 0.15-0.3 m
    assert to_wall.min() == pytest.approx(0.15, abs=1e-3)
    assert to_wall.max() <= 0.3 + 1e-3
    assert {round(g, 2) for g in to_wall} >= {0.15, 0.2, 0.3}


def test_other_gaps_are_honoured():
    w = World.from_dict(cluttered_room(radius=0.2, gaps=(0.35,), wall_gaps=(0.25,)))
    between, to_wall = gaps(w)
    assert np.allclose(between, 0.35, atol=1e-3)
    assert np.allclose(to_wall, 0.25, atol=1e-3)


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError, match='door'):
        cluttered_room(door=0.5)
    with pytest.raises(ValueError, match='gaps'):
        cluttered_room(gaps=(0.0, 0.3))


def test_pose_b_is_reached_through_the_door_and_sees_every_cylinder(shipped):
    d = cluttered_room()
    b = cluttered_room_pose_b(d)
    assert b == (3.8, 0.0, 0.0)
    cm = Costmap(rasterise_world(shipped))
    start = shipped.start_pose[:2]
    path = plan(cm, start, b[:2])
    # the way in is the door: the path crosses x = 0 within its 1 m opening
    i = int(np.argmax(path[:, 0] >= 0.0))
    assert abs(path[i, 1]) < 0.5 - 0.27 + 0.05
    # the door is the only way: closed, the room cannot be reached
    closed = dict(d, walls=d['walls'] + [{'x': -0.075, 'y': 0.0, 'length': 1.2, 'width': 0.15,
                                          'yaw_deg': 90.0}])
    with pytest.raises(PlanError):
        plan(Costmap(rasterise_world(World.from_dict(closed))), start, b[:2])
    # pose B: at least 0.65 m from everything (the evaluator's clearance for sampled poses),
    # and every cylinder in view from it
    bx, by = b[:2]
    assert min(math.hypot(c.x - bx, c.y - by) - c.radius for c in shipped.movable_obstacles) >= 0.65
    seen = visible_truth(shipped, (bx, by, math.radians(b[2])))
    assert len(seen) == len(shipped.movable_obstacles)
