"""rviz/demo.rviz shows the robot (RobotModel from robot_description) and its initial view fits
the whole map of the course world (the big room with pose B included)."""
import os

import yaml

from conftest import ROOT, WORLDS
from tiago_nav.sim.world import load_world

DOCK = 425      # [px] the Displays panel left of the 3D view (measured on a screenshot)


def config():
    with open(os.path.join(ROOT, 'rviz', 'demo.rviz')) as f:
        return yaml.safe_load(f)


def test_the_robot_model_is_shown():
    displays = config()['Visualization Manager']['Displays']
    robot = [d for d in displays if d['Class'] == 'rviz/RobotModel']
    assert len(robot) == 1 and robot[0]['Enabled'] and robot[0]['Robot Description'] == 'robot_description'


def test_the_initial_view_fits_the_course_map():
    c = config()
    view = c['Visualization Manager']['Views']['Current']
    assert view['Class'] == 'rviz/TopDownOrtho' and view['Target Frame'] == 'map'
    bounds = load_world(os.path.join(WORLDS, 'ias_lab_room_full.yaml')).bounds
    x0, y0, x1, y1 = bounds
    width, height = c['Window Geometry']['Width'] - DOCK, c['Window Geometry']['Height'] - 120   # menu and tool bars
    scale = view['Scale']                                   # [px/m]
    # every corner of the map within the 3D view (view centred at X, Y)
    for x in (x0, x1):
        assert abs(x - view['X']) * scale <= width / 2, (x, view['X'], scale, width)
    for y in (y0, y1):
        assert abs(y - view['Y']) * scale <= height / 2, (y, view['Y'], scale, height)
    # and the map fills most of it (not a speck in the middle)
    assert (x1 - x0) * scale >= 0.8 * width
