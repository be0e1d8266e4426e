"""The real-data tooling (tiago_nav_tools.testing.realdata): the CARMEN reader and its quirks, the
synthesised odometry, the map built from the scans, the map files and the scoring."""
import gzip
import math
import os

import numpy as np
import pytest

from tiago_nav.gridmap import FREE, OCCUPIED, UNKNOWN, GridMap
from tiago_nav_tools.testing.realdata import carmen, convert, mapping, odometry, scoring

DATA = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), 'data')


def flaser(ranges, pose, t):
    n = len(ranges)
    return 'FLASER %d %s %r %r %r %r %r %r %r host %r\n' % (
        (n, ' '.join('%g' % r for r in ranges)) + tuple(pose) + tuple(pose) + (t, t))


# --- reader ------------------------------------------------------------------------------------
def test_reader_quirks_no_return_headings_and_backward_times():
    lines = ['# comment\n', 'PARAM robot_use_laser on nohost 0\n', 'ODOM 1 2 3 0 0 0 5 h 5\n',
             flaser([1.0, 49.99, 50.0, 81.83], (1.0, 2.0, 4.0), 10.0),
             flaser([2.0, 3.0, 51.2, 4.0], (1.5, 2.0, -7.0), 11.0),
             flaser([2.0, 3.0, 5.0, 4.0], (1.5, 2.0, 0.5), 10.5),      # backwards
             flaser([2.0, 3.0, 5.0, 4.0], (1.5, 2.0, 0.5), 10.9)]      # still before 11.0
    log = carmen.read_lines(lines, 'x')
    assert len(log) == 4 and log.beams == 4
    assert log.ranges[0, 1] == pytest.approx(49.99)
    assert np.isinf(log.ranges[0, 2]) and np.isinf(log.ranges[0, 3]) and np.isinf(log.ranges[1, 2])
    assert np.all(np.isfinite(log.ranges[2]))
    assert np.all((log.poses[:, 2] >= -math.pi) & (log.poses[:, 2] < math.pi))
    assert log.poses[0, 2] == pytest.approx(4.0 - 2 * math.pi)
    assert log.poses[1, 2] == pytest.approx(-7.0 + 2 * math.pi)
    assert np.all(np.diff(log.times) > 0) and log.repaired == 2
    assert log.times[0] == 10.0 and log.times[1] == 11.0 and log.times[3] > log.times[2] > 11.0


def test_reader_refuses_unusable_lines():
    with pytest.raises(carmen.LogError, match='x:2'):
        carmen.read_lines([flaser([1.0, 2.0], (0, 0, 0), 1.0), 'FLASER 3 1 2\n'], 'x')
    with pytest.raises(carmen.LogError, match='x:2: 3 readings'):
        carmen.read_lines([flaser([1.0, 2.0], (0, 0, 0), 1.0),
                           flaser([1.0, 2.0, 3.0], (0, 0, 0), 2.0)], 'x')
    with pytest.raises(carmen.LogError, match='no FLASER'):
        carmen.read_lines(['ODOM 1 2 3 0 0 0 5 h 5\n'], 'x')


def test_beam_angles_are_carmens():
    a = carmen.beam_angles(180)
    assert a[0] == pytest.approx(-math.pi / 2) and np.diff(a) == pytest.approx(math.radians(1.0))
    assert np.diff(carmen.beam_angles(360)) == pytest.approx(math.radians(0.5))


def test_the_shipped_slice_reads_with_its_attribution():
    path = os.path.join(DATA, 'intel-corrected-slice.log.gz')
    with gzip.open(path, 'rt') as f:
        head = f.read(2000)
    assert 'Radish' in head
    log = carmen.read_log(path)
    assert log.name == 'intel-corrected-slice' and log.beams == 180 and len(log) >= 100
    assert np.all(np.diff(log.times) > 0)


# --- odometry ----------------------------------------------------------------------------------
def square_path(n=40, side=4.0):
    """Poses along a square's sides, turning 90° at each corner."""
    out, per = [], n // 4
    for k in range(4):
        th = k * math.pi / 2
        x0, y0 = [(0, 0), (side, 0), (side, side), (0, side)][k]
        for i in range(per):
            d = side * i / per
            out.append((x0 + d * math.cos(th), y0 + d * math.sin(th), carmen.wrap(th)))
    return np.array(out)


def test_noiseless_odometry_is_the_reference_seen_from_the_start():
    ref = square_path() + np.array([3.0, -2.0, 0.0])
    odom = odometry.synthesise(ref, seed=1, scale_sigma=0, turn_fraction=0, per_metre=0)
    assert odom[0] == pytest.approx([0, 0, 0])
    assert odometry.dead_reckoning(ref[0], odom) == pytest.approx(ref, abs=1e-9)


def test_odometry_noise_has_the_recipes_size_and_drift_accumulates():
    straight = np.array([(float(i), 0.0, 0.0) for i in range(101)])     # 100 steps of 1 m
    ends = np.array([odometry.synthesise(straight, seed=s)[-1] for s in range(300)])
    # heading: 0.5 deg per metre per step, independent steps: sqrt(100) x 0.5 deg at the end
    assert np.degrees(np.std(ends[:, 2])) == pytest.approx(5.0, rel=0.15)
    steps = odometry.noisy_steps(np.tile([1.0, 0.0, 0.0], (4000, 1)), np.random.default_rng(0))
    assert np.std(steps[:, 0]) == pytest.approx(0.02, rel=0.1)
    turns = odometry.noisy_steps(np.tile([0.0, 0.0, 1.0], (4000, 1)), np.random.default_rng(0))
    assert np.std(turns[:, 2]) == pytest.approx(0.02, rel=0.1)      # 2 % of a 1 rad turn
    # the drift is composed: dead reckoning's error grows along the way
    dr = odometry.dead_reckoning(straight[0], odometry.synthesise(straight, seed=3))
    err = np.hypot(*(dr[:, :2] - straight[:, :2]).T)
    assert err[-1] > 5 * np.mean(err[:10])


def test_kidnap_scenario_jumps_while_the_odometry_stands_still():
    ref = np.array([(0.5 * i, 0.0, 0.0) for i in range(40)])
    j = odometry.kidnap_index(ref, 10, 3.0)
    assert j == 16
    log = carmen.CarmenLog(np.arange(40.0) + 1, ref, np.ones((40, 3)))
    sc = convert.scenario(log, 'kidnap', seed=0)
    at = int(convert.KIDNAP_AT * 40)
    assert sc.event == at + 1 and len(sc.log) == 40 - (odometry.kidnap_index(ref, at, 3.0) - at - 1)
    assert np.hypot(*(sc.log.poses[sc.event, :2] - sc.log.poses[sc.event - 1, :2])) >= 3.0
    assert sc.odom[sc.event] == pytest.approx(sc.odom[sc.event - 1])
    assert np.hypot(*(sc.odom[sc.event + 1, :2] - sc.odom[sc.event, :2])) == pytest.approx(0.5, rel=0.1)
    off = convert.scenario(log, 'offset').start
    assert math.hypot(off[0] - ref[0, 0], off[1] - ref[0, 1]) == pytest.approx(2.0)
    assert off[2] == pytest.approx(math.pi / 2)


# --- map -----------------------------------------------------------------------------------
def room_scans(poses, n=360, half=2.0, person=None):
    """Ranges of a laser at ``poses`` in a square room ``[-half, half]²`` (a disc ``person``
    ``(x, y, r)`` in the way if given)."""
    angles = carmen.beam_angles(n) * 2        # 360°
    out = []
    for x, y, th in poses:
        a = angles + th
        c, s = np.cos(a), np.sin(a)
        with np.errstate(divide='ignore'):
            tx = np.where(c > 0, (half - x) / c, np.where(c < 0, (-half - x) / c, np.inf))
            ty = np.where(s > 0, (half - y) / s, np.where(s < 0, (-half - y) / s, np.inf))
        r = np.minimum(tx, ty)
        if person is not None:
            px, py, pr = person
            b = c * (px - x) + s * (py - y)
            d2 = (px - x) ** 2 + (py - y) ** 2 - b ** 2
            hit = (b > 0) & (d2 < pr ** 2)
            r = np.where(hit, np.minimum(r, b - np.sqrt(np.maximum(pr ** 2 - d2, 0))), r)
        out.append(r)
    return angles, np.array(out)


def test_map_from_scans_walls_occupied_inside_free_and_a_passer_by_left_out():
    poses = np.array([(-1.0 + 0.1 * i, 0.3 * math.sin(i / 3.0), 0.2 * i) for i in range(21)])
    angles, r = room_scans(poses)
    _, r_person = room_scans(poses[:1], person=(0.0, 1.2, 0.2))
    r[0] = r_person[0]                      # seen once, walked through by the other scans
    g = mapping.build_grid(poses, r, angles)
    assert g.resolution == 0.05

    def at(x, y):
        row, col = g.world_to_cell([(x, y)])[0]
        return g.data[row, col]

    for x, y in ((1.99, 0.0), (-1.99, 0.7), (0.4, 1.99), (-0.9, -1.99)):
        assert at(x, y) == OCCUPIED, (x, y)
    for x, y in ((0.0, 0.0), (1.5, -1.5), (-1.5, 1.0), (0.0, 1.0)):
        assert at(x, y) == FREE, (x, y)
    assert at(0.0, 1.0) == FREE                         # where the person stood once
    assert at(2.6, 0.0) == UNKNOWN                      # beyond the wall
    occupied = g.cell_to_world(np.argwhere(g.data == OCCUPIED))
    wall = np.minimum(np.abs(np.abs(occupied[:, 0]) - 2.0), np.abs(np.abs(occupied[:, 1]) - 2.0))
    assert np.max(wall) <= 0.05                         # nothing occupied off the walls


def test_map_files_round_trip_like_map_server(tmp_path):
    data = np.full((7, 5), UNKNOWN, dtype=np.int8)
    data[1:6, 1:4] = FREE
    data[0, :] = OCCUPIED
    data[3, 2] = OCCUPIED
    g = GridMap(data, 0.05, (-1.25, 3.5))
    path = mapping.save_map(g, str(tmp_path / 'm.yaml'))
    with open(tmp_path / 'm.pgm', 'rb') as f:
        raw = f.read()
    img = np.frombuffer(raw[-35:], dtype=np.uint8).reshape(7, 5)
    assert raw.startswith(b'P5\n5 7\n255\n') and np.all(img[-1] == 0)   # row 0 at the bottom
    back = mapping.load_map(path)
    assert np.array_equal(back.data, data) and back.origin == (-1.25, 3.5) and back.resolution == 0.05
    with open(path) as f:
        text = f.read().replace('0.0]', '0.3]')
    with open(path, 'w') as f:
        f.write(text)
    with pytest.raises(ValueError, match='rotated'):
        mapping.load_map(path)


# --- scoring -------------------------------------------------------------------------------
def test_estimates_carried_by_odometry_between_publications():
    ref = square_path(40)
    times = np.arange(40.0)
    odom = odometry.synthesise(ref, seed=0, scale_sigma=0, turn_fraction=0, per_metre=0)
    pub = np.arange(0, 40, 5)           # published at every fifth scan, exactly
    est = scoring.estimates_at_scans(times, odom, times[pub], ref[pub])
    e, y = scoring.errors(ref, est)
    assert np.max(e) < 1e-9 and np.max(y) < 1e-9
    # an estimate 0.5 m off at scan 10 stays 0.5 m off until the next one
    poses = ref[pub].copy()
    poses[2, 0] += 0.5
    e, _ = scoring.errors(ref, scoring.estimates_at_scans(times, odom, times[pub], poses))
    assert e[10:15] == pytest.approx(0.5) and np.max(e[15:]) < 1e-9 and np.max(e[:10]) < 1e-9
    # nothing before the first estimate
    e, _ = scoring.errors(ref, scoring.estimates_at_scans(times, odom, times[pub[1:]], ref[pub[1:]]))
    assert np.all(np.isnan(e[:5])) and np.all(np.isfinite(e[5:]))


def test_summary_lost_time_and_recovery():
    times = np.arange(20.0)
    times[10:] += 10.0                  # scans 10.. come after a 10 s gap: scan 9 weighs 11 s
    ref = np.zeros((20, 3))
    est = np.zeros((20, 3))
    est[8:12, 0] = 1.0                  # lost over scans 8-11, back at 12
    est[17:, 0] = 0.5                   # lost from 17 to the end
    s = scoring.summary(times, ref, est)
    weights = np.append(np.diff(times), 1.0)
    assert s['lost_time_share'] == pytest.approx((weights[8:12].sum() + weights[17:].sum())
                                                 / weights.sum())
    assert s['lost_episodes'] == 2 and s['recovered_episodes'] == 1
    assert s['time_to_recover_max_s'] == pytest.approx(times[12] - times[8])
    assert s['never_recovered_from_scan'] == 17 and s['tracked_until_share'] == pytest.approx(0.85)
    assert s['max_m'] == pytest.approx(1.0) and s['converged_after_scans'] == 0
    assert scoring.recovery(np.array([1, 1, 0.1, 1, 0.1, 0.1, 0.1]), 0) == 4
    assert scoring.recovery(np.array([1, 0.1, 0.1]), 0) is None


# --- the converter's command line ----------------------------------------------------------
def test_converter_writes_map_and_references(tmp_path, capsys):
    from tiago_nav_tools.testing.realdata.__main__ import main
    slice_path = os.path.join(DATA, 'intel-corrected-slice.log.gz')
    assert main([slice_path, str(tmp_path), '--scenarios', 'tracking,kidnap', '--no-bags']) == 0
    g = mapping.load_map(str(tmp_path / 'map.yaml'))
    assert g.resolution == 0.05 and (g.data == OCCUPIED).sum() > 1000
    t, ref, odom = convert.read_reference(str(tmp_path / 'tracking_reference.csv'))
    log = carmen.read_log(slice_path)
    assert np.allclose(t, log.times, atol=1e-6) and np.allclose(ref, log.poses, atol=1e-6)
    assert odom[0] == pytest.approx([0, 0, 0])
    # every scan's end points at its reference pose fall on occupied cells or next to them
    pts, _ = mapping.scan_endpoints(log.poses[50], log.ranges[50], log.angles())
    d = g.distance_field()[tuple(g.world_to_cell(pts).T)]
    assert np.median(d) <= 0.05
    tk, refk, _ = convert.read_reference(str(tmp_path / 'kidnap_reference.csv'))
    assert len(tk) < len(t)
    assert main([str(tmp_path / 'nope.log'), str(tmp_path)]) == 2
    assert 'nope.log' in capsys.readouterr().err
