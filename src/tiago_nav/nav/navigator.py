"""The per-goal state machine of the navigation server, free of ROS: costmap updates, planning
and replanning, control, progress monitoring, recovery behaviours and the terminal outcome.

``nodes/navigation`` feeds it scans and poses (map frame) and sends its commands; the benchmark
and the unit tests drive it with :class:`tiago_nav.sim.simulator.Simulator` directly.
Time is whatever clock the caller uses (sim time) [s].
"""
import math
from dataclasses import dataclass, field

import numpy as np

from tiago_nav.geometry import wrap_angle
from tiago_nav.nav.controller import Controller, ControllerConfig
from tiago_nav.nav.costmap import INSCRIBED, Costmap
from tiago_nav.nav.planner import PlanError, plan

ACTIVE, SUCCEEDED, ABORTED = 'active', 'succeeded', 'aborted'


@dataclass
class NavConfig:
    robot_radius: float = 0.27          # [m]
    inflation_radius: float = 0.8       # [m]
    cost_scaling_factor: float = 4.0    # [1/m]
    cost_weight: float = 1.5            # planner: weight of cost vs distance
    shortcut_tolerance: float = 40.0    # planner: cost a line-of-sight shortcut may add (0-252)
    obstacle_range: float = 4.0         # [m]
    raytrace_range: float = 5.0         # [m]
    planner_frequency: float = 1.0      # [Hz] periodic replanning (0: only when blocked)
    planner_patience: float = 3.0       # [s] abort when no plan is found for this long
    controller_patience: float = 6.0    # [s] no progress for this long -> next recovery
    progress_distance: float = 0.15     # [m] moving this far counts as progress
    blocked_lookahead: float = 2.5      # [m] of plan checked against the costmap every cycle
    recovery_rotate: float = 2 * math.pi  # [rad] in-place turn of the rotate recovery
    backup_distance: float = 0.3        # [m] of the back-up recovery
    backup_speed: float = 0.15          # [m/s]
    goal_timeout: float = 0.0           # [s] abort a goal after this long (0: never)
    controller: ControllerConfig = field(default_factory=ControllerConfig)


class Navigator:
    """Create with the static :class:`~tiago_nav.gridmap.GridMap`; then per goal
    :meth:`start`, per cycle :meth:`add_scan` / :meth:`step`."""

    RECOVERIES = ('clear', 'rotate', 'backup')

    def __init__(self, grid, config=NavConfig()):
        self.cfg = config
        self.costmap = Costmap(grid, config.robot_radius, config.inflation_radius,
                               config.cost_scaling_factor, config.obstacle_range,
                               config.raytrace_range)
        self.controller = Controller(config.controller)
        self.points = np.zeros((0, 2))
        self.goal = None
        self.path = None
        self.state = None
        self.reason = ''

    # --- sensing ----------------------------------------------------------------------------
    def add_scan(self, origin, angles, ranges):
        """One laser scan in map: laser ``origin (x, y)``, beam ``angles`` [rad] in map,
        ``ranges`` [m] (inf for no return). Updates the obstacle layer and the points the
        collision check uses."""
        r = np.asarray(ranges, dtype=float)
        a = np.asarray(angles, dtype=float)
        ok = np.isfinite(r)
        self.points = np.column_stack((origin[0] + r[ok] * np.cos(a[ok]),
                                       origin[1] + r[ok] * np.sin(a[ok])))
        self.costmap.add_scan(origin, a, r)
        self.costmap.update()

    def clear_costmaps(self):
        self.costmap.clear_obstacles()

    def make_plan(self, start_xy, goal_xy):
        """A plan ``(K, 2)`` on the current costmap, or :class:`PlanError`."""
        return plan(self.costmap, start_xy, goal_xy, self.cfg.cost_weight,
                    shortcut_tolerance=self.cfg.shortcut_tolerance)

    # --- goals ------------------------------------------------------------------------------
    def start(self, goal, pose, t):
        """Accept a goal ``(x, y, yaw)`` in map. Raises :class:`PlanError` for a goal that can
        never be reached (outside the map, inside an obstacle); a goal with no path *yet* is
        retried for ``planner_patience``."""
        g = self.costmap.grid
        if not g.contains([goal[:2]])[0]:
            raise PlanError('goal (%.2f, %.2f) is outside the map' % tuple(goal[:2]))
        if self.costmap.cost_at([goal[:2]])[0] >= INSCRIBED:
            raise PlanError('goal (%.2f, %.2f) is inside an obstacle (after inflation)' % tuple(goal[:2]))
        self.goal = tuple(float(v) for v in goal)
        self.t0 = t
        self.state = ACTIVE
        self.reason = ''
        self.controller.reset()
        self.path = None
        self.last_plan_ok = t
        self.last_plan_try = -math.inf
        self.progress_pose = pose
        self.progress_time = t
        self.recovery = 0
        self.recovery_action = None
        self._replan(pose, t)
        return self.path

    def _replan(self, pose, t):
        self.last_plan_try = t
        try:
            self.path = self.make_plan(pose[:2], self.goal[:2])
        except PlanError as e:
            self.plan_error = str(e)
            return False
        self.controller.set_path(self.path)
        self.last_plan_ok = t
        return True

    def _path_blocked(self):
        if self.path is None:
            return True
        i = self.controller.index
        n = int(self.cfg.blocked_lookahead / 0.05)
        seg = self.path[i:i + n]
        return bool((self.costmap.cost_at(seg) >= INSCRIBED).any())

    def _finish(self, state, reason):
        self.state, self.reason = state, reason
        self.controller.reset()
        return 0.0, 0.0, state, reason

    def step(self, pose, t, dt):
        """One control cycle at ``pose`` (map) and time ``t``. Returns ``(v, w, state, reason)``;
        the command is ``(0, 0)`` once the state is terminal."""
        cfg = self.cfg
        if self.state != ACTIVE:
            return 0.0, 0.0, self.state, self.reason
        if cfg.goal_timeout > 0 and t - self.t0 > cfg.goal_timeout:
            return self._finish(ABORTED, 'timeout: goal not reached in %.0f s' % cfg.goal_timeout)
        dg = math.hypot(self.goal[0] - pose[0], self.goal[1] - pose[1])
        # progress monitor
        if math.hypot(pose[0] - self.progress_pose[0], pose[1] - self.progress_pose[1]) > cfg.progress_distance \
                or (dg <= cfg.controller.xy_goal_tolerance
                    and abs(wrap_angle(pose[2] - self.progress_pose[2])) > 0.2):
            self.progress_pose, self.progress_time = pose, t
            if self.recovery_action is None:
                self.recovery = 0
        if self.recovery_action is not None:
            return self._recover(pose, t, dt)
        # planning
        near_goal = dg <= cfg.controller.xy_goal_tolerance
        if not near_goal:
            due = cfg.planner_frequency > 0 and t - self.last_plan_try >= 1.0 / cfg.planner_frequency
            blocked = self._path_blocked()
            if due or blocked:
                if not self._replan(pose, t) and blocked:
                    self.path = None
                    self.controller.set_path(None)
            if self.path is None:
                if t - self.last_plan_ok > cfg.planner_patience:
                    return self._finish(ABORTED, 'no path: %s (for %.1f s)'
                                        % (getattr(self, 'plan_error', 'no plan'), cfg.planner_patience))
                self.controller.v = self.controller.w = 0.0
                self.progress_time = t
                return 0.0, 0.0, ACTIVE, 'planning'
        v, w, phase = self.controller.command(pose, self.goal, self.points, dt)
        if phase == 'arrived':
            return self._finish(SUCCEEDED, 'goal reached')
        if t - self.progress_time > cfg.controller_patience:
            if self.recovery >= len(self.RECOVERIES):
                return self._finish(ABORTED, 'stuck: no progress for %.1f s after all recovery '
                                    'behaviours (%s)' % (cfg.controller_patience, ', '.join(self.RECOVERIES)))
            self.recovery_action = self.RECOVERIES[self.recovery]
            self.recovery += 1
            self.recovery_start = (pose, t)
            self.controller.v = self.controller.w = 0.0
            return self._recover(pose, t, dt)
        return v, w, ACTIVE, phase

    def _recover(self, pose, t, dt):
        cfg = self.cfg
        start_pose, t_start = self.recovery_start
        act = self.recovery_action
        done = False
        v = w = 0.0
        if act == 'clear':
            self.clear_costmaps()
            self._replan(pose, t)
            done = True
        elif act == 'rotate':
            wmax = cfg.controller.max_vel_theta * 0.6
            if t - t_start < cfg.recovery_rotate / wmax:
                w = wmax
            else:
                done = True
        elif act == 'backup':
            moved = math.hypot(pose[0] - start_pose[0], pose[1] - start_pose[1])
            behind = (pose[0] - 0.1 * math.cos(pose[2]),
                      pose[1] - 0.1 * math.sin(pose[2]))
            clear = self.costmap.cost_at([behind])[0] < INSCRIBED or \
                self.costmap.cost_at([pose[:2]])[0] >= INSCRIBED
            if moved < cfg.backup_distance and t - t_start < 3 * cfg.backup_distance / cfg.backup_speed \
                    and clear:
                v = -cfg.backup_speed
            else:
                done = True
        if done:
            self.recovery_action = None
            self.progress_pose, self.progress_time = pose, t
            self._replan(pose, t)
        return v, w, ACTIVE, 'recovery: ' + act
