#!/usr/bin/env python3
"""Compares the course mission across platforms: each row's ``ROW-mission.json`` (written by
``scripts/run_demo.py --rtf 0``, the lockstep mission at full speed, whose result is a function of
the world, seed, arguments and goal) under test-results/platforms/. Prints each row's true final
pose and obstacle centres, and how far each differs from the first row's (Debian 12's when there).

    test/platforms/compare_missions.py [DIR]

Informative: it exits 0 whatever the differences (a row's own success is judged by its tests);
2 when fewer than two rows wrote a mission.
"""
import glob
import json
import math
import os
import sys

ORDER = ('debian12', 'debian13', 'debian11')


def load(folder):
    """``{row: summary}`` of every ROW-mission.json in ``folder``, Debian 12 first."""
    out = {}
    for path in glob.glob(os.path.join(folder, '*-mission.json')):
        row = os.path.basename(path)[:-len('-mission.json')]
        with open(path) as f:
            out[row] = json.load(f)
    return dict(sorted(out.items(), key=lambda kv: (ORDER.index(kv[0]) if kv[0] in ORDER
                                                    else len(ORDER), kv[0])))


def differences(ref, other):
    """``(pose_m, yaw_deg, centre_m)``: how far ``other``'s true final pose and obstacle centres
    lie from ``ref``'s (each centre paired with the nearest of the other's; inf when the counts
    differ or a mission has no final pose)."""
    a, b = ref.get('final_pose'), other.get('final_pose')
    if not a or not b:
        return math.inf, math.inf, math.inf
    pose = math.hypot(a[0] - b[0], a[1] - b[1])
    yaw = abs(math.degrees(math.atan2(math.sin(a[2] - b[2]), math.cos(a[2] - b[2]))))
    ca = [o['center'] for o in ref.get('obstacles', [])]
    cb = [o['center'] for o in other.get('obstacles', [])]
    if len(ca) != len(cb):
        return pose, yaw, math.inf
    centre = max((min(math.hypot(p[0] - q[0], p[1] - q[1]) for q in cb) for p in ca), default=0.0)
    return pose, yaw, centre


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    folder = argv[0] if argv else os.path.join(
        os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
        'test-results', 'platforms')
    runs = load(folder)
    if len(runs) < 2:
        print('compare_missions: fewer than two platforms wrote a mission in %s' % folder)
        return 2
    ref_row = next(iter(runs))
    print('the course mission in lockstep at full speed, per platform (differences from %s):'
          % ref_row)
    print('%-14s %-9s %-32s %-9s %s' % ('platform', 'result', 'true final pose', 'RMS [cm]',
                                          'obstacle centres (x, y) [m]'))
    for row, r in runs.items():
        pose = r.get('final_pose')
        pose_s = '(%.4f, %.4f, %.2f deg)' % (pose[0], pose[1], math.degrees(pose[2])) \
            if pose else '-'
        centres = ' '.join('(%.4f, %.4f)' % tuple(o['center']) for o in r.get('obstacles', []))
        rms = r.get('rms_error_m')
        print('%-14s %-9s %-32s %-9s %s' % (
            row, 'ok' if r.get('succeeded') and not r.get('collisions') else 'FAILED', pose_s,
            '%.2f' % (100 * rms) if rms is not None else '-', centres))
    ref = runs[ref_row]
    for row, r in list(runs.items())[1:]:
        pose, yaw, centre = differences(ref, r)
        same = max(pose, centre) < 1e-9 and yaw < 1e-7
        print('%s vs %s: %sfinal pose %.2g m / %.2g deg apart, centres up to %.2g m apart'
              % (row, ref_row, 'the same (below a nanometre): ' if same else '', pose, yaw,
                 centre))
    return 0


if __name__ == '__main__':
    sys.exit(main())
