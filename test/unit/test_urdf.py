"""urdf/tiago_base.urdf agrees with the robot's constants and the simulator's laser."""
import os
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from conftest import ROOT
from tiago_nav.robot import BASE_LINK_HEIGHT, LASER_HEIGHT, LASER_OFFSET, ROBOT_RADIUS
from tiago_nav.sim.scene import LaserConfig


@pytest.fixture(scope='module')
def robot():
    return ET.parse(os.path.join(ROOT, 'urdf', 'tiago_base.urdf')).getroot()


def joints(robot):
    """``{child: (parent, xyz, rpy)}`` of every joint."""
    out = {}
    for j in robot.findall('joint'):
        o = j.find('origin')
        xyz = np.array([float(v) for v in (o.get('xyz', '0 0 0') if o is not None else '0 0 0').split()])
        rpy = np.array([float(v) for v in (o.get('rpy', '0 0 0') if o is not None else '0 0 0').split()])
        out[j.find('child').get('link')] = (j.find('parent').get('link'), xyz, rpy)
    return out


def position_in_footprint(robot, link):
    """Position of ``link`` in base_footprint (all joints are fixed and unrotated)."""
    js, p = joints(robot), np.zeros(3)
    while link != 'base_footprint':
        parent, xyz, rpy = js[link]
        assert np.allclose(rpy, 0), link
        p, link = p + xyz, parent
    return p


def test_tree_is_base_footprint_base_link_base_laser_link(robot):
    js = joints(robot)
    assert {j.get('type') for j in robot.findall('joint')} == {'fixed'}
    links = {lk.get('name') for lk in robot.findall('link')}
    assert links - set(js) == {'base_footprint'}           # the one root
    assert js['base_link'][0] == 'base_footprint'
    assert js['base_laser_link'][0] == 'base_link'


def test_laser_where_the_library_and_the_simulator_put_it(robot):
    np.testing.assert_allclose(position_in_footprint(robot, 'base_laser_link'),
                               [LASER_OFFSET, 0.0, LaserConfig().height], atol=1e-9)


def test_base_is_robot_radius_wide_and_below_the_laser(robot):
    base = next(lk for lk in robot.findall('link') if lk.get('name') == 'base_link')
    col = base.find('collision')
    cyl = col.find('geometry/cylinder')
    assert float(cyl.get('radius')) == pytest.approx(ROBOT_RADIUS)
    z = position_in_footprint(robot, 'base_link')[2] + float(col.find('origin').get('xyz').split()[2])
    top = z + float(cyl.get('length')) / 2
    assert 0.25 <= top < LaserConfig().height       # ~0.3 m tall, the laser sees over it
    radii = [float(c.get('radius')) for c in base.findall('visual/geometry/cylinder')]
    assert max(radii) == pytest.approx(ROBOT_RADIUS)


def test_base_link_height_is_the_simulators(robot):
    """The simulator publishes base_link at BASE_LINK_HEIGHT when robot_state_publisher does not."""
    assert position_in_footprint(robot, 'base_link')[2] == pytest.approx(BASE_LINK_HEIGHT)
    assert position_in_footprint(robot, 'base_laser_link')[2] == pytest.approx(LASER_HEIGHT)
