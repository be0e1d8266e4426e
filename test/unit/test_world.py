"""World files: the shipped worlds load; malformed ones fail with the file and field named."""
import os

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
    assert w.walls and w.movable_obstacles
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
