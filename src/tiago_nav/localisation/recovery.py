"""A localiser that knows when it is lost and finds itself again, without ROS.

:class:`RecoveringLocaliser` wraps the tracking :class:`~tiago_nav.localisation.localiser.Localiser`
(same calls: :meth:`~RecoveringLocaliser.due`, :meth:`~RecoveringLocaliser.update`,
:meth:`~RecoveringLocaliser.follow`, :meth:`~RecoveringLocaliser.reset`) and adds:

1. **Lost detection** (:mod:`tiago_nav.localisation.health`): after every registered scan the
   share of its points on the map at the kept pose, over a window of scans, gives OK / degraded
   / lost (:attr:`RecoveringLocaliser.health`).
2. **Relocalisation**: once lost, the scan is matched over a region of the map by branch and
   bound (:mod:`tiago_nav.localisation.global_search`): first around the estimate, as far as
   its uncertainty reaches (3 standard deviations, at least :data:`LOCAL_MIN_RADIUS`), every
   heading; if that finds no pose that holds, the whole map's free space. After
   ``/initialpose`` with a covariance wider than the tracker's own search window, around the
   given pose as far as that covariance reaches; after :meth:`global_localization`, the whole
   map at once.
3. **Verification over several scans**: each pose the search returns (up to
   :data:`HYPOTHESES`, within 90 % of the best score, one per 0.5 m / 20°) is carried by the
   odometry and registered to every following scan; one is accepted once it has fitted
   :data:`VERIFY_SCANS` scans in a row with at least ``GOOD_FIT`` of their points on the map, and
   it is unique: every other hypothesis has fitted those scans worse by at least
   :data:`UNIQUE_MARGIN`. In a symmetric corridor two look-alike places fit alike, none is
   accepted, and the estimate stays the odometry's while the status says lost. After
   :data:`MAX_VERIFY` scans without an accepted hypothesis the search runs again on the latest
   scan (the whole map once the local one failed).

While relocalising, the published estimate is the last one carried by the odometry, and its
covariance that of the region searched (a uniform disc of radius ``R``: ``R²/4`` per axis; the
whole map: its extent² / 12; heading: the window's), so it covers the error it may have; when
degraded (not lost) the registration's covariance is widened by ``inlier_distance`` in position
and ``prior_sigma_yaw_deg`` in heading, how far a scan whose points are half off the map can
have pulled the pose without the gate noticing.
"""
import math

import numpy as np

from tiago_nav.geometry import compose, inverse, wrap_angle
from tiago_nav.localisation import global_search
from tiago_nav.localisation.health import ERROR, GOOD_FIT, LOST_FIT, OK, WARN, FitMonitor, \
    Health, fit_share
from tiago_nav.localisation.localiser import LocaliserConfig, Localiser, Update, \
    register_with_information

# [m] the local search's smallest radius: beyond the tracker's own search window (0.4 m) and
# gate (0.5 m), what a wrong correction or a slip can have moved the pose without the gate
LOCAL_MIN_RADIUS = 1.0
HYPOTHESES = 8
VERIFY_SCANS = 3
MAX_VERIFY = 6
# a tenth of the points over the same 3 scans: more than twice the scatter of the 3-scan mean
# share at the right pose (its standard deviation over a whole building log: 2-4.5 %; from one
# scan to the next it changes by 1.5-4 % at most, 95th percentile), so a place that misses
# what the true one sees is told apart as soon as the scans see it. A place that fits as well
# (a symmetric corridor) stays within it, and none is accepted.
UNIQUE_MARGIN = 0.1
# [m, rad] two hypotheses closer than both are one
SAME = (0.5, math.radians(20.0))


class RecoveringLocaliser:
    """The tracker plus lost detection and relocalisation (see the module docstring).

    Args:
        grid, pose, config, odom, field: as for
            :class:`~tiago_nav.localisation.localiser.Localiser`.
        pyramid: the map's :class:`~tiago_nav.localisation.global_search.LikelihoodPyramid`
            when already built (read only); None: built here.
    """

    def __init__(self, grid, pose, config=LocaliserConfig(), odom=None, field=None,
                 pyramid=None):
        self.grid = grid
        self.config = config
        self.tracker = Localiser(grid, pose, config, odom, field)
        self.field = self.tracker.field
        self.pyramid = global_search.LikelihoodPyramid(grid) if pyramid is None else pyramid
        self.monitor = FitMonitor()
        self.health = self.monitor.health()
        self._reloc = None          # the relocalisation under way (a dict), or None

    # --- the tracker's interface -------------------------------------------------------------
    @property
    def pose(self):
        return self.tracker.pose

    @property
    def odom(self):
        return self.tracker.odom

    @property
    def map_to_odom(self):
        return self.tracker.map_to_odom

    @property
    def estimate(self):
        return self.tracker.estimate

    @property
    def relocalising(self):
        """True while the pose is being searched for (lost, after :meth:`global_localization`
        or a wide ``/initialpose``)."""
        return self._reloc is not None

    def scan_points(self, *args, **kwargs):
        return self.tracker.scan_points(*args, **kwargs)

    def due(self, odom_pose):
        """As the tracker's while the status is OK; every scan while degraded or relocalising
        (each verifies the hypotheses). A degraded estimate is judged over scans of time, not
        of motion: a person walking past degrades a few seconds of scans, a wrong pose stays
        degraded however long the robot stands, and waiting for motion to count the scans
        that tell them apart left a robot started off its pose at rest on it, unreported."""
        d = self.tracker.due(odom_pose)
        return True if self._reloc is not None or self.health.level != OK else d

    def follow(self, odom_pose):
        pose, cov = self.tracker.follow(odom_pose)
        return pose, self._published_covariance(cov)

    def reset(self, pose, covariance=None):
        """Restart from ``pose`` (``/initialpose``). With a ``covariance`` (3 × 3 of x, y, yaw)
        whose 3 standard deviations reach beyond the tracker's search window
        (``search_radius`` / ``search_yaw_deg``), the pose is searched for around ``pose`` as
        far as they reach (verified over several scans); otherwise the tracker searches its
        window at the next scan."""
        self.tracker.reset(pose, covariance)
        self.monitor.clear()
        self._reloc = None
        c = self.config
        if covariance is not None:
            cov = np.asarray(covariance, dtype=float).reshape(3, 3)
            rxy = 3.0 * math.sqrt(max(float(np.linalg.eigvalsh(cov[:2, :2])[-1]), 0.0))
            ryaw = 3.0 * math.sqrt(max(cov[2, 2], 0.0))
            if rxy > c.search_radius + 1e-9 or ryaw > math.radians(c.search_yaw_deg) + 1e-9:
                self._start('initial pose', pose, max(rxy, c.search_radius),
                            max(ryaw, math.radians(c.search_yaw_deg)))
                return
        self.health = Health(WARN, 'starting: searching around the given pose', float('nan'),
                             0, 0)

    def global_localization(self):
        """Forget the pose and search the whole map (``/global_localization``)."""
        self.monitor.clear()
        self._start('global', None, None, math.pi)

    # --- the filter --------------------------------------------------------------------------
    def update(self, odom_pose, points, sensor=None):
        """One registered scan (see :meth:`Localiser.update`); :attr:`health` says how the
        estimate stands after it."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        if self._reloc is not None:
            return self._relocalise(tuple(odom_pose), pts, sensor)
        up = self.tracker.update(odom_pose, pts, sensor)
        if len(pts) >= self.config.min_inliers:
            fit = fit_share(self.field, self.tracker.pose, pts, self.config.inlier_distance)
            self.health = self.monitor.add(fit, not up.corrected)
        if self.health.level == ERROR:
            cov = self.tracker.covariance
            r = max(3.0 * math.sqrt(max(float(np.linalg.eigvalsh(cov[:2, :2])[-1]), 0.0)),
                    LOCAL_MIN_RADIUS)
            lost = self.health
            self._start('local', self.tracker.pose, r, math.pi)
            self.health = Health(ERROR, '%s; searching within %.1f m' % (lost.message, r),
                                 lost.fit, lost.rejected, lost.scans)
        return self._with_covariance(up)

    def _start(self, stage, centre, radius, yaw_window):
        self._reloc = {'stage': stage, 'centre': None if centre is None else tuple(centre),
                       'radius': radius, 'yaw': None if centre is None else centre[2],
                       'yaw_window': yaw_window, 'hyps': None, 'odom': None, 'scans': 0}
        where = 'the whole map' if centre is None else 'within %.1f m of (%.2f, %.2f)' % (
            radius, centre[0], centre[1])
        self.health = Health(ERROR, 'lost: relocalising (%s search, %s)' % (stage, where),
                             float('nan'), 0, 0)

    def _search(self, pts, sensor):
        r = self._reloc
        regions = [(r['centre'], r['radius'], r['yaw'], r['yaw_window'])]
        if r['stage'] == 'local':
            # the whole map too: a place within the region may look like the true one outside
            # it (a corridor's look-alike stretch), and only the comparison with every
            # place that fits as well tells whether the region's best is unique
            regions.append((None, None, None, math.pi))
        out = []
        for centre, radius, yaw, window in regions:
            poses, _ = global_search.search(self.pyramid, pts, centre, radius, yaw, window,
                                            keep=HYPOTHESES, separation=SAME)
            out += [{'pose': tuple(float(v) for v in p), 'fits': []} for p in poses]
        return out

    def _relocalise(self, odom, pts, sensor):
        r, c = self._reloc, self.config
        sensor = sensor or (0.0, 0.0)
        pose, cov = self.tracker.follow(odom)     # the estimate meanwhile: odometry
        if r['hyps'] is not None and r['odom'] is not None:
            delta = compose(inverse(r['odom']), odom)
            for h in r['hyps']:
                h['pose'] = compose(h['pose'], delta)
        r['odom'] = odom
        reason = 'relocalising'
        if len(pts) >= c.min_inliers:
            if r['hyps'] is None or r['scans'] >= MAX_VERIFY or not r['hyps']:
                if r['hyps'] is not None and r['stage'] != 'global':
                    # the region failed: the whole map
                    r.update(stage='global', centre=None, radius=None, yaw=None,
                             yaw_window=math.pi)
                old = [h for h in (r['hyps'] or []) if h['fits'] and
                       np.mean(h['fits'][-VERIFY_SCANS:]) >= GOOD_FIT]
                new = self._search(pts, sensor)
                r['hyps'] = _merge(old, new)
                r['scans'] = 0
            r['scans'] += 1
            for h in r['hyps']:
                p, _, _, _ = register_with_information(self.field, pts, h['pose'], c, sensor)
                h['pose'] = tuple(float(v) for v in p)
                h['fits'].append(fit_share(self.field, p, pts, c.inlier_distance))
            r['hyps'] = _merge([], r['hyps'])
            r['hyps'] = [h for h in r['hyps'] if h['fits'][-1] >= LOST_FIT]
            won = _accepted(r['hyps'])
            if won is not None:
                self.tracker = Localiser(self.grid, won['pose'], c, odom, self.field)
                self.tracker.covariance = np.diag([c.inlier_distance ** 2] * 2
                                                  + [math.radians(c.prior_sigma_yaw_deg) ** 2])
                self._reloc = None
                self.monitor.clear()
                for f in won['fits'][-VERIFY_SCANS:]:
                    self.health = self.monitor.add(f, False)
                self.health = Health(self.health.level, 'relocalised (%s search): %s'
                                     % (r['stage'], self.health.message), self.health.fit, 0,
                                     self.health.scans)
                m2o = self.tracker.map_to_odom
                return Update(won['pose'], m2o, self._published_covariance(
                    self.tracker.published_covariance(self.tracker.covariance)), pose, True, 0,
                    len(pts), '', '', won['pose'], 0.0)
            best = max((np.mean(h['fits'][-VERIFY_SCANS:]) for h in r['hyps']), default=0.0)
            reason = 'relocalising: %d hypotheses, best fit %.0f %%' % (len(r['hyps']),
                                                                          100 * best)
            where = 'the whole map' if r['centre'] is None else 'within %.1f m' % r['radius']
            self.health = Health(ERROR, 'lost: relocalising (%s search over %s): %d hypotheses '
                                 'being verified' % (r['stage'], where, len(r['hyps'])), best,
                                 0, r['scans'])
        return Update(pose, self.tracker.map_to_odom, self._published_covariance(cov), pose,
                      False, 0, len(pts), reason, '', self.tracker.pose, 0.0)

    # --- the covariance ----------------------------------------------------------------------
    def _published_covariance(self, cov):
        cov = np.array(cov, dtype=float)
        c = self.config
        r = self._reloc
        if r is not None:
            if r['centre'] is None:
                x0, y0, x1, y1 = self.grid.bounds
                var = max(x1 - x0, y1 - y0) ** 2 / 12.0
            else:
                var = r['radius'] ** 2 / 4.0
            yvar = (r['yaw_window'] ** 2) / 3.0
            return np.maximum(cov, np.diag([var, var, yvar]))
        if self.health.level != OK:
            cov = cov + np.diag([c.inlier_distance ** 2] * 2
                                + [math.radians(c.prior_sigma_yaw_deg) ** 2])
        return cov

    def _with_covariance(self, up):
        fields = dict(up.__dict__)
        fields['covariance'] = self._published_covariance(up.covariance)
        return Update(**fields)


def _merge(old, new):
    """The hypotheses of ``old`` and ``new`` with those closer than :data:`SAME` to a better
    one (more scans fitted, then a better mean fit) dropped."""
    def key(h):
        return (len(h['fits']), np.mean(h['fits'][-VERIFY_SCANS:]) if h['fits'] else 0.0)
    out = []
    for h in sorted(old + new, key=key, reverse=True):
        if all(not _same(h['pose'], k['pose']) for k in out):
            out.append(h)
    return out[:HYPOTHESES * 2]


def _same(a, b):
    return math.hypot(a[0] - b[0], a[1] - b[1]) < SAME[0] and \
        abs(wrap_angle(a[2] - b[2])) < SAME[1]


def _accepted(hyps):
    """The hypothesis that has fitted the last :data:`VERIFY_SCANS` scans with a mean of at least
    ``GOOD_FIT`` while every other fitted the same scans worse by :data:`UNIQUE_MARGIN`, or
    None."""
    if not hyps:
        return None
    means = [np.mean(h['fits'][-VERIFY_SCANS:]) for h in hyps]
    k = int(np.argmax(means))
    h = hyps[k]
    if len(h['fits']) < VERIFY_SCANS or means[k] < GOOD_FIT:
        return None
    if any(means[j] > means[k] - UNIQUE_MARGIN for j in range(len(hyps)) if j != k):
        return None
    return h
