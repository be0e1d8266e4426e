"""The occupancy grid of a building built from its log's scans at their reference poses, and
map_server's YAML + PGM map files (pure numpy).

Each beam with a return marks its end cell hit and the cells it crossed before it passed
(sampled every half cell); a beam with no return marks nothing. A cell is occupied when at least
:data:`HIT_RATIO` of the beams that reached it ended there (so a person walking through a
corridor, seen on few scans and passed through on many, leaves no obstacle), free when beams
only crossed it, unknown when none reached it. Values as nav_msgs/OccupancyGrid (100, 0, −1) in
a :class:`tiago_nav.gridmap.GridMap` with an unrotated origin.
"""
import os

import numpy as np

from tiago_nav.gridmap import FREE, OCCUPIED, UNKNOWN, GridMap

RESOLUTION = 0.05       # [m]
HIT_RATIO = 0.25        # a cell is occupied when this share of the beams reaching it end there
MARGIN = 1.0            # [m] around the scans' end points
CHUNK = 20000           # beams per batch


def scan_endpoints(pose, ranges, angles):
    """``(M, 2)`` end points [m, map frame] of the finite ``ranges`` of a scan taken at ``pose``
    (the laser's ``(x, y, yaw)``), and their ``(M,)`` ranges."""
    ok = np.isfinite(ranges)
    r, a = ranges[ok], angles[ok] + pose[2]
    return np.column_stack((pose[0] + r * np.cos(a), pose[1] + r * np.sin(a))), r


def build_grid(poses, ranges, angles, resolution=RESOLUTION, hit_ratio=HIT_RATIO,
               margin=MARGIN):
    """The :class:`GridMap` [``resolution`` m] of the scans ``ranges`` (``(N, n)`` [m], ``inf``
    for no return; beam ``angles`` ``(n,)`` [rad]) taken at the laser poses ``poses``
    (``(N, 3)``, map frame)."""
    poses = np.asarray(poses, dtype=float)
    ranges = np.asarray(ranges, dtype=float)
    ok = np.isfinite(ranges)
    scan_idx, beam_idx = np.nonzero(ok)
    r = ranges[ok]
    a = angles[beam_idx] + poses[scan_idx, 2]
    ox, oy = poses[scan_idx, 0], poses[scan_idx, 1]
    ex, ey = ox + r * np.cos(a), oy + r * np.sin(a)
    lo = np.floor((np.minimum(np.min(ex), np.min(poses[:, 0])) - margin) / resolution) * resolution
    bo = np.floor((np.minimum(np.min(ey), np.min(poses[:, 1])) - margin) / resolution) * resolution
    cols = int(np.ceil((max(np.max(ex), np.max(poses[:, 0])) + margin - lo) / resolution))
    rows = int(np.ceil((max(np.max(ey), np.max(poses[:, 1])) + margin - bo) / resolution))

    def flat(x, y):
        c = np.floor((x - lo) / resolution).astype(np.int64)
        rr = np.floor((y - bo) / resolution).astype(np.int64)
        return rr * cols + c

    size = rows * cols
    hits = np.bincount(flat(ex, ey), minlength=size)
    passes = np.zeros(size, dtype=np.int64)
    step = resolution / 2.0
    for s in range(0, len(r), CHUNK):
        sl = slice(s, s + CHUNK)
        rs, cs, sn = r[sl], np.cos(a[sl]), np.sin(a[sl])
        n = np.maximum(((rs - resolution) / step).astype(np.int64), 0)
        total = int(n.sum())
        if not total:
            continue
        beam = np.repeat(np.arange(len(rs)), n)
        # k-th sample of each beam: 0, 1, ... n-1
        k = np.arange(total) - np.repeat(np.cumsum(n) - n, n)
        d = k * step
        cells = flat(ox[sl][beam] + d * cs[beam], oy[sl][beam] + d * sn[beam])
        # a beam counts once per cell it crosses (its samples in a cell are consecutive)
        new = np.ones(total, dtype=bool)
        new[1:] = (cells[1:] != cells[:-1]) | (beam[1:] != beam[:-1])
        cells = cells[new]
        passes += np.bincount(cells, minlength=size)
    reached = hits + passes
    data = np.full(size, UNKNOWN, dtype=np.int8)
    data[reached > 0] = FREE
    data[(hits > 0) & (hits >= hit_ratio * reached)] = OCCUPIED
    return GridMap(data.reshape(rows, cols), float(resolution), (float(lo), float(bo)))


# --- map_server's format ---------------------------------------------------------------------
PGM_OCCUPIED, PGM_FREE, PGM_UNKNOWN = 0, 254, 205
OCCUPIED_THRESH, FREE_THRESH = 0.65, 0.196


def save_map(grid, path_yaml):
    """Write ``grid`` as map_server's YAML + PGM (``path_yaml`` and the same name ``.pgm``;
    trinary: occupied 0, free 254, unknown 205; the image's first row is the map's top)."""
    base = os.path.splitext(path_yaml)[0]
    pgm = base + '.pgm'
    img = np.full(grid.data.shape, PGM_UNKNOWN, dtype=np.uint8)
    img[grid.data == FREE] = PGM_FREE
    img[grid.data == OCCUPIED] = PGM_OCCUPIED
    img = img[::-1]
    with open(pgm, 'wb') as f:
        f.write(b'P5\n%d %d\n255\n' % (img.shape[1], img.shape[0]))
        f.write(img.tobytes())
    with open(path_yaml, 'w') as f:
        f.write('image: %s\nresolution: %r\norigin: [%r, %r, 0.0]\nnegate: 0\n'
                'occupied_thresh: %r\nfree_thresh: %r\n'
                % (os.path.basename(pgm), grid.resolution, grid.origin[0], grid.origin[1],
                   OCCUPIED_THRESH, FREE_THRESH))
    return path_yaml


def read_pgm(path):
    """``(rows, cols)`` uint8 image of a binary (P5, 8-bit) PGM file."""
    with open(path, 'rb') as f:
        raw = f.read()
    tokens, pos = [], 0
    while len(tokens) < 4:
        while raw[pos:pos + 1].isspace():
            pos += 1
        if raw[pos:pos + 1] == b'#':
            pos = raw.index(b'\n', pos) + 1
            continue
        end = pos
        while not raw[end:end + 1].isspace():
            end += 1
        tokens.append(raw[pos:end])
        pos = end
    if tokens[0] != b'P5' or int(tokens[3]) > 255:
        raise ValueError('%s: not an 8-bit binary PGM (P5)' % path)
    cols, rows = int(tokens[1]), int(tokens[2])
    data = np.frombuffer(raw[pos + 1:pos + 1 + rows * cols], dtype=np.uint8)
    if data.size != rows * cols:
        raise ValueError('%s: %d pixels, expected %d x %d' % (path, data.size, cols, rows))
    return data.reshape(rows, cols)


def load_map(path_yaml):
    """The :class:`GridMap` of a map_server YAML whose image is a PGM (``negate`` and the
    thresholds as map_server's trinary mode; a rotated origin is refused with ValueError)."""
    import yaml
    with open(path_yaml) as f:
        meta = yaml.safe_load(f)
    origin = [float(v) for v in meta['origin']]
    if abs(origin[2]) > 1e-9:
        raise ValueError('%s: rotated origin (%g rad) not supported' % (path_yaml, origin[2]))
    img = read_pgm(os.path.join(os.path.dirname(path_yaml), meta['image'])).astype(float)
    p = img / 255.0 if int(meta.get('negate', 0)) else (255.0 - img) / 255.0
    data = np.full(img.shape, UNKNOWN, dtype=np.int8)
    data[p > float(meta['occupied_thresh'])] = OCCUPIED
    data[p < float(meta['free_thresh'])] = FREE
    return GridMap(data[::-1].copy(), float(meta['resolution']), (origin[0], origin[1]))
