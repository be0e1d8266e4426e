#!/usr/bin/python3
"""People's legs on real laser data: leg_tracker's recordings (../shared/data/real/, BSD
3-Clause, see LICENSE.leg_tracker there).

1. The marked bags (``legs_positive_{1,2,3,4}_extracted.bag``: 750 scans of a robot's laser
   standing still, the people's leg clusters marked on ``/leg_cluster_positions``, 1-4 a scan:
   leg_tracker marked every cluster (its 0.13 m Euclidean clustering, 3 points or more, the
   cluster's mean) in a wedge in front of the laser (within 15 deg and 5 m) that people walked
   through; every other cluster is not a person). These recordings have no map. The detection's
   pipeline (tiago_nav.detection.ObstacleDetector, its default parameters with ``shapes`` on,
   no pose correction) runs on each scan in the laser's frame over two maps:

   * ``background`` (the figures the target applies to): the static background built from the
     bag's own scans over time (tiago_nav.detection.background: the farthest range a share of
     each beam's hits gather at), as a standing laser in an unknown room would build it;
   * ``single_scan``: an empty map, everything unmapped (a room's clutter is then unmapped too).

   Recall: the share of marked leg clusters within 0.15 m of a leg of an object the detection
   labels ``legs`` (a person's). Precision: the share of those objects with a leg within 0.15 m
   of a marked leg. The thresholds of the leg classifier are a leg's physics
   (tiago_nav.detection.shapes), not fits to these files; bag 4 (``HELD_OUT``) was kept out of
   the choices made while the classifier was built on bags 1-3, though not out of the rule
   for whole flat runs (a trouser leg), chosen on the misses of all four: its figures are
   reported apart.
   leg_tracker marked every cluster in a region only (``REGION``): the precision is given over
   the whole scan (every unmarked object counts against it, as the target reads) and within
   that region (where every cluster was marked).
2. The demo (``legs_demo_stationary_simple_environment.bag``: 126 s, a laser standing still
   while people walk past): the service's own decisions (tiago_nav.detection.service, through a
   sensors object that serves the bag's scans, the laser standing at the origin) on every
   scan (``--every``: a call every so many scans), each combined with the 4 before it
   (``rest_scans`` 5, 0.4 s at 10 Hz), over the static background built from the whole
   recording (as in 1). A reported object most of whose points
   lie at least 0.3 m in front of their own beam's background (or on a beam with none) is
   something that is not always there; one whose place was seen free (most of its beams past
   it, two scans in a row) both within 1 s before the call and within 1 s after it is a person
   walking past (nothing else moves there); of those, how many are reported ``moving`` and how
   many ``static`` (the target: none).

Writes bench/results/legs_real.json and legs_real.png.

Usage: bench/bench_legs_real.py [--data ../shared/data/real] [--every 1]
"""
import argparse
import json
import math
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.append(os.path.join(ROOT, 'src'))     # after the workspace's (which has the messages)

from tiago_nav_tools.benchmarks import meta  # noqa: E402
from tiago_nav.detection import DetectionParams, ObstacleDetector  # noqa: E402
from tiago_nav.detection.background import background_map, background_ranges  # noqa: E402
from tiago_nav.gridmap import GridMap  # noqa: E402

MARKED = ['legs_positive_%d_extracted.bag' % k for k in (1, 2, 3, 4)]
HELD_OUT = ('legs_positive_4_extracted.bag',)
# where leg_tracker marked every cluster (its launch file
# extract_positive_training_clusters_res=0.33.launch): bearings [deg] and range [m]; outside it
# nothing is marked, so a person walking there (beyond 5 m in the wedge, or beside the robot)
# counts against the precision over the whole scan
REGION = {'legs_positive_1_extracted.bag': (-15.0, 15.0, 5.0),
          'legs_positive_2_extracted.bag': (-15.0, 15.0, 5.0),
          'legs_positive_3_extracted.bag': (-15.0, 15.0, 5.0),
          'legs_positive_4_extracted.bag': (-15.0, 10.0, 5.0)}
DEMO = 'legs_demo_stationary_simple_environment.bag'
NEAR = 0.15           # [m] a marked leg and a detected leg match within this
FOREGROUND = 0.3      # [m] in front of the background by this: something that is not always there
WINDOW = 10           # [scans] the demo: a place seen free within 1 s (10 Hz) of a call: passing
TARGET = 0.85


def empty_map(reach):
    """A map with nothing in it, ``reach`` [m] around the laser (everything is unmapped)."""
    res = 0.05
    n = int(math.ceil(2 * reach / res)) + 2
    return GridMap(np.zeros((n, n), dtype=np.int8), res, (-reach - res, -reach - res))


def read(path, topics):
    import rosbag
    with rosbag.Bag(path) as bag:
        return [(topic, msg) for topic, msg, _ in bag.read_messages(topics=topics)]


def marked_scans(path):
    """The scans of a marked bag with their marks: ``[(LaserScan, (K, 2) marks)]``."""
    out, marks = [], None
    for topic, msg in read(path, ['/training_scan', '/leg_cluster_positions']):
        if topic == '/leg_cluster_positions':
            marks = np.array([(p.position.x, p.position.y) for p in msg.poses]).reshape(-1, 2)
        elif marks is not None:              # a scan with its marks (they come just before)
            out.append((msg, marks))
            marks = None
    return out


def background_grid(scans):
    """The static background of a standing laser's ``scans`` (LaserScan or Scan), as a map."""
    first = scans[0]
    bg = background_ranges([np.asarray(s.ranges, dtype=float) for s in scans],
                           first.range_min, first.range_max)
    return background_map(bg, first.angle_min, first.angle_increment,
                          reach=first.range_max + 0.5), bg


def score(scans, grid, region):
    """Counts ``[marked, marked found, legs objects, legs objects on a mark, legs objects in the
    marked region, of them on a mark]`` of the pipeline on the marked ``scans`` over the map
    ``grid``; ``region``: the marked region's bearings [deg] and range [m]."""
    det = ObstacleDetector(grid, DetectionParams(correct_pose=False, shapes=True))
    n = np.zeros(6, dtype=int)
    for msg, marks in scans:
        found = det.detect(np.asarray(msg.ranges, dtype=float), msg.angle_min,
                           msg.angle_increment, msg.range_min, msg.range_max, (0.0, 0.0, 0.0))
        people = [d for d in found if d.shape == 'legs' and d.kind == 'person']
        for m in marks:
            n[0] += 1
            n[1] += any(np.min(np.hypot(*(d.legs - m).T)) <= NEAR for d in people)
        for d in people:
            ok = bool(len(marks)) and float(np.min(np.hypot(
                d.legs[:, None, 0] - marks[None, :, 0],
                d.legs[:, None, 1] - marks[None, :, 1]))) <= NEAR
            n[2] += 1
            n[3] += ok
            bearing = math.degrees(math.atan2(d.center[1], d.center[0]))
            if region[0] < bearing < region[1] and math.hypot(*d.center) < region[2]:
                n[4] += 1
                n[5] += ok
    return n


def figures(n):
    return {'marked_legs': int(n[0]), 'recall': round(n[1] / max(n[0], 1), 4),
            'legs_objects': int(n[2]), 'precision': round(n[3] / max(n[2], 1), 4),
            'legs_objects_in_marked_region': int(n[4]),
            'precision_in_marked_region': round(n[5] / max(n[4], 1), 4)}


def marked(data):
    """Per bag and over all (and over the bags used to build the classifier and the held-out
    one apart), for each of the two maps (the module's doc)."""
    per_bag, tot = [], {}
    for name in MARKED:
        scans = marked_scans(os.path.join(data, name))
        grid, _ = background_grid([m for m, _ in scans])
        row = {'bag': name, 'scans': len(scans), 'held_out': name in HELD_OUT}
        for mode, g in (('background', grid), ('single_scan', empty_map(scans[0][0].range_max
                                                                         + 0.5))):
            n = score(scans, g, REGION[name])
            row[mode] = figures(n)
            for key in ('all', 'held_out' if name in HELD_OUT else 'built_on'):
                tot[(mode, key)] = tot.get((mode, key), 0) + n
        per_bag.append(row)
        print(json.dumps(row))
    overall = {mode: {key: figures(tot[(mode, key)]) for key in ('all', 'built_on', 'held_out')}
               for mode in ('background', 'single_scan')}
    return per_bag, overall


class BagSensors:
    """The service's sensors (tiago_nav.detection.service) over a list of scans of a laser
    standing at the origin: the map, odom and robot frames all coincide with the laser's."""

    def __init__(self, scans, index):
        self.scans, self.index = scans, index

    def fresh_scan(self, timeout):
        return self.scans[self.index]

    def scan_at(self, stamp, timeout, published=False):
        return self.scans[self.index]

    def scans_before(self, scan, count):
        return self.scans[max(0, self.index - count):self.index][::-1]

    def transform(self, target, source, stamp, timeout):
        return (0.0, 0.0, 0.0)

    def pose_covariance(self, stamp):
        return None


def demo(data, every):
    from tiago_nav.detection.service import DetectionService
    from tiago_nav.detection.motion import beams_of
    from tiago_nav.scan import HIT, Scan, classify, scan_to_points
    from tiago_nav.nodes.obstacle_detection import Params
    msgs = read(os.path.join(data, DEMO), ['/scan'])
    scans = [Scan(tuple(m.ranges), m.angle_min, m.angle_increment, m.range_min, m.range_max,
                  m.header.stamp.to_sec(), 'laser') for _, m in msgs]
    first = scans[0]
    grid, background = background_grid(scans)
    ranges = [np.where(classify(s.ranges, s.range_min, s.range_max) == HIT,
                       np.asarray(s.ranges, dtype=float), np.inf) for s in scans]
    points = [scan_to_points(s.ranges, s.angle_min, s.angle_increment, s.range_min,
                             s.range_max)[0] for s in scans]
    service = DetectionService(Params(detection=DetectionParams(correct_pose=False, shapes=True)))
    service.set_map(grid)
    counts = {'calls': 0, 'objects': 0, 'foreground': 0, 'foreground_moving': 0,
              'foreground_static': 0, 'foreground_unknown': 0, 'foreground_legs': 0,
              'foreground_legs_moving': 0, 'foreground_legs_static': 0,
              'moving_with_velocity': 0, 'failures': 0, 'passing': 0, 'passing_moving': 0,
              'passing_static': 0, 'passing_unknown': 0}
    speeds, static_examples = [], []
    for i in range(4, len(scans), every):
        a = service.handle('', 0.0, 0.0, BagSensors(scans, i), scan_stamp=scans[i].stamp)
        if not a.success:
            counts['failures'] += 1
            continue
        counts['calls'] += 1
        pts_i = points[i]
        for o in a.obstacles:
            counts['objects'] += 1
            # the object's points: the scan's within its size of its centre
            near = np.hypot(pts_i[:, 0] - o.center[0], pts_i[:, 1] - o.center[1]) \
                <= o.radius + 0.05
            pts = pts_i[near]
            if not len(pts):
                continue
            # the object's own points against their beams' background: not always there
            b = beams_of(pts, (0.0, 0.0, 0.0), first.angle_min, first.angle_increment,
                         len(background))
            rng = np.hypot(*pts.T)
            front = ~(rng > background[b] - FOREGROUND)     # NaN background: nothing stays
            if np.mean(front) < 0.5:
                continue
            counts['foreground'] += 1
            key = {'moving': 'foreground_moving', 'static': 'foreground_static'}.get(
                o.motion, 'foreground_unknown')
            counts[key] += 1
            # walking past: its place seen free (most of its beams past it, or no return, in
            # two scans in a row: a dark object's dropout in one scan is no free space) both
            # within WINDOW scans before the call and within WINDOW scans after it
            def free(js):
                seen = [0 <= j < len(scans) and np.mean(~(ranges[j][b] <= rng + FOREGROUND))
                        >= 0.5 for j in js]
                return any(a and c for a, c in zip(seen[:-1], seen[1:]))
            if free(range(i - 4 - WINDOW, i - 4)) and free(range(i + 1, i + 1 + WINDOW)):
                counts['passing'] += 1
                counts['passing_' + (o.motion if o.motion in ('moving', 'static')
                                     else 'unknown')] += 1
                if o.motion == 'static' and len(static_examples) < 20:
                    static_examples.append({'scan': i, 'shape': o.shape,
                                            'center': [round(v, 3) for v in o.center],
                                            'note': o.note})
            if o.shape == 'legs':
                counts['foreground_legs'] += 1
                if o.motion in ('moving', 'static'):
                    counts['foreground_legs_' + o.motion] += 1
            if o.motion == 'moving' and all(math.isfinite(v) for v in o.velocity):
                counts['moving_with_velocity'] += 1
                speeds.append(math.hypot(*o.velocity))
    counts['share_moving_of_foreground'] = round(
        counts['foreground_moving'] / max(counts['foreground'], 1), 4)
    counts['speed_median_m_s'] = round(float(np.median(speeds)), 3) if speeds else None
    counts['speed_p95_m_s'] = round(float(np.percentile(speeds, 95)), 3) if speeds else None
    counts['static_examples'] = static_examples
    return counts, speeds


def plot(per_bag, overall, speeds, path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    names = [b['bag'].replace('legs_positive_', '').replace('_extracted.bag', '')
             + (' (held out)' if b['held_out'] else '') for b in per_bag]
    x = np.arange(len(names))
    for k, (mode, hatch) in enumerate((('background', ''), ('single_scan', '//'))):
        ax[0].bar(x - 0.3 + 0.2 * k, [b[mode]['recall'] for b in per_bag], 0.18,
                  color='C0', hatch=hatch, label='recall, %s' % mode.replace('_', ' '))
        ax[0].bar(x + 0.1 + 0.2 * k, [b[mode]['precision'] for b in per_bag], 0.18,
                  color='C1', hatch=hatch, label='precision, %s' % mode.replace('_', ' '))
    ax[0].axhline(TARGET, color='k', ls='--')
    ax[0].set_xticks(x)
    ax[0].set_xticklabels(['bag %s' % n for n in names], fontsize=8)
    ax[0].set_ylim(0, 1.05)
    ax[0].legend(loc='lower left', fontsize=7)
    o = overall['background']['all']
    ax[0].set_title('marked legs, background: recall %.0f %%, precision %.0f %%'
                    % (100 * o['recall'], 100 * o['precision']), fontsize=10)
    if speeds:
        ax[1].hist(speeds, bins=30, range=(0, 3))
    ax[1].set_xlabel('speed of what is reported moving [m/s] (demo)')
    ax[1].set_ylabel('objects')
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--data', default=os.path.join(ROOT, '..', 'shared', 'data', 'real'))
    ap.add_argument('--every', type=int, default=1, help='demo: a call every this many scans')
    args = ap.parse_args()
    if not os.path.isdir(args.data):
        sys.exit('no %s: the leg_tracker recordings are needed' % args.data)
    per_bag, overall = marked(args.data)
    print('marked:', json.dumps(overall))
    counts, speeds = demo(args.data, args.every)
    print('demo:', json.dumps({k: v for k, v in counts.items() if k != 'static_examples'}))
    out = {'near_m': NEAR, 'target': TARGET, 'held_out': list(HELD_OUT), 'marked': overall,
           'marked_per_bag': per_bag, 'demo': counts}
    out['meta'] = meta(vars(args))
    path = os.path.join(ROOT, 'bench', 'results', 'legs_real.json')
    with open(path, 'w') as f:
        json.dump(out, f, indent=1)
    plot(per_bag, overall, speeds, os.path.join(ROOT, 'bench', 'results', 'legs_real.png'))
    print('wrote', path)


if __name__ == '__main__':
    main()
