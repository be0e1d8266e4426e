"""The narrow-corridor control law: wall fitting, the law and its goal judge (no ROS)."""
