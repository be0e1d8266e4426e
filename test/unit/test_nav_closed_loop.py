"""Closed-loop tests of the navigation library (the goal runner the move_base node runs)
driving the simulator without ROS (tiago_nav_tools.testing.navigation): ground truth is the
simulator's pose and contact count."""
import math
import os

import numpy as np
import pytest

from conftest import WORLDS
from tiago_nav.nav.navigator import ABORTED, SUCCEEDED, Navigator, NavConfig
from tiago_nav.nav.planner import PlanError
from tiago_nav.sim.raster import rasterise_world
from tiago_nav.sim.world import World, load_world
from tiago_nav.nodes.navigation import Params as NavParams
from tiago_nav.params import read_params
from tiago_nav_tools.testing import navigation as simnav
from tiago_nav_tools.testing.navigation import ClosedLoop

# needs ROS: the node's Params: tiago_nav.nodes.navigation imports rospy
pytestmark = pytest.mark.ros


def drive(world, goal, start=None, limit=60.0):
    loop = ClosedLoop(world, start=start)
    try:
        return loop.run_goal(goal, limit)
    finally:
        loop.close()


def test_reaches_a_goal_behind_an_unmapped_cylinder():
    # open floor, a movable cylinder right on the straight line from start to goal
    w = World.from_dict(dict(name='t', resolution=0.05, bounds=[-1, -2, 6, 2], robot_start=[0, 0, 0],
                             walls=[], static_cylinders=[],
                             movable_obstacles=[dict(x=2.5, y=0.0, radius=0.25)]))
    r = drive(w, (5.0, 0.0, math.pi / 2))
    assert r['state'] == SUCCEEDED, r['reason']
    x, y, yaw = r['pose']
    assert math.hypot(x - 5.0, y) <= 0.15
    assert abs(math.atan2(math.sin(yaw - math.pi / 2), math.cos(yaw - math.pi / 2))) <= 0.1
    assert r['collisions'] == 0
    assert r['closest'] > 0.27                         # went around, not through


def test_drives_the_shipped_corridor_without_contact():
    w = load_world(os.path.join(WORLDS, 'ias_lab_room_full.yaml'))
    ex, ey = w.corridor.exit
    r = drive(w, (ex, ey, 0.0))
    assert r['state'] == SUCCEEDED, r['reason']
    assert math.hypot(r['pose'][0] - ex, r['pose'][1] - ey) <= 0.15
    assert r['collisions'] == 0
    length = math.hypot(ex - w.start_pose[0], ey - w.start_pose[1])
    assert r['time'] < 1.3 * length / 1.0 + 1.5       # fast in the straight corridor (sim time)


def test_path_closed_by_an_unmapped_obstacle_aborts_with_no_path():
    # a corridor the map shows open, closed by a movable cylinder the laser will see
    walls = [dict(x=3.0, y=0.6, length=6.0, width=0.15, yaw_deg=0),
             dict(x=3.0, y=-0.6, length=6.0, width=0.15, yaw_deg=0),
             dict(x=6.05, y=0.0, length=1.35, width=0.15, yaw_deg=90)]
    w = World.from_dict(dict(name='t', resolution=0.05, bounds=[-0.5, -1, 6.5, 1], robot_start=[0.5, 0, 0],
                             walls=walls, static_cylinders=[],
                             movable_obstacles=[dict(x=3.0, y=0.0, radius=0.3)]))
    r = drive(w, (5.0, 0.0, 0.0), limit=90.0)
    assert r['state'] == ABORTED
    assert 'no path' in r['reason'] or 'stuck' in r['reason']
    assert r['collisions'] == 0


def test_goal_in_wall_rejected_before_moving():
    w = load_world(os.path.join(WORLDS, 'ias_lab_room_full.yaml'))
    nav = Navigator(rasterise_world(w), NavConfig())
    wall = w.walls[5]
    with pytest.raises(PlanError, match='inside an obstacle'):
        nav.start((wall.x, wall.y, 0.0), w.start_pose, 0.0)


@pytest.mark.parametrize('value', [np.nan, 0.0])
def test_glitch_bursts_ahead_do_not_erase_an_unmapped_cylinder(value):
    """Every other scan loses the 120 middle beams (NaN or 0, REP 117 invalid) while the robot
    drives at a cylinder the map does not have: it still goes around without contact."""
    w = World.from_dict(dict(name='t', resolution=0.05, bounds=[-1, -2, 6, 2], robot_start=[0, 0, 0],
                             walls=[], static_cylinders=[],
                             movable_obstacles=[dict(x=2.5, y=0.0, radius=0.25)]))
    loop = ClosedLoop(w)
    count = [0]

    def burst(r):
        count[0] += 1
        if count[0] % 2:
            mid = len(r) // 2
            r[mid - 60:mid + 60] = value
        return r
    loop.scan_filter = burst
    try:
        r = loop.run_goal((5.0, 0.0, 0.0), 60.0)
        cm = loop.nav.costmap
        rc = cm.grid.world_to_cell([(2.5, 0.0)])[0]
        marked = cm.obstacles[rc[0] - 6:rc[0] + 7, rc[1] - 6:rc[1] + 7].any()
    finally:
        loop.close()
    assert r['state'] == SUCCEEDED, r['reason']
    assert r['collisions'] == 0
    assert r['closest'] > 0.27
    assert marked, 'the cylinder vanished from the obstacle layer'


def test_dead_laser_stops_the_robot_and_aborts():
    """The laser dies 2 s into a goal through the shipped corridor: the base is stopped (true
    speed ~0 within 1.5 s) and the goal aborts with 'no laser data', without contact."""
    w = load_world(os.path.join(WORLDS, 'ias_lab_room_full.yaml'))
    loop = ClosedLoop(w)
    speeds = []

    def kill():
        loop.laser_dead = loop.sim.time >= 2.0
        speeds.append((loop.sim.time, abs(loop.sim.velocity[0])))
    loop.on_control.append(kill)
    try:
        r = loop.run_goal((*w.corridor.exit, 0.0), 60.0)
    finally:
        loop.close()
    assert r['state'] == ABORTED
    assert r['reason'].startswith('no laser data for 3.'), r['reason']
    assert max(v for t, v in speeds if t >= 2.0 + 0.5 + 1.5) < 0.01
    assert max(v for t, v in speeds if t < 2.0) > 0.5          # it was driving before
    assert r['collisions'] == 0



OPEN = dict(name='open', resolution=0.05, bounds=[-1, -2, 6, 2], robot_start=[0, 0, 0], walls=[])


def test_the_double_uses_the_node_s_frames():
    p = read_params(NavParams, lambda name, default: default)
    assert (simnav.MAP, simnav.ODOM, simnav.BASE) == (p.global_frame, p.odom_frame,
                                                      p.robot_base_frame)


def test_a_goal_in_a_frame_without_a_transform_is_rejected_as_the_node_rejects_it():
    """The node answers a goal whose frame tf does not know 'goal rejected: no transform ...'
    (a GoalError), and does not move: not an 'unexpected error'."""
    loop = ClosedLoop(World.from_dict(OPEN))
    try:
        r = loop.run_goal((2.0, 0.0, 0.0), 10.0, frame='base_laser_link')
    finally:
        loop.close()
    assert r['state'] == ABORTED
    assert r['reason'].startswith('goal rejected: no transform base_laser_link -> map: '), r['reason']
    assert r['time'] < 0.2 + 1e-9 and r['collisions'] == 0


@pytest.mark.parametrize('frame', ['/map', '', 'odom'])
def test_goals_in_the_frames_the_node_knows_are_reached(frame):
    loop = ClosedLoop(World.from_dict(OPEN), start=(0.0, 0.0, 0.0))
    try:
        r = loop.run_goal((2.0, 0.5, 0.0), 30.0, frame=frame)
    finally:
        loop.close()
    assert r['state'] == SUCCEEDED, r['reason']
    assert math.hypot(r['pose'][0] - 2.0, r['pose'][1] - 0.5) <= NavConfig().controller.xy_goal_tolerance


def test_a_lost_pose_stops_the_base_and_aborts_naming_the_transform():
    """tf map -> base_footprint stops 1 s into a goal: the node's io fails with
    PoseUnavailable; the runner stops the base and aborts after sensor_abort_timeout."""
    cfg = NavConfig()
    loop = ClosedLoop(World.from_dict(OPEN))
    speeds = []

    def lose():
        loop.pose_lost = loop.sim.time >= 1.0
        speeds.append((loop.sim.time, abs(loop.sim.velocity[0])))
    loop.on_control.append(lose)
    try:
        r = loop.run_goal((4.5, 0.0, 0.0), 30.0)
    finally:
        loop.close()
    assert r['state'] == ABORTED
    assert 'no odometry/pose' in r['reason'] and 'no transform map -> base_footprint' in r['reason']
    assert r['time'] == pytest.approx(1.0 + cfg.sensor_abort_timeout, abs=0.35)
    assert max(v for t, v in speeds if t < 1.0) > 0.3            # it was driving before
    assert max(v for t, v in speeds if t >= 1.0 + cfg.sensor_timeout + 1.0) < 0.01


def _course_loop(marks, config=None):
    """The shipped course world, the robot at its start, and laser marks at ``marks`` (map
    points) where the world has nothing: phantoms, e.g. mixed pixels no later beam crossed.
    Beyond raytrace_range (5 m) from the start: no beam can clear them before the goal."""
    loop = ClosedLoop(load_world(os.path.join(WORLDS, 'ias_lab_room_full.yaml')), config=config)
    cm = loop.nav.costmap
    for r, c in cm.grid.world_to_cell(marks):
        cm.obstacles[r, c] = True
    cm.update()
    return loop


@pytest.mark.parametrize('reset_distance, reached', [(3.0, True), (100.0, False)])
def test_a_goal_covered_only_by_far_phantom_marks_is_driven_to(reset_distance, reached):
    """A mark 5.4 m ahead, 0.15 m from the goal: the goal is not rejected on it; the marks
    farther than reset_distance are forgotten and the goal reached. (With a reset_distance
    beyond the mark the goal is rejected on it, as before.)"""
    loop = _course_loop([(5.4, 0.15)], NavConfig(reset_distance=reset_distance))
    try:
        r = loop.run_goal((5.4, 0.0, 0.0), 60.0)
        forgot = loop.nav.reset_forgot
    finally:
        loop.close()
    if reached:
        assert r['state'] == SUCCEEDED, r['reason']
        assert math.hypot(r['pose'][0] - 5.4, r['pose'][1]) <= 0.15 and r['collisions'] == 0
        assert forgot >= 1
    else:
        assert r['state'] == ABORTED and 'the laser marked at (5.4' in r['reason'], r['reason']


def test_a_goal_covered_by_a_near_mark_or_a_wall_is_rejected_at_once():
    nav = Navigator(rasterise_world(load_world(os.path.join(WORLDS, 'ias_lab_room_full.yaml'))),
                    NavConfig())
    cm = nav.costmap
    r, c = cm.grid.world_to_cell([(1.5, 0.15)])[0]
    cm.obstacles[r, c] = True                          # 1.5 m from the robot: within reach
    cm.update()
    with pytest.raises(PlanError, match='the laser marked at'):
        nav.start((1.5, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0)
    assert cm.obstacles[r, c]                          # kept: the laser sees that place
    with pytest.raises(PlanError, match="the map's obstacle"):
        nav.start((3.0, 0.62, 0.0), (0.0, 0.0, 0.0), 0.0)


@pytest.mark.parametrize('reset_distance, reached', [(3.0, True), (100.0, False)])
def test_far_marks_closing_the_only_way_are_forgotten_after_planner_patience(reset_distance,
                                                                             reached):
    """Marks across the corridor 5.4 m ahead close the only way to a goal past it: after
    planner_patience without a plan, the marks farther than reset_distance are forgotten
    (once per goal) and the robot drives there; when none is that far, the goal aborts."""
    marks = [(5.4, y) for y in np.arange(-0.6, 0.61, 0.05)]
    loop = _course_loop(marks, NavConfig(reset_distance=reset_distance))
    try:
        res = loop.run_goal((7.5, 0.0, 0.0), 90.0)
    finally:
        loop.close()
    if reached:
        assert res['state'] == SUCCEEDED, res['reason']
        assert res['collisions'] == 0
    else:
        assert res['state'] == ABORTED and 'no path' in res['reason'], res['reason']


def test_a_goal_on_a_real_obstacle_seen_from_afar_still_aborts_naming_it():
    """The far marks are forgotten, but the laser marks the cylinder again on the way: the goal
    ends ABORTED, saying that the laser sees an obstacle there, and the robot never touches it."""
    w = World.from_dict(dict(name='t', resolution=0.05, bounds=[-1, -2, 8, 2], robot_start=[0, 0, 0],
                             walls=[], static_cylinders=[],
                             movable_obstacles=[dict(x=6.0, y=0.0, radius=0.25)]))
    loop = ClosedLoop(w)
    r, c = loop.nav.costmap.grid.world_to_cell([(6.0, 0.0)])[0]
    loop.nav.costmap.obstacles[r, c] = True            # seen earlier, from closer
    loop.nav.costmap.update()
    try:
        res = loop.run_goal((6.0, 0.0, 0.0), 90.0)
        forgot = loop.nav.reset_forgot
    finally:
        loop.close()
    assert forgot >= 1
    assert res['state'] == ABORTED and 'the laser marked at' in res['reason'], res['reason']
    assert res['collisions'] == 0
