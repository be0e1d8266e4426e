"""One real evaluation run end to end (no Dask): the course mission with the ideal sensing
profile on a slot's private master; skipped without a built, sourced workspace."""
import os
import shutil

import pytest

from conftest import NO_WORKSPACE, ROOT, WORKSPACE_REASON
from tiago_nav_tools.evaluate import run, suite

pytestmark = [pytest.mark.ros, pytest.mark.skipif(NO_WORKSPACE, reason=WORKSPACE_REASON)]


def test_one_real_run_twice(tmp_path):
    data = {'worlds': [{'file': os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml'),
                        'poses': [[11.0, 0.0, -45.0]]}],
            'profiles': {'ideal': {'laser_model': 'ideal', 'odometry_model': 'ideal',
                                   'localisation': 'ground_truth', 'laser_noise': 0.01}},
            'defaults': {'sim_time_limit': 120, 'wall_time_limit': 120, 'startup_timeout': 60}}
    (spec,), _ = suite.expand(data, 'e2e.yaml', ROOT)
    r = run.execute(spec, str(tmp_path / 'first'))
    assert r['outcome'] in run.OUTCOMES and r['outcome'] not in run.INFRA, r.get('reason')
    assert r['outcome'] == 'succeeded', r.get('reason')
    assert r['in_view'] == 4 and r['collisions'] == 0 and r['time_s'] > 0
    assert run.read_json(str(tmp_path / 'first' / 'runs' / spec['id'] / 'result.json'))['run_id'] == spec['id']
    # torn down to the last process
    assert not run.tagged_pids('%s.%d.1' % (spec['id'], os.getpid()))
    # the same row again: the same result, but for the wall-clock figures
    again = run.execute(spec, str(tmp_path / 'second'))
    assert run.differences(r, again) == []
    assert run.differences(r, dict(again, final_pose=[0.0, 0.0, 0.0])) == ['final_pose']


def every_scan(log):
    """Whether a log of ``[stamp, ...]`` has an entry for every scan, none missing."""
    from tiago_nav.sim.simulator import SimConfig
    stamps = [e[0] for e in log]
    return max(b - a for a, b in zip(stamps, stamps[1:])) < 1.5 / SimConfig().scan_rate


def test_a_run_among_walkers_records_them_and_repeats(tmp_path):
    """The office with four walkers: the supervisor records the walkers and the true poses over
    the whole mission, and the people figures are a function of the row (the same twice)."""
    data = {'worlds': [{'file': os.path.join(ROOT, 'worlds', 'office_walkers.yaml'),
                        'poses': [[11.0, 0.5, 30.0]]}],
            'profiles': {'ideal': {'laser_model': 'ideal', 'odometry_model': 'ideal',
                                   'localisation': 'ground_truth', 'laser_noise': 0.01}},
            'defaults': {'sim_time_limit': 120, 'wall_time_limit': 120, 'startup_timeout': 60}}
    (spec,), _ = suite.expand(data, 'e2e.yaml', ROOT)
    r = run.execute(spec, str(tmp_path / 'first'))
    assert r['outcome'] not in run.INFRA and r['outcome'] != 'timeout', r.get('reason')
    raw = run.read_json(str(tmp_path / 'first' / 'runs' / spec['id'] / 'raw.json'))
    truth, walkers = raw['truth_log'], raw['walkers']
    # from the goal to the result, every scan's walkers (four, none missing) and the poses
    # between them
    assert walkers and all(len(w) == 4 for _, w in walkers)
    assert truth[-1][0] - truth[0][0] == pytest.approx(r['time_s'], abs=0.2)
    assert walkers[-1][0] - walkers[0][0] == pytest.approx(r['time_s'], abs=0.2)
    assert every_scan(walkers) and r['end_missing'] == []
    assert r['collisions'] == 0 and 0.0 < r['closest_walker_m'] < 3.0
    assert 0.0 <= r['waiting_s'] < r['time_s']
    # move_base's costmap, once a second of simulated time, watched for ghosts
    assert len(raw['ghosts']) == pytest.approx(r['time_s'], abs=2.0)
    periods = [int(g[0] + 1e-6) for g in raw['ghosts']]         # one in each second, none missing
    assert periods == list(range(periods[0], periods[0] + len(periods)))
    assert r['ghost_age_s'] is not None and r['ghost_age_s'] >= 0.0
    again = run.execute(spec, str(tmp_path / 'second'))
    assert every_scan(run.read_json(str(tmp_path / 'second' / 'runs' / spec['id'] / 'raw.json'))['walkers'])
    assert run.differences(r, again) == []


def test_a_candidate_starts_on_simulated_time(tmp_path):
    """A candidate node reads /use_sim_time once, as it starts (roscpp, rospy): the evaluator
    starts it once demo.launch has set it. This candidate is the package's detection, started
    only when /use_sim_time is true at its start, and exiting at once otherwise (which the
    evaluator reports as INFRA_CONTRACT)."""
    check = 'test "$(rosparam get /use_sim_time)" = true'
    data = {'worlds': [{'file': os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml'),
                        'poses': [[11.0, 0.0, -45.0]]}],
            'profiles': {'ideal': {'laser_model': 'ideal', 'odometry_model': 'ideal',
                                   'localisation': 'ground_truth', 'laser_noise': 0.01}},
            'defaults': {'sim_time_limit': 120, 'wall_time_limit': 120, 'startup_timeout': 60},
            'candidates': [{'name': 'sim_time_detection', 'replaces': 'detection',
                            'command': "bash -c '%s && exec rosrun tiago_nav obstacle_detection "
                                       "__name:=obstacle_detection'" % check}]}
    runs, _ = suite.expand(data, 'e2e.yaml', ROOT)
    (spec,) = [r for r in runs if r['candidate'] == 'sim_time_detection']
    r = run.execute(spec, str(tmp_path / 'run'))
    assert r['outcome'] == 'succeeded', r.get('reason')
