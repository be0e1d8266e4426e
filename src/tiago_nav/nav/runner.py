"""One move_base goal from acceptance to its end, free of ROS: the fixed-rate control loop,
preemption, feedback, plan republishing, and a stop command on every end.

The runner talks to the outside through an *io* object (the ``move_base`` node wires it to
actionlib, tf and publishers; :mod:`tiago_nav.testing.navigation` to the in-process simulator;
the unit tests to fakes):

* ``clock``: a :mod:`tiago_nav.clock` clock (``now`` in ROS time [s]);
* ``pose()``: ``((x, y, yaw), stamp)`` of base_footprint in ``map`` [m, rad; s], or raises
  :class:`PoseUnavailable`;
* ``to_map(frame, pose)``: a pose ``(x, y, yaw)`` in ``frame`` → ``map``, or raises
  :class:`GoalError`;
* ``send_cmd(v, w)`` [m/s, rad/s], ``publish_plan(path)`` (``(K, 2)`` in map or None),
  ``publish_feedback(pose)``;
* ``preempt_requested()``; ``finish(status, text)`` with status :data:`SUCCEEDED`,
  :data:`ABORTED` or :data:`PREEMPTED` (called exactly once per goal).
"""
import math
import threading
from dataclasses import dataclass

from tiago_nav.clock import Ticker
from tiago_nav.geometry import quaternion_to_yaw
from tiago_nav.nav.navigator import ABORTED, ACTIVE, SUCCEEDED
from tiago_nav.nav.planner import PlanError

PREEMPTED = 'preempted'


class GoalError(ValueError):
    """A goal that cannot be used: the message says why."""


class PoseUnavailable(RuntimeError):
    """The robot's pose cannot be had now (no transform); the message says why."""


@dataclass
class Outcome:
    status: str          # SUCCEEDED, ABORTED or PREEMPTED
    text: str


def goal_pose(position, orientation):
    """A goal's ``position (x, y, z)`` [m] and ``orientation (x, y, z, w)`` quaternion →
    ``(x, y, yaw)``."""
    return float(position[0]), float(position[1]), quaternion_to_yaw(*orientation)


def _fmt(pose):
    return '(%.2f, %.2f, %.0f deg)' % (pose[0], pose[1], math.degrees(pose[2]))


class GoalRunner:
    """Runs goals on a :class:`~tiago_nav.nav.navigator.Navigator` through ``io`` (see the
    module docstring) at ``period`` [s] of ROS time. ``lock`` guards the navigator against the
    scan callback; ``log(level, text)`` with level ``'info'`` or ``'warn'``."""

    def __init__(self, nav, io, period, lock=None, log=None):
        self.nav, self.io, self.period = nav, io, float(period)
        self.lock = lock or threading.Lock()
        self.log = log or (lambda level, text: None)

    def run(self, frame, position, orientation):
        """Run one goal (``frame`` of the pose, ``position``, ``orientation`` quaternion) to its
        end; returns the :class:`Outcome` it reported through ``io.finish``."""
        try:
            return self._run(frame, position, orientation)
        except Exception:              # a bug or a broken io: still stop
            return self._end(ABORTED, 'node shutting down')

    def _end(self, status, text):
        self.io.send_cmd(0.0, 0.0)
        with self.lock:
            self.nav.cancel()
        self.log('info' if status == SUCCEEDED else 'warn', 'goal %s: %s' % (status, text))
        self.io.finish(status, text)
        return Outcome(status, text)

    def _run(self, frame, position, orientation):
        io, nav = self.io, self.nav
        clock = io.clock
        try:
            target = io.to_map(frame, goal_pose(position, orientation))
            pose, _ = io.pose()
            with self.lock:
                path = nav.start(target, pose, clock.now())
        except (GoalError, PlanError) as e:
            return self._end(ABORTED, 'goal rejected: %s' % e)
        except PoseUnavailable as e:
            return self._end(ABORTED, 'no robot pose: %s' % e)
        self.log('info', 'goal %s in map' % _fmt(target))
        io.publish_plan(path)
        ticker = Ticker(clock, self.period)
        while True:
            if io.preempt_requested():
                return self._end(PREEMPTED, 'preempted')
            t = clock.now()
            try:
                pose, _ = io.pose()
            except PoseUnavailable as e:
                return self._end(ABORTED, 'no robot pose: %s' % e)
            with self.lock:
                v, w, state, reason = nav.step(pose, t, self.period)
                new_path = nav.path
            if state != ACTIVE:
                return self._end(state, reason)
            io.send_cmd(v, w)
            if new_path is not path:
                io.publish_plan(new_path)
                path = new_path
            io.publish_feedback(pose)
            if not ticker.tick():
                return self._end(ABORTED, 'node shutting down' if clock.shutdown() else
                                 'ROS time stopped advancing (is the simulator or /clock running?)')
