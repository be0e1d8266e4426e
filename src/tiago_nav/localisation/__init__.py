"""Localisation: scan-to-map registration and the pose filter (no ROS)."""
