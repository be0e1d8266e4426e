#!/usr/bin/python3
"""Rostest of the whole mission through an L-turn (worlds/corridor_bend_90.yaml: a 1.1 m
corridor turning 90 deg) with the corridor law on: everything test_mission.py checks (pose B
reached, the obstacle in view found within 5 cm, no collision, the law drove the corridor),
and the base's disc never closer than 5 cm to a wall or cylinder, from /sim/ground_truth over
the whole mission. Private params as test_mission.py's.
"""
import rospy
import rostest
from nav_msgs.msg import Odometry

from tiago_nav.ros.conversions import pose_from_msg
from tiago_nav.robot import ROBOT_RADIUS
from tiago_nav.sim.world import clearance

from test_mission import MissionTest

MIN_CLEARANCE = 0.05    # [m] base disc to the nearest wall, ground truth


class LTurnTest(MissionTest):
    @classmethod
    def setUpClass(cls):
        cls.track = []
        super().setUpClass()
        rospy.Subscriber('/sim/ground_truth', Odometry,
                         lambda m: cls.track.append(pose_from_msg(m.pose.pose)[:2]))

    def test_1_mission_reaches_pose_b_and_finds_the_obstacles_in_view(self):
        start = len(self.track)
        super().test_1_mission_reaches_pose_b_and_finds_the_obstacles_in_view()
        track = list(self.track[start:])
        self.assertGreater(len(track), 100, 'too few ground-truth poses recorded')
        c = clearance(self.world, track, ROBOT_RADIUS)
        rospy.loginfo('L-turn mission: minimum clearance %.3f m over %d ground-truth poses',
                      c, len(track))
        self.assertGreaterEqual(c, MIN_CLEARANCE, 'came %.3f m from a wall' % c)


if __name__ == '__main__':
    rostest.rosrun('tiago_nav', 'test_corridor_lturn', LTurnTest)
