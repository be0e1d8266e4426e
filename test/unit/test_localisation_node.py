"""The localisation node's own logic (parameters, start pose, covariance layout, when a
lockstep tick needs a re-send); the decisions are the library's (test_localisation.py)."""
import math
import os

import numpy as np
import pytest
import rospy

from conftest import ROOT
from tiago_nav.nodes.localisation import Params
from tiago_nav.ros.clock import reaches_past
from tiago_nav.ros.conversions import covariance_6x6
from tiago_nav.ros.params import start_pose
from tiago_nav.params import ParamError, read_params
from tiago_nav.sim.world import WorldError

# needs ROS: rospy, tiago_nav.nodes.localisation
pytestmark = pytest.mark.ros

WORLD = os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml')


def test_start_pose_from_the_parameter_or_the_world():
    assert start_pose(Params(initial_pose=[1.0, -2.0, 90])) == pytest.approx((1.0, -2.0, math.pi / 2))
    assert start_pose(Params(world=WORLD)) == pytest.approx((0.0, 0.0, 0.0))
    # initial_pose wins over the world's robot_start
    assert start_pose(Params(world=WORLD, initial_pose=[2, 0, 0]))[0] == 2.0
    with pytest.raises(ParamError) as e:
        start_pose(Params())
    assert e.value.name == 'initial_pose'
    with pytest.raises(WorldError):
        start_pose(Params(world='/nonexistent.yaml'))


@pytest.mark.parametrize('values, name', [
    ({'initial_pose': [1.0, 2.0]}, 'initial_pose'),
    ({'initial_pose': [1.0, 2.0, 'x']}, 'initial_pose'),
    ({'map_frame': ''}, 'map_frame'),
    ({'transform_tolerance': -0.1}, 'transform_tolerance'),
    ({'robust_scale': 1.0}, 'robust_scale'),          # > initial_scale, a nested field
    ({'min_inliers': 1}, 'min_inliers'),
])
def test_bad_parameters_are_named(values, name):
    values = {'~' + k: v for k, v in values.items()}
    with pytest.raises(ParamError) as e:
        read_params(Params, lambda k, d: values.get(k, d))
    assert e.value.name == name and name in str(e.value)


def test_covariance_lands_on_x_y_yaw():
    cov = covariance_6x6(np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 5.0], [3.0, 5.0, 6.0]]))
    m = np.array(cov).reshape(6, 6)
    assert m[0, 0] == 1 and m[1, 1] == 4 and m[5, 5] == 6 and m[0, 5] == 3 and m[5, 1] == 5
    assert np.count_nonzero(m) == 9


def test_a_tick_needs_a_re_send_only_when_no_send_reaches_past_it():
    t = rospy.Time.from_sec
    scans = [t(10.0 + 0.1), t(10.0 + 1 / 15 + 0.1)]       # two scans' sends (0.1 s ahead)
    assert reaches_past(scans, t(10.1))                     # the scans flow: no re-send
    assert not reaches_past(scans, t(10.2))                 # a silent laser: re-send
    assert not reaches_past(scans, t(10.0 + 1 / 15 + 0.1))  # a send at the tick is not past it
    assert not reaches_past([], t(10.1))                    # nothing sent yet


def test_degenerate_geometry_is_logged_once_and_its_recovery_after_three_registrations():
    import types
    from tiago_nav.localisation.localiser import Update
    from tiago_nav.nodes.localisation import RECOVERED_AFTER, LocalisationNode

    def up(weak, x):
        return Update((x, 0.0, 0.0), (0.0, 0.0, 0.0), np.eye(3), (x, 0.0, 0.0), True, 100, 200,
                      '', weak)

    node = types.SimpleNamespace(degenerate=False, clear_streak=0)
    said = [LocalisationNode.degeneracy(node, up(w, 0.1 * k)) for k, w in enumerate(
        [''] * 3 + ['position along 0 deg'] * 20 + ['', 'position along 0 deg'] + [''] * 5)]
    lines = [s for s in said if s]
    assert len(lines) == 2, lines
    assert lines[0].startswith('scan geometry is degenerate at (0.30, 0.00): the position along '
                               '0 deg is unobservable')
    assert lines[1] == 'scan geometry constrains every direction again at (%.2f, 0.00)' % (
        0.1 * (25 + RECOVERED_AFTER - 1))


def test_diagnostics_at_the_period_and_at_once_when_the_state_changes():
    import collections
    import threading
    import types
    from tiago_nav.localisation.health import ERROR, OK, WARN, Health
    from tiago_nav.nodes.localisation import LocalisationNode

    sent, states = [], []
    node = types.SimpleNamespace(
        p=types.SimpleNamespace(diagnostic_period=1.0, map_frame='map'), diag=None,
        diag_lock=threading.Lock(), skipped=collections.Counter({'queue full': 2}), state=None,
        pub_state=types.SimpleNamespace(publish=lambda m: states.append(m.data)))
    node._send_diagnostics = lambda stamp, st: sent.append((stamp.to_sec(), st.level, st))
    levels = [OK] * 9 + [WARN] + [ERROR] * 3 + [OK] * 6    # a scan every 0.25 s
    for k, level in enumerate(levels):
        LocalisationNode.publish_health(node, rospy.Time(100.0 + 0.25 * k),
                                        Health(level, 'x', 0.9, 0, 3), (1.0, 2.0, 0.0),
                                        np.eye(3) * 0.01, False)
    # the first, one a second, and each change at its scan
    assert [(t, lv) for t, lv, _ in sent] == [
        (100.0, OK), (101.0, OK), (102.0, OK), (102.25, WARN), (102.5, ERROR), (103.25, OK),
        (104.25, OK)]
    assert states == ['ok', 'degraded', 'lost', 'ok']
    values = {kv.key: kv.value for kv in sent[-1][2].values}
    assert values['skipped scans'] == '2' and values['skipped scans (queue full)'] == '2'
    # the laser silent: the last status again once a period has gone by, not before
    LocalisationNode.diagnostics_heartbeat(node, rospy.Time(104.9))
    assert len(sent) == 7
    LocalisationNode.diagnostics_heartbeat(node, rospy.Time(105.25))
    assert len(sent) == 8 and sent[-1][:2] == (105.25, OK)
