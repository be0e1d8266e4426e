#!/usr/bin/python3
"""People's legs on real laser data: leg_tracker's recordings (../shared/data/real/, BSD
3-Clause, see LICENSE.leg_tracker there).

1. The marked bags (``legs_positive_{1,2,3,4}_extracted.bag``: 750 scans of a robot's laser,
   each leg cluster marked by hand on ``/leg_cluster_positions``, 1-4 a scan; every other cluster
   is not a person). These recordings have no map, so everything is treated as unmapped: the
   detection's pipeline (tiago_nav.detection.ObstacleDetector, its default parameters, no pose
   correction) runs on each scan over an empty map in the laser's frame. Recall: the share of
   marked leg clusters within 0.15 m of a leg of an object the detection labels ``legs``.
   Precision: the share of the ``legs`` objects with a leg within 0.15 m of a marked leg; both
   for the people-sized ``legs`` objects (the ones the detection calls a person) and for every
   ``legs`` object (tables' and chairs' too, which these rooms have).
2. The demo (``legs_demo_stationary_simple_environment.bag``: 126 s, a laser standing still
   while people walk past): the service's own decisions (tiago_nav.detection.service, through a
   sensors object that serves the bag's scans, the laser standing at the origin) on every 10th
   scan, each combined with the 4 before it (``rest_scans`` 5, 0.4 s at 10 Hz). The static
   background is built from the scans over time: the per-beam median of the whole recording. A
   reported object whose points lie at least 0.3 m in front of that background on most of their
   beams is a person passing (nothing else moves there); of those, how many are reported
   ``moving`` and how many ``static`` (the target: none).

The constants are the detection's, chosen from leg physics (tiago_nav.detection.shapes), not
from these files. Writes bench/results/legs_real.json and legs_real.png.

Usage: bench/bench_legs_real.py [--data ../shared/data/real] [--every 10]
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
from tiago_nav.gridmap import GridMap  # noqa: E402

MARKED = ['legs_positive_%d_extracted.bag' % k for k in (1, 2, 3, 4)]
DEMO = 'legs_demo_stationary_simple_environment.bag'
NEAR = 0.15           # [m] a marked leg and a detected leg match within this
FOREGROUND = 0.3      # [m] in front of the background by this: something that is not always there
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


def marked(data):
    per_bag = []
    legs_all, found_all = [], []
    for name in MARKED:
        msgs = read(os.path.join(data, name), ['/training_scan', '/leg_cluster_positions'])
        det = None
        marks = None
        n_marked = n_hit = n_obj = n_obj_ok = n_any = n_any_ok = scans = 0
        n_hit_centre = 0
        for topic, msg in msgs:
            if topic == '/leg_cluster_positions':
                marks = np.array([(p.position.x, p.position.y) for p in msg.poses]).reshape(-1, 2)
                continue
            if marks is None:
                continue                 # a scan without its marks (they come just before)
            if det is None:
                det = ObstacleDetector(empty_map(msg.range_max + 0.5),
                                       DetectionParams(correct_pose=False, shapes=True))
            found = det.detect(np.asarray(msg.ranges, dtype=float), msg.angle_min,
                               msg.angle_increment, msg.range_min, msg.range_max,
                               (0.0, 0.0, 0.0))
            legs = [d for d in found if d.shape == 'legs']
            people = [d for d in legs if d.kind == 'person']
            scans += 1

            def near_leg(m, objs):
                return any(np.min(np.hypot(*(d.legs - m).T)) <= NEAR for d in objs)

            for m in marks:
                n_marked += 1
                n_hit += near_leg(m, legs)
                n_hit_centre += any(math.hypot(d.center[0] - m[0], d.center[1] - m[1]) <= NEAR
                                    for d in legs)
            for d in people:
                n_obj += 1
                n_obj_ok += bool(len(marks)) and float(np.min(
                    np.hypot(d.legs[:, None, 0] - marks[None, :, 0],
                             d.legs[:, None, 1] - marks[None, :, 1]))) <= NEAR
            for d in legs:
                n_any += 1
                n_any_ok += bool(len(marks)) and float(np.min(
                    np.hypot(d.legs[:, None, 0] - marks[None, :, 0],
                             d.legs[:, None, 1] - marks[None, :, 1]))) <= NEAR
            legs_all.append(marks)
            found_all.append([(d.shape, d.kind, list(d.center)) for d in found])
            marks = None
        per_bag.append({'bag': name, 'scans': scans, 'marked_legs': n_marked,
                        'recall': round(n_hit / max(n_marked, 1), 4),
                        'recall_by_object_centre': round(n_hit_centre / max(n_marked, 1), 4),
                        'person_objects': n_obj,
                        'precision_person': round(n_obj_ok / max(n_obj, 1), 4),
                        'legs_objects': n_any,
                        'precision_all_legs': round(n_any_ok / max(n_any, 1), 4),
                        '_counts': (n_marked, n_hit, n_obj, n_obj_ok, n_any, n_any_ok,
                                    n_hit_centre)})
    tot = np.sum([b.pop('_counts') for b in per_bag], axis=0)
    overall = {'marked_legs': int(tot[0]), 'recall': round(tot[1] / max(tot[0], 1), 4),
               'recall_by_object_centre': round(tot[6] / max(tot[0], 1), 4),
               'person_objects': int(tot[2]), 'precision_person': round(tot[3] / max(tot[2], 1), 4),
               'legs_objects': int(tot[4]), 'precision_all_legs': round(tot[5] / max(tot[4], 1), 4)}
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
    from tiago_nav.scan import Scan
    from tiago_nav.nodes.obstacle_detection import Params
    msgs = read(os.path.join(data, DEMO), ['/scan'])
    scans = [Scan(tuple(m.ranges), m.angle_min, m.angle_increment, m.range_min, m.range_max,
                  m.header.stamp.to_sec(), 'laser') for _, m in msgs]
    r = np.array([s.ranges for s in scans], dtype=float)
    r[(r < scans[0].range_min) | (r > scans[0].range_max)] = np.nan
    background = np.nanmedian(r, axis=0)
    background[np.isnan(background)] = np.inf
    first = scans[0]
    service = DetectionService(Params(detection=DetectionParams(correct_pose=False, shapes=True)))
    service.set_map(empty_map(first.range_max + 0.5))
    counts = {'calls': 0, 'objects': 0, 'foreground': 0, 'foreground_moving': 0,
              'foreground_static': 0, 'foreground_unknown': 0, 'foreground_legs': 0,
              'foreground_legs_moving': 0, 'foreground_legs_static': 0,
              'moving_with_velocity': 0, 'failures': 0}
    speeds, static_examples = [], []
    for i in range(4, len(scans), every):
        a = service.handle('', 0.0, 0.0, BagSensors(scans, i), scan_stamp=scans[i].stamp)
        if not a.success:
            counts['failures'] += 1
            continue
        counts['calls'] += 1
        for o in a.obstacles:
            counts['objects'] += 1
            # the object's beams: those whose ray passes within its extent of its centre
            ang = math.atan2(o.center[1], o.center[0])
            rng = math.hypot(*o.center)
            j = int(round((ang - first.angle_min) / first.angle_increment))
            half = max(1, int(math.ceil(0.1 / max(rng, 0.1) / first.angle_increment)))
            beams = range(max(0, j - half), min(len(background), j + half + 1))
            front = [rng + 0.1 < background[b] - FOREGROUND for b in beams]
            if not front or np.mean(front) < 0.5:
                continue
            counts['foreground'] += 1
            key = {'moving': 'foreground_moving', 'static': 'foreground_static'}.get(
                o.motion, 'foreground_unknown')
            counts[key] += 1
            if o.shape == 'legs':
                counts['foreground_legs'] += 1
                if o.motion in ('moving', 'static'):
                    counts['foreground_legs_' + o.motion] += 1
            if o.motion == 'moving' and all(math.isfinite(v) for v in o.velocity):
                counts['moving_with_velocity'] += 1
                speeds.append(math.hypot(*o.velocity))
            if o.motion == 'static' and len(static_examples) < 20:
                static_examples.append({'scan': i, 'shape': o.shape,
                                        'center': [round(v, 3) for v in o.center],
                                        'note': o.note})
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
    names = [b['bag'].replace('legs_positive_', '').replace('_extracted.bag', '') for b in per_bag]
    x = np.arange(len(names))
    ax[0].bar(x - 0.2, [b['recall'] for b in per_bag], 0.4, label='recall')
    ax[0].bar(x + 0.2, [b['precision_person'] for b in per_bag], 0.4, label='precision (people)')
    ax[0].axhline(TARGET, color='k', ls='--')
    ax[0].set_xticks(x)
    ax[0].set_xticklabels(['bag %s' % n for n in names])
    ax[0].set_ylim(0, 1.05)
    ax[0].legend(loc='lower right')
    ax[0].set_title('marked legs: recall %.0f %%, precision %.0f %%'
                    % (100 * overall['recall'], 100 * overall['precision_person']))
    if speeds:
        ax[1].hist(speeds, bins=30, range=(0, 3))
    ax[1].set_xlabel('speed of what is reported moving [m/s] (demo)')
    ax[1].set_ylabel('objects')
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--data', default=os.path.join(ROOT, '..', 'shared', 'data', 'real'))
    ap.add_argument('--every', type=int, default=10, help='demo: a call every this many scans')
    args = ap.parse_args()
    if not os.path.isdir(args.data):
        sys.exit('no %s: the leg_tracker recordings are needed' % args.data)
    per_bag, overall = marked(args.data)
    print('marked:', json.dumps(overall))
    counts, speeds = demo(args.data, args.every)
    print('demo:', json.dumps({k: v for k, v in counts.items() if k != 'static_examples'}))
    out = {'near_m': NEAR, 'target': TARGET, 'marked': overall,
           'marked_per_bag': per_bag, 'demo': counts}
    out['meta'] = meta(vars(args))
    path = os.path.join(ROOT, 'bench', 'results', 'legs_real.json')
    with open(path, 'w') as f:
        json.dump(out, f, indent=1)
    plot(per_bag, overall, speeds, os.path.join(ROOT, 'bench', 'results', 'legs_real.png'))
    print('wrote', path)


if __name__ == '__main__':
    main()
