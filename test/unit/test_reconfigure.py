"""Run-time parameter changes (dynamic_reconfigure) in the library: the one table the cfg files
and the docs are made from, the checks a change gets, its coming in force only between two
control cycles, and the changed values reaching the navigator, controller, costmap and
corridor follower (their next commands obey them)."""
import math

import numpy as np
import pytest

from tiago_nav.corridor.law import CorridorFollower, CorridorParams
from tiago_nav.gridmap import GridMap
from tiago_nav.nav.costmap import MapScan
from tiago_nav.nav.navigator import NavConfig, Navigator
from tiago_nav.nav.runner import GoalRunner
from tiago_nav.params import ParamChanges, ParamError, dynamic_fields, replace, values
from tiago_nav.robot import LASER_OFFSET
from tiago_nav.sim.diffdrive import BaseLimits, DiffDrive
from tiago_nav_tools.testing.fakes import FakeClock

# the names move_base's DWA users know (dwa_local_planner's cfg, costmap_2d's inflation layer)
NAV_NAMES = {'max_vel_x', 'max_vel_theta', 'acc_lim_x', 'acc_lim_theta', 'xy_goal_tolerance',
             'yaw_goal_tolerance', 'inflation_radius'}
CORRIDOR_NAMES = {'max_speed', 'speed_limit', 'max_angular', 'stop_margin', 'end_clearance'}


def test_the_tables_hold_the_move_base_names_with_defaults_in_range():
    for cls, names in ((NavConfig, NAV_NAMES), (CorridorParams, CORRIDOR_NAMES)):
        rows = dynamic_fields(cls)
        assert {r[0] for r in rows} == names
        given = values(cls())
        for name, kind, default, lo, hi, doc in rows:
            assert kind is float and lo < hi and doc
            assert lo <= default <= hi and default == given[name]


@pytest.mark.ros
def test_the_generated_cfg_classes_hold_the_tables():
    """cfg/*.cfg, as the workspace's build generated them, say what the tables say."""
    cfg = pytest.importorskip('tiago_nav.cfg')
    from tiago_nav.cfg import CorridorControllerConfig, MoveBaseConfig
    assert cfg is not None
    for config, cls in ((MoveBaseConfig, NavConfig), (CorridorControllerConfig, CorridorParams)):
        got = [(p['name'], p['type'], p['default'], p['min'], p['max'], p['description'])
               for p in config.config_description['parameters']]
        want = [(n, 'double', d, lo, hi, doc) for n, _, d, lo, hi, doc in dynamic_fields(cls)]
        assert got == want


def test_replace_checks_a_change_as_a_start():
    nav = NavConfig()
    new = replace(nav, {'max_vel_x': 0.3, 'inflation_radius': 0.5})
    assert new.controller.max_vel_x == 0.3 and new.inflation_radius == 0.5
    assert nav.controller.max_vel_x == 1.0                       # the old one is untouched
    with pytest.raises(ParamError, match='max_vel_x.*in \\[0.05, 2\\]') as e:
        replace(nav, {'max_vel_x': 2.5})
    assert e.value.name == 'max_vel_x'
    with pytest.raises(ParamError) as e:                        # below robot_radius (0.27 m)
        replace(nav, {'inflation_radius': 0.2})
    assert e.value.name == 'inflation_radius'
    with pytest.raises(ParamError, match='cannot be changed while the node runs') as e:
        replace(nav, {'robot_radius': 0.3})
    assert e.value.name == 'robot_radius'
    with pytest.raises(ParamError, match='expected a number'):
        replace(nav, {'acc_lim_x': 'fast'})


def test_a_change_waits_for_a_cycle_boundary_while_a_loop_runs():
    applied = []
    changes = ParamChanges(NavConfig(), applied.append)
    changes.request({'max_vel_x': 0.5})                          # idle: at once
    assert [a.controller.max_vel_x for a in applied] == [0.5]
    changes.begin()
    new = changes.request({'max_vel_x': 0.3})
    assert new.controller.max_vel_x == 0.3 and changes.requested is new
    assert changes.params.controller.max_vel_x == 0.5 and len(applied) == 1   # not mid-cycle
    changes.request({'acc_lim_x': 0.5})                         # on top of the pending one
    with pytest.raises(ParamError):
        changes.request({'inflation_radius': 0.1})               # refused: nothing changes
    changes.boundary()
    assert len(applied) == 2
    assert (applied[-1].controller.max_vel_x, applied[-1].controller.acc_lim_x) == (0.3, 0.5)
    changes.boundary()
    assert len(applied) == 2                                     # nothing new, nothing applied
    changes.request({'max_vel_x': 0.4})
    changes.end()                                                # the loop's end applies it
    assert changes.params.controller.max_vel_x == 0.4 and len(applied) == 3


def test_navigator_reconfigure_reaches_controller_and_costmap():
    grid = GridMap(np.zeros((80, 160), dtype=np.int8), 0.05, (0.0, 0.0))
    grid.data[:, 100] = 100                                      # a wall at x = 5 m
    nav = Navigator(grid, NavConfig())
    assert nav.costmap.cost[40, 76] == 0                          # 1.2 m from the wall
    nav.reconfigure(replace(nav.cfg, {'max_vel_x': 0.3, 'max_vel_theta': 0.7,
                                      'xy_goal_tolerance': 0.3, 'inflation_radius': 1.5}))
    assert nav.controller.c.max_vel_x == 0.3 and nav.controller.c.max_vel_theta == 0.7
    assert nav.controller.c.xy_goal_tolerance == 0.3 and nav.cfg.controller is nav.controller.c
    assert nav.costmap.inflation_radius == 1.5
    assert nav.costmap.cost[40, 76] > 0                           # inflated that far now
    assert nav.costmap.cost_at([(3.825, 2.025)])[0] == nav.costmap.cost[40, 76]


class Rig:
    """A goal runner without ROS: a kinematic base in an empty 8 m x 4 m room, a clear laser,
    the library's Ticker on a fake clock. Cycle ``k`` sends the ``k``-th command (from 0);
    ``hooks[k]`` runs inside it (while its pose is read, before its command is computed), as a
    reconfigure request from another thread would."""

    def __init__(self):
        self.clock = FakeClock()
        self.base = DiffDrive((0.5, 2.0, 0.0), BaseLimits())
        grid = GridMap(np.zeros((80, 300), dtype=np.int8), 0.05, (0.0, 0.0))
        self.nav = Navigator(grid, NavConfig())
        self.changes = ParamChanges(NavConfig(), self.nav.reconfigure)
        self.runner = GoalRunner(self.nav, self, 0.1, changes=self.changes)
        self.hooks = {}
        self.sent = []          # (cycle, v, max_vel_x the controller held when it was sent)
        self.clock.hooks.append(self.advance)
        self.scan()

    def scan(self):
        x, y, th = self.base.pose
        lp = (x + LASER_OFFSET * math.cos(th), y + LASER_OFFSET * math.sin(th), th)
        self.nav.add_scan(MapScan(lp, np.full(221, np.inf), -math.radians(110),
                                  math.radians(1), 0.05, 25.0, self.clock.now()))

    def advance(self, dt):
        v, w = self.sent[-1][1:3] if self.sent else (0.0, 0.0)
        self.base.step(v, w, dt)
        self.scan()

    # the runner's io
    def pose(self):
        hook = self.hooks.pop(len(self.sent), None)
        if hook is not None:
            hook()
        return self.base.pose, self.clock.now()

    def to_map(self, frame, pose):
        return pose

    def send_cmd(self, v, w):
        self.sent.append((len(self.sent), v, w, self.nav.controller.c.max_vel_x))

    def publish_plan(self, path):
        pass

    def publish_feedback(self, pose):
        pass

    def preempt_requested(self):
        return False

    def finish(self, status, text):
        self.outcome = (status, text)


def test_a_change_during_a_goal_limits_the_next_cycles_commands():
    rig = Rig()
    rig.hooks[25] = lambda: rig.changes.request({'max_vel_x': 0.3})
    rig.runner.run('map', (7.0, 2.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    assert rig.outcome == ('succeeded', 'goal reached')
    by_cycle = {c: (v, limit) for c, v, _, limit in rig.sent}
    assert by_cycle[25][1] == 1.0            # the cycle it came in is computed with the old value
    assert by_cycle[25][0] > 0.9             # at full speed then
    assert all(limit == 0.3 for c, (v, limit) in by_cycle.items() if c > 25)
    # from the next cycle on: down at acc_lim_x (1 m/s^2, 0.1 m/s per 0.1 s cycle), then <= 0.3
    v25 = by_cycle[25][0]
    for c, (v, _) in by_cycle.items():
        if c > 25:
            assert v <= max(0.3, v25 - 0.1 * (c - 25)) + 1e-9, (c, v)
    assert max(v for c, (v, _) in by_cycle.items() if c >= 33) <= 0.3 + 1e-9
    assert rig.changes.params.controller.max_vel_x == 0.3


def test_corridor_follower_reconfigure_caps_its_speed():
    f = CorridorFollower(CorridorParams())
    assert f.max_speed == 1.0
    f.reconfigure(replace(CorridorParams(), {'max_speed': 0.4}))
    assert f.max_speed == 0.4 and f.p.max_speed == 0.4
    g = CorridorFollower(CorridorParams(), max_speed=0.8)         # the goal's own speed
    g.reconfigure(replace(CorridorParams(), {'speed_limit': 0.5, 'stop_margin': 0.2}))
    assert g.max_speed == 0.5 and g.p.stop_margin == 0.2
    g.reconfigure(CorridorParams())
    assert g.max_speed == 0.8
