"""Reader of CARMEN laser logs (as published by Radish), pure Python and numpy.

A ``FLASER`` line is ``FLASER n r1 … rn x y theta odom_x odom_y odom_theta timestamp host
logger_timestamp``: ``n`` ranges [m] evenly spaced over 180° from −90° (right) counter-clockwise
in the laser frame, then the laser's pose in the map frame [m, m, rad] (in a *corrected* log,
the SLAM-corrected pose: the reference) and the odometry pose (in a corrected log the same
pose: there is no raw odometry). Other lines (``ODOM``, ``PARAM``, ``NEFF``, ``#`` comments) are
skipped.

The quirks of the real logs, handled here:

- "no return" is written as the sensor's maximum (81.83 or 81.91, 50.00 or 51.x m): a reading
  at or above :data:`NO_RETURN` is given as ``+inf`` (REP 117);
- timestamps may go backwards (4 scans of the Intel log): :func:`monotonic_times` makes them
  strictly increasing, keeping every scan;
- headings are not normalised (they run past ±π): they are wrapped into [−π, π).
"""
import gzip
from dataclasses import dataclass

import numpy as np

NO_RETURN = 50.0        # [m] a reading at or above this is "no return"
FOV = np.pi             # [rad] the front laser's field of view
MIN_STEP = 1e-3         # [s] a repaired timestamp comes this long after the one before


class LogError(ValueError):
    """A log that cannot be read: the message names the file and line."""


@dataclass
class CarmenLog:
    """The laser scans of a log, in order.

    Attributes:
        times: ``(N,)`` [s] scan times, strictly increasing (see :attr:`repaired`).
        poses: ``(N, 3)`` reference poses ``(x, y, yaw)`` of the laser in the map frame [m, m,
            rad], yaw in [−π, π).
        ranges: ``(N, n)`` [m] ranges, ``inf`` for no return.
        repaired: how many timestamps went backwards (or repeated) and were moved forward.
        name: the log's name (its file name without ``.log``/``.gz``).
    """
    times: np.ndarray
    poses: np.ndarray
    ranges: np.ndarray
    repaired: int = 0
    name: str = ''

    @property
    def beams(self):
        return self.ranges.shape[1]

    def angles(self):
        """``(n,)`` beam angles [rad] in the laser frame: ``-π/2 + i·π/n`` (CARMEN's front laser:
        180 beams are 1° apart, 360 beams 0.5°)."""
        return beam_angles(self.beams)

    def __len__(self):
        return len(self.times)

    def slice(self, start, stop):
        """The scans ``start:stop`` as a new log."""
        return CarmenLog(self.times[start:stop].copy(), self.poses[start:stop].copy(),
                         self.ranges[start:stop].copy(), 0, self.name)

    def path_length(self):
        """[m] distance driven along the reference."""
        return float(np.sum(np.hypot(*np.diff(self.poses[:, :2], axis=0).T)))


def beam_angles(n):
    """``(n,)`` angles [rad] of ``n`` beams over CARMEN's 180°: ``-π/2 + i·π/n``, ``i = 0…n-1``."""
    return -FOV / 2.0 + np.arange(n) * (FOV / n)


def wrap(a):
    """Angles [rad] wrapped into [−π, π)."""
    return (np.asarray(a, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi


def monotonic_times(t, min_step=MIN_STEP):
    """``(times, repaired)``: ``t`` [s] made strictly increasing by moving each time that does
    not come after the (repaired) one before to ``min_step`` after it; ``repaired`` counts them."""
    out = np.array(t, dtype=float)
    repaired = 0
    for i in range(1, len(out)):
        if out[i] <= out[i - 1]:
            out[i] = out[i - 1] + min_step
            repaired += 1
    return out, repaired


def parse_flaser(fields):
    """``(time, pose (3,), ranges (n,))`` of one FLASER line split into fields (ranges raw)."""
    n = int(fields[1])
    if n < 1 or len(fields) < n + 9:
        raise ValueError('FLASER with %d readings has %d fields, expected at least %d'
                         % (n, len(fields), n + 9))
    ranges = np.array(fields[2:2 + n], dtype=float)
    pose = np.array(fields[2 + n:5 + n], dtype=float)
    time = float(fields[8 + n])
    return time, pose, ranges


def read_lines(lines, name=''):
    """A :class:`CarmenLog` from an iterable of text lines (:class:`LogError` naming the line
    when one is unusable, or when the log has no FLASER line or mixes beam counts)."""
    times, poses, ranges = [], [], []
    for lineno, line in enumerate(lines, 1):
        if not line.startswith('FLASER'):
            continue
        try:
            t, p, r = parse_flaser(line.split())
        except ValueError as e:
            raise LogError('%s:%d: %s' % (name, lineno, e))
        if ranges and len(r) != len(ranges[0]):
            raise LogError('%s:%d: %d readings, the log\'s first scan has %d'
                           % (name, lineno, len(r), len(ranges[0])))
        if not (np.all(np.isfinite(p)) and np.isfinite(t)):
            raise LogError('%s:%d: pose or timestamp not finite' % (name, lineno))
        times.append(t)
        poses.append(p)
        ranges.append(r)
    if not times:
        raise LogError('%s: no FLASER line' % name)
    r = np.array(ranges)
    r[~(r < NO_RETURN)] = np.inf            # the maximum written for "no return" (and nan)
    p = np.array(poses)
    p[:, 2] = wrap(p[:, 2])
    t, repaired = monotonic_times(times)
    return CarmenLog(t, p, r, repaired, name)


def log_name(path):
    """``intel-corrected`` for ``.../intel-corrected.log.gz``."""
    import os
    base = os.path.basename(path)
    for ext in ('.gz', '.log'):
        if base.endswith(ext):
            base = base[:-len(ext)]
    return base


def read_log(path):
    """The :class:`CarmenLog` of a CARMEN log file (gzip-compressed when it ends in ``.gz``)."""
    opener = gzip.open if path.endswith('.gz') else open
    with opener(path, 'rt') as f:
        return read_lines(f, log_name(path))
