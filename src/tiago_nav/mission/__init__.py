"""The mission: the stage behind the ``tiago_controller`` node (the TiagoTask proxy) and its
command-line ``client`` (no ROS here).

One goal runs three stages in order, each with its own timeout:

1. ``corridor`` (only with ``use_corridor_law``): the corridor_controller action, only when a
   corridor ahead leads toward pose B (:mod:`~tiago_nav.mission.entrance`); otherwise the
   feedback says "no corridor ahead, navigating directly" and the mission goes on;
2. ``navigation``: pose B sent to move_base;
3. ``detection``: one call of the obstacle_detection service; its ``success: false`` fails
   the mission ("detection failed: <the service's reason>").

Modules: :mod:`~tiago_nav.mission.runner` (:class:`MissionRunner`, the state machine, driven
through a backend: :mod:`tiago_nav.nodes.tiago_controller` wires it to ROS, the unit tests use a
fake, so every path is testable without a ROS master), :mod:`~tiago_nav.mission.goals`
(validating pose B), :mod:`~tiago_nav.mission.entrance` (does a corridor lead toward pose B?),
:mod:`~tiago_nav.mission.sentences` (feedback sentences, distance to go)
and :mod:`~tiago_nav.mission.client` (the client's arguments, feedback lines and obstacle table;
its node is :mod:`tiago_nav.nodes.client`).
"""
from tiago_nav.mission.goals import GoalError, parse_number, validate_goal  # noqa: F401
from tiago_nav.mission.runner import (  # noqa: F401
    ABORTED, ACTIVE, ARRIVED, CORRIDOR, DETECTING, DETECTION_DONE, GOAL_RECEIVED, LOST, MOVING,
    NAVIGATING, PREEMPTED, REJECTED, STATE_NAMES, STOPPED, SUCCEEDED, Cancelled, DetectionError, Goal,
    MissionConfig, MissionRunner, NO_CORRIDOR, Outcome, Poll, StageError)
