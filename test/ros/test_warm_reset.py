#!/usr/bin/python3
"""Rostest: a row run on a warm stack after other rows gives the result a fresh stack gives,
and a reset that does not (a planted fault) is reported.

Three rows of the course world that share a stack key (the ``tiago`` sensing profile, with
the scan-matching localisation) but differ in seed, pose B and corridor law (on, off, on: a
row after one with the other setting) run on one warm stack with every reset verified
(:func:`tiago_nav_tools.evaluate.warm.run_group`, ``verify_reset`` 1): the first on a fresh stack, the
two others after a reset, each of those two run again on a fresh stack of its own while the
warm stack stays up (:func:`tiago_nav_tools.evaluate.warm.verify`). Both must come out equal
(:func:`tiago_nav_tools.evaluate.run.differences`: every field but
:data:`~tiago_nav_tools.evaluate.run.WALL_CLOCK_FIELDS`: outcome, path, feedback with its stamps, final
pose, every field of the obstacles found with their uncertainties, the localisation's
covariance, ...), and the missions must have done what the course asks (succeeded, no contact).

Then ``evaluate --warm --verify-reset 1`` on two rows with a fault planted in the simulator's
reset (``TIAGO_NAV_TEST_RESET_LEAK=laser_noise``: its laser noise goes on from the last run's
generator instead of starting from the seed): the reset row must be counted as diverged in
``summary.json`` and ``summary.md``, keep that verdict (no retry: its first attempt) and make the
command exit with status 3."""
import glob
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import unittest

import rostest
import yaml

from tiago_nav_tools.evaluate import run as R
from tiago_nav_tools.evaluate.suite import expand
from tiago_nav_tools.evaluate.warm import run_group, stack_key

HERE = os.path.dirname(os.path.abspath(__file__))
WORLD = os.path.join(os.path.dirname(os.path.dirname(HERE)), 'worlds', 'ias_lab_room_full.yaml')
PROFILES = {'tiago': {'laser_model': 'tiago', 'odometry_model': 'drift',
                      'localisation': 'scan_matching', 'laser_noise': 0.01}}
SUITE = {
    'name': 'warm_reset',
    'defaults': {'real_time_factor': 0, 'sim_time_limit': 120, 'wall_time_limit': 240},
    'worlds': [{'file': WORLD, 'poses': [[11.0, 0.0, -45.0], [12.895, -3.725, 94.5],
                                         [8.39, -3.77, 128.1]]}],
    'profiles': PROFILES,
    'corridor_law': [True, False],
    'seeds': [1, 2, 3],
}
# two rows on one stack: the second after a reset
LEAK_SUITE = {
    'name': 'warm_reset_leak',
    'defaults': {'real_time_factor': 0, 'sim_time_limit': 120, 'wall_time_limit': 240},
    'worlds': [{'file': WORLD, 'poses': [[12.895, -3.725, 94.5]]}],
    'profiles': PROFILES,
    'corridor_law': [False],
    'seeds': [1, 2],
}


def rows():
    """(pose B 1, seed 1, law on), (pose B 2, seed 2, law off), (pose B 3, seed 3, law on)."""
    runs, _ = expand(SUITE, '<warm_reset>', os.path.dirname(WORLD))
    pick = {(tuple(r['goal']), r['seed'], r['use_corridor_law']): r for r in runs}
    poses = SUITE['worlds'][0]['poses']
    return [pick[(tuple(poses[0]), 1, True)], pick[(tuple(poses[1]), 2, False)],
            pick[(tuple(poses[2]), 3, True)]]


def stack_logs(out, lines=30):
    """The end of each warm stack's rosout log (topic lists left out) and supervisor log under
    ``out``: where a warm run that stalled stood, for a failure message (the folder itself is
    removed after the test unless TIAGO_NAV_KEEP is set)."""
    text = []
    for stack in sorted(glob.glob(os.path.join(out, 'stacks', '*'))):
        for name in ('logs/latest/rosout.log', 'supervisor.log'):
            try:
                with open(os.path.join(stack, name)) as f:
                    tail = f.readlines()[-lines:]
            except OSError:
                continue
            text.append('--- %s/%s' % (os.path.basename(stack), name))
            text += [re.sub(r' \[topics: [^]]*\]', '', ln.rstrip()) for ln in tail]
    return '\n'.join(text)


class WarmReset(unittest.TestCase):
    def setUp(self):
        self.out = tempfile.mkdtemp(prefix='tiago_nav_warm_reset_')

    def tearDown(self):
        if not os.environ.get('TIAGO_NAV_KEEP'):
            shutil.rmtree(self.out, ignore_errors=True)

    def test_rows_after_a_reset_equal_their_fresh_runs(self):
        specs = rows()
        self.assertEqual(len({stack_key(s) for s in specs}), 1)
        self.assertEqual(len({(s['seed'], tuple(s['goal'])) for s in specs}), 3)
        self.assertEqual([s['use_corridor_law'] for s in specs], [True, False, True])
        warm = run_group(specs, self.out, verify_reset=1)
        # a diverged row carries the fresh run's outcome and reason: the warm run's (after the
        # reset) are only in its reset_result, which the message must show to tell a warm run
        # that stalled to its wall limit from one that merely differed
        why = '\n'.join(json.dumps({
            'id': r['run_id'], 'stack': r.get('stack'), 'outcome': r['outcome'],
            'reason': r.get('reason'), 'run_wall_s': r.get('run_wall_s'),
            'reset_failed': r.get('reset_failed'), 'diverged': r.get('diverged'),
            'reset_result': r.get('reset_result'), 'verify_error': r.get('verify_error')})
            for r in warm)
        if any(r.get('diverged') or r.get('reset_failed') or r['outcome'] != 'succeeded'
               for r in warm):
            why += '\n' + stack_logs(self.out)
        self.assertEqual([r.get('stack') for r in warm], ['fresh', 'reset', 'reset'], why)
        self.assertEqual([r.get('verified') for r in warm], [None, True, True], why)
        for s, w in zip(specs, warm):
            self.assertEqual(w['outcome'], 'succeeded', '%s\n%s' % (w.get('reason'), why))
            self.assertEqual(w['collisions'], 0)
            self.assertGreater(w['phases']['mission']['wall_s'], 0)
            self.assertGreater(w['loc_samples'], 50)
            # what the comparison covers is there: the obstacles' uncertainty and the
            # localisation's covariance along the mission
            self.assertTrue(w['found_detail'], s['id'])
            for o in w['found_detail']:
                self.assertTrue(math.isfinite(o['center_std']) and o['center_std'] > 0, o)
                self.assertEqual(len(o['center_covariance']), 4)
                self.assertIn('center_robot', o)
            self.assertGreater(len(w['loc_covariance']), 50)
            self.assertTrue(all(c[1] > 0 and c[4] > 0 for c in w['loc_covariance']))
        for s, w in zip(specs[1:], warm[1:]):
            # the fresh twin ran on a stack of its own while the warm one stayed up
            f = R.read_json(os.path.join(self.out, 'verify', 'runs', s['id'], 'result.json'))
            self.assertEqual(f['outcome'], 'succeeded', f.get('reason'))
            self.assertNotEqual(f['port'], w['port'])
            self.assertEqual(R.differences(w, f), [], 'row %s (seed %d, B %s): %s'
                             % (s['id'], s['seed'], s['goal'], why))

    def test_a_reset_fault_is_reported(self):
        suite = os.path.join(self.out, 'leak.yaml')
        with open(suite, 'w') as f:
            yaml.safe_dump(LEAK_SUITE, f)
        out = os.path.join(self.out, 'eval')
        env = dict(os.environ, TIAGO_NAV_TEST_RESET_LEAK='laser_noise')
        p = subprocess.run([sys.executable, '-c', 'import sys; from tiago_nav_tools.evaluate.cli import '
                            'main; sys.exit(main())', suite, '--out', out, '--workers', '1',
                            '--warm', '--verify-reset', '1'], env=env, stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, universal_newlines=True, timeout=900)
        self.assertEqual(p.returncode, 3, p.stdout[-3000:])
        summary = R.read_json(os.path.join(out, 'summary.json'))
        st = summary['meta']['stacks']
        self.assertEqual((st['fresh'], st['reset'], st['checked'], st['diverged'], st['verified']),
                         (1, 1, 1, 1, 0), st)
        (rid,) = st['diverged_runs']
        r = R.read_json(os.path.join(out, 'runs', rid, 'result.json'))
        self.assertEqual((r['stack'], r['attempt'], r['verified']), ('reset', 1, False), r.get('reason'))
        self.assertNotIn('first_attempt', r)          # kept, not retried
        self.assertIn('loc_covariance', r['diverged'])
        warm = R.read_json(os.path.join(out, 'runs', rid, 'reset_result.json'))
        fresh = R.read_json(os.path.join(out, 'verify', 'runs', rid, 'result.json'))
        self.assertEqual(R.differences(warm, fresh), r['diverged'])
        self.assertEqual(r['outcome'], fresh['outcome'])
        with open(os.path.join(out, 'summary.md')) as f:
            md = f.read()
        self.assertIn('## Resets that diverged from a fresh stack', md)
        self.assertIn('`%s`' % rid, md)
        self.assertIn('1 reset run checked against a fresh stack: 0 equal, 1 diverged', md)


if __name__ == '__main__':
    rostest.rosrun('tiago_nav', 'warm_reset_test', WarmReset)
