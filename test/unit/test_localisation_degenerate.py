"""Degenerate scan geometry (no ROS): inside a corridor a scan fixes the lateral offset and the
heading but not the position along it; the localiser must correct only what the scan observes
and keep the odometry's prediction along the corridor (issue 41). Scans are synthetic: exact ray
casts to a corridor's two walls, in a map rasterised from the same world."""
import math

import numpy as np
import pytest

from tiago_nav.geometry import compose, inverse, wrap_angle
from tiago_nav.localisation.localiser import (Localiser, register_with_information, search,
                                               weak_description)
from tiago_nav.params import ParamError
from tiago_nav.robot import LASER_OFFSET
from tiago_nav.sim.raster import rasterise_world
from tiago_nav.sim.world import World
from tiago_nav.sim.worlds import corridor_world
from tiago_nav_tools.testing.localisation import raster_config

WIDTH = 1.1
# the maps here are rasterised from the world itself: no map error beyond the raster
EXACT_MAP = raster_config(map_sigma=0.0)
SENSOR = (LASER_OFFSET, 0.0)
FAN = math.radians(110.0)


def rotated(world, angle_deg):
    """``world`` (a dict) turned by ``angle_deg`` about the map origin."""
    a = math.radians(angle_deg)
    c, s = math.cos(a), math.sin(a)
    out = dict(world)
    out['walls'] = [dict(w, x=c * w['x'] - s * w['y'], y=s * w['x'] + c * w['y'],
                         yaw_deg=w['yaw_deg'] + angle_deg) for w in world['walls']]
    corners = [(c * x - s * y, s * x + c * y) for x in world['bounds'][0::2]
               for y in world['bounds'][1::2]]
    xs, ys = zip(*corners)
    out['bounds'] = [min(xs), min(ys), max(xs), max(ys)]
    sx, sy, syaw = world['robot_start']
    out['robot_start'] = [c * sx - s * sy, s * sx + c * sy, syaw + angle_deg]
    out.pop('corridor', None)
    return out


def corridor(angle_deg=0.0):
    """A 30 m straight corridor of WIDTH along ``angle_deg`` from the origin (its ends beyond
    the localiser's 12 m max_range from x = 13 .. 17 along it) and its rasterised map."""
    d = corridor_world(WIDTH, length=30.0, start=(-1.0, 0.0, 0.0))
    if angle_deg:
        d = rotated(d, angle_deg)
    return rasterise_world(World.from_dict(d))


def corridor_scan(pose, angle_deg=0.0, n=240, max_range=12.0):
    """Points [m] in base_footprint of an exact scan at ``pose`` (map) between the walls
    ``± WIDTH / 2`` of the corridor along ``angle_deg``; beams that reach no wall within
    ``max_range`` return nothing."""
    a = math.radians(angle_deg)
    # the pose in the corridor's own frame (axis along x)
    c, s = math.cos(-a), math.sin(-a)
    px, py = c * pose[0] - s * pose[1], s * pose[0] + c * pose[1]
    lx = px + LASER_OFFSET * math.cos(pose[2] - a)
    ly = py + LASER_OFFSET * math.sin(pose[2] - a)
    pts = []
    for b in np.linspace(-FAN, FAN, n):
        th = pose[2] - a + b
        dy = math.sin(th)
        if abs(dy) < 1e-9:
            continue
        r = ((WIDTH / 2.0 if dy > 0 else -WIDTH / 2.0) - ly) / dy
        if 0.05 < r <= max_range:
            pts.append((LASER_OFFSET + r * math.cos(b), r * math.sin(b)))
    return np.array(pts)


def along(delta, angle_deg):
    a = math.radians(angle_deg)
    return delta[0] * math.cos(a) + delta[1] * math.sin(a), \
        -delta[0] * math.sin(a) + delta[1] * math.cos(a)


@pytest.mark.parametrize('angle_deg', [0.0, 30.0])
def test_corridor_keeps_the_prediction_along_and_corrects_across(angle_deg):
    grid = corridor(angle_deg)
    a = math.radians(angle_deg)
    truth = (8.0 * math.cos(a) - 0.06 * math.sin(a), 8.0 * math.sin(a) + 0.06 * math.cos(a),
             a + math.radians(2.0))
    pts = corridor_scan(truth, angle_deg)
    from tiago_nav.localisation.localiser import DistanceField
    field = DistanceField(grid)
    # the prediction: 0.25 m ahead along the corridor, 5 cm across, 3 deg off
    off_along, off_across = 0.25, -0.05
    guess = (truth[0] + off_along * math.cos(a) - off_across * math.sin(a),
             truth[1] + off_along * math.sin(a) + off_across * math.cos(a),
             truth[2] - math.radians(3.0))
    pose, cov, _, info = register_with_information(field, pts, guess, raster_config(), SENSOR)
    assert info.degenerate and info.weak.shape[1] == 1
    assert weak_description(info.weak, pose, info.length) == 'position along %.0f deg' % angle_deg
    moved_along, _ = along((pose[0] - guess[0], pose[1] - guess[1]), angle_deg)
    assert abs(moved_along) < 1e-3, moved_along            # the prediction kept along the axis
    _, err_across = along((pose[0] - truth[0], pose[1] - truth[1]), angle_deg)
    tol = 0.015 if angle_deg else 0.01                     # a turned wall's raster is jagged
    assert abs(err_across) < tol, err_across                # the lateral offset corrected
    assert abs(wrap_angle(pose[2] - truth[2])) < math.radians(0.3)   # and the heading
    # the registration's covariance says nothing along the axis (the caller adds the prediction's)
    u = np.array([math.cos(a), math.sin(a)])
    assert u @ cov[:2, :2] @ u < 1e-8


def test_the_corridor_axis_has_no_information_and_ratio_0_turns_the_split_off():
    from tiago_nav.localisation.localiser import DistanceField
    field = DistanceField(corridor())
    truth = (8.0, 0.06, math.radians(2.0))
    pts = corridor_scan(truth)
    guess = (8.25, 0.01, truth[2] - math.radians(3.0))
    _, _, _, info = register_with_information(field, pts, guess, raster_config(), SENSOR)
    # the scan's information along the axis is nothing next to the lateral one
    assert info.eigenvalues[0] < 1e-4 * info.eigenvalues[-1]
    pose, _, _, info0 = register_with_information(field, pts, guess,
                                                  raster_config(degenerate_ratio=0.0), SENSOR)
    assert not info0.degenerate


def test_first_search_after_a_reset_does_not_move_along_the_corridor():
    grid = corridor()
    truth = (8.0, 0.0, 0.0)
    pts = corridor_scan(truth)
    for given_dx in (-0.3, 0.0, 0.2):
        given = (truth[0] + given_dx, 0.1, math.radians(6.0))     # 10 cm across, 6 deg off
        loc = Localiser(grid, given, EXACT_MAP)
        up = loc.update((0.0, 0.0, 0.0), pts, SENSOR)
        assert up.corrected and up.weak == 'position along 0 deg'
        assert abs(up.pose[0] - given[0]) < 1e-3, (given_dx, up.pose)
        assert abs(up.pose[1] - truth[1]) < 0.01 and abs(up.pose[2]) < math.radians(0.3)
        # /amcl_pose's covariance: the search window's spread along the axis, centimetres across
        # (the two walls' places within their 5 cm cells: about 1 cm)
        assert math.sqrt(up.covariance[0, 0]) >= raster_config().search_radius - 1e-9
        assert 0.005 < math.sqrt(up.covariance[1, 1]) < 0.02
    # the plain search alone, from the given pose: the same
    from tiago_nav.localisation.localiser import DistanceField
    res = search(DistanceField(grid), pts, (8.3, 0.0, 0.0), raster_config(), SENSOR)
    assert abs(res[0][0] - 8.3) < 1e-3


def test_covariance_along_the_corridor_grows_with_odometry():
    grid = corridor()
    c = EXACT_MAP
    loc = Localiser(grid, (2.0, 0.0, 0.0), c, odom=(0.0, 0.0, 0.0))
    loc.update((0.0, 0.0, 0.0), corridor_scan((2.0, 0.0, 0.0)), SENSOR)
    sigma0 = math.sqrt(loc.covariance[0, 0])
    sigmas, across = [], []
    for k in range(1, 41):                          # 4 m in steps of 0.1 m
        truth = (2.0 + 0.1 * k, 0.0, 0.0)
        up = loc.update((0.1 * k, 0.0, 0.0), corridor_scan(truth), SENSOR)
        assert up.corrected and up.weak
        sigmas.append(math.sqrt(up.covariance[0, 0]))
        across.append(math.sqrt(up.covariance[1, 1]))
        assert abs(up.pose[0] - truth[0]) < 1e-6   # exact odometry: exact prediction kept
    assert all(b > a for a, b in zip(sigmas, sigmas[1:]))
    # the standard deviation grows by odometry_sigma_distance per metre (a scale error's way)
    assert sigmas[-1] == pytest.approx(sigma0 + c.odometry_sigma_distance * 4.0, rel=0.05)
    assert max(across) < 0.02


def test_odometry_error_along_the_corridor_is_followed_not_amplified():
    """The odometry over-reads by 3 %: the estimate's along-axis error is the odometry's,
    with no jump; across it stays corrected."""
    grid = corridor()
    loc = Localiser(grid, (1.5, 0.0, 0.0), odom=(0.0, 0.0, 0.0), config=raster_config())
    errors = []
    for k in range(0, 81):                          # 8 m
        truth = (1.5 + 0.1 * k, 0.02 * math.sin(k / 7.0), 0.0)
        up = loc.update((0.103 * k, truth[1], 0.0), corridor_scan(truth), SENSOR)
        errors.append((up.pose[0] - truth[0], up.pose[1] - truth[1]))
    errors = np.array(errors)
    odo_err = 0.003 * np.arange(81)
    assert np.max(np.abs(errors[:, 0] - odo_err)) < 0.005
    assert np.max(np.abs(np.diff(errors[:, 0]))) < 0.01
    assert np.max(np.abs(errors[:, 1])) < 0.01


def test_a_room_scan_still_corrects_every_direction():
    import os
    from conftest import ROOT
    from tiago_nav.sim.simulator import SimConfig, Simulator
    from tiago_nav.sim.world import load_world
    world = load_world(os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml'))
    truth = (0.3, 0.2, math.radians(20.0))
    sim = Simulator(world, SimConfig(seed=1), start_pose=truth)
    try:
        las = sim.config.laser
        loc = Localiser(rasterise_world(world), truth, EXACT_MAP, odom=(0.0, 0.0, 0.0))
        loc._searching = False                      # a tracking update, not the search
        loc.pose = compose(truth, (0.08, -0.06, math.radians(3.0)))
        pts = loc.scan_points(sim.scan(), las.angle_min, las.angle_increment, las.range_min,
                              las.range_max, (las.offset, 0.0, 0.0))
        up = loc.update((0.0, 0.0, 0.0), pts, (las.offset, 0.0))
    finally:
        sim.close()
    assert up.corrected and up.weak == '' and not loc.information.degenerate
    assert math.hypot(up.pose[0] - truth[0], up.pose[1] - truth[1]) < 0.02
    assert abs(wrap_angle(up.pose[2] - truth[2])) < math.radians(0.5)
    # the walls' places within their cells, about 1 cm (the map is the world's own raster)
    assert max(np.sqrt(np.diag(up.covariance))[:2]) < 0.02


@pytest.mark.parametrize('bad', [-0.1, 1.0, 2.0])
def test_degenerate_ratio_is_validated(bad):
    with pytest.raises(ParamError, match='degenerate_ratio'):
        raster_config(degenerate_ratio=bad)


@pytest.mark.parametrize('name', ['odometry_sigma_distance', 'odometry_sigma_yaw'])
def test_odometry_sigmas_are_validated(name):
    with pytest.raises(ParamError, match=name):
        raster_config(**{name: -0.01})


def corridor_with_end(end):
    """A 30 m corridor (as :func:`corridor`) closed by a wall across it at x = ``end``, and
    exact scans there: ``(grid, scan(pose))``."""
    d = corridor_world(WIDTH, length=30.0, start=(-1.0, 0.0, 0.0))
    d['walls'].append({'x': end + 0.075, 'y': 0.0, 'length': WIDTH + 0.3, 'width': 0.15,
                       'yaw_deg': 90.0})
    grid = rasterise_world(World.from_dict(d))

    def scan(pose):
        pts = corridor_scan(pose, max_range=40.0)
        lx = pose[0] + LASER_OFFSET
        hit = pose[0] + pts[:, 0] > end
        out = pts.copy()
        t = (end - lx) / np.maximum(pts[hit, 0] - LASER_OFFSET, 1e-9)
        out[hit, 0] = LASER_OFFSET + t * (pts[hit, 0] - LASER_OFFSET)
        out[hit, 1] = t * pts[hit, 1]
        return out[np.hypot(out[:, 0] - LASER_OFFSET, out[:, 1]) <= 12.0]
    return grid, scan


def test_the_axis_is_corrected_once_the_corridor_end_comes_into_view():
    """Odometry over-reads by 5 % along a corridor whose end wall (x = 16) is out of the
    localiser's 12 m range at first: the along-axis error grows as the odometry's, then the
    first scans that reach the end wall correct it, although it is by then further off than
    the Cauchy scale (the search along the unobservable axis finds it), and it never grows by a
    step."""
    grid, scan = corridor_with_end(16.0)
    loc = Localiser(grid, (1.5, 0.0, 0.0), odom=(0.0, 0.0, 0.0), config=raster_config())
    errors, published, weak = [], [], []
    for k in range(0, 86):                          # 8.5 m, to x = 10
        truth = (1.5 + 0.1 * k, 0.0, 0.0)
        up = loc.update((0.105 * k, 0.0, 0.0), scan(truth), SENSOR)
        assert up.corrected, up.reason
        errors.append(abs(up.registered[0] - truth[0]))
        published.append(up.pose[0] - truth[0])
        weak.append(bool(up.weak))
    errors = np.array(errors)
    assert weak[5] and not weak[-1]
    fixed = int(np.argmax(np.diff(errors) < -0.05)) + 1     # the registration's correction
    # until then unobservable: the odometry's error, 5 mm per 0.1 m, more than the Cauchy scale
    assert np.allclose(errors[:fixed], 0.005 * np.arange(fixed), atol=0.005)
    assert errors[fixed - 1] > 0.1
    # then corrected, and stays so (the few end-wall points at 11-12 m drop out of the
    # registration now and then, the estimate following odometry for a few scans)
    assert np.all(errors[fixed:] < 0.035) and errors[-1] < 0.02, errors[fixed:]
    assert np.max(np.diff(errors)) <= 0.006                 # it never grows by a step
    # the published estimate follows in steps of at most max_correction_step, and converges
    steps = np.abs(np.diff(published))
    assert np.max(steps) <= raster_config().max_correction_step + 0.006, steps
    assert abs(published[-1]) < 0.02


def test_a_27_cm_re_acquisition_reaches_the_published_estimate_in_bounded_steps():
    """12 m of featureless corridor with odometry over-reading by 2.2 %: about 27 cm of
    along-axis drift when the end wall (8 m ahead) comes into the registration. The registered pose takes the whole correction
    at once (the registration and its gate work on it); the published estimate (pose,
    map -> odom) moves towards it by at most max_correction_step per estimate, registered or
    not, and converges; a reset still sets the pose at once."""
    grid, scan = corridor_with_end(22.0)
    limit = raster_config().max_correction_step
    assert 0 < limit <= 0.02
    loc = Localiser(grid, (1.5, 0.0, 0.0), odom=(0.0, 0.0, 0.0), config=raster_config())
    truth_x, odom_x = 1.5, 0.0
    published, registered, pending = [], [], []
    for k in range(180):
        truth_x += 0.1 if k < 140 else 0.0          # then at rest (the end wall in view)
        odom_x += 0.1022 if k < 140 else 0.0
        truth = (truth_x, 0.0, 0.0)
        if k % 2:                                   # every other scan is not registered
            pose, cov = loc.follow((odom_x, 0.0, 0.0))
            reg = compose(compose(loc.pose, inverse(loc.odom)), (odom_x, 0.0, 0.0))
        else:
            up = loc.update((odom_x, 0.0, 0.0), scan(truth), SENSOR)
            assert up.corrected, up.reason
            pose, reg, cov = up.pose, up.registered, up.covariance
            assert up.pending == pytest.approx(float(np.hypot(*loc.pending)))
        published.append(pose[0] - truth_x)
        registered.append(reg[0] - truth_x)
        pending.append(float(np.hypot(*loc.pending)))
        # the published covariance covers what is still pending
        assert math.sqrt(cov[0, 0]) >= pending[-1] - 1e-9
    published, registered = np.array(published), np.array(registered)
    jump = int(np.argmax(np.abs(np.diff(registered)))) + 1
    assert registered[jump - 1] > 0.25 and abs(registered[jump]) < 0.02      # in one step
    assert max(pending) > 0.2
    # never more than the limit between two estimates (the odometry's own 2.2 mm per 0.1 m
    # drives the error the other way)
    assert np.max(np.abs(np.diff(published))) <= limit + 1e-9
    # once it began, the pending correction shrinks at every estimate, except where a
    # registration refines the re-acquired position (by a centimetre or so, never a second
    # jump): it then grows by that refinement at most
    grew = [k for k in range(jump + 1, len(pending)) if pending[k] > pending[k - 1] + 1e-9]
    assert all(k % 2 == 0 for k in grew), grew                  # only at registrations
    assert all(pending[k] - pending[k - 1] <= 0.015 for k in grew)
    # converges: within (pending / limit) + 2 estimates of the last refinement the estimate is
    # the registered pose (which then follows odometry when the few end-wall points drop out
    # of the registration)
    last = max([jump] + grew)
    done = last + int(math.ceil(pending[last] / limit)) + 2
    assert done < len(pending) - 10
    assert all(p == 0.0 for p in pending[done:]) and np.all(np.abs(published[done:]) < 0.03)
    assert np.allclose(published[done:], registered[done:], atol=1e-9)
    # 0: at once (the published estimate is the registered one)
    at_once = Localiser(grid, (1.5, 0.0, 0.0), raster_config(max_correction_step=0.0),
                        odom=(0.0, 0.0, 0.0))
    for k in range(141):
        up = at_once.update((0.1022 * k, 0.0, 0.0), scan((1.5 + 0.1 * k, 0.0, 0.0)), SENSOR)
        assert up.pose == up.registered and up.pending == 0.0
    assert abs(up.pose[0] - (1.5 + 14.0)) < 0.03


def test_a_reset_sets_the_pose_at_once_even_while_a_correction_is_pending():
    grid, scan = corridor_with_end(22.0)
    loc = Localiser(grid, (1.5, 0.0, 0.0), odom=(0.0, 0.0, 0.0), config=raster_config())
    for k in range(150):
        truth = (1.5 + 0.1 * k, 0.0, 0.0)
        up = loc.update((0.1022 * k, 0.0, 0.0), scan(truth), SENSOR)
        if up.pending > 0.1:
            break
    assert up.pending > 0.1
    given = (truth[0], 0.02, 0.0)
    loc.reset(given)
    assert loc.estimate == given and not np.any(loc.pending)
    assert loc.map_to_odom == given
    up = loc.update((0.1022 * k, 0.0, 0.0), scan(truth), SENSOR)
    assert up.pose == up.registered and up.pending == 0.0
    assert abs(up.pose[0] - truth[0]) < 1e-3 and abs(up.pose[1]) < 0.01


def test_ordinary_corrections_in_a_room_are_not_smoothed():
    """A room scan observes every direction: a 8 cm correction reaches the estimate at once."""
    import os
    from conftest import ROOT
    from tiago_nav.sim.simulator import SimConfig, Simulator
    from tiago_nav.sim.world import load_world
    world = load_world(os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml'))
    truth = (0.3, 0.2, math.radians(20.0))
    sim = Simulator(world, SimConfig(seed=1), start_pose=truth)
    try:
        las = sim.config.laser
        ranges = sim.scan()
    finally:
        sim.close()
    loc = Localiser(rasterise_world(world), truth, odom=(0.0, 0.0, 0.0), config=raster_config())
    pts = loc.scan_points(ranges, las.angle_min, las.angle_increment, las.range_min,
                          las.range_max, (las.offset, 0.0, 0.0))
    loc.update((0.0, 0.0, 0.0), pts, (las.offset, 0.0))        # the search: at once
    loc.pose = compose(truth, (0.08, 0.0, 0.0))
    up = loc.update((0.0, 0.0, 0.0), pts, (las.offset, 0.0))
    assert up.corrected and up.pose == up.registered and up.pending == 0.0
    assert math.hypot(up.pose[0] - truth[0], up.pose[1] - truth[1]) < 0.02


def test_max_correction_step_is_validated():
    with pytest.raises(ParamError, match='max_correction_step'):
        raster_config(max_correction_step=-0.01)
