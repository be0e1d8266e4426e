"""Is the estimate right? How the scans fit the map over several scans, without ROS.

The measure is the share of a registered scan's points that lie within ``inlier_distance``
(0.1 m, two cells of a 0.05 m map) of a mapped surface at the pose the localiser kept. At the
true pose most of a scan's points are on walls (on real building logs 88-100 %; unmapped
furniture and people take the rest); at a pose off by more than a wall's thickness few are.
One scan says little (a person in front of the laser, a glass wall), so the status is decided
over a window of the last :data:`WINDOW` registered scans:

- **OK**: the window's mean share is at least :data:`GOOD_FIT` and no more than :data:`DROP`
  below the usual share (its exponential average over the scans found OK, weight
  :data:`NORM_WEIGHT` per scan: about the last 20);
- **WARN** (degraded): below either, or a correction was rejected in the window;
- **ERROR** (lost): the window's mean share below :data:`LOST_FIT`, every correction of the
  window rejected, or degraded for :data:`DEGRADED_LIMIT` registered scans in a row (a person
  walking past the laser degrades a few scans; a pose that stays half off the map is wrong).

:data:`GOOD_FIT` is one half: then most points sit on the map. The usual share is the
building's own (97-100 % in an empty corridor, less among furniture): a pose carried a few
metres along a corridor fits its walls but not its doors and ends, and the share falls from
its usual 97 % to 55-67 %, above one half. A quarter of the points leaving the map at once
is more than a person hides: two 0.1 m legs half a metre from the laser cover about a tenth of
a 220° scan. AMCL's recovery compares the same way (its short-term likelihood against its
long-term one). :data:`LOST_FIT` is the
registration gate's own ``min_inlier_fraction`` default (0.3): below it the localiser
itself refuses a single correction, and a whole window of such scans is no passing person.
"""
from dataclasses import dataclass

import numpy as np

OK, WARN, ERROR = 0, 1, 2          # diagnostic_msgs/DiagnosticStatus levels
LEVEL_NAMES = {OK: 'ok', WARN: 'degraded', ERROR: 'lost'}
WINDOW = 3
GOOD_FIT = 0.5
LOST_FIT = 0.3
DEGRADED_LIMIT = 2 * WINDOW
DROP = 0.25
NORM_WEIGHT = 0.05


@dataclass(frozen=True)
class Health:
    """The status after a scan: ``level`` (:data:`OK`, :data:`WARN`, :data:`ERROR`),
    ``message`` (the reason, a sentence), ``fit`` (the window's mean share of points within
    ``inlier_distance`` of the map, nan before any registered scan), ``rejected`` (rejected
    corrections in the window), ``scans`` (registered scans in the window)."""
    level: int
    message: str
    fit: float
    rejected: int
    scans: int

    @property
    def name(self):
        return LEVEL_NAMES[self.level]


class FitMonitor:
    """The windowed fit of the registered scans (see the module docstring).

    Args:
        window: scans in the window.
        good_fit, lost_fit: the shares that separate OK, degraded and lost.
    """

    def __init__(self, window=WINDOW, good_fit=GOOD_FIT, lost_fit=LOST_FIT):
        if not 0 <= lost_fit <= good_fit <= 1 or window < 1:
            raise ValueError('need 0 <= lost_fit <= good_fit <= 1 and window >= 1')
        self.window, self.good_fit, self.lost_fit = int(window), good_fit, lost_fit
        self.clear()

    def clear(self):
        """Forget the window (after a relocalisation or a reset)."""
        self._fits, self._rejected = [], []
        self._degraded = 0          # registered scans in a row found degraded
        self._norm = None           # the usual share: averaged over the scans found OK

    def add(self, fit, rejected):
        """One registered scan: ``fit`` (its share of points within ``inlier_distance`` of the
        map at the kept pose, 0..1) and whether its correction was ``rejected``; returns the
        :class:`Health`."""
        self._fits = (self._fits + [float(fit)])[-self.window:]
        self._rejected = (self._rejected + [bool(rejected)])[-self.window:]
        h = self.health()
        if h.level == OK:
            self._norm = fit if self._norm is None else \
                (1.0 - NORM_WEIGHT) * self._norm + NORM_WEIGHT * fit
        self._degraded = self._degraded + 1 if h.level == WARN else 0
        if self._degraded >= DEGRADED_LIMIT:
            h = Health(ERROR, 'lost: %s for %d scans' % (h.message, self._degraded), h.fit,
                       h.rejected, h.scans)
        return h

    def health(self):
        """The :class:`Health` of the window now."""
        n = len(self._fits)
        if not n:
            return Health(WARN, 'no scan registered yet', float('nan'), 0, 0)
        fit = float(np.mean(self._fits))
        rej = int(sum(self._rejected))
        full = n >= self.window
        if full and (fit < self.lost_fit or rej == n):
            why = ('%.0f %% of the scan points within reach of the map over the last %d scans'
                   % (100 * fit, n)) if fit < self.lost_fit else \
                'every correction of the last %d scans rejected' % n
            return Health(ERROR, 'lost: %s' % why, fit, rej, n)
        dropped = self._norm is not None and full and fit < self._norm - DROP
        if fit < self.good_fit or rej or dropped:
            parts = []
            if fit < self.good_fit:
                parts.append('%.0f %% of the scan points on the map' % (100 * fit))
            elif dropped:
                parts.append('%.0f %% of the scan points on the map (usually %.0f %%)'
                             % (100 * fit, 100 * self._norm))
            if rej:
                parts.append('%d of the last %d corrections rejected' % (rej, n))
            return Health(WARN, 'degraded: %s' % ', '.join(parts), fit, rej, n)
        return Health(OK, 'tracking: %.0f %% of the scan points on the map' % (100 * fit), fit,
                      rej, n)


def fit_share(field, pose, points, distance):
    """The share (0..1) of ``points`` (``(N, 2)`` [m] in base_footprint) within ``distance``
    [m] of a mapped surface when the robot is at ``pose`` ``(x, y, yaw)`` in map; ``field``
    gives the signed distance at ``(N, 2)`` map points (a
    :class:`tiago_nav.gridmap.DistanceField`). 0 for no points."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if not len(pts):
        return 0.0
    c, s = np.cos(pose[2]), np.sin(pose[2])
    q = np.column_stack((pose[0] + c * pts[:, 0] - s * pts[:, 1],
                         pose[1] + s * pts[:, 0] + c * pts[:, 1]))
    d = field(q)[0]
    return float(np.mean(np.abs(d) < distance))
