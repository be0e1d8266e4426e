"""A world file's optional ``world_frame`` (another named frame, e.g. the Gazebo world's): its
parsing and validation, the simulator's map -> NAME on /tf_static, and the client showing the
obstacles' centres in any frame (``--frame``)."""
import math
import os
from dataclasses import fields

import pytest
import yaml

from conftest import ROOT
from tiago_nav.geometry import transform_points
from tiago_nav.mission.client import (MAP_FRAME, UsageError, centres_in_frame, obstacle_table,
                                      parse_client_args, table_title)
from tiago_nav.sim.world import World, WorldError, load_world

BOX = os.path.join(ROOT, 'test', 'worlds', 'sim_box.yaml')
COURSE = os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml')
# the course's ground truth in its Gazebo world's frame (the world file's header): the four
# cylinders in view from pose B, the first four movable obstacles
GAZEBO_TARGETS = [(4.156, -0.295), (4.875, -2.424), (6.160, -1.347), (5.811, 0.763)]


def box(**extra):
    with open(BOX) as f:
        data = yaml.safe_load(f)
    data.update(extra)
    return data


# --- the world file ------------------------------------------------------------------------
def test_world_frame_is_optional():
    assert World.from_dict(box()).world_frame is None


def test_world_frame_is_parsed():
    wf = World.from_dict(box(world_frame={'name': 'world', 'offset': [6.58, -1.37, 90]})).world_frame
    assert wf.name == 'world' and wf.offset == (6.58, -1.37, 90.0)
    assert wf.pose == pytest.approx((6.58, -1.37, math.pi / 2))


@pytest.mark.parametrize('value, words', [
    ('world', r'world_frame must be a mapping'),
    ({'name': 'world'}, r"world_frame is missing 'offset'"),
    ({'offset': [0, 0, 0]}, r"world_frame is missing 'name'"),
    ({'name': 'world', 'offset': [0, 0, 0], 'parent': 'map'}, r'world_frame has unknown key\(s\) parent'),
    ({'name': '', 'offset': [0, 0, 0]}, r'world_frame.name must be a tf frame name'),
    ({'name': 'my world', 'offset': [0, 0, 0]}, r'world_frame.name must be a tf frame name'),
    ({'name': '/world', 'offset': [0, 0, 0]}, r'world_frame.name must be a tf frame name'),
    ({'name': 3, 'offset': [0, 0, 0]}, r'world_frame.name must be a tf frame name'),
    ({'name': 'world', 'offset': [0, 0]}, r'world_frame.offset must be a list of 3 numbers'),
    ({'name': 'world', 'offset': [0, 'a', 0]}, r'world_frame.offset\[1\] must be a finite number'),
    ({'name': 'world', 'offset': [0, 0, float('nan')]}, r'world_frame.offset\[2\] must be a finite'),
])
def test_bad_world_frame_is_refused_naming_the_field(value, words):
    with pytest.raises(WorldError, match=words):
        World.from_dict(box(world_frame=value), source='w.yaml')


def test_the_course_world_declares_the_gazebo_world_frame():
    """p_map = p_world + (6.58, -1.37): the Gazebo coordinates of the four cylinders in view,
    as the course quotes them, land on the world file's movable obstacles."""
    world = load_world(COURSE)
    wf = world.world_frame
    assert wf.name == 'world' and wf.offset == (6.58, -1.37, 0.0)
    in_map = transform_points(wf.pose, GAZEBO_TARGETS)
    truth = [(c.x, c.y) for c in world.movable_obstacles[:4]]
    assert in_map.ravel().tolist() == pytest.approx([v for p in truth for v in p], abs=1e-3)


# --- the simulator -------------------------------------------------------------------------
def _node(world_path, **kw):
    from tiago_nav.nodes.simulator import Outputs, Params, SimulatorNode
    from tiago_nav.params import read_params
    from tiago_nav_tools.testing.fakes import FakePublisher
    kw.update(world=world_path, laser_model='ideal', odometry_model='ideal')
    params = read_params(Params, lambda n, d: {'~' + k: v for k, v in kw.items()}.get(n, d))
    return SimulatorNode(params, Outputs(**{f.name: FakePublisher() for f in fields(Outputs)}))


def _write(tmp_path, **extra):
    path = tmp_path / 'w.yaml'
    path.write_text(yaml.safe_dump(box(**extra)))
    return str(path)


@pytest.mark.ros
def test_simulator_publishes_map_to_world_frame_with_its_own_static_frames(tmp_path):
    pytest.importorskip('rospy')
    from tiago_nav.ros.conversions import pose_from_transform
    node = _node(_write(tmp_path, world_frame={'name': 'gazebo', 'offset': [2.0, -1.0, 30.0]}))
    try:
        node.start()
        msg, = node.out.tf_static.messages            # one latched message holds them all
        pairs = [(t.header.frame_id, t.child_frame_id) for t in msg.transforms]
        assert pairs == [('base_footprint', 'base_link'), ('base_link', 'base_laser_link'),
                         ('map', 'gazebo')]
        assert pose_from_transform(msg.transforms[2].transform) == \
            pytest.approx((2.0, -1.0, math.radians(30)))
    finally:
        node.close()


@pytest.mark.ros
def test_simulator_publishes_the_world_frame_alone_when_urdf_frames_come_from_elsewhere(tmp_path):
    pytest.importorskip('rospy')
    node = _node(_write(tmp_path, world_frame={'name': 'gazebo', 'offset': [0, 0, 0]}),
                 publish_robot_frames=False)
    try:
        node.start()
        msg, = node.out.tf_static.messages
        assert [(t.header.frame_id, t.child_frame_id) for t in msg.transforms] == [('map', 'gazebo')]
    finally:
        node.close()


@pytest.mark.ros
def test_simulator_refuses_a_world_frame_named_like_its_own_frames(tmp_path):
    pytest.importorskip('rospy')
    with pytest.raises(WorldError, match=r"world_frame.name 'odom' is one of the simulator's own"):
        _node(_write(tmp_path, world_frame={'name': 'odom', 'offset': [0, 0, 0]}))


# --- the client ----------------------------------------------------------------------------
def test_client_frame_option():
    assert parse_client_args(['11', '0', '-45'])['frame'] == MAP_FRAME
    assert parse_client_args(['11', '0', '-45', '--frame', 'world'])['frame'] == 'world'
    assert parse_client_args(['11', '0', '-45', '--frame=/base_footprint'])['frame'] == \
        'base_footprint'


@pytest.mark.parametrize('argv, words', [
    (['1', '2', '3', '--frame', ''], 'expected a tf frame name'),
    (['1', '2', '3', '--frame', 'a b'], "expected a tf frame name (e.g. map, base_footprint, "
                                        "world), got 'a b'"),
    (['1', '2', '3', '--frame'], 'expected one argument'),
])
def test_malformed_frame_is_a_usage_error(argv, words):
    with pytest.raises(UsageError) as e:
        parse_client_args(argv)
    assert words in str(e.value) and '--frame' in str(e.value)


def test_centres_move_into_the_gazebo_world_frame():
    world = load_world(COURSE)
    rows = [(c.x, c.y, 1.0, -0.5, c.radius, 40) for c in world.movable_obstacles[:4]]
    moved = centres_in_frame(rows, world.world_frame.pose)
    assert [v for r in moved for v in r[:2]] == \
        pytest.approx([v for p in GAZEBO_TARGETS for v in p], abs=1e-3)
    assert [r[2:] for r in moved] == [r[2:] for r in rows]     # robot columns untouched


def test_centres_in_a_rotated_frame():
    """A frame at (1, 2) turned 90 deg: the map point (1, 3) is 1 m along its x axis."""
    (x, y, xr, yr, r, n), = centres_in_frame([(1.0, 3.0, 0.5, 0.0, 0.2, 9)], (1.0, 2.0, math.pi / 2))
    assert (x, y) == pytest.approx((1.0, 0.0))
    assert (xr, yr, r, n) == (0.5, 0.0, 0.2, 9)


def test_centres_in_frame_edge_cases():
    assert centres_in_frame([], (1.0, 2.0, 0.3)) == []
    with pytest.raises(ValueError):
        centres_in_frame([(0.0, 0.0, 0.0, 0.0, 0.1, 5)], (float('nan'), 0.0, 0.0))


def test_table_title_names_the_frame():
    assert table_title() == 'obstacles (map frame, and robot frame base_footprint at scan time):'
    assert table_title('world').startswith('obstacles (world frame,')
    lines = obstacle_table(centres_in_frame([(10.0, -1.0, 1.2, -0.5, 0.183, 42)],
                                            (6.58, -1.37, 0.0)))
    assert lines[2].split()[1:3] == ['3.42', '0.37']


@pytest.mark.ros
def test_known_frames_names_children_and_parents():
    pytest.importorskip('tf2_ros')
    from tiago_nav.ros.conversions import known_frames
    text = ("world: \n  parent: 'map'\n  broadcaster: 'x'\n  rate: 10000.000\n"
            "odom: \n  parent: 'map'\n  broadcaster: 'x'\n")
    assert known_frames(text) == {'world', 'odom', 'map'}
    assert known_frames('') == set()
