#!/usr/bin/python3
"""Obstacle covariance benchmark: is the uncertainty that the detection reports (tiago_nav/
Obstacle's ``center_covariance`` in the map frame, ``center_robot_covariance`` in the robot
frame) the size of the centres' actual errors, over the detections of whole ROS missions?

It reads ``rosrun tiago_nav evaluate`` output folders (``runs/ID/{spec,raw}.json``): by default
it runs ``suites/course.yaml`` and ``suites/robustness.yaml`` itself (``--workers``, ``--warm``);
``--from DIR [DIR ...]`` reads existing ones. Every run of the sensing profile ``--profile``
(``tiago``) whose mission succeeded counts; each reported centre is matched one-to-one to the
world file's movable cylinders (least total distance, within 0.3 m: the evaluator's matching,
glimpsed obstacles included, since their centres carry a covariance too). Per matched centre:

* the map frame's error ``e`` (reported minus true centre) and its normalised squared error
  ``NEES = eᵀ Σ⁻¹ e`` (2 degrees of freedom: its mean is 2 when ``Σ`` is exact, and 95 % of the
  errors lie inside the 95 % ellipse, ``NEES <= 5.99``);
* the same in the robot frame: the reported ``center_robot`` against the true centre in the true
  robot frame at the end of the mission (the base at rest, where the scan was taken), with the
  robot frame's covariance (the fit's alone);
* ``center_std``'s split into the terms of the covariance (``center_variance_terms``: the fit,
  the laser's position, its heading's lever arm, the map raster), and the map frame's NEES with
  the fit's term alone (what the covariance was before the laser pose's terms were added).

Targets (map frame): mean NEES between 1 and 3, at least 93 % of the errors inside the 95 %
ellipse, over at least 300 detections. Writes bench/results/covariance.json and
covariance.png (``--out``).

Usage: bench/bench_covariance.py [--from DIR [DIR ...]] [--suites S ...] [--workers 2] [--warm]
                                 [--profile tiago] [--keep DIR] [--out bench/results/covariance.json]
"""
import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, 'bench', 'results')
SUITES = ('suites/course.yaml', 'suites/robustness.yaml')
CHI2_95 = 5.991         # chi-square quantiles with 2 degrees of freedom
CHI2_999 = 13.816
TERMS = ('fit', 'position', 'heading', 'raster')
TARGET = {'nees_low': 1.0, 'nees_high': 3.0, 'inside_95': 0.93, 'detections': 300}

sys.path.insert(0, os.path.join(ROOT, 'src'))
from tiago_nav_tools.benchmarks import meta  # noqa: E402
from tiago_nav.geometry import compose, inverse  # noqa: E402
from tiago_nav.sim.world import load_world  # noqa: E402
from tiago_nav_tools.evaluate.matching import match_obstacles  # noqa: E402


def nees(err, cov4):
    """``eᵀ Σ⁻¹ e`` of the error ``err`` (2,) [m] for the row-major 2 × 2 ``cov4`` [m²]; None
    when the covariance is not known (non-finite, None or singular)."""
    if cov4 is None or any(v is None or not math.isfinite(v) for v in cov4):
        return None
    c = np.asarray(cov4, dtype=float).reshape(2, 2)
    c = 0.5 * (c + c.T)
    if np.linalg.det(c) <= 0:
        return None
    e = np.asarray(err, dtype=float)
    return float(e @ np.linalg.solve(c, e))


def uncertainty(detail):
    """The centre in the robot frame and the uncertainty fields of one obstacle of
    ``raw.json``'s ``obstacles_detail`` (every field of the tiago_nav/Obstacle message),
    non-finite values as None."""
    def num(v):
        return float(v) if v is not None and math.isfinite(v) else None
    return {'center_robot': [detail['center_robot']['x'], detail['center_robot']['y']],
            'center_std': num(detail.get('center_std')),
            'center_covariance': [num(v) for v in detail.get('center_covariance') or []] or None,
            'center_robot_covariance': [num(v) for v in detail.get('center_robot_covariance') or []]
            or None,
            'center_variance_terms': [num(v) for v in detail.get('center_variance_terms') or []]
            or None}


def run_detections(run_dir, profile):
    """The matched detections of one evaluated run (``runs/ID``): a list of dicts, or None
    when the run does not count (another profile, no raw record, the mission did not
    succeed)."""
    try:
        with open(os.path.join(run_dir, 'spec.json')) as f:
            spec = json.load(f)
        with open(os.path.join(run_dir, 'raw.json')) as f:
            raw = json.load(f)
    except (OSError, ValueError):
        return None
    if spec.get('profile') != profile or raw.get('state') != 3 or not raw.get('final_pose'):
        return None
    found = raw.get('obstacles') or []
    unc = [uncertainty(d) for d in raw.get('obstacles_detail') or []]
    if found and len(unc) != len(found):
        raise ValueError('%s: raw.json has no obstacles_detail (recorded before the '
                         'evaluator kept it): run the suites again' % run_dir)
    world = load_world(spec['world_path'])
    truth = [(c.x, c.y) for c in world.movable_obstacles]
    pairs, _, _ = match_obstacles(truth, [o[:2] for o in found])
    pose = tuple(raw['final_pose'][:3])
    to_robot = inverse(pose)
    out = []
    for i, j, dist in pairs:
        u = unc[j]
        e_map = (found[j][0] - truth[i][0], found[j][1] - truth[i][1])
        tr = compose(to_robot, (truth[i][0], truth[i][1], 0.0))
        e_rob = (u['center_robot'][0] - tr[0], u['center_robot'][1] - tr[1])
        terms = u.get('center_variance_terms') or [None] * 4
        fit_only = None
        cov = u.get('center_covariance')
        if cov and all(v is not None for v in cov) and terms[0] is not None:
            # the fit's term alone in the map frame: the robot frame's covariance rotated back
            c, s = math.cos(pose[2]), math.sin(pose[2])
            rot = np.array([[c, -s], [s, c]])
            rc = u.get('center_robot_covariance')
            if rc and all(v is not None for v in rc):
                fit_only = (rot @ np.asarray(rc, dtype=float).reshape(2, 2) @ rot.T).ravel()
        out.append({'run': os.path.basename(run_dir), 'world': spec['world']['name'],
                    'error_m': dist, 'error_map': e_map, 'error_robot': e_rob,
                    'center_std': u.get('center_std'),
                    'nees_map': nees(e_map, cov),
                    'nees_robot': nees(e_rob, u.get('center_robot_covariance')),
                    'nees_fit_only': nees(e_map, fit_only) if fit_only is not None else None,
                    'terms': terms, 'cov': cov})
    return out


def frame_figures(values):
    """Mean NEES, share inside the 95 % ellipse, exceedances of the 99.9 % bound and the worst,
    of the known ``values``."""
    v = [x for x in values if x is not None]
    if not v:
        return {'n': 0}
    v = np.asarray(v)
    return {'n': int(len(v)), 'mean_nees': round(float(np.mean(v)), 3),
            'median_nees': round(float(np.median(v)), 3),
            'inside_95': round(float(np.mean(v <= CHI2_95)), 4),
            'beyond_999': int(np.sum(v > CHI2_999)), 'max_nees': round(float(np.max(v)), 2)}


def summarise(dets):
    """The benchmark's figures over the matched detections ``dets``."""
    out = {'detections': len(dets), 'map': frame_figures([d['nees_map'] for d in dets]),
           'robot': frame_figures([d['nees_robot'] for d in dets]),
           'map_fit_term_only': frame_figures([d['nees_fit_only'] for d in dets])}
    shares = {k: [] for k in TERMS}
    for d in dets:
        t = d['terms']
        if t and all(x is not None for x in t) and sum(t) > 0:
            for k, x in zip(TERMS, t):
                shares[k].append(x / sum(t))
    out['variance_share_mean'] = {k: round(float(np.mean(v)), 3) if v else None
                                  for k, v in shares.items()}
    errs = [d['error_m'] for d in dets]
    stds = [d['center_std'] for d in dets if d['center_std'] is not None]
    out['error_rms_m'] = round(float(np.sqrt(np.mean(np.square(errs)))), 4) if errs else None
    out['center_std_median_m'] = round(float(np.median(stds)), 4) if stds else None
    m = out['map']
    out['targets_met'] = bool(m.get('n', 0) >= TARGET['detections']
                              and TARGET['nees_low'] <= m.get('mean_nees', 0) <= TARGET['nees_high']
                              and m.get('inside_95', 0) >= TARGET['inside_95'])
    worst = sorted((d for d in dets if d['nees_map'] is not None), key=lambda d: -d['nees_map'])
    out['worst'] = [{'run': d['run'], 'world': d['world'], 'error_m': round(d['error_m'], 4),
                     'center_std_m': d['center_std'] and round(d['center_std'], 4),
                     'nees_map': round(d['nees_map'], 2)} for d in worst[:5]]
    return out


def plot(path, dets, figures):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8))
    for ax, key, title in ((axes[0], 'nees_map', 'map frame'),
                           (axes[1], 'nees_robot', 'robot frame (the fit alone)')):
        covk = 'cov' if key == 'nees_map' else None
        pts = []
        for d in dets:
            if d[key] is None:
                continue
            e = np.asarray(d['error_map'] if key == 'nees_map' else d['error_robot'])
            if covk:
                c = np.asarray(d['cov'], dtype=float).reshape(2, 2)
            else:
                c = None
            if c is not None:
                w, v = np.linalg.eigh(0.5 * (c + c.T))
                pts.append(v.T @ e / np.sqrt(w))      # whitened: a unit circle if exact
            else:
                r = math.sqrt(d[key])
                n = np.linalg.norm(e)
                pts.append(e / n * r if n > 0 else e)
        pts = np.asarray(pts).reshape(-1, 2)
        ax.scatter(pts[:, 0], pts[:, 1], s=6, alpha=0.6)
        t = np.linspace(0, 2 * math.pi, 200)
        rr = math.sqrt(CHI2_95)
        ax.plot(rr * np.cos(t), rr * np.sin(t), 'r-', label='95 % ellipse')
        f = figures['map' if key == 'nees_map' else 'robot']
        ax.set_title('%s\nmean NEES %s, %s inside the 95 %% ellipse (n %s)'
                     % (title, f.get('mean_nees'), '%.1f %%' % (100 * f['inside_95'])
                        if f.get('n') else '–', f.get('n')), fontsize=10)
        ax.set_aspect('equal')
        lim = max(4.0, min(8.0, float(np.abs(pts).max()) if len(pts) else 4.0))
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_xlabel('normalised error (map: whitened; robot: along the error)')
        ax.legend(loc='upper right')
    ax = axes[2]
    shares = figures['variance_share_mean']
    ax.bar(list(shares), [shares[k] or 0 for k in shares])
    ax.set_ylabel('mean share of center_std²')
    ax.set_title('the covariance\'s terms (map frame)')
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def run_suite(suite, out, workers, warm):
    """``rosrun tiago_nav evaluate SUITE --out OUT --workers N [--warm]``."""
    cmd = ['rosrun', 'tiago_nav', 'evaluate', suite, '--out', out, '--workers', str(workers)]
    subprocess.run(cmd + (['--warm'] if warm else []), cwd=ROOT, check=False)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--from', dest='dirs', nargs='+', metavar='DIR',
                    help='evaluate output folders to read (default: run --suites)')
    ap.add_argument('--suites', nargs='+', default=list(SUITES))
    ap.add_argument('--workers', type=int, default=2)
    ap.add_argument('--warm', action='store_true', help='run the suites on warm stacks')
    ap.add_argument('--profile', default='tiago', help='sensing profile whose runs count')
    ap.add_argument('--keep', help='folder for the suites\' outputs (default: a temporary one)')
    ap.add_argument('--out', default=os.path.join(RESULTS, 'covariance.json'))
    args = ap.parse_args(argv)
    dirs, tmp = args.dirs, None
    t0 = time.monotonic()
    if not dirs:
        base = args.keep or tempfile.mkdtemp(prefix='bench_covariance_')
        tmp = None if args.keep else base
        dirs = []
        for s in args.suites:
            d = os.path.join(base, os.path.splitext(os.path.basename(s))[0])
            run_suite(s, d, args.workers, args.warm)
            dirs.append(d)
    dets, runs = [], 0
    for d in dirs:
        rd = os.path.join(d, 'runs')
        for rid in sorted(os.listdir(rd)):
            got = run_detections(os.path.join(rd, rid), args.profile)
            if got is not None:
                runs += 1
                dets += got
    fig = summarise(dets)
    fig['runs'] = runs
    fig['sources'] = [os.path.abspath(d) if args.dirs else os.path.basename(d) for d in dirs]
    fig['target'] = TARGET
    fig['wall_s'] = round(time.monotonic() - t0, 1)
    fig['meta'] = meta(vars(args), laser_model=args.profile, real_time_factor=0)
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, 'w') as f:
        json.dump(fig, f, indent=2)
    png = os.path.splitext(args.out)[0] + '.png'
    plot(png, dets, fig)
    m, r = fig['map'], fig['robot']
    print('%d detections over %d runs (profile %s)' % (len(dets), runs, args.profile))
    for name, f in (('map', m), ('robot', r), ('map, fit term only', fig['map_fit_term_only'])):
        if f.get('n'):
            print('  %-20s mean NEES %.2f (2 exact), %.1f %% inside the 95 %% ellipse, %d beyond '
                  'the 99.9 %% bound (worst %.1f)' % (name, f['mean_nees'], 100 * f['inside_95'],
                                                     f['beyond_999'], f['max_nees']))
    print('  variance shares (map): %s' % ', '.join(
        '%s %s' % (k, v) for k, v in fig['variance_share_mean'].items()))
    print('  centre error RMS %s m, median center_std %s m' % (fig['error_rms_m'],
                                                            fig['center_std_median_m']))
    print('targets (mean NEES 1-3, >= 93 %% inside, >= 300 detections): %s'
          % ('met' if fig['targets_met'] else 'NOT met'))
    print('wrote %s and %s' % (os.path.relpath(args.out), os.path.relpath(png)))
    if tmp:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
