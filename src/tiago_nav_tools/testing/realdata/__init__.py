"""Real laser data for the tests and benchmarks: building logs recorded by real robots (Radish,
CARMEN format, poses corrected by SLAM) read, turned into what a user's robot would give the
localisation (a bag of /scan, /odom and tf, a map, the reference trajectory) and scored.

Evaluation tooling, not run on the robot: it lives in :mod:`tiago_nav_tools.testing` (which product
modules never import, and which may use ROS: the bag writer and the player do) beside the
other benchmark support. The reader, odometry, map and scoring modules import no ROS.

- :mod:`.carmen`: the log reader (FLASER lines and their quirks).
- :mod:`.odometry`: odometry synthesised from the reference's steps (the logs hold none), and
  the kidnap splice.
- :mod:`.mapping`: the occupancy grid built from the scans at their reference poses; map_server
  YAML + PGM files.
- :mod:`.scoring`: an estimate's error against the reference, per scan and summed up.
- :mod:`.bag` and :mod:`.play` (need ROS): the bag writer, and a run of a localisation node on a
  bag played with ``rosbag play --clock``.

``python3 -m tiago_nav_tools.testing.realdata LOG OUT_DIR`` converts a log (see :mod:`.__main__`).
"""
