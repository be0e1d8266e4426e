"""The evaluator's shape scores (tiago_nav_tools.evaluate.shapes): label agreement, centre,
extent and orientation errors of synthetic detections against known true obstacles, a run's
``detection_shapes`` and summary.md's shapes table."""
import math
import os

import pytest

from conftest import ROOT
from tiago_nav.sim.world import Box, Cylinder, Furniture, load_world
from tiago_nav_tools.evaluate import report, run
from tiago_nav_tools.evaluate import shapes as S

BOX = Box(3.0, 1.0, 0.6, 0.4, yaw_deg=30.0)
TABLE = Furniture('table', 1.0, 1.0, 0.8, 1.6, yaw_deg=0.0)     # its length along y
CHAIR = Furniture('chair', 0.0, 0.0, 0.42, 0.42, yaw_deg=5.0)   # square
BIN = Cylinder(5.0, 0.0, 0.18)
NAN = float('nan')


def found(shape, extent=(NAN, NAN), orientation=NAN, center_fixed=True):
    return {'shape': shape, 'extent': list(extent), 'orientation': orientation,
            'center_fixed': center_fixed}


def test_labels_follow_the_true_shape():
    assert S.label_agrees('cylinder', 'circle') and S.label_agrees('box', 'rectangle')
    assert S.label_agrees('table', 'legs') and S.label_agrees('chair', 'legs')
    assert not S.label_agrees('box', 'circle') and not S.label_agrees('table', 'rectangle')
    assert not S.label_agrees('chair', 'unknown') and not S.label_agrees('cylinder', 'legs')


def test_a_box_turned_half_a_turn_scores_zero_and_a_quarter_turn_does_not():
    yaw = math.radians(30.0)
    assert S.orientation_error(yaw - math.pi, BOX, claimed=True) == pytest.approx(0.0, abs=1e-9)
    assert S.orientation_error(yaw + math.pi, BOX, claimed=True) == pytest.approx(0.0, abs=1e-9)
    assert S.orientation_error(yaw + math.radians(3.0), BOX) == pytest.approx(3.0)
    assert S.orientation_error(yaw - math.radians(177.0), BOX) == pytest.approx(3.0)
    # both sides reported: the length's heading is claimed, a quarter turn is 90 deg off
    assert S.orientation_error(yaw + math.pi / 2, BOX, claimed=True) == pytest.approx(90.0)
    # one face: its heading may be either side's
    assert S.orientation_error(yaw + math.pi / 2, BOX, claimed=False) == pytest.approx(0.0, abs=1e-9)
    assert S.orientation_error(yaw + math.radians(50.0), BOX, claimed=False) == pytest.approx(40.0)


def test_orientation_of_tables_squares_and_cylinders():
    # the table's length lies along y: a heading along x is 90 deg off
    assert S.orientation_error(math.pi / 2, TABLE) == pytest.approx(0.0, abs=1e-9)
    assert S.orientation_error(-math.pi / 2 + math.radians(2.0), TABLE) == pytest.approx(2.0)
    assert S.orientation_error(0.0, TABLE) == pytest.approx(90.0)
    # a square chair: modulo 90 deg
    assert S.orientation_error(math.radians(95.0), CHAIR) == pytest.approx(0.0, abs=1e-9)
    assert S.orientation_error(math.radians(49.0), CHAIR) == pytest.approx(44.0)
    assert S.orientation_error(0.3, BIN) is None
    assert S.orientation_error(NAN, BOX) is None


def test_extent_error_per_observed_side():
    yaw = math.radians(30.0)
    assert S.extent_error((0.62, 0.41), yaw, BOX) == pytest.approx(0.02)
    assert S.extent_error((0.62, 0.35), yaw + math.pi, BOX) == pytest.approx(0.05)
    # one face along the box's width: compared with the width
    assert S.extent_error((0.43, NAN), yaw + math.pi / 2, BOX) == pytest.approx(0.03)
    assert S.extent_error((0.43, NAN), yaw, BOX) == pytest.approx(0.17)
    # no orientation (a circle's fit to a box): the longer with the longer
    assert S.extent_error((0.5, 0.5), NAN, BOX) == pytest.approx(0.1)
    assert S.extent_error((0.37, 0.37), NAN, BIN) == pytest.approx(0.01)
    # the table's legs' rectangle, its length along y
    assert S.extent_error((1.58, 0.83), math.pi / 2, TABLE) == pytest.approx(0.03)
    assert S.extent_error((NAN, NAN), yaw, BOX) is None
    assert S.extent_error(None, NAN, BOX) is None


def test_score_rows_matched_missing_extent_and_unmatched():
    obstacles = [BOX, TABLE, CHAIR, BIN]
    detail = [found('rectangle', (0.61, 0.40), math.radians(30.0) - math.pi),       # 0: the box
              found('legs'),                                                         # 1: one chair leg
              found('circle', (0.36, 0.36)),                                         # 2: the bin
              found('rectangle', (0.41, 0.41), 0.0)]                                 # 3: unmatched
    rows = [{'index': 0, 'in_view': True, 'found': 0, 'error': 0.012},
            {'index': 1, 'in_view': True, 'found': None, 'error': None},
            {'index': 2, 'in_view': False, 'found': 1, 'error': 0.2},
            {'index': 3, 'in_view': True, 'found': 2, 'error': 0.004}]
    box, table, chair, bin_ = S.score(obstacles, rows, detail, {0: 2, 1: 4, 2: 1})
    assert (box['label'], box['label_agrees'], box['matched']) == ('rectangle', True, True)
    assert box['orientation_error_deg'] == pytest.approx(0.0, abs=1e-6)
    assert box['extent_error_m'] == pytest.approx(0.01) and box['centre_error_m'] == 0.012
    assert box['length_claimed'] and box['target_applies'] and box['true_extent'] == [0.6, 0.4]
    assert not table['matched'] and table['label'] is None and table['extent_error_m'] is None
    assert table['target_applies'] and table['centre_error_m'] is None
    # a glimpsed chair found as one leg: label agrees, nothing of its extent observed
    assert chair['label_agrees'] and not chair['in_view'] and chair['extent_error_m'] is None
    assert chair['orientation_error_deg'] is None and chair['extent'] == [None, None]
    assert not chair['target_applies']
    assert bin_['label_agrees'] and bin_['extent_error_m'] == pytest.approx(0.0, abs=1e-9)
    assert bin_['seen_parts'] is None and bin_['target_applies'] is None


def _result(profile, cand, rows):
    return {'profile': profile, 'candidate': cand, 'detection_shapes': rows}


def _row(shape, matched=True, in_view=True, agrees=True, centre=0.01, extent=None, orient=None,
         target=None):
    return {'shape': shape, 'matched': matched, 'in_view': in_view,
            'label_agrees': agrees if matched else None, 'centre_error_m': centre if matched else None,
            'extent_error_m': extent, 'orientation_error_deg': orient, 'target_applies': target}


def test_summary_by_shape():
    rs = [_result('tiago', 'own', [_row('box', centre=0.02, extent=0.01, orient=1.0, target=True),
                                   _row('box', centre=0.05, extent=None, orient=20.0, target=False,
                                        agrees=False),
                                   _row('box', matched=False, target=True),
                                   _row('cylinder', centre=0.004, extent=0.002)]),
          _result('tiago', 'own', [_row('box', centre=0.04, extent=0.03, orient=6.0, target=True),
                                   _row('table', in_view=False, centre=0.1, orient=2.0, target=False)])]
    cyl, box, table = S.summarise(rs)
    assert (cyl['shape'], box['shape'], table['shape']) == ('cylinder', 'box', 'table')
    assert (box['in_view'], box['found'], box['matched'], box['label_agrees']) == (4, 3, 3, 2)
    assert box['found_share'] == pytest.approx(0.75) and box['label_share'] == pytest.approx(2 / 3)
    assert box['centre_median'] == pytest.approx(0.04) and box['centre_p95'] == pytest.approx(0.05)
    assert (box['extent_n'], box['extent_median'], box['extent_p95']) == (2, 0.02, 0.03)
    assert box['orientation_p95'] == pytest.approx(20.0)
    # where the target applies: two boxes matched (the missed one has no error)
    assert box['target_n'] == 2 and box['target_centre_p95_m'] == pytest.approx(0.04)
    assert box['target_centre_share'] == pytest.approx(0.5)
    assert box['target_orientation_share'] == pytest.approx(0.5)
    # a glimpsed table: matched but not in view
    assert (table['in_view'], table['found'], table['found_share'], table['matched']) == (0, 0, None, 1)
    assert cyl['target_n'] == 0 and cyl['target_centre_p95_m'] is None
    lines = report.shape_lines(rs)
    assert any(ln.startswith('| tiago | own | box | 4 | 3 (75 %) | 2/3 (67 %) | 4.0 / 5.0 |')
               for ln in lines)
    assert any(ln.startswith('| tiago | own | cylinder | 1 | 1 (100 %) |') and ln.endswith('| - | - | - |')
               for ln in lines)


FURNITURE = os.path.join(ROOT, 'worlds', 'room_furniture.yaml')
SPEC = {'id': 'shp', 'pair': 'p1', 'world': {'name': 'room_furniture', 'group': 'furniture'},
        'world_path': FURNITURE, 'goal': [2.2, 0.0, 10.0], 'profile': 'tiago',
        'use_corridor_law': True, 'seed': 1, 'candidate': 'own', 'launch_args': {},
        'limits': {'detection_tolerance': 0.05, 'sim_time_limit': 100.0}}
POSE = [2.2, 0.0, math.radians(10.0)]


def _msg(obj, shape, dx=0.0, extent=(NAN, NAN), orientation=NAN, center_fixed=True):
    return {'center': {'x': obj.x + dx, 'y': obj.y, 'z': 0.0}, 'radius': obj.radius,
            'shape': shape, 'extent': list(extent), 'orientation': orientation,
            'center_fixed': center_fixed, 'note': ''}


@pytest.mark.ros
def test_a_run_scores_the_shapes_it_reports():
    pytest.importorskip('pybullet')
    obs = load_world(FURNITURE).movable_obstacles
    # in view from pose B (2.2, 0, 10 deg): table 0, chairs 1 2 4, boxes 7 8 9, the bin 10;
    # boxes 8 and 9 on two faces, 7 on one; the table and chairs on four legs
    box8, box9 = obs[8], obs[9]
    detail = [_msg(obs[0], 'legs', 0.02, (1.61, 0.79), 0.0),
              _msg(obs[1], 'legs', 0.01, (0.42, 0.43), math.radians(95.0)),
              _msg(obs[2], 'rectangle', 0.01),
              _msg(box8, 'rectangle', 0.015, (0.8, 0.5), box8.yaw + math.pi),    # half a turn
              _msg(box9, 'circle', 0.04, (0.66, 0.66)),
              _msg(obs[10], 'circle', 0.003, (0.36, 0.36))]       # chair 4 and box 7 missed
    raw = {'state': 3, 'state_name': 'SUCCEEDED', 'message': 'arrived', 'sim_s': 30.0, 'wall_s': 10.0,
           'collisions': 0, 'final_pose': POSE, 'timed_out': False, 'path': [[1.0, 0.0, 0.0], POSE],
           'loc_errors': [[0.01, 0.01]], 'obstacles_detail': detail,
           'obstacles': [[d['center']['x'], d['center']['y'], d['radius']] for d in detail]}
    r = run.judge(SPEC, raw)
    # the existing fields keep their meaning
    assert r['outcome'] == 'detection_failure' and 'missed 2 of 8' in r['reason']
    assert r['in_view'] == 8 and r['matched'] == 6 and r['false_positives'] == 0
    by = {s['index']: s for s in r['detection_shapes']}
    assert sorted(by) == [0, 1, 2, 4, 7, 8, 9, 10]
    assert by[0]['label_agrees'] and by[0]['centre_error_m'] == pytest.approx(0.02)
    assert by[0]['extent_error_m'] == pytest.approx(0.01) and by[0]['orientation_error_deg'] == pytest.approx(0.0)
    assert by[0]['target_applies'] and by[0]['seen_parts'] == 4
    assert by[1]['orientation_error_deg'] == pytest.approx(0.0, abs=1e-6)    # square: modulo 90
    assert not by[2]['label_agrees'] and by[2]['extent_error_m'] is None
    assert by[8]['label_agrees'] and by[8]['orientation_error_deg'] == pytest.approx(0.0, abs=1e-6)
    assert by[8]['target_applies'] and by[8]['extent_error_m'] == pytest.approx(0.0, abs=1e-9)
    assert not by[9]['label_agrees'] and by[9]['extent_error_m'] == pytest.approx(0.16)
    assert by[9]['orientation_error_deg'] is None and by[9]['target_applies']
    assert not by[7]['target_applies'] and not by[7]['matched'] and not by[4]['matched']
    assert by[10]['label'] == 'circle' and by[10]['target_applies'] is None
    # the same obstacle's row in detection_view has the same centre error
    view = {v['index']: v for v in r['detection_view']}
    assert all(view[i]['error'] == by[i]['centre_error_m'] for i in by)
    text = report.markdown(report.summarise([dict(r, run_wall_s=1.0)]), [], [r],
                           {'wall_s': 10.0, 'missions_per_minute': 1.0})
    assert '## Shapes (runs that reached pose B)' in text
    assert '| tiago | own | box | 3 | 2 (67 %) | 1/2 (50 %) |' in text
