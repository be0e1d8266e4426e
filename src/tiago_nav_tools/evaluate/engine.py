"""The engine: Dask distributed (the only module of the package that imports dask).

A ``LocalCluster`` (processes, one thread per worker, ``workers`` processes) when no
scheduler address is given; otherwise the runs go to the existing cluster at ``scheduler``,
whose workers run in shells that sourced the workspace (docs/evaluation.md). Each task is one
run (:func:`tiago_nav_tools.evaluate.run.execute_with_retry`) on the worker's slot. A candidate's
first run goes first: when it fails its interface check (INFRA_CONTRACT after the retry), the
candidate's other runs are not launched and get that verdict.
"""
import os
import time


def _task(spec, out_dir, record):
    from tiago_nav_tools.evaluate.run import execute_with_retry
    return execute_with_retry(spec, out_dir, record)


def _warm_task(specs, out_dir, record, verify_reset):
    from tiago_nav_tools.evaluate.warm import run_group
    return run_group(specs, out_dir, record, verify_reset)


def _skipped(spec, first, out_dir):
    from tiago_nav_tools.evaluate.run import SCHEMA, write_json
    r = {'schema': SCHEMA, 'run_id': spec['id'], 'pair': spec.get('pair'),
         'world': spec['world']['name'], 'world_group': spec['world'].get('group'),
         'goal': spec['goal'], 'profile': spec['profile'], 'use_corridor_law': spec['use_corridor_law'],
         'seed': spec['seed'], 'candidate': spec['candidate'], 'launch_args': spec['launch_args'],
         'outcome': 'INFRA_CONTRACT', 'attempt': 0,
         'reason': 'not run: candidate %s failed its interface check in run %s: %s'
                   % (spec['candidate'], first['run_id'], first['reason'])}
    d = os.path.join(out_dir, 'runs', spec['id'])
    os.makedirs(d, exist_ok=True)
    write_json(os.path.join(d, 'result.json'), r)
    return r


def run_all(specs, out_dir, workers=None, scheduler=None, record=False, progress=None,
            warm=False, verify_reset=0):
    """Run ``specs`` on Dask; ``progress(result)`` after each. Returns the results. ``warm``:
    the rows that can share a stack go to one worker together and run on one stack, reset
    between them (:mod:`tiago_nav_tools.evaluate.warm`; ``verify_reset`` k: the k-th, 2k-th ... reset
    row of each stack is checked against a fresh stack)."""
    from dask.distributed import Client, LocalCluster, as_completed
    if scheduler:
        client, cluster = Client(scheduler), None
    else:
        n = workers or os.cpu_count() or 1
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=40)
        client = Client(cluster)
    out_dir = os.path.abspath(out_dir)
    results = []
    try:
        firsts, rest = [], []
        seen = set()
        for s in specs:
            if s['candidate'] != 'own' and s['candidate'] not in seen:
                seen.add(s['candidate'])
                firsts.append(s)
            else:
                rest.append(s)
        by_key = {}

        def submit(s):
            f = client.submit(_task, s, out_dir, record, key='run-%s-%d' % (s['id'], time.time_ns()),
                              pure=False, retries=0)
            by_key[f.key] = s
            return f

        def submit_group(group):
            f = client.submit(_warm_task, group, out_dir, record, verify_reset,
                              key='stack-%s-%d' % (group[0]['id'], time.time_ns()),
                              pure=False, retries=0)
            by_key[f.key] = group
            return f
        pending = [submit(s) for s in firsts]
        # the rest waits behind the candidates' first runs only where it is theirs
        held = {c: [s for s in rest if s['candidate'] == c] for c in seen}
        free = [s for s in rest if s['candidate'] not in seen]
        if warm:
            from tiago_nav_tools.evaluate.warm import group_by_stack
            pending += [submit_group(g) for g in group_by_stack(free)]
        else:
            pending += [submit(s) for s in free]
        ac = as_completed(pending)
        for f in ac:
            s = by_key[f.key]
            if isinstance(s, list):         # a warm stack's rows
                try:
                    rs = f.result()
                except Exception as e:      # noqa: BLE001  (the rows have no result)
                    rs = [{'run_id': x['id'], 'candidate': x['candidate'], 'outcome': None,
                           'reason': 'task failed: %s: %s' % (type(e).__name__, e)} for x in s]
                for r in rs:
                    results.append(r)
                    if progress:
                        progress(r)
                continue
            try:
                r = f.result()
            except Exception as e:      # noqa: BLE001  (a task that raised: the run has no result)
                r = {'run_id': s['id'], 'candidate': s['candidate'], 'outcome': None,
                     'reason': 'task failed: %s: %s' % (type(e).__name__, e)}
            results.append(r)
            if progress:
                progress(r)
            c = s['candidate']
            if c in held and held[c] is not None and s in firsts:
                waiting, held[c] = held[c], None
                if r.get('outcome') == 'INFRA_CONTRACT':
                    for w in waiting:
                        rr = _skipped(w, r, out_dir)
                        results.append(rr)
                        if progress:
                            progress(rr)
                else:
                    for w in waiting:
                        ac.add(submit(w))
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return results
