"""The corridor law at bends (30 to 90 deg, in process against the simulator library): it stops
before the bend, centred, without contact and at least 5 cm from every wall, never "blocked
ahead" by the outer wall; a real obstacle in the corridor still is. And the mission's handoff:
when corridor_controller aborts, move_base drives the rest (CORRIDOR -> NAVIGATING, reason)."""
import math
import os

import numpy as np
import pytest

from tiago_nav import mission
from tiago_nav.corridor.law import CorridorParams, Walls, stop_distance
from tiago_nav.mission import SUCCEEDED, ABORTED, MissionRunner, Poll
from tiago_nav.mission.sentences import handoff_sentence
from tiago_nav.geometry import wrap_angle
from tiago_nav.robot import ROBOT_RADIUS
from tiago_nav.sim.laser import LaserModel
from tiago_nav.sim.odometry import OdometryNoise
from tiago_nav.sim.simulator import SimConfig, Simulator
from tiago_nav.sim.world import World, clearance, load_world
from tiago_nav.sim.worlds import corridor_world
from tiago_nav_tools.testing.corridor import ray_cast, run_in_simulator, world_segments

from test_mission import CFG, FakeBackend

P = CorridorParams()
WORLDS = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
                      'worlds')


def drive(world_dict, seed=0):
    world = World.from_dict(world_dict)
    sim = Simulator(world, SimConfig(laser_noise=0.01, seed=seed))
    track = []
    try:
        cmd, _ = run_in_simulator(sim, timeout=40.0, on_step=lambda s, c: track.append(s.pose))
        return cmd, np.array(track), sim.collisions, world
    finally:
        sim.close()


@pytest.mark.parametrize('bend', [30.0, 45.0, 60.0, 90.0, -45.0, -90.0])
@pytest.mark.parametrize('width', [0.8, 1.1])
def test_stops_before_the_bend_centred_and_clear(bend, width):
    cmd, track, collisions, world = drive(corridor_world(width, 6.0, bend, 3.0, mitre=True), seed=2)
    assert cmd.state == 'done', cmd.reason
    assert collisions == 0
    assert clearance(world, track[:, :2], ROBOT_RADIUS) >= 0.05
    x, y, yaw = track[-1]
    b = math.radians(bend)
    ex, ey = 3.0 + 3.0 * math.cos(b), 3.0 * math.sin(b)
    past_exit = (x - ex) * math.cos(b) + (y - ey) * math.sin(b)
    if past_exit > 0.0:
        # it followed the bend (the walls' fit turned with it: slight bends) and left the
        # second leg centred, facing along it
        assert abs(-(x - ex) * math.sin(b) + (y - ey) * math.cos(b)) < 0.05
        assert abs(wrap_angle(yaw - b)) < math.radians(6)
    else:
        # in the first leg's extension, near its centre line, facing along it, before the
        # bend's outer wall (the inner corner is at x = 3 - width/2 tan(bend/2))
        inner = 3.0 - 0.5 * width * math.tan(abs(b) / 2)
        assert inner - 0.1 < x < 3.0 + 0.5 * width + 0.1, x
        assert abs(y) < 0.05
        assert cmd.reason.startswith('reached the end of the corridor')
        if 'it bends or ends there' in cmd.reason:
            # stopped short of the outer wall: turned toward the next leg
            assert 'turned' in cmd.reason
            assert abs(wrap_angle(yaw - b)) < math.radians(8), math.degrees(yaw)
        else:
            # the inner wall ended first: stopped past it, facing along the first leg
            assert abs(yaw) < math.radians(6)


def _ahead(world, pose, radius=ROBOT_RADIUS):
    """Ground truth: how far [m] the base's disc at ``pose`` could move along +x (the first
    leg of the shipped bend worlds) before it touched anything."""
    segments = world_segments(world)
    free = math.inf
    for o in np.linspace(-radius, radius, 41):
        r = ray_cast((pose[0], pose[1] + o), np.array([0.0]), segments, 25.0)[0]
        free = min(free, r - math.sqrt(max(radius * radius - o * o, 0.0)))
    return free


# the law's documented clearance from every wall (docs/corridor.md, Bends); at 30 deg the outer
# wall crosses the first leg so shallowly that the stop end_clearance (0.25 m) short of it
# along the leg is 0.25 sin 30 = 0.125 m square to it
LAW_CLEARANCE = {30.0: 0.12, 45.0: 0.13, 60.0: 0.13}


@pytest.mark.parametrize('seed', [1, 2, 3])
@pytest.mark.parametrize('bend', [30.0, 45.0, 60.0])
def test_tiago_profile_stops_end_clearance_before_the_bend(bend, seed):
    """The shipped bend worlds in the tiago profile (its laser: self-hits, mixed pixels,
    dropouts; drifting odometry, which the law drives on): the law stops where the outer wall
    crossing the first leg is ``end_clearance`` ahead of the disc (ground truth), turns toward
    the next leg, and keeps the documented clearance from every wall all the way. A law that
    did not stop short of the bend drives on to end + exit_margin: it is blocked by the outer
    wall, or stops with it a few centimetres ahead."""
    world = load_world(os.path.join(WORLDS, 'corridor_bend_%d.yaml' % bend))
    cfg = SimConfig(laser_noise=0.01, seed=seed, laser_model=LaserModel(laser_model='tiago'),
                    odometry=OdometryNoise(odometry_model='drift'))
    sim = Simulator(world, cfg)
    track = []
    try:
        cmd, _ = run_in_simulator(sim, timeout=40.0, on_step=lambda s, c: track.append(s.pose))
        collisions = sim.collisions
    finally:
        sim.close()
    track = np.array(track)
    assert cmd.state == 'done', cmd.reason
    assert 'stopped %.2f m before a wall ahead past its end' % P.end_clearance in cmd.reason
    assert collisions == 0
    assert clearance(world, track[:, :2], ROBOT_RADIUS) >= LAW_CLEARANCE[bend]
    x, y, yaw = track[-1]
    assert abs(y) < 0.05                                     # centred in the first leg
    assert _ahead(world, track[-1]) == pytest.approx(P.end_clearance, abs=0.05)
    assert abs(wrap_angle(yaw - math.radians(bend))) < math.radians(8)   # turned to the next leg


def test_a_slight_bend_is_still_driven_through():
    cmd, track, collisions, world = drive(corridor_world(1.0, 5.0, 10.0, 2.5, mitre=True), seed=3)
    assert cmd.state == 'done' and 'bends' not in cmd.reason, cmd.reason
    assert collisions == 0
    assert track[-1, 0] > 5.0                       # past the second leg's end


def test_an_obstacle_in_the_corridor_before_a_bend_is_still_blocked_ahead():
    cmd, track, collisions, world = drive(corridor_world(1.1, 6.0, 45.0, 3.0, mitre=True,
                                                         obstacle=(1.8, 0.0, 0.2)))
    assert cmd.state == 'blocked' and cmd.reason.startswith('blocked ahead'), cmd.reason
    assert collisions == 0
    assert 0.0 < 1.8 - 0.2 - ROBOT_RADIUS - track[-1, 0] < 0.2


def test_stop_distance_counts_only_what_lies_beyond_the_end():
    walls = Walls(0.0, 0.55, -0.55, 20, 20, (0.0, 2.0), (0.0, 2.0))
    end_u = 1.0
    # nothing ahead: end + exit_margin
    assert stop_distance(np.zeros((0, 2)), walls, end_u, P) == pytest.approx(end_u + P.exit_margin)
    # a wall across at x = 1.5, beyond the end: stop end_clearance before the disc touches it
    across = np.column_stack((np.full(21, 1.5), np.linspace(-0.5, 0.5, 21)))
    assert stop_distance(across, walls, end_u, P) == pytest.approx(
        1.5 - ROBOT_RADIUS - P.end_clearance, abs=1e-6)
    # an obstacle before the end is not the stop point's business (front safety check)
    before = np.array([[0.6, 0.0]])
    assert stop_distance(before, walls, end_u, P) == pytest.approx(end_u + P.exit_margin)
    # beside the disc's path (|offset| >= radius): ignored
    aside = np.array([[1.2, 0.3], [1.2, -0.3]])
    assert stop_distance(aside, walls, end_u, P) == pytest.approx(end_u + P.exit_margin)


def test_mitred_world_keeps_the_width_through_the_bend():
    """corridor_world(mitre=True): every point of the bent centre line is width/2 from the
    nearest wall (no wall crosses the corridor at the bend)."""
    for bend in (30.0, 60.0, 90.0, -90.0):
        width = 1.1
        world = World.from_dict(corridor_world(width, 6.0, bend, 3.0, mitre=True))
        b = math.radians(bend)
        s = np.linspace(0.05, 5.95, 119)
        line = np.where(s[:, None] <= 3.0, np.column_stack((s, 0 * s)),
                        np.column_stack((3.0 + (s - 3.0) * math.cos(b), (s - 3.0) * math.sin(b))))
        assert clearance(world, line, robot_radius=0.0) == pytest.approx(width / 2, abs=1e-6)
    with pytest.raises(ValueError):
        corridor_world(1.1, 6.0, 120.0, 3.0, mitre=True)


# --- the mission's handoff ----------------------------------------------------------------------
class AbortingCorridor(FakeBackend):
    """corridor_controller aborts its goal after 1 s with ``reason``."""

    def __init__(self, reason, **kw):
        super().__init__(**kw)
        self.reason = reason

    def poll(self, stage):
        if stage == 'corridor':
            if self.t - self.started > 1.0:
                self.active = None
                return Poll(mission.ABORTED, self.reason)
            return Poll(mission.ACTIVE)
        return super().poll(stage)


def test_corridor_controller_abort_hands_over_to_move_base():
    reason = 'blocked ahead: obstacle 0.05 m in front'
    b = AbortingCorridor(reason)
    out = MissionRunner(b, CFG).run(mission.Goal(5.0, 0.0, -45.0, True))
    assert out.status == SUCCEEDED, out.message
    assert b.sent == ['corridor', 'navigation']
    assert out.final_pose[0] == pytest.approx(5.0)
    st = b.states()
    assert st[:3] == [mission.GOAL_RECEIVED, mission.CORRIDOR, mission.NAVIGATING]
    first_nav = [s for _, st_, s, _ in b.feedbacks if st_ == mission.NAVIGATING][0]
    assert first_nav == handoff_sentence(reason)
    assert reason in first_nav and 'move_base' in first_nav


def test_handoff_then_move_base_failing_aborts_with_move_base_reason():
    b = AbortingCorridor('blocked ahead: obstacle 0.05 m in front', navigation='abort')
    out = MissionRunner(b, CFG).run(mission.Goal(5.0, 0.0, -45.0, True))
    assert out.status == ABORTED and out.stage == 'navigation', out.message
    assert out.message.startswith('navigation failed: move_base aborted: ')


def test_a_corridor_stage_that_cannot_run_still_aborts():
    b = FakeBackend(corridor='hang')                 # times out: the mission gave up on it
    out = MissionRunner(b, CFG).run(mission.Goal(5.0, 0.0, -45.0, True))
    assert out.status == ABORTED and out.stage == 'corridor'
    assert b.sent == ['corridor']


def test_a_law_that_stopped_at_a_bend_says_why_before_navigating():
    b = FakeBackend()                               # corridor result: 1.0 m, 'corridor end'
    out = MissionRunner(b, CFG).run(mission.Goal(5.0, 0.0, -45.0, True))
    assert out.status == SUCCEEDED, out.message
    lines = [s for _, st_, s, _ in b.feedbacks if st_ == mission.CORRIDOR]
    assert lines[-1] == 'corridor law done after 1.0 m: corridor end; navigating on to pose B'


@pytest.mark.parametrize('bend', [30, 45, 60, 90])
def test_shipped_bend_worlds_are_what_their_generator_writes(bend, tmp_path):
    """worlds/corridor_bend_*.yaml: regenerated identically by scripts/make_bend_worlds.py;
    pose B (header) clear of every wall by 0.5 m, beyond the bend, its cylinder in view."""
    import os
    import subprocess
    import sys
    from tiago_nav.sim.world import load_world
    from tiago_nav_tools.evaluate.matching import visible_truth
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    shipped = os.path.join(root, 'worlds', 'corridor_bend_%d.yaml' % bend)
    subprocess.run([sys.executable, os.path.join(root, 'scripts', 'make_bend_worlds.py'),
                    str(tmp_path)], check=True, stdout=subprocess.DEVNULL)
    with open(shipped) as a, open(str(tmp_path / os.path.basename(shipped))) as b:
        assert a.read() == b.read(), 'rerun scripts/make_bend_worlds.py'
    with open(shipped) as f:
        line = [ln for ln in f if 'Pose B: [' in ln][0]
    x, y, yaw = [float(v) for v in line.split('Pose B: [')[1].split(']')[0].split(',')]
    world = load_world(shipped)
    assert clearance(world, [(x, y)], robot_radius=0.0) >= 0.5
    b = math.radians(bend)
    assert (x - 3.0) * math.cos(b) + y * math.sin(b) > 3.0          # past the second leg
    assert len(visible_truth(world, (x, y, math.radians(yaw)))) == 1
