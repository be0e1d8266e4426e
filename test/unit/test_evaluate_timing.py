"""Where a run's time goes: the phases from the supervisor's stage marks, the batch's
breakdown and summary.md's "Where the time goes" (tiago_nav_tools.evaluate.timing, report)."""
import os
import subprocess
import sys
import time

import pytest

from tiago_nav_tools.evaluate import report, run, timing


def test_phases_of_a_whole_run():
    marks = {'startup': (100.2, 0.1), 'mission': (104.0, 3.0), 'teardown': (106.5, 5.5),
             'done': (107.9, 5.9)}
    p = timing.phases(marks, start=100.0, end=108.0, cpu_total=6.5, judging_wall=0.3, judging_cpu=0.25)
    assert p['startup'] == {'wall_s': pytest.approx(4.0), 'cpu_s': pytest.approx(3.0)}
    assert p['mission'] == {'wall_s': pytest.approx(2.5), 'cpu_s': pytest.approx(2.5)}
    assert p['teardown'] == {'wall_s': pytest.approx(1.5), 'cpu_s': pytest.approx(1.0)}
    assert p['judging'] == {'wall_s': 0.3, 'cpu_s': 0.25}
    # the three phases of the run's processes add up to its wall time
    assert sum(p[k]['wall_s'] for k in ('startup', 'mission', 'teardown')) == pytest.approx(8.0)


def test_phases_of_a_failed_startup_and_of_no_marks():
    p = timing.phases({'startup': (10.1, 0.0), 'teardown': (40.0, 7.0)}, 10.0, 41.0, 7.5, 0.01, 0.01)
    assert p['startup']['wall_s'] == pytest.approx(30.0) and p['startup']['cpu_s'] == 7.0
    assert p['mission'] == {'wall_s': 0.0, 'cpu_s': 0.0}
    assert p['teardown']['cpu_s'] == pytest.approx(0.5)
    # a supervisor killed before its first mark: all start-up, CPU unknown
    p = timing.phases({}, 10.0, 12.0, 1.0, 0.0, 0.0)
    assert p['startup']['wall_s'] == pytest.approx(2.0) and p['startup']['cpu_s'] is None
    assert p['mission']['wall_s'] == 0.0 and p['teardown']['wall_s'] == 0.0


def test_marks_measure_the_tree_cpu(tmp_path):
    """mark() counts the CPU of the processes carrying the token, children included."""
    env = dict(os.environ, TIAGO_TEST_TOKEN='t%d' % os.getpid())
    # the child says when it has burnt its CPU (any wall time on a loaded machine)
    burn = ('import sys, time\nt = time.process_time()\nwhile time.process_time() - t < 0.5: pass\n'
            'print("burnt", flush=True)\nsys.stdin.read()')
    child = subprocess.Popen([sys.executable, '-c', burn], env=env, stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == 'burnt'
        timing.mark(str(tmp_path), 'mission', env['TIAGO_TEST_TOKEN'], 'TIAGO_TEST_TOKEN')
        timing.mark(str(tmp_path), 'mission', None, None)          # a second mark: ignored
    finally:
        child.kill()
        child.wait()
    m = timing.read_marks(str(tmp_path))
    assert set(m) == {'mission'} and 0.5 <= m['mission'][1] < 5.0
    assert abs(m['mission'][0] - time.monotonic()) < 30


def result(rid, startup, mission, teardown, judging=0.2, outcome='succeeded'):
    return {'run_id': rid, 'outcome': outcome, 'run_wall_s': startup + mission + teardown,
            'isolation': 'netns',
            'phases': {'startup': {'wall_s': startup, 'cpu_s': startup * 0.9},
                       'mission': {'wall_s': mission, 'cpu_s': mission * 1.5},
                       'teardown': {'wall_s': teardown, 'cpu_s': 0.1},
                       'judging': {'wall_s': judging, 'cpu_s': judging}}}


def test_batch_breakdown_and_mission_share():
    rs = [result('a', 4.0, 2.0, 1.8), result('b', 3.8, 1.8, 2.0), {'run_id': 'c', 'outcome': 'NO_RESULT'}]
    t = timing.batch(rs, wall_s=8.0, workers=2)
    assert t['runs'] == 2
    assert t['phases']['mission']['wall_s'] == pytest.approx(3.8)
    assert t['phases']['mission']['median_wall_s'] == pytest.approx(1.9)
    assert t['phases']['mission']['cpu_s'] == pytest.approx(5.7)
    assert t['run_wall_s'] == pytest.approx(4 + 2 + 1.8 + 3.8 + 1.8 + 2.0 + 0.4)
    assert sum(p['wall_share'] for p in t['phases'].values()) == pytest.approx(1.0)
    assert t['mission_share'] == pytest.approx(3.8 / 16.0)            # of 8 s x 2 workers
    # no worker count (a cluster of its own): of the runs' summed wall time
    assert timing.batch(rs, 8.0, None)['mission_share'] == pytest.approx(3.8 / t['run_wall_s'])
    assert timing.batch([{'run_id': 'x'}], 1.0, 1) is None


def test_summary_shows_where_the_time_goes_and_the_isolation(tmp_path):
    rs = [result('a', 4.0, 2.0, 1.8), dict(result('b', 3.8, 1.8, 2.0), isolation='loopback')]
    for r in rs:
        r.update(world='w', world_group='g', profile='ideal', candidate='own', pair=r['run_id'],
                 goal=[1.0, 2.0, 0.0], seed=0, use_corridor_law=True)
    report.write_all(str(tmp_path), [], rs, wall_s=8.0, workers=2)
    md = (tmp_path / 'summary.md').read_text()
    assert 'Isolation: loopback (the host network' in md and 'netns (each run in a network namespace' in md
    assert '## Where the time goes' in md and 'Missions took 23.8 % of the batch' in md
    assert '| mission | 3.8 |' in md
    assert '| `a` | succeeded | 4.00 / 3.60 | 2.00 / 3.00 | 0.20 / 0.20 | 1.80 / 0.10 |' in md
    s = run.read_json(str(tmp_path / 'summary.json'))
    assert s['meta']['isolation'] == {'netns': 1, 'loopback': 1}
    assert s['meta']['time']['mission_share'] == pytest.approx(3.8 / 16.0)


def test_phases_and_isolation_are_wall_clock_fields():
    a = result('a', 4.0, 2.0, 1.8)
    assert run.differences(a, dict(result('a', 9.0, 1.0, 0.5), isolation='loopback')) == []


def test_benchmarks_page_shows_where_the_time_goes():
    from tiago_nav_tools import benchmarks
    rs = [result('a', 4.0, 2.0, 1.8), result('b', 3.8, 1.8, 2.0)]
    setting = {'setting': '2 workers', 'runs': 2, 'results': 2, 'wall_s': 8.0, 'missions_per_minute': 15.0,
               'outcomes': {'succeeded': 2}, 'isolation': report.isolations(rs),
               'time': timing.batch(rs, 8.0, 2)}
    text = '\n'.join(benchmarks.render_evaluate({'run_ids': ['a', 'b'], 'suite': 's.yaml',
                                                 'settings': [setting]}))
    assert 'Where the time goes' in text
    assert '| 2 workers | netns 2 | 23.8 % | 3.9 / 3.51 | 1.9 / 2.85 | 1.9 / 0.1 | 0.2 / 0.2 |' in text
    # results without the breakdown (older JSON): no such table
    old = dict(setting)
    del old['time']
    assert 'Where the time goes' not in '\n'.join(benchmarks.render_evaluate({'settings': [old]}))
