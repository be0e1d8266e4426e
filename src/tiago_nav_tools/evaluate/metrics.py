"""The evaluator's metrics, each defined once (no ROS). Lengths in metres, times in seconds.

Per run: :func:`success`, :func:`path_length`, :func:`spl`, :func:`barn_score`,
:func:`min_clearance`, :func:`detection` (recall, false positives, centre RMS through
:func:`tiago_nav_tools.evaluate.matching.score`; the shapes' scores in
:mod:`tiago_nav_tools.evaluate.shapes`), :func:`percentile` (localisation error),
:func:`ratio` (simulated/wall), :func:`shortest_path_length` (the SPL's and BARN's reference);
among walkers :func:`closest_walker`, :func:`waiting_time` and :func:`walker_reports`.
Over runs: :func:`wilson` (a rate's 95 % interval), :func:`mcnemar_exact` (paired successes),
:func:`paired_difference` (a paired metric's mean difference and its 95 % interval),
:func:`median`.
"""
import bisect
import math

import numpy as np

ROBOT_RADIUS = 0.27     # [m] the base's footprint (config/simulator.yaml robot_radius)
MAX_SPEED = 1.0         # [m/s] the base's speed limit (config/navigation.yaml max_vel_x)
WALKER_GAP = 0.3        # [m] the least gap the base's body must keep to a walker's legs
GHOST_AGE = 2.0         # [s] the oldest a ghost may grow after the laser saw its place free
STILL = 0.02            # [m/s] and [rad/s]: a base slower than this in both stands still
GOAL_ZONE = 0.15        # [m] standing still this near pose B is not waiting
BOUND_CHI2 = 13.816     # the 99.9 % ellipse of a 2-D Gaussian (chi-squared, 2 degrees of freedom)
PERSON_WINDOW = 5.0     # [s] a report is a walker's when it lies within MATCH_GATE of where the
                        # walker was in the mission's last PERSON_WINDOW (the scans at rest)


def success(outcome):
    """1 for a succeeded run, 0 otherwise."""
    return 1 if outcome == 'succeeded' else 0


def path_length(points):
    """Length of the polyline ``points`` ``(x, y, ...)``: the sum of its segments."""
    p = np.asarray([q[:2] for q in points], dtype=float).reshape(-1, 2)
    return float(np.sum(np.hypot(*np.diff(p, axis=0).T))) if len(p) > 1 else 0.0


def spl(succeeded, shortest, driven):
    """Success weighted by path length (Anderson et al. 2018): ``S * l / max(l, p)`` with
    ``l`` the shortest path's length and ``p`` the driven one."""
    if not succeeded:
        return 0.0
    d = max(shortest, driven)
    return 1.0 if d <= 0 else shortest / d


def barn_score(succeeded, optimal_time, time):
    """BARN challenge score: ``S * OT / clip(T, 2 OT, 8 OT)`` with ``OT`` the optimal time
    (shortest path / speed limit) and ``T`` the time taken; at most 0.5."""
    if not succeeded or optimal_time <= 0:
        return 0.0
    return optimal_time / min(max(time, 2.0 * optimal_time), 8.0 * optimal_time)


def ratio(a, b):
    """``a / b``, None when ``b`` is 0 or either is None."""
    return None if a is None or not b else a / b


def percentile(values, q):
    """The ``q``-th percentile (0-100) of ``values`` as the nearest rank (a value that was
    measured), None for no values."""
    v = sorted(values)
    if not v:
        return None
    k = max(0, int(math.ceil(q / 100.0 * len(v))) - 1)
    return float(v[k])


def median(values):
    v = [x for x in values if x is not None]
    return float(np.median(v)) if v else None


def obstacle_distance_field(world, include_movable=True):
    """``(grid, distance)``: the world's static raster and, per cell centre, the distance [m]
    to the nearest static cell or (with ``include_movable``) movable obstacle's surface."""
    from tiago_nav.gridmap import distance_to_mask
    from tiago_nav.sim.raster import rasterise_world
    grid = rasterise_world(world)
    dist = distance_to_mask(grid.occupied(), grid.resolution)
    if include_movable and world.movable_obstacles:
        cx, cy = grid.cell_centres()
        for c in world.movable_obstacles:
            dist = np.minimum(dist, c.distance(cx, cy))
    return grid, dist


def min_clearance(points, world, robot_radius=ROBOT_RADIUS):
    """Least gap [m] between the robot's footprint (a disc of ``robot_radius`` about each pose
    of ``points``) and the nearest wall or cylinder of ``world``, exact
    (:func:`tiago_nav.sim.world.clearance`); None without points."""
    from tiago_nav.sim.world import clearance
    return clearance(world, points, robot_radius)


def shortest_path_length(world, start_xy, goal_xy, robot_radius=ROBOT_RADIUS):
    """Length [m] of the shortest collision-free path of the robot's centre from ``start_xy``
    to ``goal_xy`` around the static map and the movable cylinders (8-connected grid search
    on cells at least ``robot_radius`` from everything, then straightened by line of sight);
    None when the goal cannot be reached."""
    from tiago_nav.nav.planner import PlanError, grid_path, shortcut
    grid, dist = obstacle_distance_field(world)
    free = dist >= robot_radius
    (s,), (g,) = grid.world_to_cell([start_xy[:2]]), grid.world_to_cell([goal_xy[:2]])
    if not (grid.in_bounds([s])[0] and grid.in_bounds([g])[0]):
        return None
    free[g[0], g[1]] = True
    cost = np.where(free, 0, 254).astype(np.uint8)
    try:
        cells = grid_path(cost, tuple(s), tuple(g), cost_weight=0.0, passable=free)
    except PlanError:
        return None
    cells = shortcut(cells, cost, tolerance=0)
    pts = grid.cell_to_world(cells)
    pts[0], pts[-1] = start_xy[:2], goal_xy[:2]
    return path_length(pts)


def detection_score(truth_xy, found_xy, glimpsed_xy=()):
    """:func:`tiago_nav_tools.evaluate.matching.score` of the found centres against the obstacles in
    view ``truth_xy`` and the glimpsed ones ``glimpsed_xy`` (:mod:`tiago_nav_tools.evaluate.inview`:
    reached by a beam but not in view), matched one-to-one over both (Hungarian). A centre
    matched to a glimpsed obstacle is neither a false positive nor required; its error counts
    like any other. ``true``, ``matched``, ``recall``, ``missed``: over the ones in view;
    ``glimpsed``, ``matched_glimpsed``: the glimpsed ones and how many were found;
    ``rms_error``, ``max_error`` [m] and ``errors``: over every matched obstacle, rows
    ``{'index', 'in_view', 'found', 'error'}`` (``index`` into ``truth_xy`` + ``glimpsed_xy``,
    ``found`` into ``found_xy``)."""
    from tiago_nav_tools.evaluate.matching import match_obstacles
    t = [tuple(p[:2]) for p in truth_xy]
    g = [tuple(p[:2]) for p in glimpsed_xy]
    f = [tuple(p[:2]) for p in found_xy]
    every, missed, fps = match_obstacles(t + g, f)
    pairs = [(i, j, e) for i, j, e in every if i < len(t)]
    errs = [e for _, _, e in every]
    return {'true': len(t), 'found': len(f), 'matched': len(pairs),
            'recall': len(pairs) / len(t) if t else 1.0, 'false_positives': len(fps),
            'missed': [i for i in missed if i < len(t)], 'false_positive_indices': fps,
            'glimpsed': len(g), 'matched_glimpsed': len(every) - len(pairs),
            'errors': [{'index': i, 'in_view': i < len(t), 'found': j, 'error': e}
                       for i, j, e in every],
            'rms_error': math.sqrt(sum(e * e for e in errs) / len(errs)) if errs else None,
            'max_error': max(errs) if errs else None, 'pairs': pairs}


def outside_bound(true_xy, found_xy, covariance, chi2=BOUND_CHI2):
    """Whether the true centre ``true_xy`` lies outside the 99.9 % ellipse (``chi2``: the
    squared Mahalanobis distance at 2 degrees of freedom) of a reported centre ``found_xy``
    with its 2x2 ``covariance`` [m²] (row-major list or array); a covariance that is not
    finite and positive definite bounds nothing (outside)."""
    c = np.asarray(covariance, dtype=float).reshape(2, 2)
    v = np.asarray(true_xy, dtype=float)[:2] - np.asarray(found_xy, dtype=float)[:2]
    if not np.all(np.isfinite(c)) or np.linalg.det(c) <= 0 or c[0, 0] <= 0:
        return True
    return float(v @ np.linalg.solve(c, v)) > chi2


def detection(truth_xy, found_xy, tolerance, glimpsed_xy=(), walkers=None, bounds=None):
    """Judge a detection against the ground truth (:mod:`tiago_nav_tools.evaluate.inview`): ``(ok,
    figures)`` with ``ok`` false when one in view is missed, one found is not there (a false
    positive: matching neither one in view nor a glimpsed one, ``glimpsed_xy``) or a matched
    centre, in view or glimpsed, is farther than ``tolerance`` [m] (a centre reported is a
    claim, wherever it came from). ``figures``: ``in_view``, ``glimpsed``, ``found``,
    ``matched`` (in view), ``matched_glimpsed``, ``missed`` (in view, not found), recall,
    false_positives, rms_error, max_error (every matched obstacle), ``errors`` (each matched
    obstacle's, :func:`detection_score`) and ``problem`` (a sentence, '' when ok).
    ``walkers`` (:func:`walker_reports`: found index -> reported as a person): a found centre
    that matches no obstacle but a walker is no false positive; it is counted in
    ``walkers_reported`` when reported as a person and in ``walkers_static`` (a failure: a
    walker reported as a static obstacle) when not. ``bounds`` (found index -> its 2x2
    covariance [m²]): the centres the detection said it could not fix (``center_fixed``
    false: a box seen on one face, a leg partly hidden), each judged by the bound it claims
    (:func:`outside_bound`: the true centre inside the 99.9 % ellipse) instead of
    ``tolerance``; ``bounded`` counts the matched ones, ``bounded_outside`` those beyond their
    bound (a failure). Their errors stay in the RMS and maximum."""
    s = detection_score(truth_xy, found_xy, glimpsed_xy)
    bounds = bounds or {}
    every = list(truth_xy) + list(glimpsed_xy)
    bounded = [e for e in s['errors'] if e['found'] in bounds]
    outside = [e for e in bounded if outside_bound(every[e['index']], found_xy[e['found']],
                                                   bounds[e['found']])]
    fixed = [e for e in s['errors'] if e['found'] not in bounds]
    walkers = walkers or {}
    unmatched = s['false_positive_indices']
    fps = [j for j in unmatched if j not in walkers]
    people = [j for j in unmatched if walkers.get(j) is True]
    static = [j for j in unmatched if walkers.get(j) is False]
    problems = []
    if s['matched'] < s['true']:
        problems.append('missed %d of %d obstacles in view' % (s['true'] - s['matched'], s['true']))
    if fps:
        problems.append('%d false positive(s)' % len(fps))
    if static:
        problems.append('%d obstacle(s) reported where a walker was, not as a person' % len(static))
    worst = max(fixed, key=lambda e: e['error']) if fixed else None
    if worst is not None and worst['error'] > tolerance:
        problems.append('centre error %.3f m > %.3f m%s' % (
            worst['error'], tolerance, '' if worst['in_view'] else ' (a glimpsed obstacle)'))
    if outside:
        far = max(outside, key=lambda e: e['error'])
        problems.append('%d centre(s) not fixed and outside their reported bound (%.3f m off)'
                        % (len(outside), far['error']))
    return not problems, {'recall': s['recall'], 'false_positives': len(fps),
                          'walkers_reported': len(people), 'walkers_static': len(static),
                          'bounded': len(bounded), 'bounded_outside': len(outside),
                          'rms_error': s['rms_error'], 'max_error': s['max_error'],
                          'in_view': s['true'], 'glimpsed': s['glimpsed'], 'found': s['found'],
                          'matched': s['matched'], 'matched_glimpsed': s['matched_glimpsed'],
                          'missed': s['true'] - s['matched'], 'errors': s['errors'],
                          'problem': '; '.join(problems)}


def closest_walker(truth, walkers, robot_radius=ROBOT_RADIUS):
    """Least gap [m] between the base's footprint (a disc of ``robot_radius`` about its true
    pose) and a walker's leg (a disc of the walker's leg radius) over a mission: ``truth`` rows
    ``[t, x, y, yaw, v, w]`` (every ground-truth pose, time-ordered), ``walkers`` rows ``[t,
    [walker, ...]]`` with each walker ``[x, y, vx, vy, leg_radius, [[x, y], ...] legs,
    state]`` (the simulator's /sim/objects); each walkers row is compared with the newest true
    pose not after it. None without both."""
    if not truth or not walkers:
        return None
    times = [row[0] for row in truth]
    best = math.inf
    for t, people in walkers:
        k = max(0, bisect.bisect_right(times, t + 1e-9) - 1)
        x, y = truth[k][1], truth[k][2]
        for w in people:
            legs = np.asarray(w[5], dtype=float).reshape(-1, 2)
            if len(legs):
                gap = float(np.min(np.hypot(legs[:, 0] - x, legs[:, 1] - y))) - robot_radius - w[4]
                best = min(best, gap)
    return None if best == math.inf else best


def waiting_time(truth, goal_xy, still=STILL, zone=GOAL_ZONE):
    """Simulated time [s] the base stood still (true speed under ``still`` m/s and turn rate
    under ``still`` rad/s) farther than ``zone`` [m] from ``goal_xy``: each interval between
    two ``truth`` rows (``[t, x, y, yaw, v, w]``) counts when its first row stands still
    there."""
    total = 0.0
    for a, b in zip(truth, truth[1:]):
        if abs(a[4]) < still and abs(a[5]) < still and \
                math.hypot(a[1] - goal_xy[0], a[2] - goal_xy[1]) > zone:
            total += b[0] - a[0]
    return total


def is_person_report(detail):
    """Does a reported tiago_nav/Obstacle (as a dict) say it is a person: seen ``moving`` or
    labelled ``legs``? Anything else is a claim of a static obstacle."""
    return (detail or {}).get('motion') == 'moving' or (detail or {}).get('shape') == 'legs'


def walker_reports(found_xy, details, walkers, end, window=PERSON_WINDOW, gate=None):
    """Which reported obstacles are walkers: ``{j: is_person_report}`` for each index ``j`` of
    ``found_xy`` whose centre lies within ``gate`` [m] (default the matching gate) of a walker's
    centre at some time in ``[end - window, end]`` (``walkers`` as in
    :func:`closest_walker`; ``details`` the reported messages as dicts, same order)."""
    from tiago_nav_tools.evaluate.matching import MATCH_GATE
    gate = MATCH_GATE if gate is None else gate
    pts = np.asarray([w[:2] for t, people in walkers if end - window <= t <= end for w in people],
                     dtype=float).reshape(-1, 2)
    out = {}
    if not len(pts):
        return out
    for j, (x, y) in enumerate(found_xy):
        if float(np.min(np.hypot(pts[:, 0] - x, pts[:, 1] - y))) <= gate:
            out[j] = is_person_report(details[j] if j < len(details) else None)
    return out


def wilson(k, n, z=1.959963984540054):
    """Wilson score interval ``(low, high)`` of the rate ``k / n`` (95 % by default);
    ``(0, 1)`` for ``n = 0``."""
    if n <= 0:
        return 0.0, 1.0
    p = k / n
    d = 1.0 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return max(0.0, c - h), min(1.0, c + h)


def mcnemar_exact(b, c):
    """Two-sided exact McNemar test of paired successes: ``b`` pairs where only the first
    succeeded, ``c`` where only the second did. Returns the p-value
    ``min(1, 2 * P[X <= min(b, c)])`` for ``X ~ Binomial(b + c, 1/2)``; 1 when ``b + c = 0``."""
    n = b + c
    if n == 0:
        return 1.0
    k = min(b, c)
    tail = sum(math.comb(n, i) for i in range(k + 1)) / 2.0 ** n
    return min(1.0, 2.0 * tail)


def paired_difference(a, b, confidence=0.95):
    """Mean of ``a[i] - b[i]`` over pairs where both are known, with its Student-t interval:
    ``{'n', 'mean', 'low', 'high'}`` (interval None for fewer than 2 pairs)."""
    d = [x - y for x, y in zip(a, b) if x is not None and y is not None]
    if not d:
        return {'n': 0, 'mean': None, 'low': None, 'high': None}
    m = float(np.mean(d))
    if len(d) < 2:
        return {'n': 1, 'mean': m, 'low': None, 'high': None}
    from scipy.stats import t
    h = float(t.ppf(0.5 + confidence / 2, len(d) - 1) * np.std(d, ddof=1) / math.sqrt(len(d)))
    return {'n': len(d), 'mean': m, 'low': m - h, 'high': m + h}
