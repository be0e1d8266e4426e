"""The per-goal state machine of the navigation server, free of ROS: costmap updates, planning
and replanning, control, progress monitoring, recovery behaviours and the terminal outcome.

:class:`tiago_nav.nav.runner.GoalRunner` runs it for one goal (the ``move_base`` node wires that
to ROS; :mod:`tiago_nav_tools.testing.navigation` to the in-process simulator). Time is whatever clock
the caller uses (ROS time, simulated under /use_sim_time) [s]; poses are ``(x, y, yaw)`` of
base_footprint in ``map`` [m, m, rad].
"""
import math
from collections import deque
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from tiago_nav.geometry import wrap_angle
from tiago_nav.goal import ABORTED, ACTIVE, SUCCEEDED  # noqa: F401
from tiago_nav.nav.controller import Controller, ControllerConfig
from tiago_nav.nav.costmap import INSCRIBED, Costmap
from tiago_nav.nav.people import MovedMarks, person_keep_out
from tiago_nav.scan import INVALID
from tiago_nav.gridmap import distance_to_mask
from tiago_nav.nav.planner import PlanError, densify, path_to_nearest, plan
from tiago_nav.params import ParamError, nested, param, validate
from tiago_nav.robot import ROBOT_RADIUS


@dataclass(frozen=True)
class NavConfig:
    """Costmap, planner, progress, recovery and sensor-freshness settings of the navigator."""
    robot_radius: float = param(ROBOT_RADIUS, '[m] base footprint radius (tiago_nav.robot)', gt=0)
    inflation_radius: float = param(0.8, '[m] the cost gradient reaches out this far', gt=0,
                                    dynamic=(0.1, 3.0))
    cost_scaling_factor: float = param(4.0, '[1/m] cost = 252 exp(-k (d - robot_radius))', gt=0)
    cost_weight: float = param(1.5, 'planner: step cost multiplier 1 + cost_weight * cost / 252',
                               ge=0)
    shortcut_tolerance: float = param(40.0, 'planner: cost (0-252) a line-of-sight shortcut of '
                                      'the grid path may add', ge=0)
    obstacle_range: float = param(4.0, '[m] laser hits are marked up to this range', gt=0)
    raytrace_range: float = param(5.0, '[m] beams clear the obstacle layer up to this range', gt=0)
    planner_frequency: float = param(1.0, '[Hz] periodic replanning (0: only when the plan '
                                     'ahead is blocked)', ge=0)
    planner_patience: float = param(3.0, '[s] abort when no plan can be found for this long', gt=0)
    reset_distance: float = param(3.0, "[m] once per goal, when its cell is covered by the laser's "
                                  'marks only, or no plan is found for planner_patience: forget '
                                  'the marks farther than this from the robot and plan again '
                                  "(move_base's conservative_reset)", gt=0)
    controller_patience: float = param(6.0, '[s] no progress (progress_distance) for this long '
                                       '-> next recovery (clear, rotate, back up), then abort', gt=0)
    progress_distance: float = param(0.15, '[m] moving this far counts as progress for '
                                     'controller_patience', gt=0)
    blocked_lookahead: float = param(2.5, '[m] of plan checked against the costmap every cycle',
                                     gt=0)
    recovery_rotate: float = param(2 * math.pi, '[rad] in-place turn of the rotate recovery', gt=0)
    backup_distance: float = param(0.3, '[m] of the back-up recovery', ge=0)
    backup_speed: float = param(0.15, '[m/s] of the back-up recovery', gt=0)
    goal_timeout: float = param(-1.0, '[s] abort a goal after this long (not counting time spent '
                                'waiting for a person); < 0: derived from the first plan '
                                '(goal_timeout_factor * length / max_vel_x + '
                                'goal_timeout_allowance); 0: never')
    goal_timeout_factor: float = param(3.0, 'derived goal_timeout: multiple of the first '
                                       "plan's driving time at max_vel_x", gt=0)
    goal_timeout_allowance: float = param(30.0, '[s] derived goal_timeout: added for turning, '
                                          'recoveries and detours', ge=0)
    no_progress_timeout: float = param(40.0, '[s] abort when the path still to go has not '
                                       'shrunk by no_progress_distance for this long '
                                       '(oscillation, a blocked goal; a wait for a person '
                                       'starts it again; 0: never)', ge=0)
    no_progress_distance: float = param(0.5, '[m] see no_progress_timeout', gt=0)
    sensor_timeout: float = param(0.5, '[s] stop the base while the newest scan (by its stamp) '
                                  'or the robot pose is older than this', gt=0)
    sensor_abort_timeout: float = param(3.0, '[s] abort the goal when a sensor stays that '
                                        'stale this long', gt=0)
    localisation_patience: float = param(
        20.0, '[s] while the localisation says it is lost the base stops and waits for it to '
              'relocalise; lost for longer than this, the goal aborts naming the localisation '
              '(a global relocalisation takes a few scans, a stretch where the scans cannot '
              'tell the place apart takes driving, which a lost robot must not do)', gt=0)
    person_clearance: float = param(
        0.3, '[m] kept between the base and a person (a laser hit on space a recent scan saw '
             'free, tiago_nav.nav.people), beyond the footprint; 0: people are obstacles like '
             'any other (docs/navigation.md: among walkers that costs success and clearance)',
        ge=0)
    person_memory: float = param(10.0, '[s] a scan witnesses free space, and a person who '
                                 'stopped stays one, for this long', gt=0)
    person_patience: float = param(
        12.0, '[s] with no plan but one through a person, the base waits (and gives way) this '
              'long for the way to clear; then it takes them to be waiting for it, as people do, '
              'and passes them at its ordinary clearance for the rest of the goal (or, with no '
              'way past them, aborts after planner_patience)', gt=0)
    give_way_after: float = param(
        3.0, '[s] a person who has stood in the way this long (after planner_patience) may be '
             'waiting for the base, as people do: the base gives way, driving to the nearest '
             'place give_way_distance from every person beside a wall or an obstacle (else in '
             'the open), and waits there while a person is that near, up to person_patience',
        ge=0)
    give_way_distance: float = param(1.5, '[m] see give_way_after', gt=0)
    controller: ControllerConfig = nested(ControllerConfig)

    def __post_init__(self):
        validate(self)
        if self.inflation_radius < self.robot_radius:
            raise ParamError('must be >= robot_radius (%g m)' % self.robot_radius, 'inflation_radius')
        if self.controller.robot_radius != self.robot_radius:
            raise ParamError('differs from the controller\'s (%g, %g m): build both from one '
                             'value' % (self.robot_radius, self.controller.robot_radius),
                             'robot_radius')
        if self.sensor_abort_timeout < self.sensor_timeout:
            raise ParamError('must be >= sensor_timeout (%g s)' % self.sensor_timeout,
                             'sensor_abort_timeout')


class ProgressWindow:
    """Is the distance still to go shrinking? Fed ``(t, to_go)`` each cycle, it reports True
    once a whole ``window`` [s] has passed without ``to_go`` [m] falling ``distance`` below its
    value at the window's start, which catches a robot swinging back and forth as well as one
    standing still. ``window`` 0: never."""

    def __init__(self, window, distance):
        self.window, self.distance = window, distance
        self.samples = deque()

    def reset(self):
        self.samples.clear()

    def update(self, t, to_go):
        if self.window <= 0:
            return False
        s = self.samples
        s.append((t, to_go))
        while len(s) >= 2 and s[1][0] <= t - self.window:
            s.popleft()
        t0, start = s[0]
        return t - t0 >= self.window and min(v for _, v in s) > start - self.distance


class Navigator:
    """Create with the static :class:`~tiago_nav.gridmap.GridMap`; then per goal
    :meth:`start`, per cycle :meth:`add_scan` / :meth:`step`."""

    RECOVERIES = ('clear', 'rotate', 'backup')
    MEMORY_RADIUS = 2.5     # [m] occupied cells this near the laser stand in for invalid beams
    LOOK_ANGLE = 1.2        # [rad] a person's mark farther off the heading than this is turned to
    ASIDE = (0.1, 0.05)     # [m] giving way, the base's centre this far beyond its inscribed radius
                            # from the nearest wall or obstacle (centre to occupied cell centre), give
                            # or take the second: beside it, clear of the controller's safety margin

    def __init__(self, grid, config=NavConfig()):
        self.cfg = config
        self.costmap = Costmap(grid, config.robot_radius, config.inflation_radius,
                               config.cost_scaling_factor, config.obstacle_range,
                               config.raytrace_range)
        self.controller = Controller(config.controller)
        self.window = ProgressWindow(config.no_progress_timeout, config.no_progress_distance)
        self.moved = MovedMarks(grid, config.person_memory)
        self._person_check = None   # (t, was there a plan without the people layer)
        self.retreat = None         # giving way: None (not yet), a plan, or False (nowhere)
        self.aside = False          # ... the plan ends beside a wall or an obstacle
        self.gave_way_at = None     # [s] when the base began to give way
        self.waived = None          # when the people in the way were taken to wait for the base
        self.held = None            # the last cycle spent waiting for or giving way to a person
        self.points = np.zeros((0, 2))
        self.margins = np.zeros(0)  # [m] per point: how much nearer its obstacle may be
        self.blind = False          # the newest scan had no informative beam
        self.scan_stamp = None      # stamp [s] of the newest scan
        self.goal = None
        self.path = None
        self.state = None
        self.reason = ''

    # --- sensing ----------------------------------------------------------------------------
    def add_scan(self, scan):
        """One :class:`~tiago_nav.nav.costmap.MapScan`: updates the obstacle layer and the
        points the collision check uses (the hits, too-close beams at ``range_min``, and the
        costmap's occupied cells in the directions of invalid beams, which the laser cannot
        vouch for). An older scan than the newest one is ignored."""
        if self.scan_stamp is not None and scan.stamp < self.scan_stamp:
            return
        cm = self.costmap
        clearance = self.cfg.person_clearance
        people = clearance > 0 and self.waived is None
        if people:
            # which hits are a person's, beside the laser's marks before this scan
            person = self.moved.update(scan, cm.obstacles)
        cm.add_scan(scan)
        points = scan.obstacles[0]
        margins = np.zeros(len(points))
        if people:
            # a person is kept clearance farther: by the collision check (as if nearer by it)
            # and by the plan (its keep-out counts as occupied)
            keep_out = person_keep_out(clearance, self.cfg.controller.safety_margin,
                                       cm.resolution)
            margins[person] = clearance
            # and where the laser marked a person before (out of view now, or hidden)
            # (a person's mark stays one until the laser sees the place free)
            if self.moved.any_held(scan.stamp):
                marks = np.argwhere(cm.obstacles)
                marks = marks[self.moved.held(marks, scan.stamp)]
                self.moved.hold(marks, scan.stamp + self.moved.memory, grow=False)
                cm.set_people(np.vstack((points[person], cm.grid.cell_to_world(marks))),
                              keep_out)
            elif cm.people_set:
                cm.set_people(np.zeros((0, 2)), keep_out)
        self.costmap.update()
        if len(scan.ranges) and (scan.kinds == INVALID).any():
            near = self.costmap.occupied_near(scan.laser_pose[:2], self.MEMORY_RADIUS)
            near = near[scan.invalid_beam_at(near)]
            points = np.vstack((points, near))
            # a remembered cell stands for a surface anywhere in it: up to half its diagonal
            # nearer than its centre
            margins = np.concatenate((margins, np.full(len(near), self.costmap.grid.resolution
                                                       / math.sqrt(2.0))))
        self.points = points
        self.margins = margins
        self.blind = not scan.informative()
        self.scan_stamp = scan.stamp

    def clear_costmaps(self):
        """Forget what the laser marked, people included (:meth:`MovedMarks.clear`)."""
        self.costmap.clear_obstacles()
        self.moved.clear()

    def reconfigure(self, config):
        """Put the :class:`NavConfig` ``config`` in force from the next :meth:`step` on (the
        node calls it between two control cycles, :class:`tiago_nav.params.ParamChanges`): the
        controller's limits and goal tolerances, the costmap's inflation (re-inflated when next
        read). A goal in progress keeps its plan and its speed (a lower ``max_vel_x`` is
        reached at ``acc_lim_x``); its derived timeout is lengthened when the first plan at
        the new ``max_vel_x`` needs longer, never shortened."""
        old, self.cfg = self.cfg, config
        self.controller.configure(config.controller)
        if config.inflation_radius != old.inflation_radius:
            self.costmap.set_inflation(config.inflation_radius)
        if self.state == ACTIVE and getattr(self, '_first_length', None) is not None:
            self._derive_deadline(self._first_length)

    def make_plan(self, start_xy, goal_xy):
        """A plan ``(K, 2)`` on the current costmap, or :class:`PlanError`."""
        return plan(self.costmap, start_xy, goal_xy, self.cfg.cost_weight,
                    shortcut_tolerance=self.cfg.shortcut_tolerance)

    # --- goals ------------------------------------------------------------------------------
    def start(self, goal, pose, t):
        """Accept a goal ``(x, y, yaw)`` in map. Raises :class:`PlanError` for a goal that can
        never be reached (outside the map, inside an obstacle); a goal with no path *yet* is
        retried for ``planner_patience``. A goal covered only by the laser's marks, all
        farther than ``reset_distance`` from the robot, is not judged on them: what the laser
        saw from afar may be gone or a phantom (a mixed pixel that no later beam crossed), so
        they are forgotten (:meth:`_reset`) and the laser judges that place again on the way.
        A goal covered only by people (:mod:`tiago_nav.nav.people`) is accepted: people move,
        and the goal waits for them as a blocked plan does (``person_patience``)."""
        g = self.costmap.grid
        self.reset_done, self.reset_forgot = False, 0
        if not g.contains([goal[:2]])[0]:
            raise PlanError('goal (%.2f, %.2f) is outside the map' % tuple(goal[:2]))
        if self.costmap.cost_at([goal[:2]])[0] >= INSCRIBED and not self._only_people(goal):
            blocker = self.costmap.blocker(goal[:2])
            if blocker is None or blocker[1] != 'laser' or not self._reset(pose) \
                    or self.costmap.cost_at([goal[:2]])[0] >= INSCRIBED:
                raise PlanError(self.costmap.blocked_reason(goal[:2]))
        self.goal = tuple(float(v) for v in goal)
        self.t0 = t
        self.state = ACTIVE
        self.reason = ''
        self.controller.reset()
        self.path = None
        self.last_plan_ok = t
        self.last_plan_try = -math.inf
        self.patience_from = t
        self.progress_pose = pose
        self.progress_time = t
        self.recovery = 0
        self.recovery_action = None
        self.window.reset()
        self.deadline, self.timeout_reason = math.inf, ''
        self._first_length = None
        self._person_check = None
        self.retreat = None
        self.waived = None
        self.held = None
        if self.cfg.goal_timeout > 0:
            self.deadline = t + self.cfg.goal_timeout
            self.timeout_reason = 'timeout: goal not reached in %.0f s' % self.cfg.goal_timeout
        self._replan(pose, t)
        return self.path

    def _reset(self, pose):
        """Once per goal: forget the laser's marks farther than ``reset_distance`` from the
        robot at ``pose``; True when any were forgotten."""
        if self.reset_done:
            return False
        self.reset_done = True
        self.reset_forgot = self.costmap.forget_marks_beyond(pose[:2], self.cfg.reset_distance)
        return self.reset_forgot > 0

    def _reset_note(self):
        n = self.reset_forgot
        return (', the last %.1f s after forgetting %d cell%s the laser had marked farther than '
                '%g m away' % (self.cfg.planner_patience, n, '' if n == 1 else 's',
                               self.cfg.reset_distance) if self.reset_done and n else '')

    def cancel(self):
        """Forget the goal (it was preempted or ended outside :meth:`step`)."""
        self.state = None
        self.controller.reset()

    def _replan(self, pose, t):
        self.last_plan_try = t
        try:
            self.path = self.make_plan(pose[:2], self.goal[:2])
        except PlanError as e:
            self.plan_error = str(e)
            return False
        self.controller.set_path(self.path)
        self.last_plan_ok = t
        self._arc = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(self.path, axis=0).T))))
        if self.cfg.goal_timeout < 0 and math.isinf(self.deadline):
            # derived from the first plan (goal_timeout < 0)
            self._first_length = float(self._arc[-1])
            self._derive_deadline(self._first_length)
        return True

    def _derive_deadline(self, length):
        """The goal's deadline from its first plan's ``length`` [m] at ``max_vel_x`` (when
        ``goal_timeout < 0``), if later than the one it has."""
        cfg = self.cfg
        if cfg.goal_timeout >= 0:
            return
        limit = cfg.goal_timeout_factor * length / cfg.controller.max_vel_x \
            + cfg.goal_timeout_allowance
        if math.isinf(self.deadline) or self.t0 + limit > self.deadline:
            self.deadline = self.t0 + limit
            self.timeout_reason = ('timeout: goal not reached in %.0f s (%g x the %.1f m plan at '
                                   '%g m/s + %g s)' % (limit, cfg.goal_timeout_factor, length,
                                                       cfg.controller.max_vel_x,
                                                       cfg.goal_timeout_allowance))

    def to_go(self, pose):
        """Length [m] of the current plan from its point nearest to ``pose`` to the goal, plus
        the distance to that point; None without a plan."""
        if self.path is None:
            return None
        d = np.hypot(self.path[:, 0] - pose[0], self.path[:, 1] - pose[1])
        i = int(np.argmin(d))
        return float(self._arc[-1] - self._arc[i] + d[i])

    def hold(self, t):
        """The caller stopped the base this cycle instead of stepping (e.g. stale sensors): the
        controller restarts from rest and the pause does not count against progress."""
        self.controller.v = self.controller.w = 0.0
        self.progress_time = t

    def _path_blocked(self):
        if self.path is None:
            return True
        i = self.controller.index
        n = int(self.cfg.blocked_lookahead / 0.05)
        seg = self.path[i:i + n]
        return bool((self.costmap.cost_at(seg) >= INSCRIBED).any())

    def _person_in_the_way(self, pose, t):
        """With no plan: would there be one without the people (their keep-out and the laser's
        marks in it)? Then a person stands in the way, and the base waits for them. Asked again
        at most once a second."""
        cm = self.costmap
        if not cm.people_set:
            return False
        last = self._person_check
        if last is not None and t - last[0] < 1.0:
            return last[1]
        with self._without_people():
            try:
                self.make_plan(pose[:2], self.goal[:2])
                found = True
            except PlanError:
                found = False
        self._person_check = (t, found)
        return found

    def _only_people(self, goal):
        """Is the goal blocked by people only (free without them)?"""
        if not self.costmap.people_set:
            return False
        with self._without_people():
            return self.costmap.cost_at([goal[:2]])[0] < INSCRIBED

    @contextmanager
    def _without_people(self):
        """The costmap without people (their keep-out and the laser's marks in it) inside the
        ``with``; as it was after."""
        cm = self.costmap
        people, marks = cm.people.copy(), cm.obstacles.copy()
        cm.obstacles &= ~people
        cm.people[:] = False
        cm.update()
        try:
            yield
        finally:
            cm.people[:], cm.obstacles[:] = people, marks
            cm.update()

    def _give_way_path(self, pose):
        """A plan ``(K, 2)`` to the nearest place at least ``give_way_distance`` from every
        person (their keep-out in the costmap) and beside a wall or an obstacle (its centre
        :data:`ASIDE` from the robot's inscribed radius there), as a person steps aside to let
        someone pass: the most room left for them; where no such place can be reached, the
        nearest place that far from every person; False when there is none."""
        cm = self.costmap
        clear = distance_to_mask(cm.people, cm.resolution) \
            >= self.cfg.give_way_distance - self.cfg.person_clearance
        start = cm.grid.world_to_cell([pose[:2]])[0]
        beside = np.abs(cm.distance - (self.cfg.robot_radius + self.ASIDE[0])) <= self.ASIDE[1]
        self.aside = False
        for aside, targets in ((True, clear & beside), (False, clear)):
            try:
                cells = path_to_nearest(cm.cost, start, targets, self.cfg.cost_weight)
            except PlanError:
                continue
            self.aside = aside
            break
        else:
            return False
        pts = cm.grid.cell_to_world(cells)
        pts[0] = pose[:2]
        return densify(pts, 0.05)

    def _nearest_person(self, pose):
        """``(centre (2,), distance [m])`` of the people layer's cell nearest to ``pose``, or
        None without people."""
        cm = self.costmap
        if not cm.people_set:
            return None
        people = cm.grid.cell_to_world(np.argwhere(cm.people))
        if not len(people):
            return None
        d = np.hypot(people[:, 0] - pose[0], people[:, 1] - pose[1])
        i = int(np.argmin(d))
        return people[i], float(d[i])

    def _person_near(self, pose):
        """Is a person's keep-out nearer to ``pose`` than ``give_way_distance`` puts the base
        from the person?"""
        nearest = self._nearest_person(pose)
        return nearest is not None \
            and nearest[1] < self.cfg.give_way_distance - self.cfg.person_clearance

    def _wait_for_person(self, pose, t, dt):
        """Stand and face the nearest person's mark: one out of the laser's view (behind the
        base) is seen again, and cleared once the person has gone."""
        self.progress_time = t
        nearest = self._nearest_person(pose)
        if nearest is not None:
            near = nearest[0]
            err = wrap_angle(math.atan2(near[1] - pose[1], near[0] - pose[0]) - pose[2])
            if abs(err) > self.LOOK_ANGLE:
                v, w, _ = self.controller.turn(err, dt, 'rotate')
                return v, w, ACTIVE, 'waiting for a person'
        self.controller.v = self.controller.w = 0.0
        return 0.0, 0.0, ACTIVE, 'waiting for a person'

    def _give_way(self, pose, t, dt):
        """One control cycle along the give-way plan; standing still at its end."""
        end = self.retreat[-1]
        if math.hypot(end[0] - pose[0], end[1] - pose[1]) <= self.cfg.controller.xy_goal_tolerance:
            # there: wait, unless a person came near again (they are walking this way) where
            # the base stands in the open (beside a wall, it has left them the most room: they
            # pass)
            near = not self.aside and self._person_near(pose)
            if near:
                self.retreat = self._give_way_path(pose)
            if not near or self.retreat is False:
                return self._wait_for_person(pose, t, dt)
        self.controller.set_path(self.retreat)
        v, w, phase = self.controller.command(pose, (end[0], end[1], pose[2]), self.points, dt,
                                              self.blind, self.margins)
        if phase == 'arrived':
            v = w = 0.0
        return v, w, ACTIVE, 'giving way to a person'

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
        if self.held is not None:
            # the last cycle waited for or gave way to a person: the goal's own clocks (its
            # deadline, the no-progress window) stand still meanwhile; person_patience bounds it
            self.deadline += t - self.held
            self.window.reset()
            self.held = None
        if t > self.deadline:
            return self._finish(ABORTED, self.timeout_reason)
        to_go = self.to_go(pose)
        if to_go is not None and self.window.update(t, to_go):
            return self._finish(ABORTED, 'no progress: the path still to go has not shrunk by '
                                '%.2f m in %.0f s (oscillating or blocked)'
                                % (cfg.no_progress_distance, cfg.no_progress_timeout))
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
            if self.path is not None and self.retreat is not None:
                # a plan again after giving way: while the person is near (passing, or
                # waiting for the way the base left them to clear) it stays where it gave way,
                # up to person_patience
                if self.retreat is not False and t - self.gave_way_at <= cfg.person_patience \
                        and self._person_near(pose):
                    self.held = t
                    return self._give_way(pose, t, dt)
                self.retreat = None
                self.controller.set_path(self.path)
            if self.path is None:
                waited = t - max(self.last_plan_ok, self.patience_from)
                if waited > cfg.planner_patience:
                    if not self.reset_done and self._reset(pose):
                        # as move_base's recovery: marks seen from afar may be stale; the
                        # patience counts again from here
                        self.patience_from = t
                        self._replan(pose, t)
                    elif self._person_in_the_way(pose, t):
                        self.held = t       # each branch below waits or gives way
                        if waited > cfg.person_patience:
                            # they stay after the base gave way: they are waiting for it, as
                            # people do; it passes them at its ordinary clearance
                            self.waived = t
                            self.patience_from = t
                            self.retreat = None
                            self.costmap.set_people(np.zeros((0, 2)), 0.0)
                            self.margins[:] = 0.0
                            self.costmap.update()
                            self._replan(pose, t)
                            return self._wait_for_person(pose, t, dt)
                        if self.retreat is None and waited > cfg.planner_patience + cfg.give_way_after:
                            self.retreat = self._give_way_path(pose)
                            self.gave_way_at = t
                        if self.retreat is not None and self.retreat is not False:
                            return self._give_way(pose, t, dt)
                        return self._wait_for_person(pose, t, dt)
                    else:
                        return self._finish(ABORTED, 'no path: %s (for %.1f s%s)%s'
                                            % (getattr(self, 'plan_error', 'no plan'),
                                               cfg.planner_patience, self._reset_note(),
                                               '' if self.waived is None else
                                               ', after waiting %.0f s for a person in the way '
                                               '(person_patience)' % cfg.person_patience))
            if self.path is None:
                self.controller.v = self.controller.w = 0.0
                self.progress_time = t
                return 0.0, 0.0, ACTIVE, 'planning'
        v, w, phase = self.controller.command(pose, self.goal, self.points, dt, self.blind,
                                              self.margins)
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
