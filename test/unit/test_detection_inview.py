"""The one definition of "in view" (tiago_nav_tools.evaluate.inview) that the evaluator, the benchmarks,
the harness and the tests judge detection by: enough usable beams hit the obstacle (detection's
smallest cluster plus the veil filter's edge losses, within the profile's usable fan and the
detector's range), whatever its edges."""
import math

import numpy as np
import pytest

from tiago_nav.detection import DetectionParams
from tiago_nav_tools.evaluate import metrics as M
from tiago_nav_tools.evaluate import inview
from tiago_nav_tools.evaluate.inview import (MIN_BEAMS, PLAIN_BEAMS, USABLE_ANGLE, judge_view, truth,
                                         view_from)
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
    assert PLAIN_BEAMS == DetectionParams().min_points == 5
    assert inview.usable_angle('tiago') == USABLE_ANGLE
    assert inview.usable_angle('ideal') >= max(abs(L.angle_min), abs(L.angle_max))
    with pytest.raises(ValueError):
        inview.usable_angle('hokuyo')
    assert math.degrees(USABLE_ANGLE) == LaserModel().self_hit_angle == 103.5
    assert inview.MAX_RANGE == DetectionParams().max_range


def test_enough_usable_beams():
    mid = len(L.angles()) // 2
    for count, expected in ((MIN_BEAMS - 1, []), (MIN_BEAMS, [0])):
        v = judge_view(*fan(mid, count), [BODY])
        assert v.in_view == expected and v.usable_beams[0] == count
        assert v.glimpsed == ([0] if not expected else [])
    # the plain rule: detection's smallest cluster
    for count, expected in ((PLAIN_BEAMS - 1, []), (PLAIN_BEAMS, [0])):
        assert judge_view(*fan(mid, count), [BODY], min_beams=PLAIN_BEAMS).in_view == expected
    with pytest.raises(ValueError):
        judge_view(*fan(mid, 3), [BODY], min_beams=0)


def test_beams_beyond_the_self_hit_angle_count_for_the_ideal_profile_only():
    """The 45 deg bend's obstacle, 102.5-110 deg off the heading: the tiago profile's laser sees
    its own shell there (glimpsed), the ideal profile's whole fan measures it (in view)."""
    a = L.angles()
    first = int(np.argmin(np.abs(a - math.radians(102.5))))
    last = int(np.argmin(np.abs(a - math.radians(110.0))))
    cast = fan(first, last - first + 1)
    v = judge_view(*cast, [BODY])
    assert v.beams[0] == last - first + 1 >= 20
    assert v.usable_beams[0] < MIN_BEAMS and v.in_view == [] and v.glimpsed == [0]
    v = judge_view(*cast, [BODY], profile='ideal')
    assert v.usable_beams[0] == v.beams[0] and v.in_view == [0] and v.glimpsed == []


def test_beyond_the_detectors_range_does_not_count():
    mid = len(L.angles()) // 2
    v = judge_view(*fan(mid, 20, rng=DetectionParams().max_range + 0.5, background=20.0), [BODY])
    assert v.usable_beams[0] == 0 and v.glimpsed == [0]


def test_edges_do_not_matter():
    """Enough usable beams place a circle (a short arc takes the scan's shared radius), whether
    its silhouette edges are seen, hidden behind nearer things or cut by the usable fan."""
    mid = len(L.angles()) // 2
    for left, right in ((1.0, None), (None, 1.5), (1.0, 1.5)):
        assert judge_view(*fan(mid, MIN_BEAMS, left=left, right=right), [BODY]).in_view == [0]
    a = L.angles()
    stop = int(np.flatnonzero(np.abs(a) <= USABLE_ANGLE).max())       # the last usable beam
    v = judge_view(*fan(stop - MIN_BEAMS + 1, MIN_BEAMS + 5, left=1.0), [BODY])
    assert v.usable_beams[0] == MIN_BEAMS and v.in_view == [0]


def _world(movable):
    return World.from_dict({
        'name': 'inview', 'resolution': 0.05, 'bounds': [-1, -4, 9, 4], 'robot_start': [0, 0, 0],
        'walls': [{'x': 4.0, 'y': 3.5, 'length': 10.0, 'width': 0.15},
                  {'x': 4.0, 'y': -3.5, 'length': 10.0, 'width': 0.15},
                  {'x': 8.5, 'y': 0.0, 'length': 7.0, 'width': 0.15, 'yaw_deg': 90}],
        'movable_obstacles': [{'x': x, 'y': y, 'radius': r} for x, y, r in movable]})


def test_scene_half_hidden_and_fully_flanked_are_in_view():
    # the far cylinder half behind a near one: in view
    w = _world([(2.0, 0.0, 0.2), (5.0, 0.55, 0.25)])
    with Scene(w) as s:
        assert view_from(s, (0.0, 0.0, 0.0)).in_view == [0, 1]
        assert inview.view_from(s, (0.0, 0.0, 0.0)).usable_beams[1] < 15   # about half
    # the far cylinder's middle seen between two near ones that hide both its edges: in view too
    w = _world([(2.0, -0.19, 0.12), (2.0, 0.19, 0.12), (6.0, 0.0, 0.45)])
    with Scene(w) as s:
        v = inview.view_from(s, (0.0, 0.0, 0.0))
    assert v.in_view == [0, 1, 2] and v.glimpsed == [] and v.usable_beams[2] >= MIN_BEAMS
    rows_in, rows_glimpsed = truth(w, (0.0, 0.0, 0.0))
    assert [r[0] for r in rows_in] == [0, 1, 2] and rows_glimpsed == []
    # a cylinder 106 deg off the heading: beyond the tiago laser's self-hit angle only
    b = math.radians(106.0)
    w = _world([(L.offset + 3.0 * math.cos(b), 3.0 * math.sin(b), 0.15)])
    assert truth(w, (0.0, 0.0, 0.0), 'tiago')[0] == []
    assert [r[0] for r in truth(w, (0.0, 0.0, 0.0), 'ideal')[0]] == [0]


def test_the_evaluator_neither_requires_nor_refuses_a_glimpsed_obstacle_and_scores_it():
    truth_xy, glimpsed = [(2.0, 0.0)], [(6.0, 0.0)]
    ok, f = M.detection(truth_xy, [(2.01, 0.0), (6.04, 0.0)], 0.05, glimpsed)
    assert ok and f['false_positives'] == 0 and f['in_view'] == 1 and f['found'] == 2
    assert f['glimpsed'] == 1 and f['matched'] == 1 and f['matched_glimpsed'] == 1
    assert f['missed'] == 0
    # the glimpsed one's error is scored with the others
    assert f['max_error'] == pytest.approx(0.04)
    assert sorted((e['in_view'], round(e['error'], 3)) for e in f['errors']) == [
        (False, 0.04), (True, 0.01)]
    ok, f = M.detection(truth_xy, [(2.01, 0.0)], 0.05, glimpsed)
    assert ok and f['recall'] == 1.0 and f['matched_glimpsed'] == 0    # nor missed
    ok, f = M.detection(truth_xy, [(2.01, 0.0), (4.0, 1.0)], 0.05, glimpsed)
    assert not ok and 'false positive' in f['problem']
    ok, f = M.detection(truth_xy, [(6.0, 0.0)], 0.05, glimpsed)
    assert not ok and 'missed 1 of 1' in f['problem'] and f['missed'] == 1
    # a centre reported for a glimpsed obstacle beyond the tolerance fails the run
    ok, f = M.detection(truth_xy, [(2.01, 0.0), (6.079, 0.0)], 0.05, glimpsed)
    assert not ok and 'glimpsed' in f['problem'] and f['max_error'] == pytest.approx(0.079)
