#!/usr/bin/python3
"""Rostest: a mission's outcome is a function of (world, seed, launch arguments, goal), not of
when the goal is sent. Two fresh launches of demo.launch at ``real_time_factor:=0``
(:mod:`tiago_nav_tools.testing.repro`, each in a child process with its own master); in each, plain
SimpleActionClients send a corridor_controller goal (3 m of the course corridor), the course
mission from where it ended, a second mission from its end and then a move_base goal, each
after a wall delay that differs between the runs (0.1 s and 2.5 s). Every result field (the
corridor's exit pose, distance and reason; the missions' final pose, each obstacle's centres,
radius and point count, the message, the final state), the feedback published (state,
sentence, simulated stamp), each result's stamp and the true final pose must agree between
the runs. A third launch is starved while its goals run, far beyond any load: each node of the
stack, the simulator included, stopped in turn for 3 s of wall time (longer than any of
lockstep's questions: a participant's 2 s, the simulator's 1 s), 0.2 s apart; it must agree
too, for a slow node is waited for, not dropped."""
import unittest

import rostest
from actionlib_msgs.msg import GoalStatus

from tiago_nav_tools.testing.harness import STARVED
from tiago_nav_tools.testing.repro import differences, run_child


STARVE = 3.0        # [s wall] each node of the third launch is stopped this long in turn


class Reproducible(unittest.TestCase):
    def test_the_same_goals_give_the_same_results_whenever_they_are_sent_however_starved(self):
        runs = [run_child(delay, corridor=True) for delay in (0.1, 2.5)]
        runs.append(run_child(0.1, corridor=True, starve=STARVE, timeout=600.0))
        for r in runs:
            self.assertNotIn('error', r, r.get('error'))
            self.assertEqual(r['corridor']['status'], GoalStatus.SUCCEEDED, r['corridor']['text'])
            self.assertGreaterEqual(r['corridor']['distance'], 3.0)
            self.assertEqual([t['status'] for t in r['tasks']], [GoalStatus.SUCCEEDED] * 2,
                             [t.get('text') for t in r['tasks']])
            self.assertEqual(r['nav']['status'], GoalStatus.SUCCEEDED, r['nav']['text'])
            self.assertEqual(r['collisions'], 0)
            self.assertEqual(len(r['tasks'][0]['obstacles']), 4)
            self.assertEqual(r['tasks'][0]['final_state'], 7)     # DETECTION_DONE
        self.assertEqual(differences(*runs[:2]), [])
        self.assertEqual(differences(runs[0], runs[2]), [])
        self.assertGreaterEqual(runs[2]['stops'], len(STARVED))     # each node stopped once at least


if __name__ == '__main__':
    rostest.rosrun('tiago_nav', 'reproducible_test', Reproducible)
