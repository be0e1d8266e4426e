#!/usr/bin/python3
"""Cuts test/data/legs_demo_slice.bag (read by test/ros/test_people_real.py) from leg_tracker's
demo recording legs_demo_stationary_simple_environment.bag (GitHub angusleigh/leg_tracker,
rosbags/, BSD 3-Clause: LICENSE.leg_tracker here): its /scan messages 250 to 499 (0-based, in
recording order: 25.0 s to 49.9 s after its start, 250 scans at 10 Hz), unchanged, with their
recorded times, bz2-compressed.

Usage: test/data/cut_legs_demo_slice.py [SOURCE_BAG] (default ../shared/data/real/...)
"""
import os
import sys

import rosbag

HERE = os.path.dirname(os.path.abspath(__file__))
FIRST, COUNT = 250, 250


def main():
    src = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        HERE, '..', '..', '..', 'shared', 'data', 'real',
        'legs_demo_stationary_simple_environment.bag')
    out = os.path.join(HERE, 'legs_demo_slice.bag')
    with rosbag.Bag(src) as bag, rosbag.Bag(out, 'w', compression='bz2') as dst:
        for k, (topic, msg, t) in enumerate(bag.read_messages(topics=['/scan'])):
            if FIRST <= k < FIRST + COUNT:
                dst.write(topic, msg, t)
    print('wrote', out)


if __name__ == '__main__':
    main()
