#!/usr/bin/python3
"""Rostest: a row run on a warm stack after other rows gives the result a fresh stack gives.

Three rows of the course world that share a stack key (the ``tiago`` sensing profile, with
the scan-matching localisation) but differ in seed, pose B and corridor law (on, off, on: a
row after one with the other setting) run on one
warm stack (:func:`tiago_nav.evaluate.warm.run_group`): the first on a fresh stack, the two
others after a reset. Each then runs on a fresh stack of its own
(:func:`tiago_nav.evaluate.run.execute`). :func:`tiago_nav.evaluate.run.differences` between
the two results of each row (every field but :data:`~tiago_nav.evaluate.run.WALL_CLOCK_FIELDS`:
outcome, path, feedback with its stamps, final pose, obstacles, localisation errors ...) must
be empty, and the missions must have done what the course asks (succeeded, no contact)."""
import os
import shutil
import tempfile
import unittest

import rostest

from tiago_nav.evaluate import run as R
from tiago_nav.evaluate.suite import expand
from tiago_nav.evaluate.warm import run_group, stack_key

HERE = os.path.dirname(os.path.abspath(__file__))
WORLD = os.path.join(os.path.dirname(os.path.dirname(HERE)), 'worlds', 'ias_lab_room_full.yaml')
SUITE = {
    'name': 'warm_reset',
    'defaults': {'real_time_factor': 0, 'sim_time_limit': 120, 'wall_time_limit': 240},
    'worlds': [{'file': WORLD, 'poses': [[11.0, 0.0, -45.0], [12.895, -3.725, 94.5],
                                         [8.39, -3.77, 128.1]]}],
    'profiles': {'tiago': {'laser_model': 'tiago', 'odometry_model': 'drift',
                           'localisation': 'scan_matching', 'laser_noise': 0.01}},
    'corridor_law': [True, False],
    'seeds': [1, 2, 3],
}


def rows():
    """(pose B 1, seed 1, law on), (pose B 2, seed 2, law off), (pose B 3, seed 3, law on)."""
    runs, _ = expand(SUITE, '<warm_reset>', os.path.dirname(WORLD))
    pick = {(tuple(r['goal']), r['seed'], r['use_corridor_law']): r for r in runs}
    poses = SUITE['worlds'][0]['poses']
    return [pick[(tuple(poses[0]), 1, True)], pick[(tuple(poses[1]), 2, False)],
            pick[(tuple(poses[2]), 3, True)]]


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
        warm_dir, fresh_dir = os.path.join(self.out, 'warm'), os.path.join(self.out, 'fresh')
        warm = run_group(specs, warm_dir)
        self.assertEqual([r.get('stack') for r in warm], ['fresh', 'reset', 'reset'],
                         [(r['outcome'], r.get('reason'), r.get('reset_failed')) for r in warm])
        for s, w in zip(specs, warm):
            f = R.execute(s, fresh_dir)
            self.assertEqual((w['outcome'], f['outcome']), ('succeeded', 'succeeded'),
                             (w.get('reason'), f.get('reason')))
            self.assertEqual(w['collisions'], 0)
            self.assertEqual(w['isolation'], f['isolation'])
            self.assertGreater(w['phases']['mission']['wall_s'], 0)
            self.assertGreater(w['loc_samples'], 50)
            self.assertEqual(R.differences(w, f), [], 'row %s (seed %d, B %s)'
                             % (s['id'], s['seed'], s['goal']))


if __name__ == '__main__':
    rostest.rosrun('tiago_nav', 'warm_reset_test', WarmReset)
