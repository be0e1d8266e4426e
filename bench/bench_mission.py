#!/usr/bin/python3
"""Whole-mission benchmark: demo.launch (simulator, move_base, corridor_controller,
obstacle_detection, tiago_controller) driven by the client library over seeded poses B in the
shipped worlds, judged against the world files.

Per world, one launch; missions follow each other (each starts where the last ended). In
ias_lab_room_full the first mission is the course's (pose B (11, 0, -45 deg), corridor law on);
the others are seeded random poses B (mission_eval.sample_goals), corridor law off.
Figures: success, wall time per mission (target <= 20 s), simulated time, obstacles' recall,
false positives, RMS centre error (ground truth: tiago_nav_tools.evaluate.inview.view_from the final pose),
collisions. Run at each requested real_time_factor (default 5, the demo's, then 0 = flat out).
Writes bench/results/mission.json and mission.png.

Usage: bench/bench_mission.py [--quick] [--rtf 5,0] [--n 3] [--seed 7]
"""
import argparse
import json
import math
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, 'bench', 'results')
WORLDS = ['ias_lab_room_full.yaml', 'open_hall.yaml']
COURSE = {'ias_lab_room_full.yaml': (11.0, 0.0, -45.0)}
TARGET_WALL = 20.0


def run_world(world_file, n, seed, rtf):
    """Child process: one launch, the world's missions; prints ``RESULT <json>`` last."""
    import numpy as np
    from tiago_nav_tools.evaluate.matching import sample_goals
    from tiago_nav_tools.testing.harness import Harness, mission_record
    from tiago_nav.sim.world import load_world

    path = os.path.join(ROOT, 'worlds', world_file)
    world = load_world(path)
    goals = []
    if world_file in COURSE:
        goals.append(COURSE[world_file] + (True,))
    start = (goals[-1][0], goals[-1][1], 0.0) if goals else None
    rng = np.random.default_rng(seed)
    goals += [g + (False,) for g in sample_goals(world, n, rng, start=start)]
    h = Harness(path, real_time_factor=rtf)
    out = []
    try:
        h.connect(timeout=90.0)
        for x, y, yaw, corridor in goals:
            rec = mission_record(h, world, (x, y, yaw), corridor)
            del rec['lines']
            code = 0 if rec['succeeded'] else 1
            wall, sim = rec['wall_s'], rec['sim_s']
            s = {'matched': rec['matched'], 'true': rec['in_view'],
                 'false_positives': rec['false_positives'], 'rms_error': rec['rms_error_m']}
            out.append(rec)
            print('  %-18s B=(%6.2f, %6.2f, %5.0f) corridor=%-5s %-9s wall %5.1f s  sim %5.1f s  '
                  'recall %d/%d  FP %d  RMS %s  collisions %d'
                  % (world.name, x, y, yaw, corridor, 'ok' if code == 0 else 'FAILED', wall, sim,
                     s['matched'], s['true'], s['false_positives'],
                     '%.3f' % s['rms_error'] if s['rms_error'] is not None else '-',
                     rec['collisions']), flush=True)
            if code != 0:
                print('    %s' % rec['message'], flush=True)
    except Exception as e:
        print('  %s: error: %s' % (world_file, e), flush=True)
        out.append({'world': world.name, 'error': str(e), 'succeeded': False})
    finally:
        h.close()
    print('RESULT ' + json.dumps(out), flush=True)


def summarise(missions):
    ok = [m for m in missions if m.get('succeeded')]
    # detection figures over the missions that reached detection (the succeeded ones)
    errs = [e for m in ok for e in m.get('errors_m', [])]
    in_view = sum(m.get('in_view', 0) for m in ok)
    matched = sum(m.get('matched', 0) for m in ok)
    walls = [m['wall_s'] for m in missions if 'wall_s' in m]
    return {'missions': len(missions), 'succeeded': len(ok),
            'success_rate': len(ok) / len(missions) if missions else 0.0,
            'wall_s_mean': sum(walls) / len(walls) if walls else None,
            'wall_s_max': max(walls) if walls else None,
            'within_target': sum(1 for m in ok if m['wall_s'] <= TARGET_WALL),
            'recall': matched / in_view if in_view else None,
            'false_positives': sum(m.get('false_positives', 0) for m in ok),
            'rms_error_m': math.sqrt(sum(e * e for e in errs) / len(errs)) if errs else None,
            'max_error_m': max(errs) if errs else None,
            'collisions': sum(m.get('collisions', 0) for m in missions)}


def plot(runs, path):
    """Per run (real_time_factor): wall time of each mission (bars) and the centre errors."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(len(runs), 2, figsize=(13, 4.2 * len(runs)), squeeze=False)
    for (a1, a2), run in zip(axes, runs):
        ms = [m for m in run['missions'] if 'goal' in m]
        labels = ['%s\n(%.1f, %.1f, %.0f)%s' % (m['world'][:9], *m['goal'],
                                                ' C' if m['use_corridor_law'] else '') for m in ms]
        colors = ['tab:green' if m['succeeded'] else 'tab:red' for m in ms]
        a1.bar(range(len(ms)), [m['wall_s'] for m in ms], color=colors)
        a1.axhline(TARGET_WALL, color='k', ls='--', lw=1, label='target 20 s')
        a1.set_xticks(range(len(ms)))
        a1.set_xticklabels(labels, fontsize=6, rotation=60)
        a1.set_ylabel('wall time per mission [s]')
        a1.set_title('real_time_factor %g: green succeeded, red failed (C: corridor law)'
                     % run['real_time_factor'], fontsize=9)
        a1.legend(fontsize=8)
        errs = [e * 100 for m in ms for e in m.get('errors_m', [])]
        if errs:
            a2.hist(errs, bins=20, color='tab:blue')
        a2.axvline(5.0, color='k', ls='--', lw=1, label='5 cm (rostest bound)')
        a2.set_xlabel('obstacle centre error [cm]')
        a2.set_ylabel('obstacles')
        a2.set_title('centre errors of the obstacles in view (real_time_factor %g)'
                     % run['real_time_factor'], fontsize=9)
        a2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--quick', action='store_true', help='1 random pose B per world')
    ap.add_argument('--n', type=int, default=3, help='random poses B per world')
    ap.add_argument('--seed', type=int, default=7)
    ap.add_argument('--rtf', default='5,0',
                    help='simulator real_time_factor(s), comma-separated (0: flat out)')
    ap.add_argument('--run', help=argparse.SUPPRESS)
    args = ap.parse_args()
    n = 1 if args.quick else args.n
    if args.run:
        run_world(args.run, n, args.seed, float(args.rtf))
        return 0
    rtfs = [float(v) for v in args.rtf.split(',')]
    t0 = time.monotonic()
    report = {'quick': args.quick, 'seed': args.seed, 'n_random_per_world': n, 'runs': []}
    for rtf in rtfs:
        print('mission benchmark: %d random poses B per world (seed %d), real_time_factor %g'
              % (n, args.seed, rtf), flush=True)
        missions = []
        for k, w in enumerate(WORLDS):
            cmd = [sys.executable, os.path.abspath(__file__), '--run', w, '--n', str(n),
                   '--seed', str(args.seed + k), '--rtf', str(rtf)]
            p = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
            result = []
            for line in p.stdout:
                if line.startswith('RESULT '):
                    result = json.loads(line[7:])
                elif line.startswith('  '):
                    sys.stdout.write(line)
                    sys.stdout.flush()
            p.wait()
            missions += result
        s = summarise(missions)
        s['real_time_factor'] = rtf
        print('  => missions %d, succeeded %d (%.0f %%), within 20 s: %d; wall per mission mean %s s, '
              'max %s s; recall %s, false positives %d, RMS error %s, max error %s, collisions %d\n'
              % (s['missions'], s['succeeded'], 100 * s['success_rate'], s['within_target'],
                 '%.1f' % s['wall_s_mean'] if s['wall_s_mean'] is not None else '-',
                 '%.1f' % s['wall_s_max'] if s['wall_s_max'] is not None else '-',
                 '%.3f' % s['recall'] if s['recall'] is not None else '-', s['false_positives'],
                 '%.3f m' % s['rms_error_m'] if s['rms_error_m'] is not None else '-',
                 '%.3f m' % s['max_error_m'] if s['max_error_m'] is not None else '-',
                 s['collisions']), flush=True)
        report['runs'].append({'real_time_factor': rtf, 'summary': s, 'missions': missions})
    report['bench_wall_s'] = time.monotonic() - t0
    os.makedirs(RESULTS, exist_ok=True)
    from tiago_nav_tools.benchmarks import launch_models, meta
    laser, odometry = launch_models()
    report['meta'] = meta({k: v for k, v in vars(args).items() if k != 'run'}, quick=args.quick,
                          real_time_factor=rtfs, laser_model=laser, odometry_model=odometry)
    with open(os.path.join(RESULTS, 'mission.json'), 'w') as f:
        json.dump(report, f, indent=2)
    plot(report['runs'], os.path.join(RESULTS, 'mission.png'))
    print('wrote bench/results/mission.json and mission.png')
    print('| real_time_factor | missions | succeeded | within 20 s | wall/mission mean (max) | '
          'recall | false pos. | RMS error | collisions |')
    print('|---|---|---|---|---|---|---|---|---|')
    for r in report['runs']:
        s = r['summary']
        print('| %g | %d | %d | %d | %s (%s) s | %s | %d | %s | %d |' % (
            r['real_time_factor'], s['missions'], s['succeeded'], s['within_target'],
            '%.1f' % s['wall_s_mean'] if s['wall_s_mean'] is not None else '-',
            '%.1f' % s['wall_s_max'] if s['wall_s_max'] is not None else '-',
            '%.3f' % s['recall'] if s['recall'] is not None else '-', s['false_positives'],
            '%.1f mm' % (1000 * s['rms_error_m']) if s['rms_error_m'] is not None else '-',
            s['collisions']))
        met = s['missions'] > 0 and s['within_target'] == s['missions']
        print('target at real_time_factor %g (every mission succeeds in <= 20 s of wall time): %s'
              % (r['real_time_factor'], 'met' if met else 'MISSED'))
    return 0


if __name__ == '__main__':
    sys.exit(main())
