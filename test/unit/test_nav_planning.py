"""Unit tests of the navigation costmap, planner and controller (no ROS master)."""
import math
import os

import numpy as np
import pytest

from conftest import WORLDS
from tiago_nav.gridmap import GridMap
from tiago_nav.nav.controller import Controller, ControllerConfig
from tiago_nav.nav.costmap import INSCRIBED, LETHAL, Costmap, MapScan, inflate, occupancy_values
from tiago_nav.nav.planner import PlanError, grid_path, path_length, plan


def empty(rows=40, cols=60, res=0.05):
    return GridMap(np.zeros((rows, cols), dtype=np.int8), res, (0.0, 0.0))


# --- costmap -----------------------------------------------------------------------------
def test_inflation_values_follow_distance():
    occ = np.zeros((41, 41), dtype=bool)
    occ[20, 20] = True
    cost, dist = inflate(occ, 0.05, 0.27, 0.8, 4.0)
    assert cost[20, 20] == LETHAL
    assert cost[20, 20 + 5] == LETHAL                 # 0.25 m < radius
    d = 0.30                                          # 6 cells: in the gradient band
    assert cost[20, 26] == round(252 * math.exp(-4.0 * (d - 0.27)))
    assert cost[20, 20 + 17] == 0                     # 0.85 m > inflation radius
    row = cost[20, 26:37].astype(int)
    assert np.all(np.diff(row) <= 0)                  # decreasing away from the obstacle


def test_occupancy_values_are_costmap_2ds():
    # ROS's costmap_2d publishes lethal 100, inscribed 99, the gradient 1-98, free 0, unknown -1
    cost = np.array([[0, 1, 2, 126, 252, INSCRIBED, LETHAL, 255]], dtype=np.uint8)
    assert occupancy_values(cost).tolist() == [[0, 1, 1, 49, 98, 99, 100, -1]]
    assert occupancy_values(cost).dtype == np.int8
    # monotone over the gradient
    assert np.all(np.diff(occupancy_values(np.arange(1, 253, dtype=np.uint8)[None])) >= 0)


def test_costmap_inflates_once_per_read_after_scans(monkeypatch):
    """Scans taken in between two reads of the grid cost one inflation (the full-grid EDT);
    cost_at a few points costs none, and both see the newest scan's obstacle."""
    import tiago_nav.nav.costmap as costmap_module
    calls = []
    real = costmap_module.inflate
    monkeypatch.setattr(costmap_module, 'inflate', lambda *a: calls.append(1) or real(*a))
    cm = Costmap(empty(60, 60))
    assert cm.cost[30, 20] == 0
    assert calls == [1]
    for _ in range(5):
        cm.add_scan(beam((0.5, 1.5), 1.0))
        cm.update()
        assert cm.cost_at([(1.5, 1.5)])[0] == LETHAL  # the beam's hit, 1 m ahead
    assert calls == [1]                               # only points read: no inflation
    assert cm.distance[30, 30] == pytest.approx(0.0)
    assert calls == [1, 1]


@pytest.mark.parametrize('seed', range(20))
def test_cost_at_matches_the_inflated_grid(seed):
    """cost_at without inflating (distances to the static layer and to the marked cells) gives
    exactly the costs of the full-grid inflation, inside and outside the grid."""
    rng = np.random.default_rng(seed)
    data = np.zeros((80, 120), dtype=np.int8)
    for _ in range(rng.integers(0, 4)):                 # some static walls (or none)
        r, c = rng.integers(0, 80), rng.integers(0, 120)
        data[r:r + rng.integers(1, 20), c:c + rng.integers(1, 4)] = 100
    cm = Costmap(GridMap(data, 0.05, (-1.0, -2.0)))
    marked = rng.random(data.shape) < rng.choice([0.0, 0.002, 0.02])
    cm.obstacles[:] = marked
    cm.update()
    xy = np.column_stack((rng.uniform(-1.5, 5.5, 500), rng.uniform(-2.5, 2.5, 500)))
    fast = cm.cost_at(xy)
    assert cm._inflated is None                         # it did not inflate
    rc = cm.grid.world_to_cell(xy)
    inside = cm.grid.in_bounds(rc)
    expected = np.full(len(xy), LETHAL, dtype=np.uint8)
    expected[inside] = cm.cost[rc[inside, 0], rc[inside, 1]]
    assert np.array_equal(fast, expected)
    assert np.array_equal(cm.cost_at(xy), expected)    # read from the inflated grid now


def beam(origin, r, angle=0.0, range_min=0.05, range_max=25.0):
    """A one-beam scan from a laser at ``origin`` pointing along ``angle``."""
    return MapScan((origin[0], origin[1], angle), np.array([r], dtype=float), 0.0, 0.01,
                   range_min, range_max)


def test_obstacle_marking_and_clearing():
    cm = Costmap(empty(60, 60), obstacle_range=4.0, raytrace_range=5.0)
    origin = (0.5, 1.5)
    cm.add_scan(beam(origin, 1.0))                    # a hit 1 m east of the laser
    cm.update()
    assert cm.cost_at([(1.5, 1.5)])[0] == LETHAL
    assert cm.cost_at([(1.5, 1.7)])[0] >= INSCRIBED   # inflated by the robot radius (0.2 m away)
    cm.add_scan(beam(origin, np.inf))                 # the beam now sees through: cleared
    cm.update()
    assert cm.cost_at([(1.5, 1.5)])[0] == 0
    cm.add_scan(beam(origin, 1.0))
    cm.clear_obstacles()
    assert cm.cost_at([(1.5, 1.5)])[0] == 0


@pytest.mark.parametrize('glitch', [np.nan, 0.0, 0.01, 30.0, -np.inf])
def test_glitch_beams_never_erase_an_obstacle(glitch):
    """REP 117: NaN, 0, below range_min and beyond range_max are invalid (do nothing); -inf is
    too close (clears nothing, marks the cell at range_min)."""
    cm = Costmap(empty(60, 60), obstacle_range=4.0, raytrace_range=5.0)
    origin = (0.5, 1.5)
    cm.add_scan(beam(origin, 1.0))
    cm.add_scan(beam(origin, glitch))
    cm.update()
    assert cm.obstacles[cm.grid.world_to_cell([(1.5, 1.5)])[0][0], 30]
    assert cm.cost_at([(1.5, 1.5)])[0] == LETHAL
    near = cm.grid.world_to_cell([(origin[0] + 0.05, origin[1])])[0]
    assert cm.obstacles[near[0], near[1]] == (glitch == -np.inf)


def test_no_return_clears_only_to_raytrace_range():
    cm = Costmap(empty(60, 100), obstacle_range=4.0, raytrace_range=2.0)
    origin = (0.5, 1.5)
    cm.add_scan(beam(origin, 1.0))
    cm.add_scan(beam(origin, 3.0))
    cm.add_scan(beam(origin, np.inf))
    cm.update()
    assert cm.cost_at([(1.5, 1.5)])[0] == 0           # within raytrace_range: cleared
    assert cm.cost_at([(3.5, 1.5)])[0] == LETHAL      # beyond it: kept


# --- planner -----------------------------------------------------------------------------
def test_optimal_length_on_empty_grid():
    cost = np.zeros((20, 30), dtype=np.uint8)
    cells = grid_path(cost, (2, 2), (2, 22), cost_weight=0.0)
    assert len(cells) == 21                           # straight: 20 steps
    cells = grid_path(cost, (0, 0), (10, 10), cost_weight=0.0)
    assert len(cells) == 11                           # pure diagonal


def test_no_path_through_a_wall():
    g = empty(60, 60)
    g.data[:, 30] = 100                               # a full-height wall
    cm = Costmap(g)
    with pytest.raises(PlanError, match='no path'):
        plan(cm, (0.5, 1.5), (2.5, 1.5))


def test_goal_in_obstacle_and_outside_rejected():
    g = empty(60, 60)
    g.data[30, 30] = 100
    cm = Costmap(g)
    with pytest.raises(PlanError, match='inside an obstacle'):
        plan(cm, (0.5, 0.5), (1.55, 1.6))             # 0.05 m from the occupied cell
    with pytest.raises(PlanError, match='outside the map'):
        plan(cm, (0.5, 0.5), (9.0, 1.0))


@pytest.mark.parametrize('seed', range(20))
def test_a_rejected_goal_names_the_layer_and_cell_that_block_it(seed):
    """"Inside an obstacle" says whether a wall of the map or a mark of the laser is within the
    robot's radius of the goal, and where: the nearest one, as the cost counts it; exactly the
    goals the planner rejects have one."""
    rng = np.random.default_rng(seed)
    g = empty(60, 60)
    g.data[30, 30] = 100                              # the map's cell, centre (1.525, 1.525)
    cm = Costmap(g)
    cm.add_scan(beam((0.5, 0.5), 1.0))                # a laser mark at (1.5, 0.5)
    cm.update()
    for goal in rng.uniform(0.3, 2.7, size=(40, 2)):
        found = cm.blocker(goal)
        blocked = cm.cost_at([goal])[0] >= INSCRIBED
        assert (found is not None) == blocked, (goal, found)
        if not blocked:
            plan(cm, (0.5, 2.5), goal)                # no PlanError
            continue
        (x, y), layer, d = found
        assert layer == ('map' if abs(x - 1.525) < 1e-9 and abs(y - 1.525) < 1e-9 else 'laser')
        centre = g.cell_to_world(g.world_to_cell([goal]))[0]
        assert d == pytest.approx(math.hypot(x - centre[0], y - centre[1]))
        assert d == pytest.approx(cm.distance[tuple(g.world_to_cell([goal])[0])])
        with pytest.raises(PlanError) as err:
            plan(cm, (0.5, 2.5), goal)
        text = str(err.value)
        assert 'inside an obstacle' in text and '(%.2f, %.2f)' % (x, y) in text
        assert ("the map's obstacle" in text) == (layer == 'map')
        assert ('the laser marked' in text and 'clear_costmaps' in text) == (layer == 'laser')


def test_plan_goes_around_a_wall_gap_and_keeps_clear():
    g = empty(60, 80)
    g.data[:45, 40] = 100                             # wall with a gap at the top
    cm = Costmap(g)
    p = plan(cm, (0.5, 0.5), (3.5, 0.5))
    assert np.hypot(*(p[-1] - (3.5, 0.5))) < 1e-9
    assert (cm.cost_at(p) < INSCRIBED).all()
    assert p[:, 1].max() > 45 * 0.05                  # went through the gap
    lower = 2 * math.hypot(1.5, 45 * 0.05 + 0.27 - 0.5)   # straight lines via the gap
    assert lower < path_length(p) < 1.3 * lower


def test_shipped_world_corridor_is_found():
    from tiago_nav.sim.raster import rasterise_world
    from tiago_nav.sim.world import load_world
    w = load_world(os.path.join(WORLDS, 'ias_lab_room_full.yaml'))
    cm = Costmap(rasterise_world(w))
    p = plan(cm, w.start_pose[:2], w.corridor.exit)
    inside = (p[:, 0] > w.corridor.entry[0] + 0.5) & (p[:, 0] < w.corridor.exit[0] - 1.0)
    assert inside.any()
    assert np.abs(p[inside, 1] - w.corridor.entry[1]).max() < 0.1     # keeps to the middle
    assert path_length(p) < 1.05 * math.hypot(*np.subtract(w.corridor.exit, w.start_pose[:2]))


# --- controller: closed loop on a kinematic unicycle with the base's limits --------------
@pytest.mark.parametrize('goal', [(3.0, 1.0, 1.5), (-2.0, 0.5, math.pi), (0.3, -2.0, -0.5)])
def test_controller_converges_to_pose(goal):
    from tiago_nav.sim.diffdrive import BaseLimits, DiffDrive
    from tiago_nav.nav.planner import densify
    base = DiffDrive((0.0, 0.0, 0.0), BaseLimits())
    ctl = Controller(ControllerConfig())
    ctl.set_path(densify([(0.0, 0.0), goal[:2]], 0.05))
    dt = 0.1
    for _ in range(400):
        v, w, phase = ctl.command(base.pose, goal, np.zeros((0, 2)), dt)
        if phase == 'arrived':
            break
        for _ in range(6):
            base.step(v, w, dt / 6)
    x, y, yaw = base.pose
    assert phase == 'arrived'
    assert math.hypot(x - goal[0], y - goal[1]) <= 0.15
    assert abs(math.atan2(math.sin(yaw - goal[2]), math.cos(yaw - goal[2]))) <= 0.1


def test_controller_stops_before_an_obstacle():
    from tiago_nav.sim.diffdrive import BaseLimits, DiffDrive
    from tiago_nav.nav.planner import densify
    base = DiffDrive((0.0, 0.0, 0.0), BaseLimits())
    ctl = Controller(ControllerConfig())
    ctl.set_path(densify([(0.0, 0.0), (5.0, 0.0)], 0.05))
    wall = np.column_stack((np.full(21, 2.0), np.linspace(-0.5, 0.5, 21)))   # across the path
    dt = 0.1
    for _ in range(100):
        v, w, _ = ctl.command(base.pose, (5.0, 0.0, 0.0), wall, dt)
        for _ in range(6):
            base.step(v, w, dt / 6)
        assert 2.0 - base.pose[0] > 0.27             # never touches
    assert abs(base.v) < 0.05                         # and has stopped


@pytest.mark.parametrize('ahead', [1.2, 1.5, 1.8])
def test_braking_for_an_obstacle_commands_only_speeds_the_base_can_reach(ahead):
    # at full speed something appears ahead, near enough that full speed is unsafe: the
    # controller slows down, and each command is one the base can reach from its measured
    # speed within the cycle (its collision check assumes the base runs at the command; a
    # base still faster than that stops later than the check assumed)
    from tiago_nav.sim.diffdrive import BaseLimits, DiffDrive
    from tiago_nav.nav.planner import densify
    limits = BaseLimits()
    base = DiffDrive((0.0, 0.0, 0.0), limits)
    ctl = Controller(ControllerConfig())
    ctl.set_path(densify([(0.0, 0.0), (20.0, 0.0)], 0.05))
    dt = 0.1
    wall = np.zeros((0, 2))
    slowed = False
    for _ in range(150):
        if wall.size == 0 and base.v > 0.99 * limits.max_linear_velocity:
            x = base.pose[0] + ctl.c.robot_radius + ahead
            wall = np.column_stack((np.full(21, x), np.linspace(-0.5, 0.5, 21)))
        before = base.v
        v, w, _ = ctl.command(base.pose, (20.0, 0.0, 0.0), wall, dt)
        assert v >= before - limits.max_linear_acceleration * dt - 1e-9, \
            'commanded %.2f m/s from %.2f m/s in %.1f s' % (v, before, dt)
        slowed |= wall.size > 0 and v < before - 1e-6
        for _ in range(6):
            base.step(v, w, dt / 6)
        if wall.size:
            assert wall[0, 0] - base.pose[0] > ctl.c.robot_radius      # never touches
    assert slowed and abs(base.v) < 0.05                # it braked and has stopped


def test_within_its_margins_the_base_may_drive_out_but_not_further_in():
    # a person's point 0.25 m beyond the footprint, with their 0.3 m margin: the base stands
    # within it. Driving away from them, or past them (the gap growing), passes the check;
    # towards them, or on a line that brings it nearer, does not
    ctl = Controller(ControllerConfig())
    r = ctl.c.robot_radius
    person = np.array([[0.0, r + 0.25]])                 # to the base's left
    margin = np.array([0.3])
    for yaw, ok in ((-math.pi / 2, True), (0.0, True), (math.pi / 2, False), (0.5, False)):
        assert ctl.safe((0.0, 0.0, yaw), 0.3, 0.0, person, 0.1, margins=margin) is ok, yaw
    # out of the margins, a command must keep out of them, as before
    assert ctl.safe((0.0, -0.2, 0.0), 0.3, 0.0, person, 0.1, margins=margin)
    assert not ctl.safe((0.0, -0.2, math.pi / 2), 0.3, 0.0, person, 0.1, margins=margin)


def test_a_remembered_cell_counts_as_near_as_any_part_of_it():
    # a map cell remembered for a direction the laser cannot see (the base hides the fan's
    # ends) may hold its surface half a diagonal nearer than its centre: with that margin a
    # creep towards it is unsafe, as it is for a hit seen that near
    ctl = Controller(ControllerConfig())
    c = ctl.c
    pose = (0.0, 0.0, 0.0)
    centre = np.array([[c.robot_radius + c.safety_margin + 0.1, 0.0]])
    creep = 0.05
    reach = creep * (0.1 + 0.1 + creep / c.decel_x)        # how far the creep's check looks
    assert ctl.safe(pose, creep, 0.0, centre, 0.1)
    half_diagonal = 0.05 / math.sqrt(2.0)
    seen = centre - [[0.1 - reach + 0.001, 0.0]]
    assert not ctl.safe(pose, creep, 0.0, seen, 0.1)
    near = centre - [[half_diagonal, 0.0]]
    margin = np.array([0.1 - reach + 0.001 - half_diagonal])
    assert not ctl.safe(pose, creep, 0.0, near, 0.1, margins=margin)
    assert ctl.safe(pose, creep, 0.0, near, 0.1, margins=np.zeros(1))


def test_navigator_remembers_hidden_cells_with_half_their_diagonal():
    from tiago_nav.nav.navigator import Navigator
    nav = Navigator(empty(120, 120))
    nav.costmap.obstacles[60, 70] = True                 # a mark 0.5 m to the right of the laser
    x0, y0 = nav.costmap.grid.cell_to_world([(60, 60)])[0]
    n = 181
    ranges = np.full(n, 3.0)
    ranges[:20] = 0.01                                    # the fan's right end: the base
    nav.add_scan(MapScan((x0, y0, math.pi / 2), ranges, -math.pi / 2, math.pi / (n - 1), 0.05,
                         25.0))
    mark = nav.costmap.grid.cell_to_world([(60, 70)])[0]
    hit = np.hypot(*(nav.points - mark).T) < 1e-9
    assert hit.sum() == 1
    assert nav.margins[hit][0] == pytest.approx(nav.costmap.grid.resolution / math.sqrt(2.0))
    assert np.all(nav.margins[~hit] == 0.0)


def test_a_scan_clears_marked_cells_before_its_hits_and_keeps_those_behind():
    """A 666-beam fan facing a wall 2 m away (every beam hits it): marks left in front of the
    wall (an obstacle that moved away) are cleared, except within one cell of the wall; marks
    behind the wall and outside the fan are kept."""
    cm = Costmap(empty(120, 120), obstacle_range=4.0, raytrace_range=5.0)
    x0, y0 = 1.0, 3.0
    n = 666
    angles = np.linspace(-1.0, 1.0, n)
    ranges = 2.0 / np.cos(angles)                      # the wall x = x0 + 2
    rng = np.random.default_rng(3)
    cm.obstacles[:] = rng.random(cm.obstacles.shape) < 0.05
    before = cm.obstacles.copy()
    cm.add_scan(MapScan((x0, y0, 0.0), ranges, -1.0, 2.0 / (n - 1), 0.05, 25.0))
    centres = cm.grid.cell_to_world(np.argwhere(before))
    rc = np.argwhere(before)
    dx, dy = centres[:, 0] - x0, centres[:, 1] - y0
    bearing = np.arctan2(dy, dx)
    inside = (np.abs(bearing) < 0.98) & (np.hypot(dx, dy) > 0.1)
    ahead = inside & (dx < 2.0 - 0.08)                 # clearly in front of the wall
    behind = dx > 2.0 + 0.05
    kept = cm.obstacles[rc[:, 0], rc[:, 1]]
    assert ahead.sum() > 100 and not kept[ahead].any()
    assert kept[behind].all() and kept[np.abs(bearing) > 1.1].all()


@pytest.mark.parametrize('seed', range(5))
def test_planning_graph_has_exactly_the_allowed_steps(seed):
    """The graph's edges, cell by cell: into every passable 8-neighbour of a passable cell, no
    diagonal between two blocked cells, weight = step length (cells) x (1 + w cost / 252) of
    the cell entered."""
    from tiago_nav.nav.planner import build_graph
    rng = np.random.default_rng(seed)
    rows, cols = 7, 9
    cost = rng.integers(0, 256, (rows, cols)).astype(np.uint8)
    passable = cost < INSCRIBED
    g = build_graph(cost, 1.5).tocoo()
    got = {(int(i), int(j)): w for i, j, w in zip(g.row, g.col, g.data)}
    want = {}
    for r in range(rows):
        for c in range(cols):
            for dr in (-1, 0, 1):
                for dc in (-1, 0, 1):
                    rr, cc = r + dr, c + dc
                    if (dr, dc) == (0, 0) or not (0 <= rr < rows and 0 <= cc < cols):
                        continue
                    if not (passable[r, c] and passable[rr, cc]):
                        continue
                    if dr and dc and not (passable[rr, c] or passable[r, cc]):
                        continue
                    want[(r * cols + c, rr * cols + cc)] = \
                        math.hypot(dr, dc) * (1 + 1.5 * float(cost[rr, cc]) / 252)
    assert got.keys() == want.keys()
    assert all(got[k] == pytest.approx(want[k], rel=1e-12) for k in want)


def test_a_scan_leaves_no_mark_on_the_robots_footprint():
    """Hits on the robot's footprint (a mixed pixel or noise at the body) are not kept as
    marks: the robot would be touching them, and a mark left there when the robot drives on
    later rejects goals near that place. Marks outside the footprint stay."""
    base = (1.5, 1.5)

    def marks(laser_in_base):
        cm = Costmap(empty(60, 60), robot_radius=0.27)
        # a laser 0.2 m ahead of the base centre: one beam straight ahead 0.06 m (a point 0.26
        # m from the centre), one at 1.2 rad 0.6 m (0.70 m from it); one beam per scan
        for a, r in ((0.0, 0.06), (1.2, 0.6)):
            cm.add_scan(MapScan((base[0] + 0.2, base[1], a), np.array([r]), 0.0, 0.01, 0.05,
                                25.0, laser_in_base=(0.2, 0.0, a) if laser_in_base else None))
        pts = cm.grid.cell_to_world(np.argwhere(cm.obstacles))
        return np.hypot(pts[:, 0] - base[0], pts[:, 1] - base[1])

    d = marks(True)
    assert len(d) == 1 and d[0] == pytest.approx(0.70, abs=0.04)
    d = marks(False)                       # without the laser's pose in the base: no footprint
    assert len(d) == 2 and d.min() < 0.27 + 0.025
