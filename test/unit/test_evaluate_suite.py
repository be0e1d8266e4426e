"""Suite files: expansion, id stability, errors (exit 2), the command line's dry run and
resume; Dask is imported by the evaluator's engine only."""
import ast
import json
import os

import pytest
import yaml

from conftest import ROOT
from tiago_nav_tools.evaluate import cli, suite
from tiago_nav_tools.evaluate.suite import SuiteError

COURSE = os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml')
SMALL = {'name': 't', 'worlds': [{'file': COURSE, 'poses': [[11.0, 0.0, -45.0]]}],
         'corridor_law': [True, False], 'seeds': [1, 2],
         'candidates': [{'name': 'c', 'replaces': 'detection', 'command': 'true'}]}


def write(tmp_path, data, name='s.yaml'):
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data))
    return str(p)


def test_expansion_and_stable_ids():
    runs, gen = suite.expand(SMALL, 's.yaml', ROOT)
    assert len(runs) == 1 * 1 * 2 * 2 * 2 and gen == {}
    assert len({r['id'] for r in runs}) == len(runs)
    # the same row gives the same id, whatever the order of keys or where the file lies
    again, _ = suite.expand(json.loads(json.dumps(SMALL)), 'elsewhere.yaml', '/')
    assert [r['id'] for r in runs] == [r['id'] for r in again]
    for r in runs:
        assert suite.run_id(dict(r, world_file='/moved/world.yaml')) == r['id']
        assert isinstance(r['seed'], int)
    # a candidate's run pairs with the own nodes' run on the same scenario
    own = {r['pair'] for r in runs if r['candidate'] == 'own'}
    assert {r['pair'] for r in runs if r['candidate'] == 'c'} == own
    # any change of the row changes the id
    changed, _ = suite.expand(dict(SMALL, seeds=[1, 3]), 's.yaml', ROOT)
    assert len({r['id'] for r in changed} & {r['id'] for r in runs}) == 4


def test_known_id_is_pinned():
    """An id is a function of the row only: this one must not change between versions."""
    runs, _ = suite.expand({'worlds': [{'file': COURSE, 'poses': [[11.0, 0.0, -45.0]]}],
                            'seeds': [1]}, 's.yaml', ROOT)
    assert len(runs) == 1
    assert runs[0]['id'] == suite.run_id({k: v for k, v in runs[0].items()})
    assert runs[0]['launch_args'] == {'laser_model': 'tiago', 'laser_noise': 0.01,
                                      'localisation': 'scan_matching', 'odometry_model': 'drift'}


def test_generated_worlds_and_sampled_poses_repeat():
    data = {'worlds': [{'generate': {'count': 2, 'seed': 4}, 'poses': {'sample': 2, 'seed': 9}}]}
    a, ga = suite.expand(data, 's.yaml', ROOT)
    b, gb = suite.expand(data, 's.yaml', ROOT)
    assert [r['id'] for r in a] == [r['id'] for r in b] and ga == gb
    assert sorted(ga) == ['rooms_4', 'rooms_5'] and len(a) == 4


@pytest.mark.parametrize('data, field', [
    ({'worlds': []}, 'worlds'),
    ({'worlds': [{'file': 'nope.yaml', 'poses': [[0, 0, 0]]}]}, 'worlds[0].file'),
    ({'worlds': [{'file': COURSE}]}, 'worlds[0].poses'),
    ({'worlds': [{'file': COURSE, 'poses': [[0, 0]]}]}, 'worlds[0].poses[0]'),
    ({'worlds': [{'file': COURSE, 'poses': [[1, 0, 0]]}], 'profiles': {'p': {'laser_model': 'x'}}},
     'profiles.p.laser_model'),
    ({'worlds': [{'file': COURSE, 'poses': [[1, 0, 0]]}], 'seeds': [-1]}, 'seeds[0]'),
    ({'worlds': [{'file': COURSE, 'poses': [[1, 0, 0]]}], 'corridor_law': ['yes']}, 'corridor_law'),
    ({'worlds': [{'file': COURSE, 'poses': [[1, 0, 0]]}],
      'candidates': [{'name': 'x', 'replaces': 'planner', 'command': 'true'}]}, 'candidates[0].replaces'),
    ({'worlds': [{'file': COURSE, 'poses': [[1, 0, 0]]}],
      'candidates': [{'name': 'own', 'replaces': 'detection', 'command': 'true'}]}, 'candidates[0].name'),
    ({'worlds': [{'file': COURSE, 'poses': [[1, 0, 0]]}], 'defaults': {'sim_time_limit': 0}},
     'defaults.sim_time_limit'),
    ({'worlds': [{'file': COURSE, 'poses': [[1, 0, 0]]}], 'extra': 1}, '(top level)'),
])
def test_suite_errors_name_the_field_and_exit_2(tmp_path, capsys, data, field):
    path = write(tmp_path, data)
    with pytest.raises(SuiteError) as e:
        suite.expand(suite.load(path)[0], path, str(tmp_path))
    assert e.value.field == field and e.value.path == path
    assert cli.main([path, '--out', str(tmp_path / 'o'), '--dry-run']) == 2
    err = capsys.readouterr().err
    assert path in err and field in err


def test_bad_arguments_exit_2(tmp_path):
    path = write(tmp_path, SMALL)
    for argv in ([path], [path, '--out', 'o', '--workers', '0'],
                 [path, '--out', 'o', '--workers', '2', '--scheduler', 'tcp://127.0.0.1:8786'],
                 [path, '--out', 'o', '--only', 'zzzz', '--dry-run']):
        with pytest.raises(SystemExit) as e:
            code = cli.main(argv)
            raise SystemExit(code)
        assert e.value.code == 2, argv
    assert cli.main(['/no/such/suite.yaml', '--out', 'o']) == 2


def test_dry_run_lists_the_runs(tmp_path, capsys):
    path = write(tmp_path, SMALL)
    assert cli.main([path, '--out', str(tmp_path / 'o'), '--dry-run']) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[-1] == '8 runs' and len(out) == 9


def test_resume_skips_finished_runs(tmp_path, capsys, monkeypatch):
    """Runs with a result.json are not run again; the others are; every output is written."""
    path = write(tmp_path, SMALL)
    out = tmp_path / 'o'
    runs, _ = suite.expand(SMALL, path, str(tmp_path))
    from tiago_nav_tools.evaluate import engine
    calls = []

    def fake_run_all(todo, out_dir, **kw):
        calls.append([r['id'] for r in todo])
        for r in todo:
            d = os.path.join(out_dir, 'runs', r['id'])
            os.makedirs(d, exist_ok=True)
            with open(os.path.join(d, 'result.json'), 'w') as f:
                json.dump({'run_id': r['id'], 'outcome': 'succeeded', 'reason': '', 'pair': r['pair'],
                           'candidate': r['candidate'], 'world': 'w', 'profile': 'tiago',
                           'seed': r['seed'], 'goal': r['goal'], 'time_s': 10.0, 'run_wall_s': 1.0}, f)
            kw['progress']({'run_id': r['id'], 'outcome': 'succeeded'})
    monkeypatch.setattr(engine, 'run_all', fake_run_all)
    # a first batch that ran only two runs (as if killed)
    assert cli.main([path, '--out', str(out), '--only', runs[0]['id'], runs[1]['id']]) == 0
    assert calls == [[runs[0]['id'], runs[1]['id']]]
    # the whole suite without --resume would miss nothing; with it, only the other six run
    assert cli.main([path, '--out', str(out), '--resume']) == 0
    assert calls[1] == [r['id'] for r in runs[2:]]
    for f in ('results.csv', 'summary.md', 'summary.json', 'junit.xml', 'manifest.json'):
        assert (out / f).exists(), f
    # a run whose result disappeared is a failure (exit 1), never a skip
    monkeypatch.setattr(engine, 'run_all', lambda todo, out_dir, **kw: None)
    os.remove(out / 'runs' / runs[3]['id'] / 'result.json')
    assert cli.main([path, '--out', str(out), '--resume']) == 1
    assert 'NO_RESULT' in (out / 'results.csv').read_text()


def test_only_the_engine_imports_dask():
    src = os.path.join(ROOT, 'src', 'tiago_nav')
    bad = []
    for d, _, files in os.walk(src):
        for f in files:
            if not f.endswith('.py'):
                continue
            p = os.path.join(d, f)
            tree = ast.parse(open(p).read())
            for node in ast.walk(tree):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                    [node.module or ''] if isinstance(node, ast.ImportFrom) else []
                if any(n.split('.')[0] in ('dask', 'distributed') for n in names) and \
                        os.path.relpath(p, src) != os.path.join('evaluate', 'engine.py'):
                    bad.append(os.path.relpath(p, src))
    assert not bad


@pytest.mark.parametrize('name', sorted(f for f in os.listdir(os.path.join(ROOT, 'suites'))
                                        if f.endswith('.yaml')))
def test_every_shipped_suite_expands_and_its_candidates_launch_files_are_in_the_package(name):
    path = os.path.join(ROOT, 'suites', name)
    data, base = suite.load(path)
    runs, _ = suite.expand(data, path, base)
    assert runs and len({r['id'] for r in runs}) == len(runs)
    for c in data.get('candidates') or []:
        words = c.get('launch', '').split()
        if words and words[0] == 'tiago_nav':   # roslaunch finds FILE anywhere in the package
            found = [d for d, _, files in os.walk(ROOT) if words[1] in files
                     and not os.path.relpath(d, ROOT).startswith('.')]
            assert found, '%s: candidate %s: no %s in the package' % (name, c['name'], words[1])
