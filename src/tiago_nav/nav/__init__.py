"""Navigation library behind nodes/navigation (the move_base-compatible server): costmap,
global planner, local controller, recovery and the per-goal state machine. No ROS imports."""
