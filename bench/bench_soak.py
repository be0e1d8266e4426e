#!/usr/bin/python3
"""Soak benchmark: many whole missions over the real chain (demo.launch), one after the other,
over seeded random reachable poses B (tiago_nav_tools.evaluate.matching.sample_goals) in the shipped
worlds and in generated ones (tiago_nav.sim.worlds.corridor_world variants), alternating the
corridor law on and off.

Per world one launch (a private master); missions follow each other (each starts where the last
ended). Counted: successes; hangs (no terminal state within --limit wall seconds: the task is
then cancelled); collisions (/sim/collisions during the mission); node deaths (a node of the
launch that no longer answers, checked after every mission); and every non-success's message.
Target: 0 hangs, 0 collisions, 0 node deaths, every non-success explained.
Writes bench/results/soak.json and soak.png.

Usage: bench/bench_soak.py [--quick] [--n 10] [--seed 11] [--rtf 5] [--limit 150]
"""
import argparse
import collections
import json
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.abspath(os.path.dirname(__file__)))
RESULTS = os.path.join(ROOT, 'bench', 'results')
SHIPPED = ['ias_lab_room_full.yaml', 'open_hall.yaml']
# generated worlds: corridor_world keyword arguments (a closed room whose only way out is the
# corridor, open floor after it, walled in at the map's bounds; an unmapped cylinder beyond
# the corridor for detection)
GENERATED = {
    'gen_straight_0.9': dict(width=0.9, length=4.0, obstacle=(6.0, 1.0, 0.18)),
    'gen_bend_1.2': dict(width=1.2, length=5.0, bend_deg=30.0, bend_at=2.5,
                         obstacle=(6.5, 2.8, 0.2)),
    'gen_straight_1.5': dict(width=1.5, length=3.0, obstacle=(5.0, -1.2, 0.18)),
}


def world_path(name, tmp):
    """The world file of a shipped (``*.yaml``) or generated world name."""
    if name.endswith('.yaml'):
        return os.path.join(ROOT, 'worlds', name)
    import yaml
    from tiago_nav.sim.worlds import corridor_world, enclosure
    world = corridor_world(name=name, **GENERATED[name])
    world['walls'] += enclosure(world['bounds'])
    path = os.path.join(tmp, name + '.yaml')
    with open(path, 'w') as f:
        yaml.safe_dump(world, f)
    return path


def run_world(name, n, seed, rtf, limit):
    """Child process: one launch, ``n`` missions in world ``name``; prints ``RESULT <json>``."""
    import numpy as np
    from tiago_nav.sim.world import load_world
    from tiago_nav_tools.evaluate.matching import sample_goals
    from tiago_nav_tools.testing.harness import Harness, mission_record

    tmp = tempfile.mkdtemp(prefix='soak_')
    path = world_path(name, tmp)
    world = load_world(path)
    goals = sample_goals(world, n, np.random.default_rng(seed))
    h = Harness(path, real_time_factor=rtf)
    out, dead = [], []
    try:
        h.connect(timeout=120.0)
        for k, goal in enumerate(goals):
            corridor = k % 2 == 0          # the first mission (from the start) with the law
            # in view: tiago_nav_tools.evaluate.inview (obstacles behind the robot's own body are not)
            rec = mission_record(h, world, goal, corridor, limit=limit)
            rec['world'] = name
            rec['dead_nodes'] = [d for d in h.dead_nodes() if d not in dead]
            dead += rec['dead_nodes']
            out.append(rec)
            verdict = 'ok' if rec['succeeded'] else ('HANG' if rec['hang'] else 'failed')
            print('  %-22s B=(%6.2f, %6.2f, %5.0f) corridor=%-5s %-6s wall %5.1f s  sim %5.1f s  '
                  'collisions %d%s' % (name, goal[0], goal[1], goal[2], corridor, verdict,
                                       rec['wall_s'], rec['sim_s'], rec['collisions'],
                                       '  DEAD: %s' % rec['dead_nodes'] if rec['dead_nodes'] else ''),
                  flush=True)
            if not rec['succeeded']:
                print('    %s' % rec['message'], flush=True)
            if '/simulator' in dead:
                break
    except Exception as e:
        print('  %s: error: %s' % (name, e), flush=True)
        out.append({'world': name, 'error': str(e), 'succeeded': False, 'hang': False,
                    'collisions': 0, 'dead_nodes': [], 'message': 'harness: %s' % e})
    finally:
        h.close()
    print('RESULT ' + json.dumps(out), flush=True)


def summarise(missions):
    """Counts over ``missions`` (records of :func:`tiago_nav_tools.testing.harness.mission_record`)."""
    failed = [m for m in missions if not m.get('succeeded')]
    return {'missions': len(missions),
            'succeeded': len(missions) - len(failed),
            'hangs': sum(1 for m in missions if m.get('hang')),
            'collisions': sum(m.get('collisions', 0) for m in missions),
            'node_deaths': sum(len(m.get('dead_nodes', [])) for m in missions),
            'unexplained': sum(1 for m in failed if not m.get('message')),
            'failures': [{'world': m['world'], 'goal': m.get('goal'),
                          'use_corridor_law': m.get('use_corridor_law'),
                          'message': m.get('message')} for m in failed]}


def plot(missions, path):
    """Outcome of every mission per world and corridor flag (stacked bars) and wall times."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    groups = collections.OrderedDict()
    for m in missions:
        key = '%s\n%s' % (m['world'], 'law on' if m.get('use_corridor_law') else 'law off')
        groups.setdefault(key, []).append(m)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(14, 5))
    xs = range(len(groups))
    bottom = [0] * len(groups)
    for label, colour, pick in (
            ('succeeded', 'tab:green', lambda m: m.get('succeeded')),
            ('failed (explained)', 'tab:orange',
             lambda m: not m.get('succeeded') and not m.get('hang') and m.get('message')),
            ('hang', 'tab:red', lambda m: m.get('hang'))):
        vals = [sum(1 for m in ms if pick(m)) for ms in groups.values()]
        a1.bar(xs, vals, bottom=bottom, color=colour, label=label)
        bottom = [b + v for b, v in zip(bottom, vals)]
    a1.set_xticks(list(xs))
    a1.set_xticklabels(list(groups), fontsize=7)
    a1.set_ylabel('missions')
    a1.set_title('soak: outcome per world and corridor flag')
    a1.legend(fontsize=8)
    walls = [m['wall_s'] for m in missions if 'wall_s' in m]
    a2.plot(range(len(walls)), walls, 'o-', ms=3)
    a2.set_xlabel('mission (in order)')
    a2.set_ylabel('wall time [s]')
    a2.set_title('wall time per mission')
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--quick', action='store_true', help='2 missions per world')
    ap.add_argument('--n', type=int, default=10, help='missions per world')
    ap.add_argument('--seed', type=int, default=11)
    ap.add_argument('--rtf', type=float, default=5.0, help='simulator real_time_factor')
    ap.add_argument('--limit', type=float, default=150.0,
                    help='[s wall] a mission without a terminal state by then is a hang')
    ap.add_argument('--run', help=argparse.SUPPRESS)
    args = ap.parse_args()
    n = 2 if args.quick else args.n
    if args.run:
        run_world(args.run, n, args.seed, args.rtf, args.limit)
        return 0
    t0 = time.monotonic()
    worlds = SHIPPED + list(GENERATED)
    print('soak: %d missions per world in %d worlds (seed %d), real_time_factor %g, hang bound '
          '%g s' % (n, len(worlds), args.seed, args.rtf, args.limit), flush=True)
    missions = []
    for k, w in enumerate(worlds):
        cmd = [sys.executable, os.path.abspath(__file__), '--run', w, '--n', str(n),
               '--seed', str(args.seed + k), '--rtf', str(args.rtf), '--limit', str(args.limit)]
        p = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
        for line in p.stdout:
            if line.startswith('RESULT '):
                missions += json.loads(line[7:])
            elif line.startswith('  '):
                sys.stdout.write(line)
                sys.stdout.flush()
        p.wait()
    s = summarise(missions)
    report = {'seed': args.seed, 'missions_per_world': n, 'real_time_factor': args.rtf,
              'hang_bound_s': args.limit, 'worlds': worlds, 'generated': GENERATED,
              'summary': s, 'by_world': {}, 'missions': missions,
              'bench_wall_s': time.monotonic() - t0}
    print('\n| world | corridor law | missions | succeeded | hangs | collisions | node deaths |')
    print('|---|---|---|---|---|---|---|')
    for w in worlds:
        for law in (True, False):
            ms = [m for m in missions if m['world'] == w and m.get('use_corridor_law', law) == law]
            g = summarise(ms)
            report['by_world']['%s/%s' % (w, 'on' if law else 'off')] = g
            print('| %s | %s | %d | %d | %d | %d | %d |' % (w, 'on' if law else 'off',
                                                           g['missions'], g['succeeded'],
                                                           g['hangs'], g['collisions'],
                                                           g['node_deaths']))
    print('| all | | %d | %d | %d | %d | %d |' % (s['missions'], s['succeeded'], s['hangs'],
                                                 s['collisions'], s['node_deaths']))
    print('\nevery non-success and its message:')
    for f in s['failures']:
        print('  %s B=%s corridor=%s: %s' % (f['world'], f['goal'], f['use_corridor_law'],
                                              f['message'] or '(NO MESSAGE)'))
    met = (s['hangs'] == 0 and s['collisions'] == 0 and s['node_deaths'] == 0
           and s['unexplained'] == 0)
    print('target (0 hangs, 0 collisions, 0 node deaths, every non-success explained): %s'
          % ('met' if met else 'MISSED'))
    os.makedirs(RESULTS, exist_ok=True)
    from tiago_nav_tools.benchmarks import launch_models, meta
    laser, odometry = launch_models()
    report['meta'] = meta({k: v for k, v in vars(args).items() if k != 'run'}, quick=args.quick,
                          real_time_factor=args.rtf, laser_model=laser, odometry_model=odometry)
    with open(os.path.join(RESULTS, 'soak.json'), 'w') as f:
        json.dump(report, f, indent=2)
    plot(missions, os.path.join(RESULTS, 'soak.png'))
    print('wrote bench/results/soak.json and soak.png (%.0f s)' % report['bench_wall_s'])
    return 0


if __name__ == '__main__':
    sys.exit(main())
