#!/usr/bin/python3
"""The same scan under the ``ideal`` and ``tiago`` laser models, from the course world's pose B
(11, 0, -45 deg), zoomed where the tiago model's effects show: the robot's own body (self-hits,
and the consumers' self-filter), a depth edge (mixed pixels) and dropouts (NaN, more at grazing
incidence, counted over many scans).

Writes bench/results/laser_models.png (and prints the effect counts of the scan).
Usage: bench/plot_laser_models.py [--seed N]
"""
import argparse
import math
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if os.path.join(ROOT, 'src') not in sys.path:
    sys.path.append(os.path.join(ROOT, 'src'))
RESULTS = os.path.join(ROOT, 'bench', 'results')

from tiago_nav.geometry import transform_points  # noqa: E402
from tiago_nav.robot import ROBOT_RADIUS  # noqa: E402
from tiago_nav.scan import BODY_MARGIN, body_returns  # noqa: E402
from tiago_nav.sim.laser import DROPOUT, MIXED, SELF_HIT, LaserModel, incidence_angles  # noqa: E402
from tiago_nav.sim.scene import LaserConfig, Scene  # noqa: E402
from tiago_nav.sim.world import load_world  # noqa: E402

POSE_B = (11.0, 0.0, math.radians(-45.0))
CORRIDOR = (1.5, 0.0, 0.0)    # in the corridor, 4.8 m from its end: its walls meet many beams at grazing incidence
NOISE = 0.01            # [m] the simulator's default laser_noise
DROPOUT_SCANS = 1500    # scans averaged for the dropout-rate panel (100 s at 15 Hz)


def points(laser_pose, ranges, angles):
    """Map-frame points of the finite ranges, and their beam indices."""
    idx = np.flatnonzero(np.isfinite(ranges))
    r, a = ranges[idx], angles[idx]
    return transform_points(laser_pose, np.column_stack((r * np.cos(a), r * np.sin(a)))), idx


def draw_world(ax, world):
    for w in world.walls:
        c = np.vstack((w.corners(), w.corners()[:1]))
        ax.fill(c[:, 0], c[:, 1], color='0.8', zorder=0)
    for c in list(world.static_cylinders) + list(world.movable_obstacles):
        ax.add_patch(_circle((c.x, c.y), c.radius, fill=True, color='0.85', zorder=0))


def _circle(xy, r, **kw):
    from matplotlib.patches import Circle
    return Circle(xy, r, **kw)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--seed', type=int, default=1)
    args = ap.parse_args()
    world = load_world(os.path.join(ROOT, 'worlds', 'ias_lab_room_full.yaml'))
    laser = LaserConfig()
    angles = laser.angles()
    with Scene(world, robot_radius=ROBOT_RADIUS, laser=laser) as scene:
        exact, ids = scene.cast(POSE_B)
        corridor, _ = scene.cast(CORRIDOR)
        laser_pose = scene.laser_pose(POSE_B)
        movable = set(scene.movable_ids)
    ideal = LaserModel(laser_model='ideal').apply(exact, laser, NOISE, np.random.default_rng(args.seed))
    tiago = LaserModel().apply(exact, laser, NOISE, np.random.default_rng(args.seed))
    counts = {name: int((tiago.effect == e).sum())
              for name, e in (('self_hits', SELF_HIT), ('mixed', MIXED), ('dropouts', DROPOUT))}
    print('tiago scan from pose B: %s' % counts)

    rng = np.random.default_rng(args.seed + 1)
    dropout_rates = []          # (incidence [deg], dropout fraction) of the beams that hit
    for cast in (exact, corridor):
        dropped = np.zeros(laser.num_beams)
        for _ in range(DROPOUT_SCANS):
            dropped += np.isnan(LaserModel().apply(cast, laser, NOISE, rng).ranges)
        hit = np.isfinite(cast)
        dropout_rates.append((np.degrees(incidence_angles(cast, angles))[hit],
                              dropped[hit] / DROPOUT_SCANS))

    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(2, 2, figsize=(13, 11))
    ip, _ = points(laser_pose, ideal.ranges, angles)
    tp, tidx = points(laser_pose, tiago.ranges, angles)
    colours = {SELF_HIT: ('red', 'self-hit (robot body)'), MIXED: ('darkorange', 'mixed pixel')}

    def scatter(ax, size):
        draw_world(ax, world)
        ax.add_patch(_circle(POSE_B[:2], ROBOT_RADIUS, fill=False, color='b', lw=1.5,
                             label='footprint r = %.2f m' % ROBOT_RADIUS))
        ax.add_patch(_circle(POSE_B[:2], ROBOT_RADIUS + BODY_MARGIN, fill=False, color='b', ls=':',
                             label='self-filter (footprint + %.2f m)' % BODY_MARGIN))
        ax.plot(ip[:, 0], ip[:, 1], '.', color='0.3', ms=size, label='ideal')
        plain = ~np.isin(tiago.effect[tidx], list(colours))
        ax.plot(tp[plain, 0], tp[plain, 1], '.', color='tab:green', ms=size, label='tiago')
        for e, (c, label) in colours.items():
            m = tiago.effect[tidx] == e
            ax.plot(tp[m, 0], tp[m, 1], 'o', color=c, ms=size + 2, mfc='none', label=label)
        nan = np.isnan(tiago.ranges)
        dp, _ = points(laser_pose, np.where(nan, exact, np.inf), angles)
        ax.plot(dp[:, 0], dp[:, 1], 'kx', ms=size + 4, label='dropout (NaN; ideal point shown)')
        ax.set_aspect('equal')

    ax = axes[0, 0]
    scatter(ax, 2)
    ax.set_title('pose B (11, 0, -45°): the whole scan, map frame\n'
                 'tiago: %d self-hits, %d mixed pixels, %d dropout(s) in this scan' %
                 (counts['self_hits'], counts['mixed'], counts['dropouts']))
    ax.set_xlim(POSE_B[0] - 2.5, POSE_B[0] + 6.5)
    ax.set_ylim(POSE_B[1] - 7, POSE_B[1] + 2.5)
    ax.legend(loc='lower left', fontsize=8)

    ax = axes[0, 1]
    scatter(ax, 5)
    body = body_returns(tiago.ranges, angles, (laser.offset, 0.0, 0.0))
    for k in np.flatnonzero(tiago.effect == SELF_HIT):
        end = transform_points(laser_pose, np.array([[tiago.ranges[k] * math.cos(angles[k]),
                                                      tiago.ranges[k] * math.sin(angles[k])]]))[0]
        ax.plot([laser_pose[0], end[0]], [laser_pose[1], end[1]], color='red', lw=0.3)
    ax.plot(*laser_pose[:2], 'k^', ms=8, label='laser')
    ax.legend(loc='lower right', fontsize=8)
    ax.set_title('the robot\'s own body: %d beams at each end of the fan hit the shell;\n'
                 'scan.body_returns drops %d beams (every self-hit, no wall)'
                 % (counts['self_hits'] // 2, int(body.sum())))
    ax.set_xlim(POSE_B[0] - 0.6, POSE_B[0] + 0.6)
    ax.set_ylim(POSE_B[1] - 0.6, POSE_B[1] + 0.6)

    ax = axes[1, 0]
    scatter(ax, 6)
    # the mixed pixel at an obstacle's edge with the smallest jump (the clearest zoom)
    jump = np.abs(np.diff(exact))
    best = None
    for i in np.flatnonzero(tiago.effect == MIXED):
        for j in (i - 1, i + 1):
            if 0 <= j < ids.size and (ids[i] in movable or ids[j] in movable) and \
                    jump[min(i, j)] > 0.3 and (best is None or jump[min(i, j)] < best[0]):
                best = (jump[min(i, j)], i, j)
    _, i, j = best
    near_far = transform_points(laser_pose, np.array(
        [[exact[k] * math.cos(angles[k]), exact[k] * math.sin(angles[k])] for k in (i, j)]))
    mixed_pt = transform_points(laser_pose, np.array([[tiago.ranges[i] * math.cos(angles[i]),
                                                       tiago.ranges[i] * math.sin(angles[i])]]))
    box = np.vstack((near_far, mixed_pt))
    for end in near_far:
        ax.plot([laser_pose[0], end[0]], [laser_pose[1], end[1]], color='darkorange', lw=0.5)
    lo, hi = box.min(axis=0) - 0.4, box.max(axis=0) + 0.4
    half = (hi - lo).max() / 2
    mid = (lo + hi) / 2
    ax.set_xlim(mid[0] - half, mid[0] + half)
    ax.set_ylim(mid[1] - half, mid[1] + half)
    ax.set_title('a depth edge (beam %d): the straddling beam returns a range\n'
                 'between the near and far surface (ideal: %.3f m, tiago: %.3f m)'
                 % (i, ideal.ranges[i], tiago.ranges[i]))

    ax = axes[1, 1]
    m = LaserModel()
    for (inc, rate), c, where in zip(dropout_rates, ('tab:red', 'tab:purple'),
                                     ('pose B', 'the corridor (1.5, 0, 0°)')):
        ax.plot(inc, 100 * rate, '.', color=c, ms=4,
                label='measured per beam, %d scans from %s' % (DROPOUT_SCANS, where))
    ax.step([0, m.grazing_angle, 90], [100 * m.dropout_rate, 100 * m.grazing_dropout_rate,
                                       100 * m.grazing_dropout_rate],
            where='post', color='k', label='model: dropout_rate, grazing_dropout_rate')
    ax.set_xlabel('incidence of the beam from the surface normal [deg] (from neighbouring beams)')
    ax.set_ylabel('dropouts (NaN) [% of scans]')
    ax.set_xlim(0, 90)
    ax.legend(loc='upper left', fontsize=8)
    ax.set_title('dropouts: %.1f %% at ordinary incidence, %.1f %% beyond %g° (grazing)'
                 % (100 * m.dropout_rate, 100 * m.grazing_dropout_rate, m.grazing_angle))
    fig.tight_layout()
    os.makedirs(RESULTS, exist_ok=True)
    path = os.path.join(RESULTS, 'laser_models.png')
    fig.savefig(path, dpi=80)
    print('wrote %s' % path)


if __name__ == '__main__':
    main()
