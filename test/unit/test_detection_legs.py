"""People's legs (tiago_nav.detection.shapes), the static background of a standing laser
(tiago_nav.detection.background) and a walker's planted leg over the scans at rest
(tiago_nav.detection.motion): a calf alone is a person, a table's thin leg is not; two legs side
by side in one run are split at the notch between them, a board or a wide cylinder is not; the
background is the farthest surface a beam keeps returning to; a walker's leg that stood still
for the scans at rest is never a static object."""
import math

import numpy as np
import pytest

from tiago_nav.detection import DetectionParams, ObstacleDetector, shapes
from tiago_nav.detection.background import background_map, background_ranges
from tiago_nav.detection.motion import combine, seen_free_before
from tiago_nav.detection.pipeline import Detection
from tiago_nav.gridmap import GridMap

INC = math.radians(0.35)          # the marked recordings' beam spacing


def cast(circles, angles, noise=0.0, seed=0):
    """Ranges [m] of beams from the origin at ``angles`` [rad] to the nearest of ``circles``
    ``(x, y, r)`` (inf: none), with Gaussian range noise."""
    out = np.full(len(angles), np.inf)
    d = np.column_stack((np.cos(angles), np.sin(angles)))
    for cx, cy, r in circles:
        b = d @ np.array([cx, cy])
        disc = b * b - (cx * cx + cy * cy - r * r)
        hit = disc >= 0
        t = b[hit] - np.sqrt(disc[hit])
        out[hit] = np.minimum(out[hit], np.where(t > 0, t, np.inf))
    finite = np.isfinite(out)
    out[finite] += np.random.default_rng(seed).normal(0.0, noise, int(finite.sum()))
    return out


def points_of(ranges, angles):
    ok = np.isfinite(ranges)
    return np.column_stack((ranges[ok] * np.cos(angles[ok]), ranges[ok] * np.sin(angles[ok])))


def empty_grid():
    return GridMap(np.zeros((240, 240), dtype=np.int8), 0.05, (-6.0, -6.0))


def detect(circles, seed=0):
    angles = -math.pi / 2 + INC * np.arange(int(math.pi / INC))
    r = cast(circles, angles, 0.01, seed)
    det = ObstacleDetector(empty_grid(), DetectionParams(correct_pose=False, shapes=True))
    return det.detect(r, -math.pi / 2, INC, 0.02, 5.6, (0.0, 0.0, 0.0))


@pytest.mark.parametrize('seed', range(3))
def test_a_calf_alone_is_a_person_and_a_thin_table_leg_is_not(seed):
    calf, table_leg = (2.5, 0.8, 0.06), (2.0, -1.0, 0.015)
    found = detect([calf, table_leg], seed)
    people = [d for d in found if d.shape == 'legs' and d.kind == 'person']
    assert len(people) == 1, [(d.shape, d.kind, d.center) for d in found]
    p = people[0]
    # one leg seen (the other hidden): the leg is placed, the person's centre is not fixed
    assert len(p.legs) == 1 and not p.center_fixed
    assert math.hypot(p.legs[0][0] - calf[0], p.legs[0][1] - calf[1]) < 0.03
    assert all(math.hypot(d.center[0] - table_leg[0], d.center[1] - table_leg[1]) > 0.3
               for d in people)


def test_two_legs_side_by_side_in_one_run_are_split_into_a_person():
    # two calves 0.17 m apart, their surfaces 3 cm apart: one run of points at 2 m
    legs = [(2.0, -0.085, 0.07), (2.02, 0.085, 0.07)]
    angles = np.linspace(-0.12, 0.12, 200)
    p = points_of(cast(legs, angles, 0.005), angles)
    assert np.max(np.hypot(*np.diff(p, axis=0).T)) < 0.08          # one run
    two = shapes.split_pair(p, (0.0, 0.0), INC, 0.005)
    assert two is not None
    centres = sorted((found[0] for _, found in two), key=lambda c: c[1])
    for c, (x, y, _) in zip(centres, legs):
        assert math.hypot(c[0] - x, c[1] - y) < 0.03
    # and the pipeline reports one person with both legs
    found = detect(legs)
    people = [d for d in found if d.shape == 'legs' and d.kind == 'person']
    assert len(people) == 1 and len(people[0].legs) == 2, [(d.shape, d.note) for d in found]


@pytest.mark.parametrize('heading,dist,seed', [(75, 0.7, 1), (75, 1.2, 0), (105, 0.9, 1),
                                               (60, 1.0, 0), (120, 1.5, 2)])
def test_a_walker_seen_from_the_side_is_one_person_with_the_back_legs_sliver(heading, dist, seed):
    # a walker standing 0.2 m wide, seen nearly side on: the front leg hides all but a sliver
    # of the back one (too narrow for a calf on its own), among cylinders of one radius
    h = math.radians(heading)
    legs = [(dist - 0.1 * math.sin(h), 0.1 * math.cos(h), 0.06),
            (dist + 0.1 * math.sin(h), -0.1 * math.cos(h), 0.06)]
    angles = -math.pi / 2 + math.radians(0.25) * np.arange(720)
    r = cast(legs + [(2.5, 1.5, 0.2), (2.5, -1.5, 0.2), (1.0, -2.0, 0.2)], angles, 0.01, seed)
    det = ObstacleDetector(empty_grid(), DetectionParams(correct_pose=False, shapes=True))
    found = det.detect(r, -math.pi / 2, math.radians(0.25), 0.02, 5.6, (0.0, 0.0, 0.0))
    near = [d for d in found if math.hypot(d.center[0] - dist, d.center[1]) < 0.5]
    assert [(d.shape, d.kind, len(d.legs)) for d in near] == [('legs', 'person', 2)], \
        [(d.shape, d.radius, d.note) for d in near]
    # the person's centre between the legs; the sliver's leg is placed at what is seen of it,
    # up to a calf's radius in front of its centre
    assert math.hypot(near[0].center[0] - dist, near[0].center[1]) < 0.05
    for x, y, _ in legs:
        assert min(math.hypot(x - lx, y - ly) for lx, ly in near[0].legs) < 0.08
    # the cylinders stay circles
    assert sorted(d.shape for d in found if d not in near) == ['circle'] * 3


def test_a_board_or_a_wide_cylinder_is_no_pair_of_legs():
    angles = np.linspace(-0.1, 0.1, 60)
    # a flat board 0.4 m wide at 2 m: no notch
    board = np.column_stack((np.full(len(angles), 2.0), 2.0 * np.tan(angles)))
    board = board[np.abs(board[:, 1]) <= 0.2]
    assert shapes.split_pair(board, (0.0, 0.0), INC, 0.005) is None
    # a cylinder of 0.2 m radius: one front, no notch
    p = points_of(cast([(2.0, 0.0, 0.2)], angles, 0.005), angles)
    assert shapes.split_pair(p, (0.0, 0.0), INC, 0.005) is None
    # nor is a straight wall 1 m long a person's leg
    wall = np.column_stack((np.full(100, 2.5), np.linspace(-0.5, 0.5, 100)))
    assert shapes.leg(wall, (0.0, 0.0), INC) is None


def test_person_sized_by_a_legs_physics():
    assert shapes.person_sized(0.06, 0.05)          # a calf
    assert not shapes.person_sized(0.02, 0.012)     # a chair's tube
    assert not shapes.person_sized(0.04, 0.015)     # a table leg widened by a beam spacing
    assert not shapes.person_sized(0.2, 0.18)       # a bin


def test_the_background_is_the_farthest_surface_a_beam_keeps_returning_to():
    rng = np.random.default_rng(0)
    k = 100
    scans = np.full((k, 6), np.inf)
    scans[:, 0] = 3.0 + rng.normal(0, 0.01, k)                 # a wall
    scans[:30, 0] = 1.2 + rng.normal(0, 0.01, 30)              # ... a person stood before it
    scans[::5, 1] = 2.5 + rng.normal(0, 0.01, k // 5)          # a dark surface: 1 scan in 5
    scans[:, 2] = np.linspace(0.5, 4.5, k)                     # a walker along the beam
    scans[:2, 3] = 1.0                                         # two stray returns
    scans[30:70, 4] = 1.5                  # a person standing for a while, nothing behind
    scans[::3, 5] = 4.0                    # a chair leg there all along, nothing behind
    bg = background_ranges(scans, 0.02, 5.6)
    assert abs(bg[0] - 3.0) < 0.01 and abs(bg[1] - 2.5) < 0.01
    assert np.isnan(bg[2]) and np.isnan(bg[3]) and np.isnan(bg[4])
    assert bg[5] == 4.0
    grid = background_map(bg, 0.0, 0.5)
    assert grid.occupied().sum() == 3
    with pytest.raises(ValueError):
        background_ranges(np.empty((0, 4)), 0.02, 5.6)
    with pytest.raises(ValueError):
        background_ranges(scans, 0.02, 5.6, share=0.0)
    with pytest.raises(ValueError):
        background_ranges(scans, 0.02, 5.6, parts=0)


def leg_detection(centre, r=0.06, kind='person', legs=None, shape='legs'):
    a = np.linspace(math.pi - 1.0, math.pi + 1.0, 7) + math.atan2(centre[1], centre[0])
    pts = np.column_stack((centre[0] + r * np.cos(a), centre[1] + r * np.sin(a)))
    legs = np.array([centre] if legs is None else legs, dtype=float)
    return Detection(tuple(centre), r, len(pts), pts, np.eye(3) * 1e-4, shape=shape,
                     legs=legs if shape == 'legs' else None, kind=kind)


def changed_on(dets, n=1600, inc=0.002):
    changed = np.zeros(n, dtype=bool)
    for d in dets:
        a = np.arctan2(d.points[:, 1], d.points[:, 0])
        changed[np.round((a + math.pi / 2) / inc).astype(int)] = True
    return changed


def test_a_walkers_planted_leg_is_never_a_static_object():
    inc = 0.002
    planted = leg_detection((2.0, 0.0))
    swinging = leg_detection((2.3, 0.1))          # the newest scan's other leg, moving
    before = leg_detection((2.0, 0.1))            # where it was in the oldest scan
    changed = changed_on([swinging, before])
    out = combine([planted], [swinging], [before], changed, 0.4, (0.0, 0.0, 0.0),
                  -math.pi / 2, inc)
    assert [d.motion for d in out] == ['moving']
    assert len(out[0].legs) == 2                  # the planted leg joined the walker
    assert abs(out[0].velocity[0] - 0.75) < 1e-6
    # the other leg swung behind it, hidden in the newest scan: moving, velocity not measured
    out = combine([leg_detection((2.0, 0.0))], [], [leg_detection((2.3, 0.15))],
                  changed_on([leg_detection((2.3, 0.15))]), 0.4, (0.0, 0.0, 0.0),
                  -math.pi / 2, inc)
    assert [d.motion for d in out] == ['moving'] and math.isnan(out[0].velocity[0])


def test_what_stands_where_a_scan_a_stride_before_saw_free_came_there():
    """A walker's foot stands on the floor for about 0.6 s of a stride, longer than the
    scans at rest: a leg standing still through all of them, with the other leg hidden, whose
    place a scan at rest up to a stride earlier saw free (its beams reached farther then) came
    down there: moving, its velocity not measured. A table's leg whose one edge beam flickers
    (a third of its points' places seen free before), one whose beams were nearer before
    (someone passed in front of it) and one with no earlier scan stay static; one of several
    earlier scans seeing the place free is enough, and any shape that came there moved."""
    inc = 0.002
    leg = leg_detection((2.0, 0.0))
    beams = np.round((np.arctan2(leg.points[:, 1], leg.points[:, 0]) + math.pi / 2)
                     / inc).astype(int)
    newest = np.full(1600, 4.0)
    newest[beams] = np.hypot(leg.points[:, 0], leg.points[:, 1])
    earlier = newest.copy()
    earlier[beams] = 4.0                              # the floor there seen free
    flicker = newest.copy()
    flicker[beams[:2]] = 4.0
    passed = newest.copy()
    passed[beams] = 1.0                               # someone in front of it then

    def motion_with(before, shape='legs'):
        arrived = [seen_free_before(newest, b, 0.05, 5.6) for b in before]
        out = combine([leg_detection((2.0, 0.0), shape=shape)], [], [],
                      np.zeros(1600, dtype=bool), 0.4, (0.0, 0.0, 0.0), -math.pi / 2, inc,
                      arrived)
        return [(d.motion, math.isnan(d.velocity[0])) for d in out]
    assert motion_with([passed, earlier]) == [('moving', True)]
    assert motion_with([flicker]) == [('static', False)]
    assert motion_with([passed, flicker]) == [('static', False)]
    assert motion_with([]) == [('static', False)]
    # whatever its shape: it was not there a stride before, as the laser stood still
    assert motion_with([earlier], 'rectangle') == [('moving', True)]
    inf = earlier.copy()
    inf[beams] = np.inf                               # no return then: seen free to the range's end
    assert seen_free_before(newest, inf, 0.05, 5.6)[beams].all()


def test_a_leg_sized_unknown_beside_a_walker_is_their_planted_leg_and_a_wide_one_is_not():
    """The shapes detection may read a planted leg's run as ``unknown`` (neither round nor
    straight, a trouser's fold; leg_tracker's demo recording, 41.8 s and 106.6 s in): one no
    wider than a calf within a stride of a moving leg joins that walker, as a leg does. An
    ``unknown`` wider than a calf there (a bin, a box's corner) stays a static object."""
    inc = 0.002
    swinging, before = leg_detection((2.3, 0.1)), leg_detection((2.0, 0.1))
    changed = changed_on([swinging, before])
    piece = leg_detection((2.0, -0.2), r=0.05, shape='unknown')
    out = combine([piece], [swinging], [before], changed, 0.4, (0.0, 0.0, 0.0), -math.pi / 2,
                  inc)
    assert [(d.shape, d.motion) for d in out] == [('legs', 'moving')]
    assert len(out[0].legs) == 2                  # the planted leg joined the walker
    wide = leg_detection((2.0, -0.4), r=0.2, shape='unknown')
    out = combine([wide], [leg_detection((2.3, 0.1))], [leg_detection((2.0, 0.1))], changed,
                  0.4, (0.0, 0.0, 0.0), -math.pi / 2, inc)
    assert sorted((d.shape, d.motion) for d in out) == [('legs', 'moving'), ('unknown', 'static')]


def test_a_leg_far_from_what_moves_and_a_circle_stay_static():
    inc = 0.002
    swinging, before = leg_detection((2.3, 1.5)), leg_detection((2.0, 1.5))
    changed = changed_on([swinging, before])
    still = [leg_detection((2.0, 0.0)), leg_detection((2.1, 1.2), shape='circle')]
    out = combine(still, [swinging], [before], changed, 0.4, (0.0, 0.0, 0.0), -math.pi / 2,
                  inc)
    motions = sorted((d.shape, d.motion) for d in out)
    # a person standing 1.5 m from a walker stays static; a circle (no shapes) is judged alone
    assert motions == [('circle', 'static'), ('legs', 'moving'), ('legs', 'static')], motions


def test_a_chair_whose_leg_edges_flicker_stays_static_and_a_leg_never_does():
    """A chair seen in the median of the scans at rest with a third of its points on changed
    beams (a thin leg's edge beam hit in one scan and missed in the other): the newest and the
    oldest scans see it at its place and the newest one does not move, so it is static, not
    lost. A calf-sized circle (a walker's leg when the shapes detection is off) on the same
    beams is never static."""
    inc = 0.002
    corners = [(2.0, -0.2), (2.0, 0.2), (2.4, 0.2), (2.4, -0.2)]

    def chair():
        return leg_detection((2.2, 0.0), r=0.3, kind='furniture', legs=corners)

    median, newest, oldest = chair(), chair(), chair()
    changed = np.zeros(1600, dtype=bool)
    b = np.round((np.arctan2(median.points[:, 1], median.points[:, 0]) + math.pi / 2)
                 / inc).astype(int)
    changed[b[:3]] = True                         # 3 of its 7 points' beams changed
    newest.points = newest.points[3:]             # the newest scan missed the leg's edge
    out = combine([median], [newest], [oldest], changed, 0.27, (0.0, 0.0, 0.0), -math.pi / 2,
                  inc)
    assert [(d.shape, d.motion) for d in out] == [('legs', 'static')]
    # the newest scan's chair (missing a leg's far edge) has most of its points on the
    # changed beams, but the oldest scan placed it there too: one chair, static, not moving
    newest = chair()
    newest.points = newest.points[:5]             # 3 of its 5 points' beams changed
    out = combine([median], [newest], [oldest], changed, 0.27, (0.0, 0.0, 0.0), -math.pi / 2,
                  inc)
    assert [(d.shape, d.motion) for d in out] == [('legs', 'static')]
    # one that stood elsewhere in the oldest scan is not kept static
    newest = chair()
    newest.points = newest.points[3:]
    out = combine([chair()], [newest], [leg_detection((2.5, 0.0), r=0.3, kind='furniture',
                                                      legs=corners)],
                  changed, 0.27, (0.0, 0.0, 0.0), -math.pi / 2, inc)
    assert [d.motion for d in out if d.motion == 'static'] == []
    leg = leg_detection((2.2, 0.0), r=0.06, shape='circle')
    out = combine([leg], [leg_detection((2.2, 0.0), r=0.06, shape='circle')],
                  [leg_detection((2.2, 0.0), r=0.06, shape='circle')],
                  changed_on([leg]), 0.27, (0.0, 0.0, 0.0), -math.pi / 2, inc)
    assert [d.motion for d in out if d.motion == 'static'] == []
