"""Localisation without ROS: track base_footprint's pose in ``map`` by registering laser scans
to the static map's distance field.

Frames (REP 105): ``map`` is the world frame of the static map; ``odom`` is where odometry
integrates (continuous, drifting); ``base_footprint`` is the robot's base on the floor;
``base_laser_link`` is the laser, ``laser_pose`` [m, m, rad] in ``base_footprint``. Poses are
``(x, y, yaw)`` [m, m, rad].

Each scan is one :meth:`Localiser.update`:

1. **predict**: the last estimate moved by the odometry delta since the last scan
   (``odom → base_footprint`` then and now);
2. **correct**: the scan's hits (``tiago_nav.scan.scan_to_points``; points within
   ``self_filter_radius`` of base_footprint are the robot's own body and dropped) are
   registered to the map: Gauss-Newton on the bilinearly interpolated distance field, iteratively
   reweighted with Cauchy weights whose scale anneals from ``initial_scale`` to ``robust_scale``,
   so points far from any mapped cell (unmapped obstacles, people, mixed pixels) lose their pull;
   only the directions the scan observes are corrected (:func:`observable_directions`, from the
   information of the scan's own surface normals): along the others (a corridor's axis) the
   pose stays the prediction, and so does its covariance (:meth:`Localiser.predicted_covariance`,
   growing with the distance driven);
   then (``raster_band``) the translation moves to the middle of what the map's cells allow for
   the axis-aligned walls in view (:func:`refine_on_raster`);
3. **gate**: the correction is kept only if enough points end within ``inlier_distance`` of the
   map and it moves the pose no more than ``max_correction`` / ``max_correction_yaw_deg`` (each
   widened by 3 standard deviations of the prediction) from the prediction; otherwise the
   prediction is kept (and the update says why);
4. **fuse** (``fuse_prediction``): a registration taken an update's distance or turn from the
   last one is weighed against the prediction in the directions it observes
   (:func:`fuse_with_prediction`, a Kalman update whose covariance counts the two's shared
   errors), so that the scans' own noise averages out over registrations;
5. **publish**: after a registration that left a position unobservable (a corridor's axis),
   a position correction (the axis seen again) reaches the published estimate
   (:attr:`Localiser.estimate`, ``map_to_odom``) by at most ``max_correction_step`` per
   estimate (every scan, :meth:`Localiser.follow` between registrations), while the
   registered pose, from which the next prediction and registration start, takes it at once;
   every other correction at once.

The result gives ``map → odom`` (``pose_map ∘ inverse(pose_odom)``), what a localisation node
publishes on tf, and a 3 × 3 covariance of ``(x, y, yaw)`` for a PoseWithCovarianceStamped.
"""
import math
from dataclasses import dataclass, field as dataclass_field
from functools import cached_property

import numpy as np

from tiago_nav.geometry import compose, inverse, transform_points, wrap_angle
from tiago_nav.gridmap import SCAN_MAP_DEPTH, DistanceField
from tiago_nav.params import ParamError, param, validate
from tiago_nav.robot import LASER_OFFSET, ROBOT_RADIUS
from tiago_nav.scan import scan_to_points, usable_ranges

# [m] beyond the base's radius, what still counts as the robot's own body for the self-filter
# (TIAGo's laser sees the base's front corners at both ends of its ±110° fan)
SELF_FILTER_MARGIN = 0.1
# a registered point whose field gradient (unit length near surfaces) has more than this
# component along its beam is on a surface facing away from the laser: ignored
BACKFACE_COS = 0.2
# covariance of (x, y, yaw) [m², m², rad²] added per scan whose correction is rejected
UNCORRECTED_GROWTH = np.diag([0.01 ** 2, 0.01 ** 2, math.radians(0.5) ** 2])


@dataclass(frozen=True)
class LocaliserConfig:
    """Scan-to-map registration and its gate."""
    self_filter_radius: float = param(
        ROBOT_RADIUS + SELF_FILTER_MARGIN,
        "[m] hits closer than this to base_footprint are the robot's own body and ignored", gt=0)
    max_range: float = param(12.0, '[m] hits further than this from the laser are ignored', gt=0)
    max_points: int = param(240, 'at most this many scan points per update (evenly subsampled)',
                            ge=10)
    initial_scale: float = param(0.1, '[m] Cauchy loss scale of the first registration iteration',
                                 gt=0)
    robust_scale: float = param(0.05, '[m] Cauchy loss scale of the last iterations: points '
                                      'much further than this from the map barely pull', gt=0)
    iterations: int = param(12, 'Gauss-Newton iterations per scan', ge=1)
    inlier_distance: float = param(0.1, '[m] a registered point this close to the map is an '
                                         'inlier', gt=0)
    min_inliers: int = param(40, 'fewer inliers than this: the correction is rejected', ge=3)
    min_inlier_fraction: float = param(0.3, 'smaller inlier fraction than this: the correction '
                                            'is rejected', ge=0, le=1)
    max_correction: float = param(0.5, '[m] a correction moving the pose further than this from '
                                        'the prediction is rejected', gt=0)
    max_correction_yaw_deg: float = param(15.0, '[deg] a correction turning the pose more than '
                                                'this from the prediction is rejected', gt=0)
    search_radius: float = param(0.4, '[m] after a (re)set, the first scan searches start poses '
                                      'this far around the given one', ge=0)
    search_yaw_deg: float = param(15.0, '[deg] after a (re)set, the first scan searches start '
                                        'headings this far around the given one', ge=0)
    prior_sigma_xy: float = param(0.1, '[m] std of the prediction as a prior (holds directions '
                                       'the scan does not constrain)', gt=0)
    prior_sigma_yaw_deg: float = param(5.0, '[deg] std of the prediction yaw as a prior', gt=0)
    min_update_distance: float = param(
        0.2, '[m] a scan is registered once the odometry has moved this far, or turned '
             'min_update_yaw_deg, since the last registered one (AMCL\'s update_min_d, its '
             'default); the scans between follow odometry (0 with min_update_yaw_deg 0: every '
             'scan)', ge=0)
    min_update_yaw_deg: float = param(
        11.5, '[deg] see min_update_distance (AMCL\'s update_min_a at 0.2 rad)', ge=0)
    raster_band: bool = param(
        True, 'after each registration, move the pose to the middle of what the map\'s cells '
              'allow: an axis-aligned wall lies somewhere within its raster cell, unknown, and '
              'the registration alone is pulled by each wall\'s offset in it (refine_on_raster)')
    degenerate_ratio: float = param(
        0.01, 'a direction of the pose (x, y and the heading times the points\' RMS distance) '
              'along which the scan\'s information is below this fraction of its strongest '
              'direction\'s is unobservable from the scan (a corridor\'s axis): the correction '
              'keeps the prediction along it (observable_directions)', ge=0, lt=1)
    odometry_sigma_distance: float = param(
        0.02, '[m/m] std of the odometry\'s position error per metre driven: the covariance '
              'along unobservable directions grows by it', ge=0)
    odometry_sigma_yaw: float = param(
        0.03, '[rad/rad] std of the odometry\'s heading error per radian turned', ge=0)
    map_surface_depth: float = param(
        SCAN_MAP_DEPTH, '[cells] how deep inside the boundary of its occupied cells a surface '
                        'lies on average, which depends on how the map was made: 0.5 for a map '
                        'built from laser scans (a cell is occupied when a hit falls in it: '
                        'gmapping, cartographer, slam_toolbox), 0.25 for a map rasterised from '
                        'geometry with a cell occupied when an obstacle covers its central half '
                        '(the simulator\'s); the wrong one moves the pose a quarter cell away '
                        'from the surfaces in view (tiago_nav.gridmap.DistanceField)', ge=0, le=1)
    map_sigma: float = param(
        0.025, '[m] std of where the map puts the building\'s surfaces, beyond its raster, '
               'shared by everything a scan sees (the map\'s local error: a map built by SLAM '
               'from scans is locally consistent to about half a 0.05 m cell; 0 for a map '
               'rasterised from the world itself, as the simulator\'s): the published '
               'covariance adds it to the position, and it over the scan points\' RMS '
               'distance to the heading (the registration cannot see it)', ge=0)
    max_correction_step: float = param(
        0.01, '[m] after a registration that left a position unobservable (a corridor\'s '
              'axis), a position correction (the axis seen again after a long stretch) moves '
              'the published estimate (pose, map -> odom) towards the registered pose by at '
              'most this per estimate (scan), until it has converged; the registration itself '
              'works on the registered pose (0: at once)', ge=0)
    fuse_prediction: bool = param(
        True, 'a registration taken an update\'s distance or turn from the last one is weighed '
              'against the odometry\'s prediction (a Kalman update in the directions the scan '
              'observes, its covariance kept as if the two shared their errors: '
              'fuse_with_prediction); off: the registered pose replaces the prediction')
    rest_updates: int = param(
        5, 'scans registered anyway once the robot has come to rest (odometry unchanged since '
           'the scan before), until it moves again: at rest they refine the estimate that places '
           'what the robot then sees (detection at pose B)', ge=0)

    def __post_init__(self):
        validate(self)
        if self.robust_scale > self.initial_scale:
            raise ParamError('must be <= initial_scale (%g)' % self.initial_scale, 'robust_scale')


@dataclass(frozen=True)
class Update:
    """What one scan did.

    ``pose``: base_footprint in map after the update; ``map_to_odom``: the pose of odom in map;
    ``covariance``: 3 × 3 of ``(x, y, yaw)`` [m², m·rad, rad²]; ``predicted``: the prediction
    before correction; ``corrected``: whether the registration was accepted; ``inliers``: number
    of points within ``inlier_distance`` after registration; ``points``: points used;
    ``reason``: why a correction was rejected ('' when accepted); ``weak``: the directions
    the scan did not observe, kept at the prediction (:func:`weak_description`, e.g.
    ``'position along 0 deg'``; '' when the scan constrains every direction or was not
    registered); ``registered``: the registered pose (the filter's state, what the next
    prediction starts from), which ``pose`` (the published estimate) converges to by at most
    ``max_correction_step`` per estimate after a re-acquisition; ``pending`` [m]: how
    far ``pose`` still is from it (0 once converged).
    """
    pose: tuple
    map_to_odom: tuple
    covariance: np.ndarray
    predicted: tuple
    corrected: bool
    inliers: int
    points: int
    reason: str = ''
    weak: str = ''
    registered: tuple = None
    pending: float = 0.0


def beam_directions(points, sensor):
    """Unit vectors ``(N, 2)`` from the laser at ``sensor`` ``(x, y)`` [m] to each point, in the
    points' frame (base_footprint)."""
    beams = np.asarray(points, dtype=float) - np.asarray(sensor, dtype=float)
    return beams / np.maximum(np.hypot(beams[:, 0], beams[:, 1]), 1e-9)[:, None]


def _sample(field, poses, points, beams):
    """Field value and back-face flag of every point under every pose: ``(K, N)`` arrays."""
    poses = np.atleast_2d(poses)
    c, s = np.cos(poses[:, 2:3]), np.sin(poses[:, 2:3])
    qx = poses[:, 0:1] + c * points[:, 0] - s * points[:, 1]
    qy = poses[:, 1:2] + s * points[:, 0] + c * points[:, 1]
    r, gx, gy = (a.reshape(qx.shape) for a in field(np.column_stack((qx.ravel(), qy.ravel()))))
    along = gx * (c * beams[:, 0] - s * beams[:, 1]) + gy * (s * beams[:, 0] + c * beams[:, 1])
    return r, gx, gy, along > BACKFACE_COS


def _sample_one(field, pose, points, beams):
    """:func:`_sample` under one pose ``(x, y, yaw)``: ``(N,)`` arrays."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    px, py = points[:, 0], points[:, 1]
    r, gx, gy = field.at(pose[0] + c * px - s * py, pose[1] + s * px + c * py)
    along = gx * (c * beams[:, 0] - s * beams[:, 1]) + gy * (s * beams[:, 0] + c * beams[:, 1])
    return r, gx, gy, along > BACKFACE_COS


def score(field, poses, points, beams, scale):
    """Robust misfit of the scan under each candidate pose (lower is better): the sum over points
    of the truncated Cauchy loss ``log(1 + (r / scale)²)``, capped at ``r = 3 scale``; a back-face
    point counts as the cap.

    Args:
        field: the map's :class:`DistanceField`.
        poses: ``(K, 3)`` candidate poses of base_footprint in map [m, m, rad].
        points: ``(N, 2)`` scan points [m] in base_footprint.
        beams: ``(N, 2)`` unit beam directions of the points (:func:`beam_directions`).
        scale: [m] the loss scale.

    Returns:
        ``(K,)`` misfits.
    """
    r, _, _, back = _sample(field, poses, points, beams)
    cap = math.log1p(9.0)
    rho = np.minimum(np.log1p((r / scale) ** 2), cap)
    rho[back] = cap
    return rho.sum(axis=1)


NORMAL_GAP = 0.5         # [m] scan neighbours further apart than this are not one surface
NORMAL_FLATNESS = 0.1    # a neighbourhood whose spread across its line exceeds this fraction
                         # of its spread along it is not one straight surface (a corner): no normal


def scan_normals(points, half_window=4, max_gap=NORMAL_GAP):
    """Unit surface normals of scan points, from the points themselves (not from the map): the
    direction across the line fitted (principal axes) to each point and its up to
    ``half_window`` neighbours on either side in scan order that lie within ``max_gap`` [m] of
    it. A point with no such neighbour, or whose neighbourhood is not straight (a corner,
    :data:`NORMAL_FLATNESS`), gets none.

    Args:
        points: ``(N, 2)`` scan points [m] in scan order (any frame).

    Returns:
        ``(normals, ok)``: ``(N, 2)`` unit normals (sign arbitrary) in the points' frame and an
        ``(N,)`` mask of the points that have one.
    """
    pts = np.asarray(points, dtype=float)
    n = len(pts)
    if n < 2:
        return np.zeros((n, 2)), np.zeros(n, dtype=bool)
    # every point's window at once: (n, 2 half_window + 1) neighbour indices
    idx = np.arange(n)[:, None] + np.arange(-half_window, half_window + 1)[None, :]
    j = np.clip(idx, 0, n - 1)
    nx, ny = pts[j, 0], pts[j, 1]
    near = (idx >= 0) & (idx < n) & (np.hypot(nx - pts[:, 0:1], ny - pts[:, 1:2]) <= max_gap)
    count = np.count_nonzero(near, axis=1)
    mx = np.where(near, nx, 0.0).sum(axis=1) / count
    my = np.where(near, ny, 0.0).sum(axis=1) / count
    dx = np.where(near, nx - mx[:, None], 0.0)
    dy = np.where(near, ny - my[:, None], 0.0)
    sxx, syy, sxy = (dx * dx).sum(axis=1), (dy * dy).sum(axis=1), (dx * dy).sum(axis=1)
    # principal axis angle of the neighbourhood; the normal is across it
    phi = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)
    tr = sxx + syy
    root = np.sqrt(np.maximum((0.5 * (sxx - syy)) ** 2 + sxy ** 2, 0.0))
    major, minor = 0.5 * tr + root, 0.5 * tr - root
    ok = (count >= 2) & (major > 0) & (minor <= NORMAL_FLATNESS ** 2 * major)
    normals = np.column_stack((-np.sin(phi), np.cos(phi)))
    return normals, ok


def scan_information(points, normals, weights, yaw):
    """The information ``Jᵀ W J`` [1/m², 1/(m·rad), 1/rad²] (unit point variance) a scan's
    points give about a pose ``(x, y, yaw)`` when each constrains only the distance along its
    surface normal: ``J_i = (nx, ny, n · ∂q/∂yaw)`` with ``n`` the normal in map.

    The normals are the scan's own (:func:`scan_normals`), not the map field's gradient: a wall
    not aligned with the grid is a staircase of cells in the map, whose field gradients tilt
    back and forth along it and would claim a hold along the wall that the wall does not give.

    Args:
        points: ``(N, 2)`` points [m] in base_footprint; ``normals`` ``(N, 2)`` theirs, in
            base_footprint; ``weights`` ``(N,)`` (0 for points without a normal or not on the
            map); ``yaw`` [rad] the pose's heading.
    """
    j = normal_jacobian(points, normals)
    return _rotate_information((j * weights[:, None]).T @ j, yaw)


def normal_jacobian(points, normals):
    """The rows ``(nx, ny, n · ∂q/∂yaw)`` of :func:`scan_information`'s ``J`` at heading 0, in
    base_footprint: ``(N, 3)``. At heading ``yaw`` the normal turns with the pose and the
    third column does not change (``R n · R' p = n · R₉₀ p``), so the information at any
    heading is this one's turned (:func:`_rotate_information`): a registration computes it
    once."""
    return np.column_stack((normals[:, 0], normals[:, 1],
                            normals[:, 1] * points[:, 0] - normals[:, 0] * points[:, 1]))


def _turn(yaw):
    """``T = diag(R(yaw), 1)``, which takes ``(x, y, yaw)`` directions from base_footprint's
    heading to map."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rotate_information(info, yaw):
    """``T info Tᵀ``: an information about ``(x, y, yaw)`` at heading 0 at heading ``yaw``."""
    t = _turn(yaw)
    return t @ info @ t.T


def observable_directions(info, points, weights, ratio):
    """Which directions of a pose correction a scan constrains, from its information matrix.

    The correction ``(dx, dy, dyaw)`` mixes metres and radians; the heading is scaled by the
    points' weighted RMS distance from base_footprint, ``length`` (a turn by ``dyaw`` moves a
    typical point by ``length · dyaw``), so that the three eigenvalues of the scaled information
    compare what one point contributes along each. A direction whose eigenvalue is below
    ``ratio`` times the largest is unobservable: between two parallel walls (a corridor) the
    position along them, in a round room the heading.

    Args:
        info: ``(3, 3)`` information of the scan alone about ``(x, y, yaw)`` [1/m², 1/(m·rad),
            1/rad²] (Gauss-Newton ``Jᵀ W J``, without any prior).
        points: ``(N, 2)`` scan points [m] in base_footprint.
        weights: ``(N,)`` the points' weights in ``info``.
        ratio: the threshold, relative to the strongest direction (0: every direction counts as
            observable, the split is off).

    Returns:
        ``(strong, weak, eigenvalues, length)``: ``strong`` ``(3, k)`` and ``weak``
        ``(3, 3 - k)`` orthonormal bases of the observable and unobservable directions in the
        scaled space ``(x, y, length · yaw)`` [m], the scaled eigenvalues (ascending) and
        ``length`` [m]. A correction ``d`` in ``(x, y, yaw)`` becomes ``S d`` in the scaled space,
        ``S = diag(1, 1, length)``.
    """
    w = np.asarray(weights, dtype=float)
    pts = np.asarray(points, dtype=float)
    return _split(info, float(np.sum(w * np.sum(pts ** 2, axis=1))), float(np.sum(w)), ratio)


def _split(info, moment, total, ratio, turn=None):
    """:func:`observable_directions` from the points' weighted second moment ``moment``
    (``Σ w |p|²`` [m²]) and weight ``total``; ``turn``: a ``(3, 3)`` ``T`` (:func:`_turn`)
    taking the result's directions to another frame (``info`` given in base_footprint's heading,
    the eigenvalues are the same and the directions turn)."""
    length = max(math.sqrt(moment / max(total, 1e-9)), 0.1)
    s_inv = np.array([1.0, 1.0, 1.0 / length])
    scaled = info * s_inv[:, None] * s_inv[None, :]
    vals, vecs = np.linalg.eigh(0.5 * (scaled + scaled.T))
    if turn is not None:
        vecs = turn @ vecs
    top = max(float(vals[-1]), 0.0)
    if ratio <= 0:
        weak = np.zeros(3, dtype=bool)
    else:
        weak = vals < ratio * top if top > 0 else np.ones(3, dtype=bool)
    return vecs[:, ~weak], vecs[:, weak], vals, length


def weak_description(weak, pose, length):
    """A short text naming the unobservable directions ``weak`` (from
    :func:`observable_directions`) at ``pose`` (map): e.g. ``'position along 0 deg'`` (a
    corridor along x) or ``'heading'``; '' when there are none."""
    parts = []
    for v in np.asarray(weak).T:
        if abs(v[2]) > math.hypot(v[0], v[1]):
            parts.append('heading')
        else:
            ang = int(round(math.degrees(math.atan2(v[1], v[0])))) % 180
            parts.append('position along %d deg' % ang)
    return ', '.join(parts)


def _keep_weak(pose, anchor, strong, length):
    """``pose`` with its components along the unobservable directions (those not in the scaled
    basis ``strong``) set back to ``anchor``'s."""
    d = np.asarray(pose, dtype=float) - anchor
    d[2] = wrap_angle(d[2])
    scale = np.array([1.0, 1.0, length])
    u = strong @ (strong.T @ (d * scale))
    out = anchor + u / scale
    out[2] = wrap_angle(out[2])
    return out


def register(field, points, guess, config, sensor=(0.0, 0.0), anchor=None):
    """:func:`register_with_information` without the :class:`Information`: ``(pose,
    covariance, residuals)``."""
    return register_with_information(field, points, guess, config, sensor, anchor)[:3]


def register_with_information(field, points, guess, config, sensor=(0.0, 0.0), anchor=None):
    """Scan-to-map registration: the base pose in map that puts ``points`` on the map, corrected
    only along the directions the scan observes.

    Gauss-Newton, iteratively reweighted with Cauchy weights whose scale anneals from
    ``config.initial_scale`` to ``config.robust_scale``, plus a weak prior towards ``guess``.
    At each iteration the scan's information (``Jᵀ W J`` of the distance-field residuals in
    ``(x, y, yaw)``) is split by :func:`observable_directions` (``config.degenerate_ratio``);
    the step is solved in the observable subspace only, and along the unobservable directions
    the pose stays ``anchor``'s (a corridor's axis keeps the prediction).

    Args:
        field: the map's :class:`DistanceField`.
        points: ``(N, 2)`` scan points [m] in base_footprint.
        guess: initial pose ``(x, y, yaw)`` of base_footprint in map (the prediction).
        config: :class:`LocaliserConfig` (loss scales, iterations, prior, degenerate_ratio).
        sensor: ``(x, y)`` [m] of the laser in base_footprint: a point whose field gradient
            points along its beam (away from the laser) would be seen from behind a mapped
            surface (the back face of a thin wall is the classic false minimum) and gets no
            weight.
        anchor: the pose whose components the unobservable directions keep (default
            ``guess``; :func:`search` starts from nearby poses but anchors at the given one).

    Returns:
        ``(pose, covariance, residuals, info)``: the registered pose, its 3 × 3 covariance in
        the observable directions (the inverse of the Gauss-Newton normal matrix restricted to
        them, the points weighted by the inverse of their weighted residual variance, plus the
        prior's information; zero along the unobservable ones, where the caller knows the
        prediction's), the final per-point signed distances [m] to the map, and a
        :class:`Information` (the split).
    """
    prior = np.array(guess, dtype=float)
    anchor = prior.copy() if anchor is None else np.array(anchor, dtype=float)
    pose = prior.copy()
    beams = beam_directions(points, sensor)
    normals, has_normal = scan_normals(points)
    # what the information split needs that does not change between iterations: the normals'
    # Jacobian at heading 0 and the points' squared distances (only the weights change)
    jn = normal_jacobian(points, normals)[has_normal]
    p2 = np.sum(points[has_normal] ** 2, axis=1)
    info_prior = np.diag([1.0 / config.prior_sigma_xy ** 2] * 2
                         + [1.0 / math.radians(config.prior_sigma_yaw_deg) ** 2])
    scales = _scales(config)
    last = None         # (pose, r, back, step) before the last step
    for it in range(config.iterations + 1):
        scale = scales[min(it, len(scales) - 1)]
        r, gx, gy, back = _sample_one(field, pose, points, beams)
        if last is not None:
            # a step is kept only if it lowers the objective: the scan's misfit (the truncated
            # loss of score(), a back-face point at the cap) plus the prior's. The Gauss-Newton
            # step gives the back-face points no weight, which alone would let it slide the
            # scan behind surfaces, where they cost nothing; a step that does not lower it is
            # halved, and after HALVINGS the pose stays where it was
            before = _objective(last[1], last[2], scale, last[0], prior, info_prior)
            for _ in range(HALVINGS):
                if _objective(r, back, scale, pose, prior, info_prior) <= before:
                    break
                step = 0.5 * last[3]
                last = last[:3] + (step,)
                pose = last[0] + step
                pose[2] = wrap_angle(pose[2])
                r, gx, gy, back = _sample_one(field, pose, points, beams)
            else:
                if _objective(r, back, scale, pose, prior, info_prior) > before:
                    pose = last[0]
                    break
        if it == config.iterations:
            break
        c, s = math.cos(pose[2]), math.sin(pose[2])
        # d q / d yaw = R'(yaw) p
        dqx = -s * points[:, 0] - c * points[:, 1]
        dqy = c * points[:, 0] - s * points[:, 1]
        j = np.column_stack((gx, gy, gx * dqx + gy * dqy))
        w = 1.0 / (1.0 + (r / scale) ** 2)     # Cauchy weights
        w[back] = 0.0
        # the loss scale stands for the points' range std: their information is 1 / scale²
        jtw = (j * w[:, None]).T
        jtwj = jtw @ j
        wn = w[has_normal]
        split = ((jn * wn[:, None]).T @ jn, float(wn @ p2), float(np.sum(wn)),
                 config.degenerate_ratio, pose[2])
        # every direction observable (the usual case): the step is the whole space's, and the
        # directions are needed only for the last iteration's Information
        length = _observable_everywhere(*split[:4])
        if length is None:
            strong, weak, vals, length = _split(*split[:4], _turn(split[4]))
            if weak.shape[1]:
                pose = _keep_weak(pose, anchor, strong, length)
        else:
            strong = weak = None
        dp = prior - pose
        dp[2] = wrap_angle(dp[2])
        h = jtwj / scale ** 2 + info_prior
        g = -jtw @ r / scale ** 2 + info_prior @ dp
        if strong is None:
            step = np.linalg.solve(h, g)
        else:
            # the step within the observable subspace: pose = pose + B a, B = S⁻¹ strong
            b = strong / np.array([1.0, 1.0, length])[:, None]
            step = b @ np.linalg.solve(b.T @ h @ b, b.T @ g) if b.shape[1] else np.zeros(3)
        last = (pose.copy(), r, back, step)
        pose = pose + step
        pose[2] = wrap_angle(pose[2])
        if abs(step[0]) + abs(step[1]) < 1e-4 and abs(step[2]) < 1e-4 and scale == scales[-1]:
            break
    if strong is None:
        strong, weak, vals, length = _split(*split[:4], _turn(split[4]))
    b = strong / np.array([1.0, 1.0, length])[:, None]
    if config.raster_band:
        pose[:2] = refine_on_raster(field, points, pose)[0][:2]
        if weak.shape[1]:
            pose = _keep_weak(pose, anchor, strong, length)
    r, gx, gy = field(transform_points(tuple(pose), points))
    w = 1.0 / (1.0 + (r / config.robust_scale) ** 2)
    dof = max(float(np.sum(w)) - 3.0, 1.0)
    sigma2 = max(float(np.sum(w * r ** 2)) / dof, (0.25 * field.grid.resolution) ** 2)
    normal = h - jtwj / scale ** 2 + jtwj / sigma2
    cov = b @ np.linalg.inv(b.T @ normal @ b) @ b.T if b.shape[1] else np.zeros((3, 3))
    # what the localiser publishes: the same pose's covariance with the beams' shared errors
    # (one surface's map error is every one of its points') counted
    along = gx * (math.cos(pose[2]) * beams[:, 0] - math.sin(pose[2]) * beams[:, 1]) \
        + gy * (math.sin(pose[2]) * beams[:, 0] + math.cos(pose[2]) * beams[:, 1])
    w[along > BACKFACE_COS] = 0.0
    scan = (points, normals, has_normal, r, w, pose[2], b, sensor, field.grid.resolution)
    return ((float(pose[0]), float(pose[1]), float(pose[2])), cov, r,
            Information(strong, weak, vals, length, scan))


SEGMENT_COS = 0.9   # neighbouring scan points whose normals differ by more than ~25 deg are
                    # not on one surface (a corner between them)
SEGMENT_MIN_WEIGHT = 3.0   # a surface's mean residual tells its offset once it has this much
                           # weight (points) behind it


def scan_segments(points, normals, has_normal, max_gap=NORMAL_GAP):
    """Which surface each scan point lies on: runs of consecutive points (scan order) with a
    normal (:func:`scan_normals`), no more than ``max_gap`` [m] apart, whose normals agree
    within :data:`SEGMENT_COS`. Returns ``(N,)`` int labels (points without a normal get a label
    of their own)."""
    pts = np.asarray(points, dtype=float)
    n = len(pts)
    if n == 0:
        return np.zeros(0, dtype=int)
    gap = np.hypot(*(pts[1:] - pts[:-1]).T) > max_gap
    turn = np.abs(np.sum(normals[1:] * normals[:-1], axis=1)) < SEGMENT_COS
    cut = gap | turn | ~has_normal[1:] | ~has_normal[:-1]
    return np.concatenate(([0], np.cumsum(cut)))


def scan_covariance(points, normals, has_normal, residuals, weights, yaw, basis, sensor,
                    resolution):
    """The covariance [m², m·rad, rad²] of a registered pose ``(x, y, yaw)`` with the scan's
    errors as they are: not independent per beam.

    A point's residual (its signed distance to the map, along the surface's normal) is the sum
    of an error of its own (range noise, surface roughness) and one its whole surface shares:
    where the map put that surface, known only to within its raster cell (a straight surface
    lies anywhere in its cell, uniformly: ``resolution² / 12``) and to within how well the map
    and the surface agree (a map built from scans, a wall moved since). The shared part does
    not average out over the surface's points: a surface bounds the pose to its offset whatever
    its number of points. The pose error of the weighted least squares is ``H⁻¹ Jᵀ W e`` (``H
    = Jᵀ W J``), so its covariance is the sandwich ``H⁻¹ Jᵀ W C W J H⁻¹`` with ``C = σ_w² I +
    σ_s² Σ_s 1_s 1_sᵀ``:

    - the surfaces ``s`` are :func:`scan_segments`; ``J`` has the rows ``(n, n · ∂q/∂yaw)`` of
      the points' own normals (:func:`normal_jacobian`), which hold only across a surface;
    - ``σ_w²``: the weighted variance of the residuals about their surface's mean (measured on
      this scan, ``Σ w (r - m_s)² / (Σ w - surfaces)``), at least ``(resolution / 4)²``
      (the field's own interpolation between cell centres);
    - ``σ_s²``: the surfaces' mean residuals' spread (those with at least
      :data:`SEGMENT_MIN_WEIGHT` of weight, less their own noise ``σ_w² / Σ w``, over the
      surfaces less the 3 the pose absorbs), at least ``resolution² / 12``.

    Both are measured per scan, so a blurred map, a cluttered room or a noisier laser widen the
    covariance by what they do to this scan.

    Args:
        points: ``(N, 2)`` scan points [m] in base_footprint (scan order).
        normals, has_normal: their :func:`scan_normals`.
        residuals: ``(N,)`` [m] signed distances to the map at the pose.
        weights: ``(N,)`` the points' weights in the registration (0: not used).
        yaw: [rad] the pose's heading.
        basis: ``(3, k)`` directions of ``(x, y, yaw)`` the registration corrected (the
            covariance is zero along the others).
        sensor: ``(x, y)`` [m] of the laser in base_footprint (the normals are turned to face
            it).
        resolution: [m] the map's cell size.

    Returns:
        ``(3, 3)`` covariance in map.
    """
    basis = np.asarray(basis, dtype=float).reshape(3, -1)
    if not basis.shape[1]:
        return np.zeros((3, 3))
    pts = np.asarray(points, dtype=float)
    n = np.array(normals, dtype=float)
    flip = np.sum(n * (np.asarray(sensor, dtype=float) - pts), axis=1) < 0
    n[flip] *= -1.0
    w = np.where(has_normal, np.asarray(weights, dtype=float), 0.0)
    r = np.asarray(residuals, dtype=float)
    seg = scan_segments(pts, n, has_normal)
    if not len(seg):
        return np.zeros((3, 3))
    # the labels rise along the scan: each surface is one run, summed at once
    starts = np.flatnonzero(np.r_[True, seg[1:] != seg[:-1]])
    j = _rotate_rows(normal_jacobian(pts, n), yaw)
    jw = j * w[:, None]
    # each point's position along its surface [m] (from the surface's middle)
    along = pts[:, 1] * n[:, 0] - pts[:, 0] * n[:, 1]
    sums = np.add.reduceat(np.column_stack((w, w * r, jw, along)), starts, axis=0)
    ws, g = sums[:, 0], sums[:, 2:5]
    counts = np.diff(np.r_[starts, len(seg)])
    along = along - (sums[:, 5] / counts)[seg]
    length = np.maximum(np.maximum.reduceat(along, starts) - np.minimum.reduceat(along, starts),
                        resolution)
    tilt = np.add.reduceat(jw * along[:, None], starts, axis=0)
    mean = sums[:, 1] / np.maximum(ws, 1e-12)
    surfaces = int(np.count_nonzero(ws > 0))
    within = float(np.sum(w * (r - mean[seg]) ** 2)) / max(float(np.sum(w)) - surfaces, 1.0)
    sw2 = max(within, (0.25 * resolution) ** 2)
    big = ws >= SEGMENT_MIN_WEIGHT
    shared = float(np.sum(mean[big] ** 2 - sw2 / ws[big])) / max(int(np.sum(big)) - 3, 1)
    ss2 = max(shared, resolution ** 2 / 12.0)
    # a straight surface lies anywhere within its raster cell: its offset uniform across the
    # cell (resolution² / 12: the grid aligned with the surface, every point of it shifted
    # alike), and its direction as far as its two ends can move within their cells
    # independently (a tilt of variance 2 (resolution² / 12) / L² over its length L)
    tilt = tilt * (resolution / np.sqrt(6.0) / length)[:, None]
    h = jw.T @ j
    m = sw2 * (jw.T @ jw) + ss2 * (g.T @ g) + tilt.T @ tilt
    hinv = _inverse_small(basis.T @ h @ basis)
    if hinv is None:
        return np.zeros((3, 3))
    return basis @ (hinv @ (basis.T @ m @ basis) @ hinv) @ basis.T


# the 99.9 % quantiles of chi-square with 1, 2 and 3 degrees of freedom: a registration's
# correction beyond them (its Mahalanobis distance under the prediction's and the registration's
# covariances) is not fused
INNOVATION_LIMIT = {1: 10.83, 2: 13.82, 3: 16.27}


def fuse_with_prediction(predicted, predicted_cov, registered, info):
    """The prediction updated by a registration, in the directions the scan observes.

    The registration is a measurement of the pose's observable part with covariance ``R``
    (:attr:`Information.covariance`: the scan's errors, its surfaces' shared ones counted); the
    prediction has ``P`` (:meth:`Localiser.predicted_covariance`). In the coordinates ``a`` of
    the observable subspace (``Information.strong``: scaled ``(x, y, length · yaw)``), the pose
    is the Kalman update's, ``a = K a_z`` with ``K = P (P + R)⁻¹`` (the registration's
    correction ``a_z`` weighed against the odometry's): the scan's own noise averages out over
    registrations. Its covariance is not the Kalman ``(I - K) P``, which holds for independent
    errors only: consecutive scans see the same surfaces with the same map errors, and the
    prediction carries the last registration's. With the errors taken as fully correlated the
    standard deviations add, ``P⁺ = (A + B)(A + B)ᵀ`` with ``A = (I - K) √P`` and ``B = K √R``
    (symmetric square roots): along every direction it lies between ``P``'s and ``R``'s, so
    fusing claims no more certainty than the surer of the two. A correction the two make improbable (``a_zᵀ (P + R)⁻¹ a_z``
    beyond :data:`INNOVATION_LIMIT`: the odometry slipped beyond its model) is not fused: the
    registration is kept as it is. Along the unobservable directions the registered pose (the
    prediction there, or where the search along them put it) is kept.

    Args:
        predicted: ``(x, y, yaw)`` [m, m, rad] of base_footprint in map, the prediction.
        predicted_cov: its 3 × 3 covariance [m², m·rad, rad²].
        registered: ``(x, y, yaw)`` the registered pose.
        info: the registration's :class:`Information`.

    Returns:
        ``(pose, covariance)``: the fused pose and its 3 × 3 covariance in the observable
        directions (zero along the others, as :attr:`Information.covariance`).
    """
    r_cov = info.covariance
    if not info.strong.shape[1]:
        return tuple(registered), r_cov
    scale = np.array([1.0, 1.0, info.length])
    to_a = info.strong.T * scale[None, :]       # (k, 3): (dx, dy, dyaw) → a
    from_a = info.strong / scale[:, None]       # (3, k): a → (dx, dy, dyaw)
    d = np.array(registered, dtype=float) - np.array(predicted, dtype=float)
    d[2] = wrap_angle(d[2])
    a_z = to_a @ d
    p, r = to_a @ predicted_cov @ to_a.T, to_a @ r_cov @ to_a.T
    try:
        gain = np.linalg.solve(p + r, p).T      # P (P + R)⁻¹, both symmetric
        innovation = float(a_z @ np.linalg.solve(p + r, a_z))
    except np.linalg.LinAlgError:
        return tuple(registered), r_cov
    if innovation > INNOVATION_LIMIT[len(p)]:
        # a correction the two covariances make improbable: the odometry went wrong beyond
        # its model (a wheel slipped, the robot was pushed), and the scan is right
        return tuple(registered), r_cov
    root = (np.eye(len(p)) - gain) @ _sqrtm(p) + gain @ _sqrtm(r)
    out = np.array(registered, dtype=float) + from_a @ (gain @ a_z - a_z)
    out[2] = wrap_angle(out[2])
    return (float(out[0]), float(out[1]), float(out[2])), from_a @ (root @ root.T) @ from_a.T


def _inverse_small(a):
    """The inverse of a 1 × 1, 2 × 2 or 3 × 3 matrix by its adjugate (a LAPACK call costs
    more than the arithmetic at this size), or None when it is singular."""
    n = a.shape[0]
    if n == 1:
        return None if a[0, 0] == 0 else np.array([[1.0 / a[0, 0]]])
    if n == 2:
        det = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
        return None if det == 0 else np.array([[a[1, 1], -a[0, 1]], [-a[1, 0], a[0, 0]]]) / det
    (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = a.tolist()
    c00, c01, c02 = a11 * a22 - a12 * a21, a12 * a20 - a10 * a22, a10 * a21 - a11 * a20
    det = a00 * c00 + a01 * c01 + a02 * c02
    scale = max(abs(v) for v in (a00, a01, a02, a10, a11, a12, a20, a21, a22)) ** 3
    if not abs(det) > 1e-12 * scale:
        return None
    return np.array([[c00, a02 * a21 - a01 * a22, a01 * a12 - a02 * a11],
                     [c01, a00 * a22 - a02 * a20, a02 * a10 - a00 * a12],
                     [c02, a01 * a20 - a00 * a21, a00 * a11 - a01 * a10]]) / det


def _rotate_rows(j, yaw):
    """Rows ``(nx, ny, t)`` of a Jacobian at heading 0 turned to heading ``yaw`` (the normal
    turns, the heading's column does not: :func:`normal_jacobian`)."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.column_stack((c * j[:, 0] - s * j[:, 1], s * j[:, 0] + c * j[:, 1], j[:, 2]))


HALVINGS = 3     # a registration step that raises the objective is halved at most this often


def _objective(r, back, scale, pose, prior, info_prior):
    """What a registration step must lower: the scan's misfit at the residuals ``r`` [m] and
    back-face flags ``back`` (:func:`score`'s truncated Cauchy loss at ``scale``) plus the
    prior's ``dpᵀ P dp`` (``dp`` from ``pose`` to ``prior``), in the units of ``2 ×`` the
    negative log-likelihood the Gauss-Newton step approximates."""
    rho = np.minimum(np.log1p((r / scale) ** 2), _CAP)
    rho[back] = _CAP
    dp = prior - pose
    dp[2] = wrap_angle(dp[2])
    return float(rho.sum()) + float(dp @ info_prior @ dp)


_CAP = math.log1p(9.0)      # the truncated loss's cap (at 3 scales)


def _observable_everywhere(info, moment, total, ratio):
    """The ``length`` of :func:`_split` when every direction is clearly observable (the
    smallest eigenvalue of the scaled information at least twice ``ratio`` times the
    largest, from the closed form of a symmetric 3 × 3 matrix's eigenvalues), else None (then
    :func:`_split` decides, with the eigenvectors)."""
    length = max(math.sqrt(moment / max(total, 1e-9)), 0.1)
    if ratio <= 0:
        return length
    k = 1.0 / length
    a00, a11, a22 = info[0, 0], info[1, 1], info[2, 2] * k * k
    a01, a02, a12 = info[0, 1], info[0, 2] * k, info[1, 2] * k
    q = (a00 + a11 + a22) / 3.0
    p1 = a01 * a01 + a02 * a02 + a12 * a12
    p2 = (a00 - q) ** 2 + (a11 - q) ** 2 + (a22 - q) ** 2 + 2.0 * p1
    if not p2 > 0.0:                    # a multiple of the identity (or not finite)
        return length if q > 0.0 else None
    p = math.sqrt(p2 / 6.0)
    b00, b11, b22 = (a00 - q) / p, (a11 - q) / p, (a22 - q) / p
    b01, b02, b12 = a01 / p, a02 / p, a12 / p
    det = (b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02)
           + b02 * (b01 * b12 - b11 * b02))
    phi = math.acos(min(1.0, max(-1.0, det / 2.0))) / 3.0
    top = q + 2.0 * p * math.cos(phi)
    least = q + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0)
    return length if top > 0.0 and least >= 2.0 * ratio * top else None


_SCALES = {}


def _scales(config):
    """The loss scales of a registration's iterations (annealed from ``initial_scale`` to
    ``robust_scale``), computed once per configuration."""
    key = (config.initial_scale, config.robust_scale, config.iterations)
    if key not in _SCALES:
        _SCALES[key] = np.geomspace(config.initial_scale, config.robust_scale,
                                    max(1, config.iterations // 2))
    return _SCALES[key]


@dataclass(frozen=True)
class Information:
    """How a registration's scan constrains the pose (:func:`observable_directions`):
    orthonormal bases ``strong`` ``(3, k)`` and ``weak`` ``(3, 3 - k)`` in the scaled space
    ``(x, y, length · yaw)`` [m], the scaled eigenvalues (ascending) and ``length`` [m];
    ``scan``: the arguments of :func:`scan_covariance` for the registered pose (None: none)."""
    strong: np.ndarray
    weak: np.ndarray
    eigenvalues: np.ndarray
    length: float
    scan: tuple = dataclass_field(default=None, repr=False, compare=False)

    @cached_property
    def covariance(self):
        """``(3, 3)`` [m², m·rad, rad²] of the registered pose from the scan with its points'
        shared errors counted (:func:`scan_covariance`; zero along ``weak``), what the
        localiser publishes for the corrected directions; computed when first asked for (a
        search registers several start poses and keeps one)."""
        return np.zeros((3, 3)) if self.scan is None else scan_covariance(*self.scan)

    @property
    def degenerate(self):
        """Whether some direction is unobservable from the scan."""
        return self.weak.shape[1] > 0

    def weak_projector(self):
        """``(3, 3)`` matrix ``W`` taking a correction ``(dx, dy, dyaw)`` to its part along the
        unobservable directions (``W = S⁻¹ V Vᵀ S``, ``V`` = ``weak``)."""
        scale = np.array([1.0, 1.0, self.length])
        return (self.weak / scale[:, None]) @ (self.weak.T * scale[None, :])


AXIS_COS = 0.995       # a field gradient this close to an axis: the point faces a raster edge
RASTER_GROUP_MIN = 10  # points on one raster edge line before it bounds the translation
RASTER_NOISE = 0.01    # [m] a scan point's range noise (TIAGo's laser): the mean of a wall's
                       # points is known to 2 standard errors of it


def refine_on_raster(field, points, pose, band=None, noise=RASTER_NOISE,
                     min_points=RASTER_GROUP_MIN, inlier=0.05, widths=False):
    """The translation of ``pose`` that best agrees with where an occupancy grid can put a
    surface, after :func:`register`.

    An occupancy grid knows a straight surface only to within a cell: every surface whose
    raster has the same occupied cells is as likely, and the field puts them all at the middle
    of that band (:class:`DistanceField`). :func:`register` averages every point's residual to
    that middle, so each surface in view pulls the pose by its own sub-cell offset, unknown
    but shared by all its points: on the course map at pose B about 1 cm. Here the points
    facing one axis-aligned raster edge line (at least ``min_points`` of them, grouped by the
    line's position) form one surface; its mean residual must lie within the band, half a cell
    (``band``, default ``field.grid.resolution / 2``) each side of the middle, widened by the
    mean's noise (``noise`` [m] per point, 2 standard errors). Each surface so bounds the
    translation along its axis to an interval; the pose moves to the middle of the
    intersection of those intervals along x and along y (where they do not all intersect,
    the middle between the tightest bounds: the least largest violation). Heading and axes
    with no bound keep :func:`register`'s answer.

    Args:
        field: the map's :class:`DistanceField`.
        points: ``(N, 2)`` scan points [m] in the frame ``pose`` places in map.
        pose: ``(x, y, yaw)`` [m, m, rad], the registered pose.
        band, noise, min_points: see above; ``inlier`` [m]: points further than this from the
            band's middle are not on a mapped surface and take no part.

    Returns:
        ``(pose, counts)``: the refined pose and how many surfaces bounded x and y; with
        ``widths``, ``(pose, counts, widths)``: per axis the width [m] of the intersection of
        the surfaces' intervals (negative when they do not intersect: by how much the tightest
        bounds overlap the wrong way; None for an axis no surface bounds).
    """
    band = field.grid.resolution / 2.0 if band is None else band
    q = transform_points(tuple(pose), np.asarray(points, dtype=float))
    r, gx, gy = field(q)
    g = np.hypot(gx, gy)
    ok = (np.abs(r) <= inlier) & (g > 0.5)
    shift, counts, width = [0.0, 0.0], [0, 0], [None, None]
    for axis, grad in ((0, gx), (1, gy)):
        face = ok & (np.abs(grad) >= AXIS_COS * g)
        if not np.any(face):
            continue
        rf, sign = r[face], np.sign(grad[face])
        # the band's middle line along this axis: the same for every point of one surface
        line = q[face, axis] - sign * rf
        key = np.round(line / (field.grid.resolution / 8.0)).astype(int) * 2 + (sign > 0)
        lo, hi = [], []
        for k in np.unique(key):
            sel = key == k
            n = int(np.count_nonzero(sel))
            if n < min_points:
                continue
            m, s = float(np.mean(rf[sel])), float(sign[sel][0])
            w = band + 2.0 * noise / math.sqrt(n)
            # moving the pose by d along the axis changes this surface's mean residual by s d
            a, b = (-w - m) * s, (w - m) * s
            lo.append(min(a, b))
            hi.append(max(a, b))
        if lo:
            shift[axis] = 0.5 * (max(lo) + min(hi))
            counts[axis] = len(lo)
            width[axis] = float(min(hi) - max(lo))
    out = (float(pose[0] + shift[0]), float(pose[1] + shift[1]), float(pose[2])), tuple(counts)
    return out + (tuple(width),) if widths else out


def search(field, points, guess, config, sensor=(0.0, 0.0), keep=4):
    """Registration from an uncertain pose (after a (re)set): score a grid of start poses within
    ``config.search_radius`` and ``config.search_yaw_deg`` of ``guess`` (steps of 0.1 m and
    5 deg), register from the ``keep`` best and keep the result whose final :func:`score` is
    lowest. Every registration is anchored at ``guess``: along a direction the scan does not
    observe (a corridor's axis, where every start pose along it scores the same) the result
    keeps the given pose instead of whichever start pose happened to score first.

    Args:
        field, points, config, sensor: as for :func:`register`.
        guess: the given pose ``(x, y, yaw)`` of base_footprint in map.
        keep: how many of the best-scored start poses are registered.

    Returns:
        the :func:`register_with_information` result ``(pose, covariance, residuals,
        information)`` of the best.
    """
    nxy = 2 * int(math.ceil(config.search_radius / 0.1)) + 1
    nyaw = 2 * int(math.ceil(config.search_yaw_deg / 5.0)) + 1
    d = np.linspace(-config.search_radius, config.search_radius, nxy)
    dyaw = np.radians(np.linspace(-config.search_yaw_deg, config.search_yaw_deg, nyaw))
    ox, oy, oyaw = np.meshgrid(d, d, dyaw, indexing='ij')
    cand = np.column_stack((guess[0] + ox.ravel(), guess[1] + oy.ravel(), guess[2] + oyaw.ravel()))
    beams = beam_directions(points, sensor)
    # stable: among equal scores the start poses nearest the given one (the grid's centre) first
    near = np.hypot(ox.ravel(), oy.ravel()) + np.abs(oyaw.ravel())
    misfit = score(field, cand, points, beams, config.inlier_distance)
    order = np.lexsort((near, misfit))[:keep]
    results = [register_with_information(field, points, tuple(cand[k]), config, sensor,
                                         anchor=guess) for k in order]
    finals = score(field, np.array([res[0] for res in results]), points, beams,
                   config.inlier_distance)
    return results[int(np.argmin(finals))]


def weak_axes(info):
    """The unit directions ``(2, k)`` in map of the positions an :class:`Information` finds
    unobservable (a corridor's axis); a weak direction that is mostly a heading gives none."""
    out = []
    for v in info.weak.T:
        d = v / np.array([1.0, 1.0, info.length])
        n = math.hypot(d[0], d[1])
        if n / np.linalg.norm(d) >= 0.5:
            out.append(d[:2] / n)
    if not out:
        return np.zeros((2, 0))
    # orthonormal (two weak positions: every position)
    q, _ = np.linalg.qr(np.array(out).T)
    return q[:, :len(out)]


# the search along an unobservable direction (Localiser.search_along_weak): step [m], reach at
# most [m], and by how many points' worth of the score cap the best pose must beat the prediction
WEAK_SEARCH_STEP = 0.05
WEAK_SEARCH_MAX = 2.0
WEAK_SEARCH_MARGIN = 5


def _sqrtm(a):
    """The symmetric positive semi-definite square root of a symmetric ``a``."""
    vals, vecs = np.linalg.eigh(0.5 * (a + a.T))
    return (vecs * np.sqrt(np.maximum(vals, 0.0))) @ vecs.T


class Localiser:
    """Tracks base_footprint in ``map`` from odometry and scans (see the module docstring).

    Args:
        grid: the static map, a :class:`tiago_nav.gridmap.GridMap` in ``map``.
        pose: the initial pose ``(x, y, yaw)`` of base_footprint in map (uncertain: the first
            scan searches around it, see :meth:`reset`).
        config: :class:`LocaliserConfig`.
        odom: base_footprint in odom ``(x, y, yaw)`` when the robot was at ``pose`` (the first
            update predicts the motion since); None: at the first update's time.
        field: ``grid``'s :class:`DistanceField` when already built (it is read only); None:
            built here.

    Attributes: ``pose``, the registered pose (the filter's state: predictions, registrations
    and the gate start from it); :attr:`estimate`, the published one (``pose`` plus what a
    re-acquired direction's correction still has to apply, :attr:`pending`), which
    :attr:`map_to_odom` and every :class:`Update` give.
    """

    def __init__(self, grid, pose, config=LocaliserConfig(), odom=None, field=None):
        self.config = config
        self.field = DistanceField(grid, config.map_surface_depth) if field is None else field
        self.reset(pose)
        self._odom = None if odom is None else tuple(odom)

    @property
    def odom(self):
        """base_footprint in odom at the last update (None before one)."""
        return self._odom

    @property
    def map_to_odom(self):
        """The published pose of odom in map: ``estimate ∘ inverse(odom pose)`` of the last
        update (the registered one, :attr:`pose`, shifted by the :attr:`pending` offset in map),
        or the estimate itself before any odometry was seen."""
        off = (float(self._offset[0]), float(self._offset[1]), 0.0)
        if self._odom is None:
            return self.estimate
        return compose(off, compose(self.pose, inverse(self._odom)))

    @property
    def estimate(self):
        """The published pose of base_footprint in map at the last update: the registered
        :attr:`pose` (the filter's state, which every prediction and registration starts from)
        plus the :attr:`pending` offset still to be applied."""
        return (self.pose[0] + float(self._offset[0]), self.pose[1] + float(self._offset[1]),
                self.pose[2])

    @property
    def pending(self):
        """``(2,)`` [m] in map: the published estimate minus the registered pose, what a
        re-acquired direction's correction still has to apply (zero once converged)."""
        return self._offset.copy()

    def published_covariance(self, covariance):
        """``covariance`` (the registered pose's) widened by the pending offset ``o`` (``+ o
        oᵀ`` in x, y): the published estimate is that much further from the best one; and by
        the map's own error, ``map_sigma²`` in x and y (the same for every scan of a place, so
        it is no part of the filter's state: it neither grows with the odometry nor widens the
        gate)."""
        out = np.array(covariance, dtype=float)
        out[:2, :2] += np.outer(self._offset, self._offset) \
            + np.eye(2) * self.config.map_sigma ** 2
        if self.information is not None:
            out[2, 2] += (self.config.map_sigma / self.information.length) ** 2
        return out

    def _step_pending(self):
        """One estimate's worth of convergence: the pending offset shrinks by at most
        ``max_correction_step`` (all of it when that is 0); once it is gone the re-acquired
        directions are ordinary again."""
        limit = self.config.max_correction_step
        norm = float(np.hypot(*self._offset))
        if limit <= 0 or norm <= limit:
            self._offset = np.zeros(2)
        else:
            self._offset = self._offset * (1.0 - limit / norm)

    def follow(self, odom_pose):
        """The published estimate at a scan that is not registered (not :meth:`due`): the
        last ``map_to_odom`` carried by the odometry, after one step of a pending correction
        (:meth:`_step_pending`, so a re-acquisition converges also between registrations and at
        rest). Returns ``(pose, covariance)``: base_footprint in map and the 3 × 3 covariance
        (the prediction's, :meth:`predicted_covariance`, widened by what is pending)."""
        self._step_pending()
        return (compose(self.map_to_odom, tuple(odom_pose)),
                self.published_covariance(self.predicted_covariance(odom_pose)))

    def reset(self, pose, covariance=None):
        """Restart from ``pose`` (``(x, y, yaw)`` of base_footprint in map, e.g. /initialpose):
        the next update predicts from it with zero odometry motion and searches start poses
        within ``search_radius`` / ``search_yaw_deg`` of it (the gate then allows a correction
        that far beyond its usual limits)."""
        self.pose = tuple(float(v) for v in pose)
        self.covariance = np.diag([self.config.search_radius ** 2] * 2
                                  + [math.radians(self.config.search_yaw_deg) ** 2]) \
            if covariance is None else np.asarray(covariance, dtype=float).reshape(3, 3)
        self._odom = None       # odom → base_footprint at the last update
        self._searching = True
        self.information = None  # the last registration's Information
        self._seen = None       # odom → base_footprint of the scan before (due)
        self._rest = 0          # scans due at rest since the robot stopped
        # the published estimate minus the registered pose [m, map], and the unit directions
        # (2, k) in map of the positions unobservable at the last registration (kept while
        # the offset converges): while there are any, position corrections go through the
        # offset. A (re)set sets the pose at once
        self._offset = np.zeros(2)
        self._axes = np.zeros((2, 0))

    def predict(self, odom_pose):
        """The pose in map predicted from the odometry delta since the last update.

        Args:
            odom_pose: base_footprint in odom ``(x, y, yaw)`` at the scan's time.
        """
        if self._odom is None:
            return self.pose
        return compose(self.pose, compose(inverse(self._odom), odom_pose))

    def predicted_covariance(self, odom_pose):
        """The covariance of :meth:`predict` ``(odom_pose)``: the last one, ``P``, carried
        through the odometry delta ``d`` (first-order, ``pose ∘ d``: ``J P Jᵀ``), plus the
        odometry's own error over it, ``Q``: ``odometry_sigma_distance`` per metre driven (along
        and across) and ``odometry_sigma_yaw`` per radian turned, in base_footprint then rotated
        into map. Wheel odometry's error is mostly a scale error, the same at every step, so the
        standard deviations add rather than the variances: ``(√(J P Jᵀ) + √Q)²`` (symmetric
        square roots), which grows the standard deviation along a corridor linearly with the
        distance driven, as the error does."""
        if self._odom is None:
            return self.covariance.copy()
        dx, dy, dyaw = compose(inverse(self._odom), odom_pose)
        th = self.pose[2]
        c, s = math.cos(th), math.sin(th)
        jp = np.array([[1.0, 0.0, -s * dx - c * dy], [0.0, 1.0, c * dx - s * dy], [0.0, 0.0, 1.0]])
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        dist = math.hypot(dx, dy)
        # √(R Q Rᵀ) = R √Q Rᵀ, and Q is diagonal
        sq = np.array([self.config.odometry_sigma_distance * dist] * 2
                      + [self.config.odometry_sigma_yaw * abs(dyaw)])
        root = _sqrtm(jp @ self.covariance @ jp.T) + (rot * sq[None, :]) @ rot.T
        return root @ root.T

    def scan_points(self, ranges, angle_min, angle_increment, range_min, range_max,
                    laser_pose=None):
        """The scan's hits as points [m] in base_footprint, self-hits (closer than
        ``self_filter_radius`` to base_footprint), veils (:func:`tiago_nav.scan.usable_ranges`)
        and far hits dropped, evenly subsampled to
        at most ``max_points``.

        Args:
            ranges, angle_min, angle_increment, range_min, range_max: the LaserScan's fields
                (REP 117 rules, :func:`tiago_nav.scan.scan_to_points`).
            laser_pose: base_laser_link in base_footprint (default: TIAGo's, ``LASER_OFFSET``
                ahead of base_footprint).
        """
        c = self.config
        laser_pose = laser_pose or (LASER_OFFSET, 0.0, 0.0)
        ranges = usable_ranges(ranges, angle_min, angle_increment, range_min, range_max,
                               laser_pose, radius=c.self_filter_radius, margin=0.0)
        pts, _ = scan_to_points(ranges, angle_min, angle_increment, range_min,
                                min(range_max, c.max_range))
        pts = transform_points(laser_pose, pts)
        # near points in any direction say little about the map: dropped (not only the body)
        pts = pts[np.hypot(pts[:, 0], pts[:, 1]) >= c.self_filter_radius]
        if len(pts) > c.max_points:
            pts = pts[np.linspace(0, len(pts) - 1, c.max_points).round().astype(int)]
        return pts

    def _moved(self, odom_pose):
        """Whether the odometry has moved ``min_update_distance`` or turned
        ``min_update_yaw_deg`` since the last registered scan (False before the first)."""
        if self._odom is None:
            return False
        dx, dy, dyaw = compose(inverse(self._odom), tuple(odom_pose))
        return math.hypot(dx, dy) >= self.config.min_update_distance \
            or abs(dyaw) >= math.radians(self.config.min_update_yaw_deg)

    def due(self, odom_pose):
        """Whether the scan at ``odom_pose`` (base_footprint in odom) is to be registered (call
        once per scan, in order): always after a (re)set and at the first scan; else once the
        odometry has moved ``min_update_distance`` or turned ``min_update_yaw_deg`` since the
        last registered scan (AMCL's update_min_d / update_min_a: a scan taken from about the
        same pose adds little, and registering it costs most of the node's time), and the first
        ``rest_updates`` scans after the robot came to rest (odometry unchanged since the scan
        before: without them the estimate at a stop, where the robot looks for obstacles, was
        one registration taken on the move; detection's centre RMS at pose B went from about
        1.3 to 2.2 cm). Between, the estimate is ``map_to_odom`` ∘ odometry, unchanged."""
        odom_pose = tuple(odom_pose)
        still, self._seen = odom_pose == self._seen, odom_pose
        if not still:
            self._rest = 0
        if self._searching or self._odom is None or self._moved(odom_pose):
            return True
        if still and self._rest < self.config.rest_updates:
            self._rest += 1
            return True
        return False

    def search_along_weak(self, points, predicted, predicted_cov, sensor):
        """The start pose of a tracking registration: ``predicted``, or, after registrations
        that left a direction unobservable and while the prediction's standard deviation along
        it exceeds :data:`WEAK_SEARCH_STEP`, the best-scoring pose along that direction within 3
        standard deviations (at most :data:`WEAK_SEARCH_MAX`) of the prediction, if it beats the
        prediction's :func:`score` by at least :data:`WEAK_SEARCH_MARGIN` points' worth.

        Why: after a long corridor the along-axis drift is larger than the Cauchy scale, so the
        first surfaces that would fix it (the corridor's end, the room beyond) are too far off
        the map to pull, and the axis would stay unobservable; scoring whole poses along it
        finds them. In a corridor every pose along it scores the same and the prediction stays.
        """
        info = self.information
        if info is None or not info.degenerate:
            return predicted
        c = self.config
        beams = beam_directions(points, sensor)
        best, best_score = np.array(predicted, dtype=float), None
        here = None         # the prediction's score, once a direction is searched
        for v in info.weak.T:
            d = v / np.array([1.0, 1.0, info.length])
            if math.hypot(d[0], d[1]) < 0.5:          # a heading: not searched
                continue
            d = d / math.hypot(d[0], d[1])
            sigma = math.sqrt(max(float(d @ predicted_cov @ d), 0.0))
            if sigma < WEAK_SEARCH_STEP:
                continue
            reach = min(3.0 * sigma, WEAK_SEARCH_MAX)
            offsets = np.arange(-reach, reach + 1e-9, WEAK_SEARCH_STEP)
            cand = np.array(predicted, dtype=float)[None, :] + offsets[:, None] * d[None, :]
            scores = score(self.field, cand, points, beams, c.inlier_distance)
            if here is None:
                here = float(score(self.field, np.array([predicted]), points, beams,
                                   c.inlier_distance)[0])
            k = int(np.argmin(scores))
            if here - scores[k] >= WEAK_SEARCH_MARGIN * math.log1p(9.0) and \
                    (best_score is None or scores[k] < best_score):
                best, best_score = cand[k], float(scores[k])
        return tuple(float(x) for x in best)

    def update(self, odom_pose, points, sensor=None):
        """Predict from odometry, correct with the scan, gate; returns an :class:`Update`.

        Args:
            odom_pose: base_footprint in odom ``(x, y, yaw)`` at the scan's time.
            points: ``(N, 2)`` scan points [m] in base_footprint (:meth:`scan_points`).
            sensor: ``(x, y)`` [m] of the laser in base_footprint (default
                ``(LASER_OFFSET, 0)``).
        """
        c = self.config
        predicted = self.predict(odom_pose)
        predicted_cov = self.predicted_covariance(odom_pose)
        moved = self._moved(odom_pose)
        self._odom = tuple(odom_pose)
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        reason = ''
        inliers = 0
        info = None
        if len(pts) < c.min_inliers:
            reason = 'only %d scan points (need %d)' % (len(pts), c.min_inliers)
        else:
            sensor = sensor or (LASER_OFFSET, 0.0)
            if self._searching:
                pose, cov, r, info = search(self.field, pts, predicted, c, sensor)
            else:
                start = self.search_along_weak(pts, predicted, predicted_cov, sensor)
                pose, cov, r, info = register_with_information(self.field, pts, start, c, sensor)
            extra = (c.search_radius, c.search_yaw_deg) if self._searching else (0.0, 0.0)
            # a direction unobservable for a while (a corridor's axis) has drifted as far as the
            # odometry has: the gate allows 3 standard deviations of the prediction beyond the
            # usual limits, so the first scan that sees it again can correct it
            spread = 3.0 * math.sqrt(max(float(np.linalg.eigvalsh(predicted_cov[:2, :2])[-1]),
                                         0.0))
            extra = (extra[0] + spread,
                     extra[1] + 3.0 * math.degrees(math.sqrt(max(predicted_cov[2, 2], 0.0))))
            inliers = int(np.sum(np.abs(r) < c.inlier_distance))
            jump = math.hypot(pose[0] - predicted[0], pose[1] - predicted[1])
            turn = abs(wrap_angle(pose[2] - predicted[2]))
            if inliers < c.min_inliers or inliers < c.min_inlier_fraction * len(pts):
                reason = '%d of %d points match the map' % (inliers, len(pts))
            elif jump > c.max_correction + extra[0] \
                    or turn > math.radians(c.max_correction_yaw_deg + extra[1]):
                reason = 'correction of %.2f m / %.1f deg is implausible' % (jump, math.degrees(turn))
        if reason:
            self.pose = predicted
            # the prediction's covariance (odometry since the last correction included), and
            # what a scan that does not fit may say about the pose
            self.covariance = predicted_cov + UNCORRECTED_GROWTH
        else:
            # along the unobservable directions the pose is the prediction, and so is its
            # uncertainty: the prediction's covariance projected on them
            weak = info.weak_projector()
            # while a position was unobservable at the last registration (or its
            # re-acquisition is still converging), a correction of the position (the drift of
            # a long corridor, corrected by the first scans that see its end) is applied to the
            # registered pose at once but reaches the published estimate in steps of at most
            # max_correction_step, straight from the prediction: the offset keeps the estimate
            # at the prediction. All of the position correction, not only its part along the
            # weak direction: that direction is a few degrees off the corridor's axis when the
            # room beyond starts to show, and a projection on it would turn an along-axis
            # correction into a lateral jump. Corrections within one step (the lateral ones in
            # a corridor, millimetres) still arrive at once
            if self._axes.size:
                self._offset = self._offset - np.array([pose[0] - predicted[0],
                                                        pose[1] - predicted[1]])
            # the registration fused with the prediction (fuse_with_prediction) once the robot
            # has moved an update's distance since the last one, so that the two see the
            # building from different places; not after a (re)set, whose prediction is the
            # search window, nor while a re-acquisition converges (the offset already smooths
            # that correction, and fusing would spread it over registrations that each add to
            # the offset), nor at rest, where a scan sees what the last one saw
            observed = info.covariance
            if c.fuse_prediction and moved and not self._searching and not self._axes.size:
                pose, observed = fuse_with_prediction(predicted, predicted_cov, pose, info)
            self.pose = pose
            self.covariance = observed + weak @ predicted_cov @ weak.T
            self._searching = False
            if info.degenerate:
                self._axes = weak_axes(info)
        self._step_pending()
        if not reason and not info.degenerate and not np.any(self._offset):
            self._axes = np.zeros((2, 0))       # observed and converged: ordinary again
        self.information = info
        weak = weak_description(info.weak, self.pose, info.length) \
            if info is not None and not reason else ''
        return Update(self.estimate, self.map_to_odom, self.published_covariance(self.covariance),
                      predicted, not reason, inliers, len(pts), reason, weak, self.pose,
                      float(np.hypot(*self._offset)))
