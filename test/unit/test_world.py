"""World files: the shipped worlds load; malformed ones fail with the file and field named."""
import math
import os

import numpy as np
import pytest
import yaml

from conftest import WORLDS
from tiago_nav.sim.world import World, WorldError, load_world

GOOD = {
    'name': 't', 'resolution': 0.05, 'bounds': [0, 0, 4, 3], 'robot_start': [1, 1, 90],
    'walls': [{'x': 2, 'y': 0, 'length': 4, 'width': 0.1}],
    'static_cylinders': [{'x': 3, 'y': 2, 'radius': 0.2}],
    'movable_obstacles': [{'x': 1, 'y': 2, 'radius': 0.15}],
}


def write(tmp_path, data, name='w.yaml'):
    p = tmp_path / name
    p.write_text(data if isinstance(data, str) else yaml.safe_dump(data))
    return str(p)


@pytest.mark.parametrize('name', sorted(os.listdir(WORLDS)))
def test_shipped_worlds_load(name):
    w = load_world(os.path.join(WORLDS, name))
    assert w.walls and (w.movable_obstacles or w.walkers)
    xmin, ymin, xmax, ymax = w.bounds
    assert xmin <= w.robot_start[0] <= xmax and ymin <= w.robot_start[1] <= ymax


def test_course_world_matches_reference():
    """The shipped course world is the reference measurement, unchanged (it only adds the
    declaration of the Gazebo world's frame, checked in test_world_frame.py)."""
    ref = os.path.join(WORLDS, '..', '..', 'shared', 'reference', 'ias_lab_room_full.yaml')
    if not os.path.exists(ref):
        pytest.skip('../shared/reference is not beside the repository')
    with open(ref) as a, open(os.path.join(WORLDS, 'ias_lab_room_full.yaml')) as b:
        shipped = yaml.safe_load(b)
        shipped.pop('world_frame')
        assert yaml.safe_load(a) == shipped


def test_course_world_facts():
    w = load_world(os.path.join(WORLDS, 'ias_lab_room_full.yaml'))
    assert len(w.movable_obstacles) == 9
    assert all(abs(c.radius - 0.183) < 1e-9 for c in w.movable_obstacles)
    assert w.start_pose == (0.0, 0.0, 0.0)
    assert w.corridor is not None and abs(w.corridor.width - 1.07) < 1e-9


def test_good_world_parsed(tmp_path):
    w = load_world(write(tmp_path, GOOD))
    assert w.name == 't' and w.bounds == (0, 0, 4, 3)
    assert w.start_pose[2] == pytest.approx(1.5707963, abs=1e-6)
    assert w.walls[0].yaw_deg == 0.0 and w.corridor is None
    assert w.static_cylinders[0].radius == 0.2


def test_missing_file_is_named(tmp_path):
    missing = str(tmp_path / 'nope.yaml')
    with pytest.raises(WorldError, match='nope.yaml.*not found'):
        load_world(missing)


def test_invalid_yaml(tmp_path):
    p = write(tmp_path, 'name: [unclosed\n')
    with pytest.raises(WorldError, match='w.yaml: not valid YAML'):
        load_world(p)


@pytest.mark.parametrize('change, field', [
    (lambda d: d.pop('bounds'), "'bounds'"),
    (lambda d: d.update(resolution=-1), 'resolution must be > 0'),
    (lambda d: d.update(bounds=[4, 0, 0, 3]), 'bounds must be'),
    (lambda d: d.update(robot_start=[1, 1]), 'robot_start must be a list of 3'),
    (lambda d: d.update(robot_start=[9, 1, 0]), 'robot_start .* outside bounds'),
    (lambda d: d['walls'][0].pop('length'), r"walls\[0\] is missing 'length'"),
    (lambda d: d['walls'][0].update(width='thick'), r'walls\[0\].width must be a finite number'),
    (lambda d: d['walls'][0].update(height=2), r'walls\[0\] has unknown key\(s\) height'),
    (lambda d: d['movable_obstacles'][0].update(radius=0), r'movable_obstacles\[0\].radius must be > 0'),
    (lambda d: d.update(static_cylinders={'x': 1}), 'static_cylinders must be a list'),
    (lambda d: d.update(corridor={'entry': [0, 0], 'exit': [1, 0]}), "corridor is missing 'width'"),
    (lambda d: d.update(wals=[]), r'unknown key\(s\) wals'),
])
def test_malformed_world_names_file_and_field(tmp_path, change, field):
    data = yaml.safe_load(yaml.safe_dump(GOOD))
    change(data)
    path = write(tmp_path, data, 'bad_world.yaml')
    with pytest.raises(WorldError, match='bad_world.yaml: .*' + field):
        load_world(path)


def test_not_a_mapping(tmp_path):
    with pytest.raises(WorldError, match='must be a YAML mapping'):
        load_world(write(tmp_path, '- 1\n- 2\n'))


def test_from_dict_validates():
    with pytest.raises(WorldError, match='<test>: missing required field'):
        World.from_dict({'name': 'x'}, source='<test>')


def test_clearance_is_exact_to_walls_and_cylinders():
    from tiago_nav.sim.world import clearance
    w = World.from_dict({'name': 'c', 'resolution': 0.05, 'bounds': [0, 0, 4, 4],
                         'robot_start': [1, 1, 0],
                         'walls': [{'x': 2.0, 'y': 0.0, 'length': 4.0, 'width': 0.2, 'yaw_deg': 0}],
                         'movable_obstacles': [{'x': 3.0, 'y': 2.0, 'radius': 0.2}]})
    # the wall's face is at y = 0.1; the cylinder's surface 0.8 m from (3, 3)
    assert clearance(w, [(1.0, 1.0)]) == pytest.approx(0.9, abs=1e-12)
    assert clearance(w, [(1.0, 1.0, 0.5), (3.0, 3.0, 0.0)], robot_radius=0.27) == pytest.approx(0.53)
    assert clearance(w, [(3.0, 3.0)], cylinders=False) == pytest.approx(2.9)
    assert clearance(w, [(3.0, 2.3)], robot_radius=0.27) < 0          # overlapping the cylinder
    assert clearance(w, []) is None


SHAPES = dict(GOOD, movable_obstacles=[
    {'x': 1, 'y': 2, 'radius': 0.15},
    {'shape': 'cylinder', 'x': 2, 'y': 2, 'radius': 0.1},
    {'shape': 'box', 'x': 3.0, 'y': 1.0, 'length': 0.6, 'width': 0.4, 'yaw_deg': 90},
    {'shape': 'table', 'x': 1.5, 'y': 1.0, 'length': 1.2, 'width': 0.8},
    {'shape': 'chair', 'x': 0.5, 'y': 0.5, 'length': 0.4, 'width': 0.4, 'yaw_deg': 45,
     'leg_radius': 0.02},
], walkers=[{'path': [[0.5, 2.5], [3.5, 2.5]], 'speed': 1.2, 'loop': True, 'start_delay': 2},
            {'path': [[3.5, 0.5], [0.5, 0.5], [0.5, 2.0]], 'speed': 0.8}])


def test_movable_shapes_and_walkers(tmp_path):
    w = load_world(write(tmp_path, SHAPES))
    cyl, cyl2, box, table, chair = w.movable_obstacles
    assert [o.shape for o in w.movable_obstacles] == ['cylinder', 'cylinder', 'box', 'table', 'chair']
    assert cyl.radius == 0.15 and cyl2.radius == 0.1 and not len(cyl.legs())
    # a box 0.6 long along y (yaw 90 deg): 0.3 m from its centre along y, 0.2 along x
    assert box.distance(3.0, 1.5) == pytest.approx(0.2)
    assert box.distance(3.5, 1.0) == pytest.approx(0.3)
    assert box.distance(3.0, 1.0) == pytest.approx(-0.2)      # inside: to the nearest face
    assert box.radius == pytest.approx(0.5 * math.hypot(0.6, 0.4))
    assert sorted(map(tuple, box.outline().round(6).tolist())) == [(2.8, 0.7), (2.8, 1.3), (3.2, 0.7), (3.2, 1.3)]
    # a table: legs at the corners, default leg radius; the robot touches only the legs
    assert table.leg_radius == 0.03
    assert sorted(map(tuple, table.legs().round(6).tolist())) == [(0.9, 0.6), (0.9, 1.4), (2.1, 0.6), (2.1, 1.4)]
    assert table.distance(1.5, 1.0) == pytest.approx(math.hypot(0.6, 0.4) - 0.03)
    assert table.distance(0.9, 0.5) == pytest.approx(0.07)
    assert chair.leg_radius == 0.02 and chair.yaw == pytest.approx(math.pi / 4)
    assert np.allclose(chair.legs().mean(axis=0), (0.5, 0.5))
    assert np.allclose(np.hypot(*(chair.legs() - (0.5, 0.5)).T), 0.2 * math.sqrt(2))
    a, b = w.walkers
    assert a.path == ((0.5, 2.5), (3.5, 2.5)) and a.speed == 1.2 and a.loop and a.start_delay == 2
    assert not b.loop and b.start_delay == 0


def test_chair_default_leg_radius(tmp_path):
    data = dict(GOOD, movable_obstacles=[{'shape': 'chair', 'x': 1, 'y': 1, 'length': 0.4, 'width': 0.4}])
    assert load_world(write(tmp_path, data)).movable_obstacles[0].leg_radius == 0.015


def test_clearance_to_shapes_is_to_what_the_base_touches():
    from tiago_nav.sim.world import clearance
    w = World.from_dict(dict(SHAPES, walls=[], static_cylinders=[], walkers=[],
                             movable_obstacles=SHAPES['movable_obstacles'][2:4]))
    # (1.5, 1.0) is under the table, 0.69 m from its legs; the box is farther
    assert clearance(w, [(1.5, 1.0)]) == pytest.approx(math.hypot(0.6, 0.4) - 0.03)
    assert clearance(w, [(3.0, 1.6)], robot_radius=0.1) == pytest.approx(0.2)


@pytest.mark.parametrize('change, field', [
    (lambda d: d['movable_obstacles'][2].update(shape='sofa'), r'movable_obstacles\[2\].shape must be one of'),
    (lambda d: d['movable_obstacles'][2].pop('width'), r"movable_obstacles\[2\] is missing 'width'"),
    (lambda d: d['movable_obstacles'][2].update(length=0), r'movable_obstacles\[2\].length must be > 0'),
    (lambda d: d['movable_obstacles'][2].update(leg_radius=0.1), r'movable_obstacles\[2\] has unknown key\(s\) leg_radius'),
    (lambda d: d['movable_obstacles'][1].update(length=1), r'movable_obstacles\[1\] has unknown key\(s\) length'),
    (lambda d: d['movable_obstacles'][3].update(yaw_deg='north'), r'movable_obstacles\[3\].yaw_deg must be a finite number'),
    (lambda d: d['movable_obstacles'][3].update(leg_radius=-0.01), r'movable_obstacles\[3\].leg_radius must be > 0'),
    (lambda d: d['movable_obstacles'][4].update(leg_radius=0.2), r'movable_obstacles\[4\].leg_radius must be less than half'),
    (lambda d: d['movable_obstacles'][4].update(radius=0.2), r'movable_obstacles\[4\] has unknown key\(s\) radius'),
    (lambda d: d.update(walkers={'path': []}), 'walkers must be a list'),
    (lambda d: d['walkers'][0].pop('speed'), r"walkers\[0\] is missing 'speed'"),
    (lambda d: d['walkers'][0].update(speed=0), r'walkers\[0\].speed must be > 0'),
    (lambda d: d['walkers'][0].update(path=[[0, 0]]), r'walkers\[0\].path must be a list of at least 2'),
    (lambda d: d['walkers'][1].update(path=[[0, 0], [1]]), r'walkers\[1\].path\[1\] must be a list of 2'),
    (lambda d: d['walkers'][1].update(path=[[0, 0], [1, 1], [1, 1]]), r'walkers\[1\].path\[2\] repeats'),
    (lambda d: d['walkers'][0].update(loop='yes'), r'walkers\[0\].loop must be true or false'),
    (lambda d: d['walkers'][1].update(path=[[1, 1], [9, 1]]), r'walkers\[1\].path\[1\] .* lies outside bounds'),
    (lambda d: d['walkers'][0].update(start_delay=-1), r'walkers\[0\].start_delay must be >= 0'),
    (lambda d: d['walkers'][0].update(name='bob'), r'walkers\[0\] has unknown key\(s\) name'),
])
def test_malformed_shapes_and_walkers_name_the_field(tmp_path, change, field):
    data = yaml.safe_load(yaml.safe_dump(SHAPES))
    change(data)
    with pytest.raises(WorldError, match='bad_world.yaml: .*' + field):
        load_world(write(tmp_path, data, 'bad_world.yaml'))
