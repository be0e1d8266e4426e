"""Shapes other than circles and motion over the scans at rest (tiago_nav.detection.shapes,
tiago_nav.detection.motion): a box is one rectangle (two faces: its centre and heading; one
face: a centre bounded, not fixed, whose covariance covers it), a table's legs one object, a
person's two legs one object, and what moves between the scans at rest is moving, with its
velocity, never static."""
import math

import numpy as np
import pytest

from tiago_nav.detection import DetectionParams, ObstacleDetector
from tiago_nav.detection import shapes
from tiago_nav.sim.raster import rasterise_world
from tiago_nav.sim.scene import LaserConfig, Scene, noisy
from tiago_nav.sim.world import World

L = LaserConfig()
WALLS = [{'x': 3.5, 'y': 3.0, 'length': 9.0, 'width': 0.15},
         {'x': 3.5, 'y': -3.0, 'length': 9.0, 'width': 0.15},
         {'x': 7.5, 'y': 0.0, 'length': 6.0, 'width': 0.15, 'yaw_deg': 90}]


def world(movable):
    return World.from_dict({'name': 'shapes', 'resolution': 0.05, 'bounds': [-1, -4, 8, 4],
                            'robot_start': [0, 0, 0], 'walls': WALLS,
                            'movable_obstacles': movable})


def detect(w, seed=0, pose=(0.0, 0.0, 0.0), grid_world=None):
    with Scene(w) as s:
        r, _ = s.cast(pose)
        laser = s.laser_pose(pose)
    r = noisy(r, 0.01, np.random.default_rng(seed), L.range_min, L.range_max)
    det = ObstacleDetector(rasterise_world(grid_world or w), DetectionParams(correct_pose=False, shapes=True))
    return det.detect(r, L.angle_min, L.angle_increment, L.range_min, L.range_max, laser)


def heading_error(a, b, period=math.pi):
    d = math.fmod(a - b, period)
    return abs(min(d % period, period - d % period))


@pytest.mark.parametrize('seed', range(3))
def test_a_box_seen_on_two_faces_is_one_rectangle_with_its_centre_and_heading(seed):
    # the 0.6 m face is seen at about 18 deg to the beams: its points lie 6-9 cm apart
    box = {'shape': 'box', 'x': 3.0, 'y': 1.2, 'length': 0.6, 'width': 0.4, 'yaw_deg': 40}
    found = detect(world([box]), seed)
    assert [d.shape for d in found] == ['rectangle'], [(d.shape, d.note) for d in found]
    d = found[0]
    assert d.center_fixed and d.note == 'two faces seen'
    assert math.hypot(d.center[0] - 3.0, d.center[1] - 1.2) < 0.03
    assert heading_error(d.orientation, math.radians(40)) < math.radians(5)
    assert abs(d.extent[0] - 0.6) < 0.05 and abs(d.extent[1] - 0.4) < 0.05


def test_a_box_seen_on_one_face_has_a_bounded_centre_its_covariance_covers():
    box = {'shape': 'box', 'x': 3.0, 'y': 0.0, 'length': 0.3, 'width': 0.8, 'yaw_deg': 0}
    found = detect(world([box]))
    assert [d.shape for d in found] == ['rectangle']
    d = found[0]
    assert not d.center_fixed and 'one face' in d.note
    err = np.array([d.center[0] - 3.0, d.center[1] - 0.0])
    # the depth is not seen: the error lies inside the 95 % ellipse, though far from 0
    assert err @ np.linalg.solve(d.center_covariance, err) < 5.99
    assert abs(err[1]) < 0.03                       # along the face it is fixed


def test_a_tables_legs_are_one_object_at_its_centre():
    table = {'shape': 'table', 'x': 3.5, 'y': 0.5, 'length': 1.4, 'width': 0.8, 'yaw_deg': 10}
    found = detect(world([table]))
    assert [d.shape for d in found] == ['legs'], [(d.shape, d.note) for d in found]
    d = found[0]
    assert d.kind == 'furniture' and len(d.legs) >= 3
    assert math.hypot(d.center[0] - 3.5, d.center[1] - 0.5) < 0.03
    assert heading_error(d.orientation, math.radians(10)) < math.radians(5)


def test_a_persons_two_legs_are_one_legs_object_and_cylinders_stay_circles():
    legs = [{'x': 3.0, 'y': -0.1, 'radius': 0.06}, {'x': 3.05, 'y': 0.12, 'radius': 0.06},
            {'x': 4.0, 'y': 1.5, 'radius': 0.183}]
    found = detect(world(legs))
    assert sorted(d.shape for d in found) == ['circle', 'legs'], [(d.shape, d.note) for d in found]
    person = [d for d in found if d.shape == 'legs'][0]
    assert person.kind == 'person' and len(person.legs) == 2
    assert math.hypot(person.center[0] - 3.025, person.center[1] - 0.01) < 0.05


def test_an_unmapped_wall_end_is_not_a_leg():
    # a flat face as narrow as a leg, seen square on: a line fits it better than a circle
    p = np.column_stack((np.full(9, 2.0), np.linspace(-0.05, 0.05, 9)))
    p[:, 0] += np.random.default_rng(0).normal(0, 0.003, 9)
    assert shapes.leg(p, (0.0, 0.0), math.radians(0.33), 0.003) is None
    a = np.linspace(-1.2, 1.2, 9)
    arc = np.column_stack((2.06 - 0.06 * np.cos(a), 0.06 * np.sin(a)))
    assert shapes.leg(arc, (0.0, 0.0), math.radians(0.33), 0.003) is not None


@pytest.mark.ros
def test_what_moves_between_the_scans_at_rest_is_moving_with_its_velocity():
    from test_detection_service import FakeSensors, POSE, service
    still = {'x': 4.0, 'y': 1.5, 'radius': 0.183}

    def scan(dx, seed):
        legs = [{'x': 3.0 + dx, 'y': -0.1, 'radius': 0.06},
                {'x': 3.05 + dx, 'y': 0.12, 'radius': 0.06}, still]
        with Scene(world(legs)) as s:
            r, _ = s.cast(POSE)
        return noisy(r, 0.01, np.random.default_rng(seed), L.range_min, L.range_max)

    # a person walking +x at 0.9 m/s: 0.06 m between scans 1/15 s apart
    scans = [scan(0.06 * (4 - k), k) for k in range(5)]      # newest first
    rest = [(r, (1.0, 2.0, 0.5)) for r in scans[1:]]
    a = service(rasterise_world(world([])), detection=DetectionParams(shapes=True)).handle(
        '', 0.0, 0.0, FakeSensors(scans[0], earlier=rest), scan_stamp=12.5)
    assert a.success, a.message
    motions = sorted((o.motion, o.shape) for o in a.obstacles)
    assert ('static', 'circle') in motions
    moving = [o for o in a.obstacles if o.motion == 'moving']
    assert moving and all(o.motion != 'static' for o in a.obstacles if o.shape == 'legs')
    v = [o.velocity for o in moving if o.shape == 'legs']
    assert v, motions
    assert abs(v[0][0] - 0.9) < 0.2 and abs(v[0][1]) < 0.2, v
