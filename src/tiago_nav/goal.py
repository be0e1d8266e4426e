"""How a goal ends: the one vocabulary of the package's action servers and of the mission that
runs them (no ROS). The statuses are actionlib's states as words (``LOST``: the server went
away); :class:`GoalError` is a goal that cannot be used; :class:`Outcome` is how a goal ended.
"""
from dataclasses import dataclass, field
from typing import Any, List, Optional, Tuple

ACTIVE, SUCCEEDED, ABORTED, PREEMPTED, REJECTED, LOST = ('active', 'succeeded', 'aborted',
                                                         'preempted', 'rejected', 'lost')


class GoalError(ValueError):
    """A goal that cannot be used (not a number, not finite, out of range, an unknown frame):
    the message says why."""


@dataclass
class Outcome:
    """How a goal ended: ``status`` SUCCEEDED, ABORTED or PREEMPTED and a sentence saying why;
    a mission's also carries what it found, where the robot stopped and the stage that failed
    or was cancelled (poses ``(x, y, yaw)`` [m, m, rad] in ``map``)."""
    status: str
    message: str
    obstacles: List[Any] = field(default_factory=list)
    final_pose: Optional[Tuple[float, float, float]] = None
    stage: Optional[str] = None
