"""The evaluation run's end of a mission (tiago_nav_tools.evaluate.supervisor.mission_over): a goal is over
when its result has come, not when the status topic first names its end state."""
import pytest

pytestmark = pytest.mark.ros         # actionlib, tiago_nav_tools.evaluate.supervisor
pytest.importorskip('actionlib')
from actionlib import SimpleGoalState                       # noqa: E402
from actionlib_msgs.msg import GoalStatus                   # noqa: E402

from tiago_nav_tools.evaluate.supervisor import END_WAIT, mission_over   # noqa: E402


class Client:
    """SimpleActionClient's two views of a goal: ``get_state`` follows the status topic (and the
    result), ``simple_state`` is DONE only once the result message has come."""

    def __init__(self, state, simple_state):
        self.state, self.simple_state = state, simple_state

    def get_state(self):
        return self.state


def test_active_goal_is_not_over():
    assert mission_over(Client(GoalStatus.ACTIVE, SimpleGoalState.ACTIVE), None, 5.0) == (False, None)


def test_status_ended_before_the_result_waits_for_the_result():
    c = Client(GoalStatus.SUCCEEDED, SimpleGoalState.ACTIVE)
    over, since = mission_over(c, None, 10.0)
    assert (over, since) == (False, 10.0)
    assert mission_over(c, since, 10.0 + END_WAIT / 2) == (False, 10.0)
    c.simple_state = SimpleGoalState.DONE          # the result arrives
    assert mission_over(c, since, 10.0 + END_WAIT / 2)[0]


def test_a_result_that_never_comes_is_bounded():
    c = Client(GoalStatus.ABORTED, SimpleGoalState.ACTIVE)
    assert mission_over(c, 10.0, 10.0 + END_WAIT + 0.1) == (True, 10.0)


def test_simulated_time_standing_still_is_said_once_and_the_wall_limit_ends_the_mission():
    """In lockstep simulated time stands still while no node works (a goal nobody received):
    the supervisor says so once per stand-still, and ends the mission at its wall limit with
    a reason naming both, instead of waiting in simulated time for the watchdog to kill it."""
    from tiago_nav_tools.evaluate.supervisor import STILL_SAY, ClockWatch
    w = ClockWatch(1.0, 100.0, 60.0)
    assert w.update(1.5, 101.0) is None                 # time goes on
    assert w.update(1.5, 101.0 + STILL_SAY - 0.1) is None
    said = w.update(1.5, 101.0 + STILL_SAY + 0.1)
    assert said and '1.500 s' in said and 'stood still' in said
    assert w.update(1.5, 101.0 + 2 * STILL_SAY) is None  # said once
    assert w.over(159.0) is None
    why = w.over(161.0)
    assert why and '60 s of wall time' in why and 'standing still for the last 60 s' in why
    assert w.update(1.6, 162.0) is None                 # it moves again: a new stand-still is said anew
    assert w.update(1.6, 162.0 + STILL_SAY + 0.1)
    moving = ClockWatch(1.0, 0.0, 60.0)
    for k in range(1, 62):
        moving.update(1.0 + k, float(k))
    assert 'standing still' not in moving.over(61.0)
