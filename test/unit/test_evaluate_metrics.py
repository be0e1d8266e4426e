"""The evaluator's metrics against values computed by hand."""
import math

import pytest

from tiago_nav_tools.evaluate import metrics as M


def test_success():
    assert M.success('succeeded') == 1
    for o in ('aborted', 'collision', 'timeout', 'detection_failure', 'INFRA_LAUNCH'):
        assert M.success(o) == 0


def test_path_length():
    assert M.path_length([(0, 0), (3, 4), (3, 0)]) == pytest.approx(9.0)     # 5 + 4
    assert M.path_length([(1, 1, 0.3)]) == 0.0
    assert M.path_length([]) == 0.0


def test_spl():
    assert M.spl(True, 10.0, 12.5) == pytest.approx(0.8)       # 10 / max(10, 12.5)
    assert M.spl(True, 10.0, 9.0) == pytest.approx(1.0)        # 10 / max(10, 9)
    assert M.spl(False, 10.0, 10.0) == 0.0


def test_barn_score():
    # OT = 10 s: clip(T, 20, 80)
    assert M.barn_score(True, 10.0, 15.0) == pytest.approx(0.5)     # 10 / 20
    assert M.barn_score(True, 10.0, 40.0) == pytest.approx(0.25)    # 10 / 40
    assert M.barn_score(True, 10.0, 100.0) == pytest.approx(0.125)  # 10 / 80
    assert M.barn_score(False, 10.0, 15.0) == 0.0


def test_percentile_and_median():
    v = [0.05, 0.01, 0.03, 0.02, 0.04]
    assert M.percentile(v, 95) == 0.05       # rank ceil(4.75) = 5
    assert M.percentile(v, 50) == 0.03       # rank ceil(2.5) = 3
    assert M.percentile([], 95) is None
    assert M.median([3.0, None, 1.0, 2.0]) == 2.0
    assert M.ratio(6.0, 2.0) == 3.0 and M.ratio(1.0, 0) is None


def test_wilson_by_hand():
    # k = 8, n = 10, z = 1.96: centre (0.8 + 0.19208) / 1.38416 = 0.71676,
    # half width 1.96 * sqrt(0.016 + 0.009604) / 1.38416 = 0.22658
    lo, hi = M.wilson(8, 10)
    assert lo == pytest.approx(0.4902, abs=1e-4)
    assert hi == pytest.approx(0.9433, abs=1e-4)
    assert M.wilson(0, 0) == (0.0, 1.0)
    lo, hi = M.wilson(10, 10)
    assert hi == pytest.approx(1.0) and lo == pytest.approx(0.7225, abs=1e-4)     # 10 / (10 + 3.8415)


def test_mcnemar_exact_by_hand():
    # b = 1, c = 5: 2 * (C(6,0) + C(6,1)) / 2^6 = 2 * 7 / 64
    assert M.mcnemar_exact(1, 5) == pytest.approx(14 / 64)
    assert M.mcnemar_exact(5, 1) == pytest.approx(14 / 64)
    assert M.mcnemar_exact(0, 0) == 1.0
    assert M.mcnemar_exact(3, 3) == 1.0
    assert M.mcnemar_exact(0, 6) == pytest.approx(2 / 64)


def test_paired_difference_by_hand():
    # differences 1, 2, 3: mean 2, sd 1, t(0.975, 2) = 4.3027 -> half width 4.3027 / sqrt(3)
    d = M.paired_difference([2, 4, 6, None], [1, 2, 3, 5])
    assert d['n'] == 3 and d['mean'] == pytest.approx(2.0)
    assert d['high'] - d['mean'] == pytest.approx(4.302653 / math.sqrt(3), rel=1e-5)
    assert M.paired_difference([], [])['mean'] is None


def test_detection_judgement():
    truth = [(0.0, 0.0), (2.0, 0.0)]
    ok, f = M.detection(truth, [(0.01, 0.0), (2.0, 0.02)], 0.05)
    assert ok and f['recall'] == 1.0 and f['false_positives'] == 0
    assert f['rms_error'] == pytest.approx(math.sqrt((0.01 ** 2 + 0.02 ** 2) / 2))
    ok, f = M.detection(truth, [(0.01, 0.0)], 0.05)
    assert not ok and f['recall'] == 0.5 and 'missed 1 of 2' in f['problem']
    ok, f = M.detection(truth, [(0.0, 0.0), (2.0, 0.0), (5.0, 5.0)], 0.05)
    assert not ok and 'false positive' in f['problem']
    ok, f = M.detection(truth, [(0.08, 0.0), (2.0, 0.0)], 0.05)
    assert not ok and 'centre error 0.080' in f['problem']


def _box_world(movable=()):
    from tiago_nav.sim.world import World
    from tiago_nav.sim.worlds import enclosure
    b = [0.0, 0.0, 6.0, 4.0]
    return World.from_dict({'name': 'box', 'resolution': 0.05, 'bounds': b, 'robot_start': [1, 2, 0],
                            'walls': enclosure(b),
                            'movable_obstacles': [{'x': x, 'y': y, 'radius': r} for x, y, r in movable]})


def test_shortest_path_and_clearance():
    w = _box_world()
    # straight across the open box: 4 m
    assert M.shortest_path_length(w, (1.0, 2.0), (5.0, 2.0)) == pytest.approx(4.0, abs=0.08)
    # a cylinder on the line makes it longer
    w2 = _box_world([(3.0, 2.0, 0.3)])
    assert M.shortest_path_length(w2, (1.0, 2.0), (5.0, 2.0)) > 4.1
    # the enclosure walls (0.15 thick, centred 0.15 inside the bounds): inner faces at y = 0.225 and
    # 3.775, so a robot at y = 2 has 1.775 - 0.27 clear, exactly
    assert M.min_clearance([(3.0, 2.0, 0.0)], w) == pytest.approx(1.775 - 0.27, abs=1e-9)
    assert M.min_clearance([], w) is None
    # a cylinder (3, 2, r 0.3) 0.8 m from the robot's centre: 0.5 - 0.27 clear
    assert M.min_clearance([(3.0, 2.8)], w2) == pytest.approx(0.5 - 0.27, abs=1e-9)


def test_same_and_differences():
    from tiago_nav_tools.evaluate.run import differences, same
    assert same(0.1 + 0.2, 0.3) and not same(0.3, 0.3 + 1e-6)
    assert same([1.0, {'a': [2.0]}], [1.0, {'a': [2.0 + 1e-13]}])
    assert not same([1.0], [1.0, 2.0]) and not same({'a': 1}, {'b': 1})
    assert not same(True, 1) and not same(None, 0.0) and same('x', 'x')
    a = {'run_id': 'r', 'final_pose': [1.0, 2.0, 0.5], 'wall_s': 3.0, 'outcome': 'succeeded'}
    assert differences(a, dict(a, wall_s=9.0)) == []          # wall-clock fields left out
    assert differences(a, dict(a, final_pose=[1.0, 2.001, 0.5], outcome='aborted')) == \
        ['final_pose', 'outcome']
