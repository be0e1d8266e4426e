"""Walkers and movable shapes in the simulator without ROS: walkers follow their paths at their
speed after their delay, the laser sees their two legs (and a table's legs, not its top), a
walker stops for the robot, the robot bumping into a leg is a collision, and runs repeat."""
import math

import numpy as np
import pytest

from tiago_nav.sim.simulator import SimConfig, Simulator
from tiago_nav.sim.walkers import KEEPOUT, LEG_RADIUS, PATIENCE, Path, Walkers, legs_at
from tiago_nav.sim.world import Walker, World

ROOM = {'name': 'walk', 'resolution': 0.05, 'bounds': [-5, -5, 5, 5], 'robot_start': [0, 0, 0]}


def make(walkers=(), movable=(), start=(0, 0, 0), **cfg):
    world = World.from_dict(dict(ROOM, robot_start=list(start), walkers=list(walkers),
                                 movable_obstacles=list(movable)))
    return Simulator(world, SimConfig(laser_noise=0.0, **cfg))


def run(sim, seconds, v=None, w=0.0):
    for _ in range(int(round(seconds * sim.config.rate))):
        if v is not None:
            sim.command(v, w)
        sim.step()


def test_path_positions_loop_and_end():
    p = Path([(0, 0), (2, 0), (2, 1)], loop=False)
    assert p.total == pytest.approx(3.0)
    assert p.at(1.0)[:2] == pytest.approx((1.0, 0.0)) and p.at(1.0)[2] == pytest.approx(0.0)
    assert p.at(2.5)[:2] == pytest.approx((2.0, 0.5)) and p.at(2.5)[2] == pytest.approx(math.pi / 2)
    assert p.at(10.0)[:2] == pytest.approx((2.0, 1.0)) and p.finished(3.0)
    q = Path([(0, 0), (2, 0), (2, 1)], loop=True)
    assert q.total == pytest.approx(3.0 + math.sqrt(5.0)) and not q.finished(100.0)
    assert q.at(q.total + 1.0)[:2] == pytest.approx((1.0, 0.0))


def test_legs_swing_in_opposite_phase_about_the_walking_line():
    still = legs_at(1.0, 2.0, 0.0, 0.0)
    assert np.allclose(still, [[1.0, 2.1], [1.0, 1.9]])
    quarter = legs_at(1.0, 2.0, 0.0, 0.35)                  # a quarter of a 1.4 m stride
    assert np.allclose(quarter, [[1.2, 2.1], [0.8, 1.9]])


def test_walker_walks_at_its_speed_after_its_delay_and_stops_at_the_end():
    sim = make([{'path': [[2, 3], [-2, 3]], 'speed': 1.0, 'start_delay': 1.0}])
    try:
        run(sim, 1.0)
        assert sim.walkers.pose(0)[:2] == pytest.approx((2.0, 3.0))
        assert sim.walkers.state(0, sim.time) == 'walking'
        run(sim, 1.5)
        assert sim.walkers.pose(0)[:2] == pytest.approx((0.5, 3.0), abs=1e-9)
        assert sim.walkers.velocity[0] == pytest.approx((-1.0, 0.0))
        run(sim, 3.0)
        assert sim.walkers.pose(0)[:2] == pytest.approx((-2.0, 3.0))
        assert sim.walkers.velocity[0] == (0.0, 0.0) and sim.walkers.state(0, sim.time) == 'arrived'
    finally:
        sim.close()


def test_a_scene_shows_no_walker_until_it_is_placed():
    # a bare scene (the evaluator's, inview.view's) holds the walkers' leg bodies from the
    # start: none may stand anywhere a beam reaches before they are placed, not even at the
    # world's origin the bodies are built about
    from tiago_nav.sim.scene import Scene
    world = World.from_dict(dict(ROOM, robot_start=[1.0, 0.0, 180.0],
                                 walkers=[{'path': [[3, 3], [3, -3]], 'speed': 0.5}] * 2))
    with Scene(world) as scene:
        legs = set(b for pair in scene.walker_leg_ids for b in pair)
        ranges, ids = scene.cast()
        assert not legs & set(ids.tolist())
        scene.set_walker_legs(1, [[0.0, 0.1], [0.0, -0.1]])
        ranges, ids = scene.cast()
        assert set(ids.tolist()) & legs == set(scene.walker_leg_ids[1])


def test_laser_sees_a_walkers_two_legs_where_they_are():
    sim = make([{'path': [[2, 1], [2, -1]], 'speed': 0.5}])
    try:
        for _ in range(3):
            run(sim, 0.5)
            ranges, ids = sim.scene.cast()
            legs = sim.walkers.legs(0)
            for body, (x, y) in zip(sim.scene.walker_leg_ids[0], legs):
                hit = ids == body
                assert hit.sum() >= 3
                # the nearest return of a leg is its surface facing the laser
                lx, ly, _ = sim.scene.laser_pose()
                assert ranges[hit].min() == pytest.approx(math.hypot(x - lx, y - ly) - LEG_RADIUS,
                                                          abs=2e-3)
    finally:
        sim.close()


def test_laser_sees_table_legs_and_box_faces_not_the_table_top():
    sim = make(movable=[{'shape': 'table', 'x': 2.0, 'y': 0.0, 'length': 1.0, 'width': 0.6},
                        {'shape': 'box', 'x': -2.0, 'y': 2.0, 'length': 1.0, 'width': 0.5}],
               start=(0, 0, 0))
    try:
        ranges, ids = sim.scene.cast()
        table, box = sim.scene.movable_ids
        angles = sim.config.laser.angles()
        lx = sim.scene.laser_pose()[0]
        hit = ids == table
        assert hit.sum() > 0
        # every return of the table is on a leg (the near legs at x = 1.5 - 0.03), none in between
        pts = np.column_stack((lx + ranges[hit] * np.cos(angles[hit]), ranges[hit] * np.sin(angles[hit])))
        legs = sim.world.movable_obstacles[0].legs()
        d = np.min(np.hypot(pts[:, None, 0] - legs[None, :, 0], pts[:, None, 1] - legs[None, :, 1]), axis=1)
        assert d.max() == pytest.approx(0.03, abs=2e-3)
        # straight ahead, between the legs, the beam passes under the top
        assert math.isinf(ranges[np.argmin(np.abs(angles))])
        # the box is behind the laser's fan (at 135 deg): turn to it and see its face
        sim.scene.set_robot_pose((0.0, 0.0, math.radians(135)))
        ranges, ids = sim.scene.cast()
        assert (ids == box).sum() > 10
    finally:
        sim.close()


def test_a_walker_stops_for_the_robot_and_walks_round_it_after_its_patience():
    # the walker's path crosses the robot's position in an open room; the robot stands still
    sim = make([{'path': [[3, 0], [-3, 0]], 'speed': 1.0}])
    try:
        closest, stood, walked_round = math.inf, 0, False
        for _ in range(int(12.0 * sim.config.rate)):
            sim.step()
            legs = sim.walkers.legs(0)
            closest = min(closest, float(np.hypot(legs[:, 0], legs[:, 1]).min()))
            if sim.walkers.state(0, sim.time) == 'yielding':
                assert sim.walkers.velocity[0] == (0.0, 0.0)
                stood += 1
            x, y, _ = sim.walkers.pose(0)
            walked_round |= abs(y) > 0.5
        # it stopped short (no nearer than one step of 1 m/s), stood for its patience, and
        # went round off its line to the end of its path
        assert stood / sim.config.rate == pytest.approx(PATIENCE, abs=1.5 / sim.config.rate)
        assert walked_round
        assert sim.walkers.pose(0)[:2] == pytest.approx((-3.0, 0.0))
        assert sim.walkers.state(0, sim.time) == 'arrived'
        # its legs never came within 0.4 m of the robot's body (the bar for the robot is 0.3 m)
        assert closest - sim.config.robot_radius - LEG_RADIUS >= 0.4 - 1e-9
        assert sim.collisions == 0
    finally:
        sim.close()


def test_a_walker_the_robot_came_near_steps_back_before_walking_round():
    # the walker stops for the robot standing still; the robot then drives towards it
    # and stops: the walker steps back and walks round, its legs never nearer than they stood
    sim = make([{'path': [[3, 0], [-3, 0]], 'speed': 1.0}])
    try:
        run(sim, 2.2)
        assert sim.walkers.state(0, sim.time) == 'yielding'
        run(sim, 0.8, v=0.6)
        run(sim, 0.7, v=0.0)                                # braked to a stop, before the
        assert sim.walkers.state(0, sim.time) == 'yielding'  # walker's patience ran out

        def gap():
            legs = sim.walkers.legs(0)
            x, y, _ = sim.pose
            return float(np.hypot(legs[:, 0] - x, legs[:, 1] - y).min()) - sim.config.robot_radius - LEG_RADIUS
        stood = gap()
        assert stood < 0.4                                   # the robot's doing
        least = math.inf
        for _ in range(int(12.0 * sim.config.rate)):
            sim.step()
            least = min(least, gap())
        assert least >= stood - 1e-9
        assert sim.walkers.pose(0)[:2] == pytest.approx((-3.0, 0.0))
        assert sim.collisions == 0
    finally:
        sim.close()


def test_a_walker_whose_way_round_runs_out_of_room_goes_back_and_on_later():
    # walls at y = 1.25 and y = -1.5 (their gap to a point, as world.clearance gives it): no
    # room above the robot at (0, 0), room below; walking round below, the robot moves 0.4 m
    # down and the way round has no room either: the walker goes back to where it left its
    # path, and once the robot's new place leaves room above, walks round there to its end
    walkers = Walkers([Walker(path=[(3.0, 0.0), (-3.0, 0.0)], speed=1.0, loop=False, start_delay=0.0)],
                      lambda xy: float(np.min(np.minimum(1.25 - xy[:, 1], xy[:, 1] + 1.5))))
    dt, radius, robot = 1.0 / 60, 0.27, (0.0, 0.0)
    left, lowest, back, closest = None, 0.0, False, math.inf
    for k in range(int(20.0 / dt)):
        walkers.step(k * dt, dt, robot, radius)
        x, y, _ = walkers.pose(0)
        if left is None and walkers.rounding[0] is not None:
            left = walkers.s[0]
        lowest = min(lowest, y)
        if lowest < -0.5 and robot == (0.0, 0.0):
            robot = (0.0, -0.4)                     # the robot moves down, under the walker
        if walkers.rounding[0] is not None and walkers.rounding[0][2]:
            back = True
        if robot == (0.0, 0.0):                     # before the robot moved at it
            legs = walkers.legs(0)
            closest = min(closest, float(np.hypot(legs[:, 0], legs[:, 1]).min()))
    assert left is not None and back
    assert walkers.pose(0)[:2] == pytest.approx((-3.0, 0.0))
    assert walkers.state(0, 20.0) == 'arrived'
    assert closest - radius - LEG_RADIUS >= 0.4 - 1e-9


def test_a_walker_with_no_room_to_walk_round_waits_until_the_robot_has_gone():
    # the walker comes out of a 2 m corridor (x 0.5-4, walls at y = +-1) towards the robot
    # standing at its mouth: the corridor's walls leave no room for a way round the robot
    walls = [{'x': 2.25, 'y': y, 'length': 3.5, 'width': 0.1} for y in (-1.05, 1.05)]
    world = World.from_dict(dict(ROOM, walls=walls, walkers=[{'path': [[3, 0], [-3, 0]], 'speed': 1.0}]))
    sim = Simulator(world, SimConfig(laser_noise=0.0))
    try:
        run(sim, 8.0)
        x, y, _ = sim.walkers.pose(0)
        gap = math.hypot(x, y) - sim.config.robot_radius
        assert y == 0.0 and KEEPOUT <= gap < KEEPOUT + 1.0 / sim.config.rate   # one step short
        assert sim.walkers.state(0, sim.time) == 'yielding' and sim.walkers.velocity[0] == (0.0, 0.0)
        # the robot turns and drives out of the way (along +y); the walker goes on
        run(sim, 2.0, v=0.0, w=math.pi / 4)
        run(sim, 3.0, v=0.5)
        run(sim, 6.0)
        assert sim.walkers.pose(0)[:2] == pytest.approx((-3.0, 0.0))
        assert sim.collisions == 0
    finally:
        sim.close()


def test_the_robot_driving_into_a_walker_is_a_collision():
    sim = make([{'path': [[1.5, 0.3], [1.5, -0.3]], 'speed': 0.2}])
    try:
        run(sim, 5.0, v=0.5)
        assert sim.collisions == 1
        assert sim.pose[0] < 1.5 - LEG_RADIUS - sim.config.robot_radius + 0.3
    finally:
        sim.close()


def test_walkers_repeat_exactly_and_a_new_simulator_puts_them_back():
    walkers = [{'path': [[3, 2], [-3, 2], [-3, -2]], 'speed': 1.1, 'loop': True, 'start_delay': 0.5},
               {'path': [[-2, -3], [2, -3]], 'speed': 0.7, 'loop': True}]

    def trace():
        sim = make(walkers)
        try:
            out = []
            for _ in range(4):
                run(sim, 2.5, v=0.3, w=0.2)
                out.append([sim.walkers.legs(i).tolist() for i in range(2)] + [sim.pose])
            start = [sim.walkers.legs(i).tolist() for i in range(2)]
            return out, start
        finally:
            sim.close()
    a, _ = trace()
    b, _ = trace()
    assert a == b
    fresh = make(walkers)
    try:
        assert [fresh.walkers.legs(i).tolist() for i in range(2)] == \
            [legs_at(3, 2, math.pi, 0.0).tolist(), legs_at(-2, -3, 0.0, 0.0).tolist()]
    finally:
        fresh.close()


def test_a_robot_start_on_a_walkers_legs_is_refused():
    with pytest.raises(ValueError, match='overlaps an obstacle'):
        make([{'path': [[0.1, 0.0], [3, 0]], 'speed': 1.0}])
