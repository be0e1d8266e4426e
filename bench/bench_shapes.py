#!/usr/bin/python3
"""Shapes: how well detection places boxes, tables and chairs (and the cylinders among them) in
the furnished worlds, with the tiago laser profile.

Worlds room_furniture and lab_mixed (its walkers left out: people are measured apart), 30 seeded
random reachable poses each (bench_detection's sampler: clear of everything, at least one
movable obstacle in view), one scan with 0.01 m range noise and the tiago laser model, and the
per-beam median of 5 such scans (as the service combines them at rest), placed with the exact
pose (no pose correction: the figures are the shape fits', not the localisation's).

Per object in view (tiago_nav_tools.evaluate.inview), by shape: the detections are matched to
the objects in view as the evaluator matches them (tiago_nav_tools.evaluate.matching: one to
one, least total distance, within 0.3 m); found once (matched to a detection of its shape, box
-> rectangle, table/chair -> legs, cylinder -> circle), found as something else (matched to
another shape), missed; centre error; orientation error; whether its 95 %
ellipse holds the error, and the mean normalised squared error (NEES, 2 when the covariance is
exact). The rules (labels, orientation periods, where the targets apply) are
the evaluator's, tiago_nav_tools.evaluate.shapes: orientation of the length modulo 180 deg, 90
deg for a square and for a box whose length the detection does not claim (one face, or a face
that may go on); the targets (centre <= 3 cm, orientation <= 5 deg) apply where two faces of a
box are seen whole (the noise-free cast's hits span 90 % of each) or three legs of a table or
chair (2 hits each). Detections matching no object are false positives. Writes bench/results/shapes.json and
shapes.png.

Usage: bench/bench_shapes.py [--poses 30] [--seed 7]
"""
import argparse
import json
import math
import os
import sys

import numpy as np
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, 'src'))
sys.path.insert(0, os.path.join(ROOT, 'bench'))

from bench_detection import sample_poses  # noqa: E402
from tiago_nav_tools.benchmarks import meta  # noqa: E402
from tiago_nav_tools.evaluate.inview import view_from  # noqa: E402
from tiago_nav.detection import DetectionParams, ObstacleDetector  # noqa: E402
from tiago_nav.geometry import compose, inverse  # noqa: E402
from tiago_nav.scan import median_ranges  # noqa: E402
from tiago_nav_tools.evaluate import inview  # noqa: E402
from tiago_nav_tools.evaluate.matching import MATCH_GATE, match_obstacles  # noqa: E402
from tiago_nav_tools.evaluate.shapes import (EXPECT, TARGET_CENTRE, TARGET_ORIENTATION,  # noqa: E402
                                             length_claimed, orientation_error, seen_parts)
from tiago_nav.sim.laser import LaserModel  # noqa: E402
from tiago_nav.sim.raster import rasterise_world  # noqa: E402
from tiago_nav.sim.scene import LaserConfig, Scene  # noqa: E402
from tiago_nav.sim.world import World  # noqa: E402

WORLDS = ('room_furniture', 'lab_mixed')
NOISE = 0.01
REST = 5
GATE = 0.1                    # [m] an unmatched detection this near an object (+ its radius)
                              # out of view is a glimpse of it, not a false positive
CHI2_2_95 = 5.991


def load(name):
    with open(os.path.join(ROOT, 'worlds', name + '.yaml')) as f:
        data = yaml.safe_load(f)
    data.pop('walkers', None)
    return World.from_dict(data, source=name)


def run(poses_n, seed):
    cfg = LaserConfig()
    model = LaserModel(laser_model='tiago')
    rows, fps = [], []
    for name in WORLDS:
        w = load(name)
        grid = rasterise_world(w)
        det = ObstacleDetector(grid, DetectionParams(correct_pose=False, shapes=True))
        rng = np.random.default_rng(seed)
        poses, _ = sample_poses(w, grid, poses_n, rng, max_tries=40 * poses_n)
        with Scene(w) as scene:
            for k, pose in enumerate(poses):
                clean, ids = scene.cast(pose)
                laser = scene.laser_pose(pose)
                in_base = compose(inverse(pose), laser)
                visible = set(view_from(scene, pose, 'tiago').in_view)
                ang = cfg.angles() + laser[2]
                pts = np.column_stack((laser[0] + clean * np.cos(ang), laser[1] + clean * np.sin(ang)))
                usable = np.abs(cfg.angles()) <= inview.usable_angle('tiago')
                scans = [model.apply(clean, cfg, NOISE, rng).ranges for _ in range(REST)]
                for mode, ranges in (('one scan', scans[0]),
                                     ('median of 5', median_ranges(scans, cfg.range_min, cfg.range_max))):
                    found = det.detect(ranges, cfg.angle_min, cfg.angle_increment, cfg.range_min,
                                       cfg.range_max, laser, laser_in_base=in_base)
                    # the evaluator's matching: one to one, least total distance, within the gate
                    vis = sorted(visible)
                    pairs, _, _ = match_obstacles(
                        [(w.movable_obstacles[i].x, w.movable_obstacles[i].y) for i in vis],
                        [d.center for d in found])
                    paired = {vis[a]: (j, e) for a, j, e in pairs}
                    used = {j for j, _ in paired.values()}
                    for i in vis:
                        obj = w.movable_obstacles[i]
                        hit = pts[(ids == scene.movable_ids[i]) & usable & np.isfinite(clean)]
                        parts = seen_parts(obj, hit)
                        row = {'world': name, 'pose': k, 'mode': mode, 'shape': obj.shape,
                               'object': i, 'seen_parts': parts,
                               'target_applies': (obj.shape == 'box' and parts >= 2)
                               or (obj.shape in ('table', 'chair') and parts >= 3)}
                        if i not in paired:
                            row['found'] = 'missed'
                        elif found[paired[i][0]].shape != EXPECT[obj.shape]:
                            row['found'] = 'as ' + found[paired[i][0]].shape
                        else:
                            j, e = paired[i]
                            d = found[j]
                            err = np.array([d.center[0] - obj.x, d.center[1] - obj.y])
                            cov = d.center_covariance
                            nees = float(err @ np.linalg.solve(cov, err)) \
                                if np.all(np.isfinite(cov)) and np.linalg.det(cov) > 0 else None
                            # more of the same shape within the gate, matched to nothing
                            dup = sum(1 for m, o in enumerate(found) if m not in used
                                      and o.shape == d.shape and math.hypot(
                                          o.center[0] - obj.x, o.center[1] - obj.y) <= MATCH_GATE)
                            row.update(found='once', centre_error_m=round(float(e), 4),
                                       orientation_error_deg=orientation_error(
                                           d.orientation, obj,
                                           length_claimed(d.extent, d.center_fixed)),
                                       center_fixed=bool(d.center_fixed),
                                       nees=None if nees is None else round(nees, 3),
                                       inside_95=None if nees is None else nees <= CHI2_2_95,
                                       duplicates=dup)
                        rows.append(row)
                    for j, d in enumerate(found):
                        if j in used:
                            continue
                        # near an object out of view (glimpsed) is not false; beside one in
                        # view, matched to another detection or not, it is
                        if any(math.hypot(d.center[0] - o.x, d.center[1] - o.y) <= o.radius + GATE
                               for i, o in enumerate(w.movable_obstacles) if i not in visible):
                            continue
                        fps.append({'world': name, 'pose': k, 'mode': mode, 'shape': d.shape,
                                    'center': [round(v, 3) for v in d.center], 'note': d.note})
    return rows, fps


def stats(rows):
    e = np.array([r['centre_error_m'] for r in rows if r.get('found') == 'once'])
    o = np.array([r['orientation_error_deg'] for r in rows
                  if r.get('found') == 'once' and r.get('orientation_error_deg') is not None])
    inside = [r['inside_95'] for r in rows if r.get('inside_95') is not None]
    out = {'objects': len(rows), 'found_once': int(sum(r.get('found') == 'once' for r in rows)),
           'found_as_other': int(sum(str(r.get('found')).startswith('as ') for r in rows)),
           'missed': int(sum(r.get('found') == 'missed' for r in rows))}
    if e.size:
        out.update(centre_rms_m=round(float(np.sqrt(np.mean(e ** 2))), 4),
                   centre_p95_m=round(float(np.percentile(e, 95)), 4),
                   centre_max_m=round(float(e.max()), 4),
                   within_3cm=round(float(np.mean(e <= TARGET_CENTRE)), 4))
    if o.size:
        out.update(orientation_p95_deg=round(float(np.percentile(o, 95)), 2),
                   orientation_max_deg=round(float(o.max()), 2),
                   within_5deg=round(float(np.mean(o <= TARGET_ORIENTATION)), 4))
    if inside:
        out['inside_95_ellipse'] = round(float(np.mean(inside)), 4)
        out['mean_nees'] = round(float(np.mean([r['nees'] for r in rows
                                                if r.get('nees') is not None])), 3)
    return out


def plot(rows, path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    for shape in ('box', 'table', 'chair', 'cylinder'):
        sel = [r for r in rows if r['shape'] == shape and r.get('found') == 'once'
               and r['mode'] == 'median of 5' and (r['target_applies'] or shape == 'cylinder')]
        if sel:
            ax[0].hist([100 * r['centre_error_m'] for r in sel], bins=30, range=(0, 6),
                       histtype='step', label='%s (%d)' % (shape, len(sel)))
            o = [r['orientation_error_deg'] for r in sel if r['orientation_error_deg'] is not None]
            if o:
                ax[1].hist(o, bins=30, range=(0, 10), histtype='step', label='%s (%d)' % (shape, len(o)))
    ax[0].axvline(100 * TARGET_CENTRE, color='k', ls='--')
    ax[1].axvline(TARGET_ORIENTATION, color='k', ls='--')
    ax[0].set_xlabel('centre error [cm] (two faces / three legs seen)')
    ax[1].set_xlabel('orientation error [deg]')
    for a in ax:
        a.set_ylabel('objects')
        a.legend()
    fig.suptitle('Shapes, tiago laser, median of 5 scans at rest, exact pose')
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--poses', type=int, default=30)
    ap.add_argument('--seed', type=int, default=7)
    args = ap.parse_args()
    rows, fps = run(args.poses, args.seed)
    summary = {}
    for mode in ('one scan', 'median of 5'):
        m = [r for r in rows if r['mode'] == mode]
        summary[mode] = {
            'targets_apply': {s: stats([r for r in m if r['shape'] == s and r['target_applies']])
                              for s in ('box', 'table', 'chair')},
            'all_in_view': {s: stats([r for r in m if r['shape'] == s])
                            for s in ('box', 'table', 'chair', 'cylinder')},
            'false_positives': sum(f['mode'] == mode for f in fps),
            'center_not_fixed_when_target_applies': sum(
                1 for r in m if r['target_applies'] and r.get('found') == 'once'
                and not r['center_fixed'])}
    out = {'worlds': list(WORLDS), 'noise_m': NOISE, 'rest_scans': REST,
           'targets': {'centre_m': TARGET_CENTRE, 'orientation_deg': TARGET_ORIENTATION},
           'summary': summary, 'false_positives': fps[:30], 'rows': rows}
    out['meta'] = meta(vars(args), laser_model='tiago')
    os.makedirs(os.path.join(ROOT, 'bench', 'results'), exist_ok=True)
    path = os.path.join(ROOT, 'bench', 'results', 'shapes.json')
    with open(path, 'w') as f:
        json.dump(out, f, indent=1)
    plot(rows, os.path.join(ROOT, 'bench', 'results', 'shapes.png'))
    print(json.dumps(summary, indent=1))
    print('wrote', path)


if __name__ == '__main__':
    main()
