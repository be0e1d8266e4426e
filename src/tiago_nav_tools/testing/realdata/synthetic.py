"""A synthetic building as large as a big real one, for what grows with the map (memory, the
time to take a map in): ``SIZE_M`` × ``SIZE_M`` at 0.05 m (2000 × 2000 cells for 100 m),
10 m rooms with 0.2 m walls and a 1.2 m door in the middle of every wall between two rooms,
a few boxes per room (seeded) so that rooms differ, and a log driven through a row of rooms
(door to door, straight along the rooms' centres): 180 beams over 180° ray-cast in the map
(no return beyond :data:`MAX_RANGE`, range noise ``N(0, 0.01)``), a scan every
:data:`STEP_M`, one a second.

:func:`prepare` writes what :func:`tiago_nav_tools.testing.realdata.convert.prepare` writes for a
real log (map, per scenario a bag and a reference), the map being the generated one instead
of one built from the scans (the whole building, not only what the log saw). Only the
``tracking`` scenario (started on the reference).
"""
import json
import os

import numpy as np

from tiago_nav.gridmap import FREE, OCCUPIED, GridMap
from tiago_nav_tools.testing.realdata import mapping, odometry
from tiago_nav_tools.testing.realdata.carmen import CarmenLog, beam_angles
from tiago_nav_tools.testing.realdata.convert import (FORMAT_VERSION, Scenario, cached_info,
                                                      write_reference)

NAME = 'synthetic-100m'
SIZE_M = 100.0          # [m] the building's side
ROOM_M = 10.0           # [m] a room's side
WALL_M = 0.2            # [m] wall thickness
DOOR_M = 1.2            # [m] door width
RESOLUTION = 0.05       # [m]
MAX_RANGE = 30.0        # [m] no return beyond
STEP_M = 0.7            # [m] between scans
BEAMS = 180
SEED = 0


def building(size=SIZE_M, room=ROOM_M, seed=SEED, resolution=RESOLUTION):
    """The building's :class:`GridMap` (origin (0, 0), every cell known: walls and boxes
    occupied, the rest free)."""
    n = int(round(size / resolution))
    x = (np.arange(n) + 0.5) * resolution
    xx, yy = np.meshgrid(x, x)
    occ = np.zeros((n, n), dtype=bool)
    k = int(round(size / room))
    for i in range(k + 1):
        w = i * room
        # walls along x at y = w and along y at x = w, each with a door in the middle of every
        # room's side (outer walls closed)
        for a, b in ((yy, xx), (xx, yy)):
            on = np.abs(a - w) <= WALL_M / 2
            if 0 < i < k:
                door = np.abs(np.mod(b, room) - room / 2) <= DOOR_M / 2
                on &= ~door
            occ |= on
    rng = np.random.default_rng(seed)
    for cx in range(k):
        for cy in range(k):
            for _ in range(3):          # boxes away from the doors' line through the centres
                w, h = rng.uniform(0.4, 1.5, 2)
                bx = cx * room + rng.choice([rng.uniform(1.0, 3.5), rng.uniform(6.5, 9.0)])
                by = cy * room + rng.choice([rng.uniform(1.0, 3.5), rng.uniform(6.5, 9.0)])
                occ |= (np.abs(xx - bx) <= w / 2) & (np.abs(yy - by) <= h / 2)
    data = np.where(occ, OCCUPIED, FREE).astype(np.int8)
    return GridMap(data, resolution, (0.0, 0.0))


def route(size=SIZE_M, room=ROOM_M, step=STEP_M):
    """``(N, 3)`` poses along the first row of rooms, through their doors, facing the way."""
    x = np.arange(room / 2, size - room / 2 + 1e-9, step)
    return np.column_stack((x, np.full_like(x, room / 2), np.zeros_like(x)))


def cast(grid, poses, angles, max_range=MAX_RANGE, noise=0.01, seed=SEED):
    """``(N, n)`` ranges [m] of beams at ``angles`` from ``poses`` to the first occupied cell
    (marched every quarter cell; ``inf`` beyond ``max_range``), plus ``N(0, noise)``."""
    rng = np.random.default_rng(seed)
    occ = grid.occupied()
    steps = np.arange(0.0, max_range, grid.resolution / 4)
    out = np.full((len(poses), len(angles)), np.inf)
    for k, (px, py, pyaw) in enumerate(poses):
        a = pyaw + angles
        xs = px + np.cos(a)[:, None] * steps[None, :]
        ys = py + np.sin(a)[:, None] * steps[None, :]
        rc = grid.world_to_cell(np.column_stack((xs.ravel(), ys.ravel())))
        inside = grid.in_bounds(rc)
        hit = np.ones(len(rc), dtype=bool)      # outside the grid: a hit (nothing beyond)
        hit[inside] = occ[rc[inside, 0], rc[inside, 1]]
        hit = hit.reshape(xs.shape)
        first = np.argmax(hit, axis=1)
        found = hit[np.arange(len(angles)), first]
        out[k, found] = steps[first[found]] + rng.normal(0.0, noise, int(found.sum()))
    return out


def log(grid, seed=SEED):
    """The :class:`CarmenLog` driven along :func:`route` in ``grid``."""
    poses = route()
    angles = beam_angles(BEAMS)
    times = 1.0 + np.arange(len(poses), dtype=float)
    return CarmenLog(times, poses, cast(grid, poses, angles, seed=seed), 0, NAME)


def prepare(out_dir, scenarios=('tracking',), seed=SEED, bags=True):
    """As :func:`tiago_nav_tools.testing.realdata.convert.prepare` for the synthetic building (files
    already there from the same seed and code are kept)."""
    bad = [s for s in scenarios if s != 'tracking']
    if bad:
        raise ValueError('the synthetic building has only the tracking scenario, not %s'
                         % ', '.join(bad))
    os.makedirs(out_dir, exist_ok=True)
    info_path = os.path.join(out_dir, 'info.json')
    key = {'log': NAME, 'seed': seed, 'version': FORMAT_VERSION, 'size_m': SIZE_M}
    info = cached_info(info_path, key)
    map_yaml = os.path.join(out_dir, 'map.yaml')
    ref = os.path.join(out_dir, 'tracking_reference.csv')
    bag = os.path.join(out_dir, 'tracking.bag')
    grid = building(seed=seed)
    lg = log(grid, seed)
    if not info or not os.path.exists(map_yaml) or not os.path.exists(ref) \
            or (bags and not os.path.exists(bag)):
        mapping.save_map(grid, map_yaml)
        sc = Scenario('tracking', lg, odometry.synthesise(lg.poses, seed),
                      tuple(float(v) for v in lg.poses[0]))
        write_reference(ref, sc)
        if bags:
            from tiago_nav_tools.testing.realdata.bag import write_bag
            write_bag(bag + '.part', sc.log, sc.odom)
            os.replace(bag + '.part', bag)
        info = {'key': key}
    with open(info_path, 'w') as f:
        json.dump(info, f)
    return {'map': map_yaml,
            'log': {'name': NAME, 'scans': len(lg), 'beams': lg.beams,
                    'path_m': lg.path_length(), 'duration_s': float(lg.times[-1] - lg.times[0]),
                    'repaired_times': 0, 'map_cells': int(grid.data.size),
                    'map_size_m': [SIZE_M, SIZE_M]},
            'tracking': {'bag': bag if bags else None, 'reference': ref,
                         'start': [float(v) for v in lg.poses[0]], 'event': None,
                         'scans': len(lg), 'duration_s': float(lg.times[-1] - lg.times[0]),
                         'last_stamp': float(lg.times[-1])}}
