"""The corridor control law: wall estimation and the law on synthetic scans, then closed loops
with the simulator library's laser (no ROS) in corridors 0.8-1.5 m wide, one with a bend."""
import math

import numpy as np
import pytest

from tiago_nav.corridor.law import (CorridorFollower, CorridorParams, control_law, find_corridor,
                                fit_walls, front_free_distance, wall_end)
from tiago_nav.scan import Scan
from tiago_nav.geometry import inverse, transform_points, wrap_angle
from tiago_nav.robot import ROBOT_RADIUS
from tiago_nav.sim.simulator import SimConfig, Simulator
from tiago_nav.sim.world import World
from tiago_nav.sim.worlds import corridor_world
from tiago_nav_tools.testing.corridor import run_in_simulator

P = CorridorParams()
ROBOT_R = ROBOT_RADIUS


def synthetic_scan(width, offset, heading, rng, noise=0.01, left_end=None, right_end=None,
                   turn_left=None, length=6.0, behind=1.0):
    """Robot-frame points of two parallel walls ``width`` apart, the robot ``offset`` [m] left
    of the centre line and turned ``heading`` [rad] left of it. A wall may end at
    ``*_end`` [m] ahead; ``turn_left`` [deg] makes the left wall turn away there instead."""
    pts = []
    for side, end in ((1, left_end), (-1, right_end)):
        stop = length if end is None else end
        s = np.arange(-behind, stop, 0.02)
        pts.append(np.column_stack((s, np.full(s.size, side * width / 2))))
        if side == 1 and turn_left is not None and end is not None:
            t = np.arange(0.0, 1.5, 0.02)
            a = math.radians(turn_left)
            pts.append(np.column_stack((end + t * math.cos(a), width / 2 + t * math.sin(a))))
    corridor = np.vstack(pts)
    corridor = corridor + rng.normal(0.0, noise, corridor.shape)
    # corridor frame -> robot frame: the robot sits at (0, offset) with heading `heading`
    return transform_points(inverse((0.0, offset, heading)), corridor)


@pytest.mark.parametrize('width,offset,heading', [
    (1.07, 0.0, 0.0), (1.07, 0.12, math.radians(8)), (0.8, -0.08, math.radians(-12)),
    (1.5, 0.3, math.radians(20))])
def test_fit_recovers_offset_heading_and_width(width, offset, heading):
    rng = np.random.default_rng(1)
    pts = synthetic_scan(width, offset, heading, rng)
    # the follower's path: the free strip gives the guess the walls are fitted from
    walls = find_corridor(pts, P)
    assert walls is not None
    assert walls.lateral_offset == pytest.approx(offset, abs=0.01)
    assert walls.heading_error == pytest.approx(heading, abs=math.radians(0.7))
    assert walls.width == pytest.approx(width, abs=0.01)
    assert walls.d_left == pytest.approx(width / 2 - offset, abs=0.015)


def test_fit_is_robust_to_clutter_on_a_wall():
    rng = np.random.default_rng(2)
    pts = synthetic_scan(1.0, 0.05, 0.05, rng)
    # a door recess and a pillar sticking out of the left wall
    clutter = np.column_stack((np.linspace(1.0, 1.4, 20), np.full(20, 0.8)))
    pillar = np.column_stack((np.linspace(0.5, 0.6, 5), np.full(5, 0.35)))
    walls = fit_walls(np.vstack((pts, transform_points(inverse((0, 0.05, 0.05)), clutter),
                                 transform_points(inverse((0, 0.05, 0.05)), pillar))), 0.0, 0.0, P)
    assert walls.lateral_offset == pytest.approx(0.05, abs=0.01)
    assert walls.heading_error == pytest.approx(0.05, abs=0.01)


def test_no_walls_or_too_narrow_is_no_corridor():
    rng = np.random.default_rng(3)
    assert fit_walls(np.zeros((0, 2)), 0.0, 0.0, P) is None
    one_side = synthetic_scan(1.0, 0, 0, rng)
    assert fit_walls(one_side[one_side[:, 1] > 0], 0.0, 0.0, P) is None
    assert fit_walls(synthetic_scan(0.5, 0, 0, rng), 0.0, 0.0, P) is None        # < robot
    assert fit_walls(synthetic_scan(3.0, 0, 0, rng), 0.0, 0.0, P) is None        # a hall
    assert find_corridor(np.zeros((0, 2)), P) is None


def test_law_steers_toward_the_centre_line():
    # left of the centre, aligned: turn right; right of it: turn left; pointing left: turn right
    assert control_law(0.1, 0.0, 1.0, P)[1] < 0
    assert control_law(-0.1, 0.0, 1.0, P)[1] > 0
    assert control_law(0.0, 0.2, 1.0, P)[1] < 0
    # already converging at the reference angle: no turn needed
    v, w = control_law(0.05, -math.asin(P.k_lateral * 0.05 / P.k_heading), 1.0, P)
    assert abs(w) < 1e-9
    # slower with errors, never above the limits
    v0, w0 = control_law(0.0, 0.0, 1.0, P)
    assert v0 == pytest.approx(P.max_speed) and w0 == 0
    assert control_law(0.15, 0.3, 1.0, P)[0] < 0.5 * v0
    for ey in np.linspace(-0.5, 0.5, 11):
        for eth in np.linspace(-1.5, 1.5, 11):
            v, w = control_law(ey, eth, 0.8, P, max_speed=5.0)
            assert 0 <= v <= P.speed_limit and abs(w) <= P.max_angular + 1e-9


def test_linearised_law_converges_in_distance():
    """Integrate the kinematics with the law (no sensing): offset and heading decay within 2.5 m."""
    x, y, th = 0.0, 0.15, math.radians(15)
    dt = 0.01
    steps = 0
    while x < 2.5 and steps < 2000:             # 20 s: more than enough at >= 0.1 m/s
        v, w = control_law(y, th, 1.07, P)
        x += v * math.cos(th) * dt
        y += v * math.sin(th) * dt
        th = wrap_angle(th + w * dt)
        steps += 1
    assert x >= 2.5
    assert abs(y) < 0.01 and abs(th) < math.radians(1.5)


@pytest.mark.parametrize('turn', [None, 60.0])
def test_wall_end_detected(turn):
    rng = np.random.default_rng(4)
    pts = synthetic_scan(1.07, 0.0, 0.0, rng, left_end=1.6, turn_left=turn)
    walls = fit_walls(pts, 0.0, 0.0, P)
    end = wall_end(pts, walls, P)
    assert end is not None
    assert 1.5 <= end <= 1.9
    # a continuous corridor has no end within the look-ahead; nor does a slight bend
    assert wall_end(synthetic_scan(1.07, 0.0, 0.0, rng), walls, P) is None
    bent = synthetic_scan(1.07, 0.0, 0.0, rng, left_end=1.6, turn_left=8.0)
    assert wall_end(bent, fit_walls(bent, 0.0, 0.0, P), P) is None


def test_front_free_distance():
    pts = np.array([[1.0, 0.0], [0.5, 0.5], [0.8, -0.2]])
    assert front_free_distance(pts, ROBOT_R) == pytest.approx(0.8 - math.sqrt(ROBOT_R ** 2 - 0.04))
    assert front_free_distance(np.array([[1.0, 0.3]]), ROBOT_R) == 25.0


def test_follower_stops_for_an_obstacle_and_reports_no_corridor():
    rng = np.random.default_rng(5)
    f = CorridorFollower(P)
    pose = (0.0, 0.0, 0.0)
    scan = synthetic_scan(1.07, 0.0, 0.0, rng)
    blocker = np.array([[ROBOT_R + 0.05, 0.0], [ROBOT_R + 0.05, 0.05]])
    f.update_scan(scan, pose)
    assert f.command(pose).state == 'driving'
    f.update_scan(np.vstack((scan, blocker)), pose)
    cmd = f.command(pose)
    assert cmd.state == 'blocked' and cmd.v == 0 and 'blocked' in cmd.reason
    # further away: drives, but slowly enough to brake before it
    f2 = CorridorFollower(P)
    f2.update_scan(scan, pose)
    f2.update_scan(np.vstack((scan, blocker + [0.3, 0])), pose)
    cmd = f2.command(pose)
    assert cmd.state == 'driving'
    assert 0 < cmd.v <= math.sqrt(2 * P.decel * (0.3 + 0.05 - P.stop_margin)) + 1e-9
    lost = CorridorFollower(P)
    for _ in range(3):
        lost.update_scan(np.array([[5.0, 5.0], [5.0, -5.0]]), pose)
    cmd = lost.command(pose)
    assert cmd.state == 'failed' and 'no corridor ahead' in cmd.reason


# --- closed loop with the simulator's laser ---------------------------------------------------

def drive(world_dict, seed=0, **kw):
    world = World.from_dict(world_dict)
    sim = Simulator(world, SimConfig(laser_noise=0.01, seed=seed))
    track = []
    try:
        cmd, f = run_in_simulator(sim, timeout=40.0,
                                  on_step=lambda s, c: track.append(s.pose), **kw)
        return cmd, np.array(track), sim.collisions, f
    finally:
        sim.close()


def track_clearance(track, width, bend_at=None, bend_deg=0.0):
    """Minimum distance [m] of the base's edge to the straight corridor's walls, from x = 0."""
    inside = track[(track[:, 0] > 0.0) & (track[:, 0] < (bend_at or 1e9))]
    return float((width / 2 - np.abs(inside[:, 1])).min() - ROBOT_R)


@pytest.mark.parametrize('width,start', [
    (0.8, (-1.0, 0.1, 12.0)), (1.07, (-1.5, -0.15, -15.0)), (1.07, (0.3, 0.2, 10.0)),
    (1.5, (-1.2, 0.15, 15.0))])
def test_closed_loop_straight_corridors(width, start):
    cmd, track, collisions, _ = drive(corridor_world(width, 5.0, start=start), seed=7)
    assert cmd.state == 'done', cmd.reason
    assert collisions == 0
    x, y, yaw = track[-1]
    # stopped just past the exit (x = 5), on the centre line, facing along the corridor
    assert 5.0 + 0.1 < x < 5.0 + 0.7
    assert abs(y) < 0.05 and abs(yaw) < math.radians(5)
    assert track_clearance(track, width) > 0.05
    after_first_metre = track[(track[:, 0] > 1.0) & (track[:, 0] < 5.0)]
    assert np.sqrt(np.mean(after_first_metre[:, 1] ** 2)) < 0.03


def test_closed_loop_slight_bend():
    bend = 10.0
    cmd, track, collisions, _ = drive(corridor_world(1.0, 5.0, bend, 2.5, start=(-1.0, -0.1, -10.0)),
                                      seed=3)
    assert cmd.state == 'done', cmd.reason
    assert collisions == 0
    # distance to the bent centre line, over the whole corridor
    b = math.radians(bend)
    x, y = track[:, 0], track[:, 1]
    second = x > 2.5
    d = np.where(second, -(x - 2.5) * math.sin(b) + y * math.cos(b), y)
    inside = (x > 0.0) & ((x - 2.5) * math.cos(b) + y * math.sin(b) < 2.5)
    assert np.abs(d[inside]).max() < 0.5 - ROBOT_R - 0.05
    ex, ey = 2.5 + 2.5 * math.cos(b), 2.5 * math.sin(b)
    along = (track[-1, 0] - ex) * math.cos(b) + (track[-1, 1] - ey) * math.sin(b)
    assert 0.1 < along < 0.7
    assert abs(wrap_angle(track[-1, 2] - b)) < math.radians(5)


def test_closed_loop_blocked_ahead_stops_without_contact():
    cmd, track, collisions, f = drive(corridor_world(1.07, 5.0, start=(-0.5, 0.0, 0.0),
                                                     obstacle=(2.5, 0.0, 0.2)))
    assert cmd.state == 'blocked' and 'blocked ahead' in cmd.reason
    assert collisions == 0
    # stopped in front of the cylinder, within a few cm of the stop margin
    gap = 2.5 - 0.2 - ROBOT_R - track[-1, 0]
    assert 0.0 < gap < 0.2


def test_closed_loop_no_corridor_fails_fast_without_moving():
    open_floor = {'name': 'open', 'resolution': 0.05, 'bounds': [-5, -5, 5, 5],
                  'robot_start': [0, 0, 0],
                  'walls': [{'x': 4.5, 'y': 0, 'length': 8, 'width': 0.2, 'yaw_deg': 90}]}
    cmd, track, collisions, _ = drive(open_floor)
    assert cmd.state == 'failed' and 'no corridor ahead' in cmd.reason
    assert np.abs(track[-1, :2]).max() < 1e-6
    assert len(track) < 3 * 60                                  # gave up within ~1 s + braking


def test_max_distance_stops_early():
    cmd, track, collisions, f = drive(corridor_world(1.07, 5.0, start=(-0.5, 0.0, 0.0)),
                                      max_distance=2.0)
    assert cmd.state == 'done' and 'max_distance' in cmd.reason
    assert track[-1, 0] - (-0.5) == pytest.approx(2.0, abs=0.1)


def test_scan_hits_become_odom_points():
    """Only the hits of a scan (REP 117) are points; they land where the laser's pose puts them."""
    f = CorridorFollower(P)
    scan = Scan(np.array([1.0, np.inf, np.nan, 0.01, 2.0]), 0.0, math.pi / 8, 0.05, 25.0,
                0.0, 'laser')
    f.update_laser(scan, (1.0, 2.0, math.pi / 2), (0.8, 2.0, math.pi / 2))
    assert f.points == pytest.approx(np.array([[1.0, 3.0], [-1.0, 2.0]]))


def test_corridor_toward_needs_a_corridor_leading_to_the_target():
    import os
    from conftest import WORLDS
    from tiago_nav.corridor.law import corridor_toward
    from tiago_nav.scan import scan_to_points
    from tiago_nav.sim.scene import Scene
    from tiago_nav.sim.world import load_world
    w = load_world(os.path.join(WORLDS, 'ias_lab_room_full.yaml'))
    p = CorridorParams()

    def points(pose):
        with Scene(w) as scene:
            r, _ = scene.cast(pose)
            L = scene.laser
            pts, _ = scan_to_points(r, L.angle_min, L.angle_increment, L.range_min, L.range_max)
        return transform_points((L.offset, 0.0, 0.0), pts)

    start = w.start_pose
    at_start = points(start)
    b_in_robot = transform_points(inverse(start), [[11.0, 0.0]])[0]
    assert corridor_toward(at_start, b_in_robot, p) is not None
    behind = transform_points(inverse(start), [[-3.0, 0.0]])[0]
    assert corridor_toward(at_start, behind, p) is None          # the corridor leads elsewhere
    pose_b = (11.0, 0.0, math.radians(-45.0))                     # the big room: no corridor
    assert corridor_toward(points(pose_b), transform_points(inverse(pose_b), [[6.5, -3.0]])[0], p) is None
    # pose B beside the corridor (behind its right wall) or inside the stretch of it in view:
    # reached without the law
    for b in ((1.0, -1.2), (1.5, 0.0)):
        assert corridor_toward(at_start, transform_points(inverse(start), [b])[0], p) is None, b
    with pytest.raises(ValueError, match='finite'):
        corridor_toward(at_start, (float('nan'), 0.0), p)
