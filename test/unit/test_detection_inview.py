"""The one definition of "in view" (tiago_nav.sim.inview) that the evaluator, the benchmarks,
the harness and the tests judge detection by: enough usable beams (detection's smallest
cluster plus the veil filter's edge losses, within the real laser's self-hit angle and the
detector's range) and an outline edge seen."""
import math

import numpy as np

from tiago_nav.detection import DetectionParams
from tiago_nav.evaluate import metrics as M
from tiago_nav.sim import inview
from tiago_nav.sim.inview import MIN_BEAMS, USABLE_ANGLE, judge_view, truth
from tiago_nav.sim.laser import LaserModel
from tiago_nav.sim.scene import LaserConfig, Scene
from tiago_nav.sim.world import World

L = LaserConfig()
BODY, NEAR = 7, 9                  # body ids: the obstacle, a nearer one


def fan(first, count, rng=2.0, background=5.0, left=None, right=None):
    """A cast of the 666-beam fan: the obstacle (BODY) on ``count`` beams from ``first`` at
    ``rng`` [m], the wall behind at ``background``; ``left``/``right``: the range of a nearer
    body (NEAR) on the beam just before/after it (an occluded silhouette edge)."""
    a = L.angles()
    r = np.full(len(a), background)
    ids = np.full(len(a), 1)
    r[first:first + count] = rng
    ids[first:first + count] = BODY
    for j, v in ((first - 1, left), (first + count, right)):
        if v is not None and 0 <= j < len(a):
            r[j], ids[j] = v, NEAR
    return r, ids, a


def test_the_rule_is_detections_cluster_size_and_the_lasers_usable_fan():
    assert MIN_BEAMS == DetectionParams().min_points + 2 == 7
    assert math.degrees(USABLE_ANGLE) == LaserModel().self_hit_angle == 103.5
    assert inview.MAX_RANGE == DetectionParams().max_range


def test_enough_usable_beams():
    mid = len(L.angles()) // 2
    for count, expected in ((MIN_BEAMS - 1, []), (MIN_BEAMS, [0])):
        v = judge_view(*fan(mid, count), [BODY])
        assert v.in_view == expected and v.usable_beams[0] == count
        assert v.glimpsed == ([0] if not expected else [])


def test_beams_beyond_the_self_hit_angle_do_not_count():
    """The 45 deg bend's miss: an obstacle 101-112 deg off the heading has most of its beams
    where the real laser sees its own shell: with fewer than MIN_BEAMS short of the self-hit
    angle, not in view (glimpsed), whatever the model."""
    a = L.angles()
    first = int(np.argmin(np.abs(a - math.radians(102.5))))
    last = int(np.argmin(np.abs(a - math.radians(110.0))))
    v = judge_view(*fan(first, last - first + 1), [BODY])
    assert v.beams[0] == last - first + 1 >= 20
    assert v.usable_beams[0] < MIN_BEAMS and v.in_view == [] and v.glimpsed == [0]


def test_beyond_the_detectors_range_does_not_count():
    mid = len(L.angles()) // 2
    v = judge_view(*fan(mid, 20, rng=DetectionParams().max_range + 0.5, background=20.0), [BODY])
    assert v.usable_beams[0] == 0 and v.glimpsed == [0]


def test_an_outline_edge_must_be_seen():
    mid = len(L.angles()) // 2
    # one edge behind a nearer obstacle, the other against the wall: in view
    assert judge_view(*fan(mid, 12, left=1.0), [BODY]).in_view == [0]
    assert judge_view(*fan(mid, 12, right=1.0), [BODY]).in_view == [0]
    # both edges hidden: its arc says nothing of where it ends
    v = judge_view(*fan(mid, 12, left=1.0, right=1.5), [BODY])
    assert v.in_view == [] and v.glimpsed == [0]
    # touching a wall behind it still shows its edges (the wall is farther there)
    assert judge_view(*fan(mid, 12, background=2.05), [BODY]).in_view == [0]


def test_one_edge_at_the_end_of_the_usable_fan():
    a = L.angles()
    stop = int(np.flatnonzero(np.abs(a) <= USABLE_ANGLE).max())       # the last usable beam
    # its run ends at the last usable beam: that edge is cut; the other is seen
    v = judge_view(*fan(stop - 11, 12), [BODY])
    assert v.in_view == [0]
    # and with the other edge behind a nearer obstacle: both hidden
    v = judge_view(*fan(stop - 11, 12, left=1.0), [BODY])
    assert v.glimpsed == [0]


def _world(movable):
    return World.from_dict({
        'name': 'inview', 'resolution': 0.05, 'bounds': [-1, -4, 9, 4], 'robot_start': [0, 0, 0],
        'walls': [{'x': 4.0, 'y': 3.5, 'length': 10.0, 'width': 0.15},
                  {'x': 4.0, 'y': -3.5, 'length': 10.0, 'width': 0.15},
                  {'x': 8.5, 'y': 0.0, 'length': 7.0, 'width': 0.15, 'yaw_deg': 90}],
        'movable_obstacles': [{'x': x, 'y': y, 'radius': r} for x, y, r in movable]})


def test_scene_half_hidden_is_in_view_fully_flanked_is_not():
    # the far cylinder half behind a near one: one silhouette edge seen -> in view
    w = _world([(2.0, 0.0, 0.2), (5.0, 0.55, 0.25)])
    with Scene(w) as s:
        assert s.visible_obstacles((0.0, 0.0, 0.0)) == [0, 1]
        assert inview.view_from(s, (0.0, 0.0, 0.0)).usable_beams[1] < 15   # about half
    # the far cylinder's middle seen between two near ones that hide both its edges
    w = _world([(2.0, -0.19, 0.12), (2.0, 0.19, 0.12), (6.0, 0.0, 0.45)])
    with Scene(w) as s:
        v = inview.view_from(s, (0.0, 0.0, 0.0))
    assert v.in_view == [0, 1] and v.glimpsed == [2] and v.usable_beams[2] >= MIN_BEAMS
    rows_in, rows_glimpsed = truth(w, (0.0, 0.0, 0.0))
    assert [r[0] for r in rows_in] == [0, 1] and [r[0] for r in rows_glimpsed] == [2]


def test_the_evaluator_neither_requires_nor_refuses_a_glimpsed_obstacle():
    truth_xy, glimpsed = [(2.0, 0.0)], [(6.0, 0.0)]
    ok, f = M.detection(truth_xy, [(2.01, 0.0), (6.05, 0.02)], 0.05, glimpsed)
    assert ok and f['false_positives'] == 0 and f['in_view'] == 1 and f['found'] == 2
    assert f['max_error'] < 0.02                          # the glimpsed one is not scored
    ok, f = M.detection(truth_xy, [(2.01, 0.0)], 0.05, glimpsed)
    assert ok and f['recall'] == 1.0                      # nor missed
    ok, f = M.detection(truth_xy, [(2.01, 0.0), (4.0, 1.0)], 0.05, glimpsed)
    assert not ok and 'false positive' in f['problem']
    ok, f = M.detection(truth_xy, [(6.0, 0.0)], 0.05, glimpsed)
    assert not ok and 'missed 1 of 1' in f['problem']
