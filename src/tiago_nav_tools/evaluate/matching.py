"""Judging a mission against the world's ground truth: which movable obstacles the robot could
see, how the found centres match them, random reachable goals, and a picture of a run. Used by
scripts/run_demo.py, bench/bench_mission.py and the mission rostests; no ROS needed.

Everything is in the map (= world) frame, metres; yaw in radians unless a name says ``_deg``.
"""
import math

import numpy as np
from scipy.optimize import linear_sum_assignment

from tiago_nav_tools.evaluate.inview import truth

MATCH_GATE = 0.30      # [m] a found centre farther than this from every true one is a false positive


def visible_truth(world, base_pose, profile='tiago'):
    """``(index, x, y, radius)`` of the world's movable obstacles in view from ``base_pose``
    ``(x, y, yaw)`` for the laser ``profile``: the one definition of "in view",
    :mod:`tiago_nav_tools.evaluate.inview` (``tiago``: beams beyond the real laser's self-hit angle do not
    count; ``ideal``: its whole fan does)."""
    return truth(world, base_pose, profile)[0]


def match_obstacles(true_xy, found_xy, gate=MATCH_GATE):
    """One-to-one matching of found centres to true ones minimising the total distance
    (Hungarian), pairs farther than ``gate`` [m] discarded.

    Returns ``(pairs, missed, false_positives)``: ``pairs`` a list of ``(i_true, j_found,
    error [m])``, ``missed`` the unmatched true indices, ``false_positives`` the unmatched found
    indices.
    """
    t = np.asarray(true_xy, dtype=float).reshape(-1, 2)
    f = np.asarray(found_xy, dtype=float).reshape(-1, 2)
    pairs = []
    if len(t) and len(f):
        d = np.hypot(t[:, None, 0] - f[None, :, 0], t[:, None, 1] - f[None, :, 1])
        rows, cols = linear_sum_assignment(d)
        pairs = [(int(i), int(j), float(d[i, j])) for i, j in zip(rows, cols) if d[i, j] <= gate]
    mt = {i for i, _, _ in pairs}
    mf = {j for _, j, _ in pairs}
    return (sorted(pairs), [i for i in range(len(t)) if i not in mt],
            [j for j in range(len(f)) if j not in mf])


def score(true_xy, found_xy, gate=MATCH_GATE):
    """Summary of a detection against the truth: dict with ``true``, ``found``, ``matched``,
    ``recall`` (1.0 when nothing is to be found), ``false_positives``, ``rms_error``,
    ``max_error`` [m] (None without matches) and the ``pairs``."""
    pairs, missed, fps = match_obstacles(true_xy, found_xy, gate)
    errs = [e for _, _, e in pairs]
    n_true = len(np.asarray(true_xy).reshape(-1, 2))
    return {'true': n_true, 'found': len(np.asarray(found_xy).reshape(-1, 2)),
            'matched': len(pairs), 'recall': len(pairs) / n_true if n_true else 1.0,
            'false_positives': len(fps), 'missed': missed, 'false_positive_indices': fps,
            'rms_error': math.sqrt(sum(e * e for e in errs) / len(errs)) if errs else None,
            'max_error': max(errs) if errs else None, 'pairs': pairs}


def truth_table(truth, found_xy, gate=MATCH_GATE):
    """A printable comparison of the ground truth with the found centres.

    Args:
        truth: rows ``(world index, x, y, radius)`` of :func:`visible_truth`.
        found_xy: found centres ``(x, y)`` [m].
        gate: matching gate [m] (:func:`match_obstacles`).

    Returns ``(lines, score)``: the table's lines and the :func:`score` dict.
    """
    s = score([(x, y) for _, x, y, _ in truth], found_xy, gate)
    by_true = {i: (j, e) for i, j, e in s['pairs']}
    lines = ['ground truth (movable obstacles in laser view) vs found:',
             ' world#  true x  true y  found#  found x  found y  error [m]',
             ' ------  ------  ------  ------  -------  -------  ---------']
    for k, (i, x, y, _) in enumerate(truth):
        if k in by_true:
            j, e = by_true[k]
            fx, fy = found_xy[j]
            lines.append(' %6d  %6.2f  %6.2f  %6d  %7.2f  %7.2f  %9.3f' % (i, x, y, j + 1, fx, fy, e))
        else:
            lines.append(' %6d  %6.2f  %6.2f  %6s  %7s  %7s  %9s' % (i, x, y, '-', '-', '-', 'MISSED'))
    for j in s['false_positive_indices']:
        fx, fy = found_xy[j]
        lines.append(' %6s  %6s  %6s  %6d  %7.2f  %7.2f  %9s' % ('-', '-', '-', j + 1, fx, fy,
                                                                   'FALSE POS.'))
    lines.append('recall %d/%d, false positives %d, RMS error %s, max error %s' % (
        s['matched'], s['true'], s['false_positives'],
        '%.3f m' % s['rms_error'] if s['rms_error'] is not None else '-',
        '%.3f m' % s['max_error'] if s['max_error'] is not None else '-'))
    return lines, s


def sample_goals(world, n, rng, start=None, clearance=0.65, passage=0.35, min_distance=2.0):
    """Random reachable poses B for missions in ``world``.

    Args:
        world: a :class:`tiago_nav.sim.world.World`.
        n: how many goals.
        rng: a seeded ``numpy.random.Generator``.
        start: ``(x, y, ...)`` the missions start from [m] (default: the world's start).
        clearance: each goal is at least this far [m] from the static map's occupied cells
            and from every movable obstacle.
        passage: ... and reachable from ``start`` through space at least this far [m] from
            anything.
        min_distance: each goal is at least this far [m] from the previous one.

    Returns up to ``n`` tuples ``(x, y, yaw_deg)``, each facing a random movable obstacle
    (±30 deg) so that something is usually in view; fewer when the space runs out.
    """
    from scipy import ndimage
    from tiago_nav.sim.raster import rasterise_world
    grid = rasterise_world(world)
    dist = grid.distance_field()
    centres = np.stack(grid.cell_centres(), axis=-1)             # (rows, cols, 2) [m]
    to_movable = np.full(dist.shape, np.inf)
    for c in world.movable_obstacles:
        to_movable = np.minimum(to_movable, c.distance(centres[..., 0], centres[..., 1]))
    clear = np.minimum(dist, to_movable)
    labels, _ = ndimage.label((clear >= passage) & (grid.data == 0))
    sx, sy = (start or world.start_pose)[:2]
    (r0, c0), = grid.world_to_cell([[sx, sy]])
    if not labels[r0, c0]:            # the start may sit closer than ``passage`` to something
        rr, cc = np.nonzero(labels)
        k = np.argmin((rr - r0) ** 2 + (cc - c0) ** 2)
        r0, c0 = rr[k], cc[k]
    cells = np.argwhere((labels == labels[r0, c0]) & (clear >= clearance))
    if not len(cells):
        return []
    goals, prev = [], (sx, sy)
    for _ in range(100 * n):
        if len(goals) == n:
            break
        r, c = cells[rng.integers(len(cells))]
        x, y = centres[r, c]
        if math.hypot(x - prev[0], y - prev[1]) < min_distance:
            continue
        if world.movable_obstacles:
            o = world.movable_obstacles[rng.integers(len(world.movable_obstacles))]
            yaw = math.degrees(math.atan2(o.y - y, o.x - x)) + rng.uniform(-30, 30)
        else:
            yaw = rng.uniform(-180, 180)
        yaw = (yaw + 180.0) % 360.0 - 180.0
        goals.append((round(float(x), 3), round(float(y), 3), round(float(yaw), 1)))
        prev = (x, y)
    return goals


def plot_run(path_png, grid, world, robot_path, scan_xy, truth, found_xy, goal=None, title=''):
    """Write a PNG of a run.

    Args:
        path_png: the file to write.
        grid: the static map (:class:`tiago_nav.gridmap.GridMap`) or None.
        world: the world (its movable obstacles are drawn grey, dashed).
        robot_path: the robot's poses ``(x, y, ...)`` [m] in order.
        scan_xy: the final scan's points ``(x, y)`` [m] in map, or None.
        truth: :func:`visible_truth` rows, drawn green.
        found_xy: the found centres, drawn as red crosses.
        goal: pose B ``(x, y, yaw)`` [m, m, rad], drawn as an arrow, or None.
        title: the figure's title.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Polygon

    fig, ax = plt.subplots(figsize=(10, 6))
    if grid is not None:
        xmin, ymin, xmax, ymax = grid.bounds
        img = np.where(grid.data == 100, 0.15, np.where(grid.data == 0, 1.0, 0.75))
        ax.imshow(img, cmap='gray', vmin=0, vmax=1, origin='lower', extent=(xmin, xmax, ymin, ymax))
    for c in world.movable_obstacles:
        if c.shape == 'cylinder':
            ax.add_patch(Circle((c.x, c.y), c.radius, fill=False, ec='0.5', ls='--', lw=1))
        else:
            ax.add_patch(Polygon(c.outline(), closed=True, fill=False, ec='0.5', ls='--', lw=1))
            for lx, ly in c.legs():
                ax.add_patch(Circle((lx, ly), c.leg_radius, fill=True, fc='0.5', ec='none'))
    for k, wk in enumerate(world.walkers):
        path = np.array(wk.path + ((wk.path[0],) if wk.loop else ()))
        ax.plot(path[:, 0], path[:, 1], '--', color='tab:brown', lw=0.8,
                label='walker paths' if k == 0 else None)
    for _, x, y, r in truth:
        ax.add_patch(Circle((x, y), r, fill=False, ec='tab:green', lw=2))
    if len(robot_path):
        p = np.asarray(robot_path)
        ax.plot(p[:, 0], p[:, 1], '-', color='tab:blue', lw=1.5, label='robot path')
        ax.plot(p[0, 0], p[0, 1], 'o', color='tab:blue', ms=6)
    if scan_xy is not None and len(scan_xy):
        s = np.asarray(scan_xy)
        ax.plot(s[:, 0], s[:, 1], '.', color='tab:orange', ms=2, label='final scan')
    if len(found_xy):
        f = np.asarray(found_xy)
        ax.plot(f[:, 0], f[:, 1], 'x', color='tab:red', ms=9, mew=2, label='found centres')
    if goal is not None:
        gx, gy, gyaw = goal
        ax.arrow(gx, gy, 0.5 * math.cos(gyaw), 0.5 * math.sin(gyaw), width=0.04, color='tab:purple')
        ax.plot([], [], color='tab:purple', label='pose B')
    ax.plot([], [], color='tab:green', label='in view (truth)')
    ax.plot([], [], color='0.5', ls='--', label='other movable obstacles')
    ax.set_aspect('equal')
    ax.set_xlabel('x [m] (map)')
    ax.set_ylabel('y [m] (map)')
    ax.set_title(title)
    ax.legend(loc='upper left', bbox_to_anchor=(1.01, 1.0), fontsize=8)
    fig.tight_layout()
    fig.savefig(path_png, dpi=110)
    plt.close(fig)
