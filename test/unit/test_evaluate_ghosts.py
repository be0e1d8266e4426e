"""The evaluator's ghost watch (tiago_nav_tools.evaluate.ghosts) on costmaps made by the
navigation's own inflation and published values: a mark a walker left is a ghost from the first
scan that sees its place free, its age grows with the costmaps until it clears; a mark where a
walker or an obstacle stands, near the map's walls, or never seen free is none, and so is a
region whose cells between marks were seen free while a mark was not."""
import numpy as np
import pytest

from tiago_nav.gridmap import FREE, OCCUPIED, GridMap
from tiago_nav.nav.costmap import Costmap, MapScan, inflate, occupancy_values
from tiago_nav.nav.people import person_keep_out
from tiago_nav.robot import LASER_OFFSET, ROBOT_RADIUS
from tiago_nav.sim.scene import LaserConfig
from tiago_nav.sim.world import World
from tiago_nav_tools.evaluate.ghosts import GhostWatch, seen_free

RES = 0.05
ORIGIN = (-1.0, -3.0)
SHAPE = (120, 160)          # 6 m x 8 m: x -1..7, y -3..3


def cell(x, y):
    return int((y - ORIGIN[1]) / RES), int((x - ORIGIN[0]) / RES)


def static_map():
    occ = np.zeros(SHAPE, dtype=bool)
    occ[:, -2:] = True                       # a wall at x = 6.9-7
    return occ


def costmap(marks=()):
    """The published values of the navigation's costmap with the map and these marks."""
    occ = static_map()
    for x, y in marks:
        occ[cell(x, y)] = True
    cost, _ = inflate(occ, RES, ROBOT_RADIUS, 0.8, 4.0)
    return occupancy_values(cost)


def grid_map():
    return GridMap(np.where(static_map(), OCCUPIED, FREE).astype(np.int8), RES, ORIGIN)


def watch(movables=(), keep_out=0.0):
    return GhostWatch(grid_map(), movables, ROBOT_RADIUS, LASER_OFFSET, 5.0, keep_out)


def scan(w, stamp, ranges=6.0):
    """A scan from the robot at the origin facing +x: every beam reaches ``ranges`` [m]."""
    c = LaserConfig()
    n = len(c.angles())
    w.scan(stamp, np.full(n, ranges), c.angle_min, c.angle_increment, 0.05, 25.0)


def at(w, t, pose=(0.0, 0.0, 0.0), legs=((4.0, 2.0), (4.0, 2.2))):
    """The true pose and the walkers at ``t``."""
    w.pose(t, pose)
    w.walkers(t, legs, 0.06)


def test_a_mark_left_by_a_walker_is_a_ghost_from_the_scan_that_sees_it_free():
    w = watch()
    at(w, 0.0, legs=[[2.0, 0.0], [2.0, 0.2]])
    w.costmap(0.0, costmap([(2.0, 0.0)]))
    assert w.records[-1][1:] == [0.0, 0, 0]          # the walker is there: no phantom
    at(w, 1.0)                                       # it walked on
    w.costmap(1.0, costmap([(2.0, 0.0)]))
    assert w.records[-1][2] == 0 and w.records[-1][3] > 0   # a phantom, not yet seen free
    scan(w, 1.5)                                     # every beam to 6 m: its place seen free
    at(w, 2.0)
    w.costmap(2.0, costmap([(2.0, 0.0)]))
    assert w.records[-1][1] == pytest.approx(0.5) and w.records[-1][2] == w.records[-1][3]
    at(w, 4.0)
    w.costmap(4.0, costmap([(2.0, 0.0)]))
    assert w.records[-1][1] == pytest.approx(2.5)
    at(w, 5.0)
    w.costmap(5.0, costmap())                        # cleared
    assert w.records[-1][1:] == [0.0, 0, 0]
    assert max(r[1] for r in w.records) == pytest.approx(2.5)


def test_marks_of_what_is_there_or_never_seen_free_are_no_ghosts():
    world = World.from_dict({'name': 'g', 'resolution': RES, 'bounds': [-1, -3, 7, 3],
                             'robot_start': [0, 0, 0],
                             'movable_obstacles': [{'x': 3.0, 'y': 1.0, 'radius': 0.2}]})
    w = watch(world.movable_obstacles)
    at(w, 0.0)
    # a mark on the obstacle's outline, one 5 cm off the wall (the localisation), one behind
    # the laser (outside its fan): only the last is a phantom
    marks = [(3.0, 0.8), (6.85, 0.0), (-0.5, 0.0)]
    w.costmap(0.0, costmap(marks))
    behind = w.records[-1][3]
    w.costmap(0.0, costmap([(-0.5, 0.0)]))
    assert behind == w.records[-1][3] > 0
    scan(w, 0.5)
    scan(w, 0.6, ranges=1.0)                         # a wall 1 m ahead: nothing seen beyond
    at(w, 1.0)
    w.costmap(1.0, costmap(marks))
    assert w.records[-1][1:3] == [0.0, 0]            # never seen free: no ghost
    # a phantom ahead seen only up to a wall in front of it (1 m) is no ghost either
    at(w, 2.0)
    w.costmap(2.0, costmap(marks + [(2.0, 0.0)]))
    scan(w, 2.5, ranges=1.0)
    at(w, 3.0)
    w.costmap(3.0, costmap(marks + [(2.0, 0.0)]))
    assert w.records[-1][1:3] == [0.0, 0] and w.records[-1][3] > behind


def test_the_keep_out_round_a_walker_who_is_there_is_no_ghost():
    # the navigation keeps a person's keep-out round the hits of a standing walker's legs
    # (person_clearance 0.3 m); the laser sees the floor round them free. The keep-out is
    # what is there, and is no ghost; a watch that does not know of it calls it one
    legs = [(3.0, 0.0), (3.0, 0.25)]
    keep_out = person_keep_out(0.3, 0.04, RES)
    cm = Costmap(grid_map())
    cm.set_people(np.array([(x - 0.06, y) for x, y in legs]), keep_out)
    cost, _ = inflate(static_map() | cm.people, RES, ROBOT_RADIUS, 0.8, 4.0)
    ages = []
    for k in (0.0, keep_out):
        w = watch(keep_out=k)
        at(w, 0.0, legs=legs)
        w.costmap(0.0, occupancy_values(cost))
        scan(w, 0.5)
        at(w, 1.0, legs=legs)
        w.costmap(1.0, occupancy_values(cost))
        ages.append(w.records[-1])
    assert ages[0][1] == pytest.approx(0.5) and ages[0][2] > 0
    assert ages[1][1:] == [0.0, 0, 0]


def test_streams_out_of_step_are_looked_at_in_stamp_order():
    # the scan and the costmap come before the true pose and the walkers of their stamps (a
    # loaded machine): nothing is judged until those come; the robot then faces away (-x)
    # and sees nothing of the mark ahead of where it stood
    w = watch()
    at(w, 0.0)
    w.costmap(0.0, costmap([(2.0, 0.0)]))
    scan(w, 0.5)
    w.costmap(1.0, costmap([(2.0, 0.0)]))
    assert len(w.records) == 1
    at(w, 0.5, pose=(0.0, 0.0, np.pi))
    at(w, 1.0, pose=(0.0, 0.0, np.pi))
    assert len(w.records) == 2
    assert w.records[-1][1:3] == [0.0, 0] and w.records[-1][3] > 0
    # the end of the mission judges what is left, with the poses there are
    scan(w, 1.5)
    w.costmap(2.0, costmap([(2.0, 0.0)]))
    w.flush()
    assert len(w.records) == 3


def test_a_region_is_a_ghost_only_once_all_of_it_was_seen_free():
    """Two marks 0.25 m apart across the laser's view (a walker's two legs' trails): their
    inflated discs merge, and the cells between them survive the erosion. A scan that ends
    on the far mark sees the near half of the region free, not the far mark: no ghost. Once a
    scan sees past both, the region is one, aged from that scan."""
    w = watch()
    marks = [(2.0, 0.0), (2.25, 0.0)]
    at(w, 0.0)
    w.costmap(0.0, costmap(marks))
    assert w.records[-1][3] > 0
    scan(w, 0.5, ranges=2.25 - LASER_OFFSET)         # every beam ends on the far mark
    at(w, 1.0)
    w.costmap(1.0, costmap(marks))
    assert len(w.seen_free) > 0 and w.records[-1][1:3] == [0.0, 0]
    scan(w, 1.5)                                     # every beam to 6 m
    at(w, 2.0)
    w.costmap(2.0, costmap(marks))
    assert w.records[-1][1] == pytest.approx(0.5) and w.records[-1][2] == w.records[-1][3]


def test_a_cell_is_seen_free_exactly_where_the_costmap_clears_it():
    """At the edge of ``raytrace_range`` a beam reaching beyond a mark does not clear it when
    the cell's centre lies within half a cell of the range: the watch must not count such a
    cell seen free, or a mark move_base cannot clear yet is called a ghost."""
    grid = GridMap(np.zeros((240, 160), dtype=np.int8), RES, (0.0, 0.0))
    cm = Costmap(grid, obstacle_range=4.0, raytrace_range=5.0)
    laser = (1.013, 6.007, 0.0)
    rng = np.random.default_rng(3)
    d = rng.uniform(4.5, 5.5, 400)
    a = rng.uniform(-1.5, 1.5, 400)
    rc = np.unique(grid.world_to_cell(np.column_stack((laser[0] + d * np.cos(a),
                                                       laser[1] + d * np.sin(a)))), axis=0)
    cm.obstacles[rc[:, 0], rc[:, 1]] = True
    c = LaserConfig()
    s = MapScan(laser, np.full(len(c.angles()), 8.0), c.angle_min, c.angle_increment, 0.05, 25.0)
    xy = grid.cell_to_world(rc)
    free = seen_free(s, xy, RES, cm.raytrace_range)
    centre = np.hypot(xy[:, 0] - laser[0], xy[:, 1] - laser[1])
    edge = (centre > 5.0 - 0.5 * RES) & (centre <= 5.0) & s.seen_beyond(xy, RES)
    assert edge.sum() >= 5 and not free[edge].any()   # seen through, but on the range's edge
    cm.add_scan(s)
    cleared = ~cm.obstacles[rc[:, 0], rc[:, 1]]
    assert free.sum() >= 50
    assert np.array_equal(free, cleared & s.seen_beyond(xy, RES))
    assert not (free & ~cleared).any()
