"""The evaluator's Dask engine (tiago_nav_tools.evaluate.engine.run_all) on a real in-process Dask
cluster, with the runs themselves faked: every run is submitted and its result returned; a
candidate's other runs wait for its first, and are not run when that one fails its interface
check. Checks the engine against whichever dask[distributed] is installed (2023.5.0, the last
for Noetic's Python 3.8, as well as the newest)."""
import pytest

pytest.importorskip('distributed')
from distributed import LocalCluster                          # noqa: E402

from tiago_nav_tools.evaluate import engine, run                    # noqa: E402


def spec(run_id, candidate):
    return {'id': run_id, 'candidate': candidate, 'pair': None, 'world': {'name': 'w', 'group': None},
            'goal': [1.0, 0.0, 0.0], 'profile': 'ideal', 'use_corridor_law': False, 'seed': 0,
            'launch_args': {}}


@pytest.fixture
def cluster():
    c = LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None,
                     silence_logs=40)
    yield c
    c.close()


def test_run_all_on_dask(tmp_path, monkeypatch, cluster):
    done = []

    def fake(s, out_dir, record=False):
        done.append(s['id'])
        outcome = 'INFRA_CONTRACT' if s['id'] == 'bad-1' else 'SUCCEEDED'
        return {'run_id': s['id'], 'candidate': s['candidate'], 'outcome': outcome,
                'reason': 'fake: ' + outcome}
    monkeypatch.setattr(run, 'execute_with_retry', fake)      # the workers are threads here
    specs = [spec('own-1', 'own'), spec('own-2', 'own'), spec('bad-1', 'bad'), spec('bad-2', 'bad'),
             spec('good-1', 'good'), spec('good-2', 'good')]
    seen = []
    results = engine.run_all(specs, str(tmp_path), scheduler=cluster.scheduler_address,
                             progress=lambda r: seen.append(r['run_id']))
    by_id = {r['run_id']: r for r in results}
    assert sorted(by_id) == sorted(s['id'] for s in specs) and sorted(seen) == sorted(by_id)
    assert sorted(done) == ['bad-1', 'good-1', 'good-2', 'own-1', 'own-2']     # bad-2 never ran
    assert by_id['bad-2']['outcome'] == 'INFRA_CONTRACT' and 'not run' in by_id['bad-2']['reason']
    assert (tmp_path / 'runs' / 'bad-2' / 'result.json').exists()
    assert done.index('good-2') > done.index('good-1')         # a candidate's first run goes first
    assert all(by_id[i]['outcome'] == 'SUCCEEDED' for i in ('own-1', 'own-2', 'good-1', 'good-2'))
