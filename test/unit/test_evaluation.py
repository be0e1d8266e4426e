"""Ground-truth judging of missions (tiago_nav_tools.evaluate.matching): matching, scores, goal sampling."""
import math
import os

import numpy as np
import pytest

from tiago_nav_tools.evaluate.matching import match_obstacles, sample_goals, score, truth_table, visible_truth
from tiago_nav.sim.raster import rasterise_world
from tiago_nav.sim.world import load_world

from conftest import WORLDS


def test_matching_is_one_to_one_and_gated():
    truth = [(0, 0), (1, 0), (5, 5)]
    found = [(1.02, 0.0), (0.01, 0.0), (3, 3), (0.05, 0.05)]
    pairs, missed, fps = match_obstacles(truth, found, gate=0.3)
    assert sorted((i, j) for i, j, _ in pairs) == [(0, 1), (1, 0)]
    assert missed == [2]
    assert sorted(fps) == [2, 3]
    s = score(truth, found)
    assert s['recall'] == pytest.approx(2 / 3)
    assert s['false_positives'] == 2
    assert s['max_error'] == pytest.approx(0.02)
    assert score([], [])['recall'] == 1.0


def test_truth_table_marks_misses_and_false_positives():
    lines, s = truth_table([(0, 1.0, 2.0, 0.2), (4, 3.0, 3.0, 0.2)], [(1.01, 2.0), (9.0, 9.0)])
    text = '\n'.join(lines)
    assert 'MISSED' in text and 'FALSE POS.' in text and '0.010' in text
    assert s['matched'] == 1


def test_course_pose_b_sees_four_cylinders():
    world = load_world(os.path.join(WORLDS, 'ias_lab_room_full.yaml'))
    truth = visible_truth(world, (11.0, 0.0, math.radians(-45)))
    assert [i for i, *_ in truth] == [0, 1, 2, 3]


@pytest.mark.parametrize('name', ['ias_lab_room_full.yaml', 'open_hall.yaml'])
def test_sampled_goals_are_free_reachable_and_seeded(name):
    world = load_world(os.path.join(WORLDS, name))
    a = sample_goals(world, 5, np.random.default_rng(3))
    b = sample_goals(world, 5, np.random.default_rng(3))
    assert a == b and len(a) == 5
    grid = rasterise_world(world)
    cx, cy = grid.cell_centres()
    occ = np.column_stack((cx[grid.occupied()], cy[grid.occupied()]))
    xmin, ymin, xmax, ymax = world.bounds
    for x, y, yaw in a:
        assert xmin < x < xmax and ymin < y < ymax and -180 <= yaw <= 180
        assert np.min(np.hypot(occ[:, 0] - x, occ[:, 1] - y)) >= 0.6
        for c in world.movable_obstacles:
            assert math.hypot(c.x - x, c.y - y) >= c.radius + 0.6


def test_obstacles_behind_the_robots_body_are_out_of_view():
    """The soak's open_hall mission that ended at (1.24, 4.06, -24 deg) counted cylinder 5 as
    in view and missed: all 16 beams that reach it are the fan's last ones, beyond the real
    laser's self-hit angle (its own shell). One definition for every laser model
    (tiago_nav_tools.evaluate.inview): not in view, only glimpsed (a detector may report it)."""
    from tiago_nav_tools.evaluate.inview import truth
    world = load_world(os.path.join(WORLDS, 'open_hall.yaml'))
    pose = (1.2373, 4.0634, -0.42264)
    in_view = [i for i, *_ in visible_truth(world, pose)]
    assert 5 not in in_view and in_view == [0, 3]
    view, glimpsed = truth(world, pose)
    assert [r[0] for r in view] == in_view and 5 in [r[0] for r in glimpsed]