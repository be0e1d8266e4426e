"""The evaluator among walkers (docs/evaluation.md#people): the least gap to a walker's legs,
the time spent waiting, and a walker reported as a person or as a static obstacle."""
import math
import os

import pytest

from conftest import ROOT
from tiago_nav.robot import LASER_OFFSET
from tiago_nav_tools.evaluate import metrics as M
from tiago_nav_tools.evaluate import report, run

OFFICE = os.path.join(ROOT, 'worlds', 'office_walkers.yaml')
SPEC = {'id': 'w1', 'pair': 'p1', 'world': {'name': 'office_walkers', 'group': 'office_walkers'},
        'world_path': OFFICE, 'goal': [11.0, 0.5, 30.0], 'profile': 'tiago', 'use_corridor_law': True,
        'seed': 1, 'candidate': 'own', 'launch_args': {},
        'limits': {'detection_tolerance': 0.05, 'sim_time_limit': 100.0}}
BINS = [(11.5, 2.6), (12.4, -1.0)]          # the world's movable cylinders, in view from B
WALKER = (11.12, -0.23)                     # a walker standing 0.76 m from the base at B


def walker_row(x, y, vx=0.0, state='yielding'):
    """One walker as the supervisor records it: centre, velocity, leg radius, legs, state."""
    return [x, y, vx, 0.0, 0.06, [[x, y - 0.1], [x, y + 0.1]], state]


def raw(found_walker=None, motion='static', shape='circle'):
    """A mission that reached B at t = 20 s, the base still from 15 s, a walker near it."""
    truth = [[0.1 * k, 1.5 + 0.05 * k, 0.0, 0.0, 0.5, 0.0] for k in range(150)] + \
        [[0.1 * k, 11.0, 0.5, 0.52, 0.0, 0.0] for k in range(150, 201)]
    walkers = [[0.1 * k, [walker_row(*WALKER)]] for k in range(0, 201, 2)]
    obstacles = [[x, y, 0.2] for x, y in BINS]
    detail = [{'shape': 'circle', 'motion': 'static'} for _ in BINS]
    if found_walker is not None:
        obstacles.append([found_walker[0], found_walker[1], 0.1])
        detail.append({'shape': shape, 'motion': motion})
    return {'state': 3, 'state_name': 'SUCCEEDED', 'status_text': '', 'message': 'arrived',
            'obstacles': obstacles, 'obstacles_detail': detail, 'sim_s': 20.0, 'wall_s': 5.0,
            'collisions': 0, 'final_pose': [11.0, 0.5, math.radians(30)], 'timed_out': False,
            'path': [[1.5, 0.0, 0.0], [11.0, 0.5, 0.52]], 'loc_errors': [[0.01, 0.01, 1.0]],
            'truth_log': truth, 'walkers': walkers}


def test_closest_walker_is_the_gap_of_body_and_leg():
    truth = [[0.0, 0.0, 0.0, 0.0, 0.0, 0.0], [1.0, 1.0, 0.0, 0.0, 0.0, 0.0]]
    walkers = [[0.5, [walker_row(2.0, 0.0)]],           # paired with the pose at t = 0
               [1.0, [walker_row(2.0, 0.1)]]]           # with the pose at t = 1: a leg at 1 m
    gap = M.closest_walker(truth, walkers)
    assert gap == pytest.approx(1.0 - M.ROBOT_RADIUS - 0.06)
    assert M.closest_walker(truth, []) is None and M.closest_walker([], walkers) is None


def test_waiting_counts_standing_still_away_from_the_goal():
    rows = [[0.0, 0.0, 0.0, 0.0, 0.0, 0.0],            # still at the start: 1 s
            [1.0, 0.0, 0.0, 0.0, 0.5, 0.0],            # driving: 1 s
            [2.0, 0.5, 0.0, 0.0, 0.0, 0.3],            # turning on the spot: 1 s
            [3.0, 0.5, 0.0, 0.0, 0.0, 0.0],            # still: 2 s
            [5.0, 2.0, 0.0, 0.0, 0.0, 0.0],            # still at the goal: 1 s
            [6.0, 2.0, 0.0, 0.0, 0.0, 0.0]]
    assert M.waiting_time(rows, (2.0, 0.0)) == pytest.approx(3.0)


def test_a_walker_reported_as_a_person_is_no_false_positive():
    r = run.judge(SPEC, raw(found_walker=(11.10, -0.20), motion='moving'))
    assert r['outcome'] == 'succeeded', r['reason']
    assert (r['walkers_reported'], r['walkers_static'], r['false_positives']) == (1, 0, 0)
    assert run.judge(SPEC, raw(found_walker=(11.10, -0.20), shape='legs'))['outcome'] == 'succeeded'
    assert r['closest_walker_m'] == pytest.approx(
        math.hypot(11.0 - 11.12, 0.5 - (-0.23 + 0.1)) - M.ROBOT_RADIUS - 0.06, abs=1e-6)
    assert r['waiting_s'] == pytest.approx(0.0)     # still only at B


def test_a_walker_reported_as_a_static_obstacle_fails_the_run():
    r = run.judge(SPEC, raw(found_walker=(11.10, -0.20)))
    assert r['outcome'] == 'detection_failure'
    assert 'reported where a walker was, not as a person' in r['reason']
    assert (r['walkers_static'], r['false_positives']) == (1, 0)
    unknown = run.judge(SPEC, raw(found_walker=(11.10, -0.20), motion='unknown'))
    assert unknown['walkers_static'] == 1


def test_a_report_where_no_walker_was_is_a_false_positive():
    r = run.judge(SPEC, raw(found_walker=(9.5, 2.0), motion='moving'))
    assert r['outcome'] == 'detection_failure' and r['false_positives'] == 1
    assert r['walkers_reported'] == 0


def test_worlds_without_walkers_get_no_people_fields():
    spec = dict(SPEC, world_path=os.path.join(ROOT, 'worlds', 'open_hall.yaml'))
    r = run.judge(spec, raw())
    assert 'closest_walker_m' not in r and 'waiting_s' not in r


def test_people_summary_and_section():
    rs = [dict(run.judge(SPEC, raw(found_walker=(11.10, -0.20), motion='moving')), run_wall_s=1.0),
          dict(run.judge(dict(SPEC, id='w2'), raw(found_walker=(11.10, -0.20))), run_wall_s=1.0)]
    (g,) = report.people_summary(rs)
    assert (g['runs'], g['walkers_reported'], g['walkers_static'], g['runs_walker_static']) == (2, 1, 1, 1)
    assert g['runs_under_gap'] == 0 and g['closest_walker_m'] > M.WALKER_GAP
    text = '\n'.join(report.people_lines(rs))
    assert '## People' in text and '| tiago | own | 2 | 0 |' in text


def test_a_centre_not_fixed_is_judged_by_its_bound():
    truth = [(0.0, 0.0)]
    found = [(0.0, 0.20)]                     # 20 cm off along y, the unseen depth
    wide = [0.0004, 0.0, 0.0, 0.0225]        # std 2 cm across, 15 cm along the depth
    narrow = [0.0004, 0.0, 0.0, 0.0004]      # 2 cm both ways: 10 std away
    ok, f = M.detection(truth, found, 0.05)
    assert not ok and 'centre error 0.200' in f['problem']
    ok, f = M.detection(truth, found, 0.05, bounds={0: wide})
    assert ok and (f['bounded'], f['bounded_outside']) == (1, 0)
    assert f['max_error'] == pytest.approx(0.20)            # the error stays in the figures
    ok, f = M.detection(truth, found, 0.05, bounds={0: narrow})
    assert not ok and f['bounded_outside'] == 1 and 'outside their reported bound' in f['problem']
    assert M.outside_bound((0, 0), (0, 0.1), [float('nan')] * 4)
    assert M.outside_bound((0, 0), (0, 0.1), [0.0, 0.0, 0.0, 0.0])


def test_an_obstacle_a_walker_hides_is_not_in_view():
    """The view is cast with the walkers' legs where they stood at the end: a walker standing
    between the base and a cylinder hides it (not in view, no miss); away, the cylinder is in
    view again, and missing it fails the run."""
    lx = 11.0 + LASER_OFFSET * math.cos(math.radians(30.0))
    ly = 0.5 + LASER_OFFSET * math.sin(math.radians(30.0))
    a = math.atan2(BINS[0][1] - ly, BINS[0][0] - lx)
    x, y = lx + 0.8 * math.cos(a), ly + 0.8 * math.sin(a)       # 0.8 m along the line to it
    legs = [[x - 0.06 * math.sin(a), y + 0.06 * math.cos(a)],   # side by side across the line
            [x + 0.06 * math.sin(a), y - 0.06 * math.cos(a)]]
    hidden = raw()
    hidden['walkers'][-1] = [20.0, [[x, y, 0.0, 0.0, 0.06, legs, 'yielding']]]
    hidden['obstacles'] = hidden['obstacles'][1:]
    hidden['obstacles_detail'] = hidden['obstacles_detail'][1:]
    r = run.judge(SPEC, hidden)
    assert r['outcome'] == 'succeeded', r['reason']
    assert not [v for v in r['detection_view'] if v['x'] == BINS[0][0] and v['in_view']]
    seen = raw()
    seen['obstacles'] = seen['obstacles'][1:]
    seen['obstacles_detail'] = seen['obstacles_detail'][1:]
    assert run.judge(SPEC, seen)['outcome'] == 'detection_failure'
