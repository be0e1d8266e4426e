"""A log turned into what a robot gives its localisation: the map, the odometry, the reference
and (with ROS) the bag, for each way of starting a run.

Scenarios (:data:`SCENARIOS`), all with odometry from :func:`tiago_nav_tools.testing.realdata.odometry.synthesise`:

- ``tracking``: the whole log, the node started at the reference's first pose;
- ``offset``: the same, started :data:`OFFSET_M` to the left of it and turned
  :data:`OFFSET_DEG`;
- ``kidnap``: the robot carried :data:`KIDNAP_M` in one step at :data:`KIDNAP_AT` of the log
  (the scans in between dropped, the odometry reporting no motion there);
- ``global``: the whole log, ``/global_localization`` called before it plays.

Files in ``out_dir``: ``map.yaml`` + ``map.pgm`` (every scan at its reference pose, 0.05 m), and
per scenario ``<scenario>.bag`` and ``<scenario>_reference.csv`` (time [s], reference x, y, yaw,
odometry x, y, yaw: one row per scan of the bag).
"""
import json
import os

import numpy as np

from tiago_nav_tools.testing.realdata import mapping, odometry
from tiago_nav_tools.testing.realdata.carmen import read_log

SCENARIOS = ('tracking', 'offset', 'kidnap', 'global')
OFFSET_M, OFFSET_DEG = 2.0, 90.0
KIDNAP_M, KIDNAP_AT = 3.0, 0.4
SEED = 0


class Scenario:
    """A run's inputs: ``log`` (its scans), ``odom`` (``(N, 3)``), ``start`` (the pose the node
    is given), ``event`` (the scan index where the kidnap lands, or None)."""

    def __init__(self, name, log, odom, start, event=None):
        self.name, self.log, self.odom, self.start, self.event = name, log, odom, start, event

    def reference_rows(self):
        return np.column_stack((self.log.times, self.log.poses, self.odom))


def scenario(log, name, seed=SEED):
    """The :class:`Scenario` ``name`` of ``log`` (see :data:`SCENARIOS`)."""
    if name not in SCENARIOS:
        raise ValueError('unknown scenario %r (known: %s)' % (name, ', '.join(SCENARIOS)))
    start = tuple(float(v) for v in log.poses[0])
    if name == 'kidnap':
        at = int(KIDNAP_AT * len(log))
        j = odometry.kidnap_index(log.poses, at, KIDNAP_M)
        keep = np.r_[0:at + 1, j:len(log)]
        cut = log.slice(0, len(log))
        cut.times, cut.poses, cut.ranges = log.times[keep], log.poses[keep], log.ranges[keep]
        return Scenario(name, cut, odometry.synthesise(cut.poses, seed, still=(at + 1,)), start,
                        at + 1)
    if name == 'offset':
        start = odometry.offset_pose(start, OFFSET_M, OFFSET_DEG)
    return Scenario(name, log, odometry.synthesise(log.poses, seed), start)


def write_reference(path, sc):
    np.savetxt(path, sc.reference_rows(), fmt='%.6f', delimiter=',',
               header='time_s,ref_x,ref_y,ref_yaw,odom_x,odom_y,odom_yaw')


def read_reference(path):
    """``(times, reference poses, odometry poses)`` of a ``*_reference.csv``."""
    rows = np.loadtxt(path, delimiter=',', ndmin=2)
    return rows[:, 0], rows[:, 1:4], rows[:, 4:7]


def cached_info(info_path, key):
    """What ``info_path`` (an ``info.json``) records of the files beside it, or ``{}`` when it
    is absent or was written for another ``key`` (source, seed, format version)."""
    if not os.path.exists(info_path):
        return {}
    with open(info_path) as f:
        info = json.load(f)
    return info if info.get('key') == key else {}


def prepare(log_path, out_dir, scenarios=SCENARIOS, seed=SEED, bags=True):
    """Write the map and each scenario's reference (and bag, with ``bags``) of the log at
    ``log_path`` into ``out_dir`` (files already there from the same log, seed and code are
    kept: ``info.json`` records what they were made from); returns ``{'map', 'log',
    scenario: {'bag', 'reference', 'start', 'event', 'scans', 'duration_s', 'last_stamp'}}``."""
    os.makedirs(out_dir, exist_ok=True)
    info_path = os.path.join(out_dir, 'info.json')
    stat = os.stat(log_path)
    key = {'log': os.path.abspath(log_path), 'size': stat.st_size, 'seed': seed,
           'version': FORMAT_VERSION}
    info = cached_info(info_path, key)
    log = read_log(log_path)
    map_yaml = os.path.join(out_dir, 'map.yaml')
    if 'map' not in info or not os.path.exists(map_yaml):
        mapping.save_map(mapping.build_grid(log.poses, log.ranges, log.angles()), map_yaml)
        info = {'key': key, 'map': map_yaml}
    out = {'map': map_yaml, 'log': {'name': log.name, 'scans': len(log), 'beams': log.beams,
                                     'path_m': log.path_length(),
                                     'duration_s': float(log.times[-1] - log.times[0]),
                                     'repaired_times': log.repaired}}
    for name in scenarios:
        sc = scenario(log, name, seed)
        ref = os.path.join(out_dir, '%s_reference.csv' % name)
        bag = os.path.join(out_dir, '%s.bag' % name)
        if name not in info or not os.path.exists(ref) or (bags and not os.path.exists(bag)):
            write_reference(ref, sc)
            if bags:
                from tiago_nav_tools.testing.realdata.bag import write_bag
                write_bag(bag + '.part', sc.log, sc.odom)
                os.replace(bag + '.part', bag)
            info[name] = True
        out[name] = {'bag': bag if bags else None, 'reference': ref, 'start': list(sc.start),
                     'event': sc.event, 'scans': len(sc.log),
                     'duration_s': float(sc.log.times[-1] - sc.log.times[0]),
                     'last_stamp': float(sc.log.times[-1])}
    with open(info_path, 'w') as f:
        json.dump(info, f)
    return out


FORMAT_VERSION = 1      # of the files prepare() writes: a change makes it write them again
