"""Laser scans as plain arrays: one validity rule (REP 117) and one scan → points conversion,
used by the costmap, the collision checks, the corridor law and detection.

REP 117 values of a ``sensor_msgs/LaserScan`` range ``r`` with limits ``[range_min, range_max]``:

* a finite ``r`` within the limits is a **hit** (something at ``r``);
* ``+inf`` is **no return**: nothing within ``range_max`` along the beam (free space, may clear);
* ``-inf`` is **too close**: something nearer than ``range_min`` (never clears; for a safety
  check the beam is blocked);
* ``NaN`` and a finite value outside the limits are **invalid**: the measurement says nothing
  and is used for nothing.

Angles are in the laser's frame (``base_laser_link``), radians; ranges and points in metres.
"""
import numpy as np

HIT, NO_RETURN, TOO_CLOSE, INVALID = 0, 1, 2, 3


def beam_angles(angle_min, angle_increment, n):
    """Beam angles [rad] of a scan with ``n`` beams, in the laser frame."""
    return angle_min + angle_increment * np.arange(n)


def classify(ranges, range_min, range_max):
    """Per beam, one of :data:`HIT`, :data:`NO_RETURN`, :data:`TOO_CLOSE`, :data:`INVALID`
    (the module's REP 117 rule). Returns an int8 array."""
    r = np.asarray(ranges, dtype=float)
    out = np.full(r.shape, INVALID, dtype=np.int8)
    with np.errstate(invalid='ignore'):
        out[np.isfinite(r) & (r >= range_min) & (r <= range_max)] = HIT
    out[r == np.inf] = NO_RETURN
    out[r == -np.inf] = TOO_CLOSE
    return out


def hits(ranges, range_min, range_max):
    """Boolean mask of the beams that measured something within the limits."""
    return classify(ranges, range_min, range_max) == HIT


def informative_fraction(ranges, range_min, range_max):
    """Fraction of the beams that say something (a hit, no return or too close); 0 for an
    empty scan. A scan far below 1 is too broken to judge the scene from."""
    c = classify(ranges, range_min, range_max)
    return float(np.mean(c != INVALID)) if c.size else 0.0


def scan_to_points(ranges, angle_min, angle_increment, range_min=0.0, range_max=np.inf):
    """The hits of a scan as points in the laser frame.

    Returns ``(points, index)``: the ``(M, 2)`` points [m] of the :data:`HIT` beams and the beam
    index of each point (no return, too close and invalid beams have no point).
    """
    r = np.asarray(ranges, dtype=float)
    idx = np.flatnonzero(hits(r, range_min, range_max))
    ang = angle_min + angle_increment * idx
    rv = r[idx]
    return np.column_stack((rv * np.cos(ang), rv * np.sin(ang))), idx
