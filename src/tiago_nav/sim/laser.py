"""Laser model profiles: what the mock laser reports, given the exact ray cast.

``ideal`` is the exact cast plus Gaussian range noise (:func:`tiago_nav.sim.scene.noisy`),
nothing else. ``tiago`` adds what TIAGo's base laser does on the real robot. Current TIAGos
carry a SICK TiM571 (older ones a Hokuyo URG-04LX); its datasheet (SICK TiM571-2050101,
product page and operating instructions) gives 0.05–25 m, 15 Hz, 0.33° angular resolution,
a systematic error of ±60 mm and a statistical error of 20 mm (1σ), range independent, and a
range output in whole millimetres. The effects, in the order they are applied (each one a field
of :class:`LaserModel`, default and source in its documentation):

1. **self-hits** (``self_hit_angle``, ``self_hit_radius``): the laser sits in a recess at the
   front of the base; beams further than ``self_hit_angle`` from its forward axis hit the base's
   own shell behind it, a circle of ``self_hit_radius`` about base_footprint. With the default
   666 beams over ±110°, 103.5° makes 20 beams at each end of the fan hit the body at
   0.23–0.26 m, as the course's reports of the real robot say ("the first and last 20 of the 666
   ranges hit the robot's own body"). It is geometry, so the count follows the fan's settings.
2. **mixed pixels** (``mixed_pixel_probability``, ``mixed_pixel_min_jump``): the beam has a
   finite footprint; where two neighbouring beams see surfaces more than ``min_jump`` apart, the
   beam that straddles the edge (one of the two, at random) returns, with the given probability,
   a range uniformly between the near and the far surface (the "mixed pixel" / veil of
   Ye & Borenstein, ICRA 2002, on a SICK LMS 200; Tuley, Vandapel & Hebert, ICRA 2005). The
   beam footprint is taken as one angular step wide, so each edge is straddled by exactly one
   beam; the probability is an estimate (no TiM571 figure is published).
3. **range noise**: Gaussian, ``std`` (the simulator's ``laser_noise``) plus
   ``noise_per_metre`` × range (combined in quadrature). The TiM571's statistical error does
   not grow with range (datasheet), hence 0 by default; the URG-04LX's datasheet gives 1 % of
   the range from 1 to 4 m (set 0.01 to model the older laser).
4. **quantisation** (``range_resolution``): ranges are whole millimetres in the TiM571's output
   telegram, so 0.001 m.
5. **dropouts** (``dropout_rate``, ``grazing_angle``, ``grazing_dropout_rate``): a beam returns
   no valid measurement (REP 117: NaN) with ``dropout_rate``, and with
   ``grazing_dropout_rate`` where it meets the surface more than ``grazing_angle`` from the
   surface's normal (the echo's power falls with the cosine of the incidence). The incidence is
   computed from the neighbouring beams' exact hit points. Both rates are estimates.

Angles are in base_laser_link [rad], ranges [m]. Every random draw comes from the numpy
Generator passed in, so a seed reproduces a scan bit for bit.
"""
import math
from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from tiago_nav.params import ParamError, param, validate
from tiago_nav.robot import ROBOT_RADIUS
from tiago_nav.sim.scene import noisy

# What happened to each beam (LaserReading.effect); a dropout overrides the others.
EXACT, SELF_HIT, MIXED, DROPOUT = 0, 1, 2, 3

LaserReading = namedtuple('LaserReading', 'ranges effect')
LaserReading.__doc__ = """One modelled scan: ``ranges`` [m] (REP 117 values) and ``effect``, per
beam one of :data:`EXACT`, :data:`SELF_HIT`, :data:`MIXED`, :data:`DROPOUT` (the ground truth
of what the model did, for tests and figures; the real laser does not tell)."""


@dataclass(frozen=True)
class LaserModel:
    """The laser model profile and the parameters of its effects (see the module's docstring
    for each default's source)."""
    laser_model: str = param('tiago', 'laser model: tiago (self-hits, mixed pixels, dropouts, '
                             '1 mm quantisation on top of the noise) or ideal (exact cast + '
                             'Gaussian noise)', choices=('tiago', 'ideal'))
    self_hit_angle: float = param(103.5, '[deg] beams further than this from the laser\'s '
                                  'forward axis hit the robot\'s own shell (20 beams at each end '
                                  'of the 666-beam +-110 deg fan, as reported on TIAGo)',
                                  gt=0, le=180)
    self_hit_radius: float = param(ROBOT_RADIUS, '[m] radius about base_footprint of the base '
                                   'shell those beams hit (the footprint)', gt=0)
    mixed_pixel_probability: float = param(0.5, '[1] probability that the beam straddling a '
                                           'depth edge returns a range between the two surfaces '
                                           '(estimate)', ge=0, le=1)
    mixed_pixel_min_jump: float = param(0.1, '[m] range difference between neighbouring beams '
                                        'that makes a depth edge (estimate)', gt=0)
    noise_per_metre: float = param(0.0, '[m/m] range noise std per metre of range, added in '
                                   'quadrature to laser_noise (TiM571: 0, range independent; '
                                   'URG-04LX: 0.01)', ge=0, lt=1)
    range_resolution: float = param(0.001, '[m] ranges are rounded to this (TiM571 telegram: '
                                    'whole mm); 0 = no rounding', ge=0, lt=1)
    dropout_rate: float = param(0.001, '[1] probability of an invalid reading (NaN) at '
                                'ordinary incidence (estimate)', ge=0, le=1)
    grazing_angle: float = param(75.0, '[deg] incidence from the surface normal beyond which '
                                 'grazing_dropout_rate applies (estimate)', gt=0, lt=90)
    grazing_dropout_rate: float = param(0.05, '[1] probability of an invalid reading (NaN) at '
                                        'grazing incidence (estimate)', ge=0, le=1)

    def __post_init__(self):
        validate(self)
        if self.grazing_dropout_rate < self.dropout_rate:
            raise ParamError('must be >= dropout_rate (%g): grazing incidence loses more echoes'
                             % self.dropout_rate, 'grazing_dropout_rate')

    @property
    def is_ideal(self):
        return self.laser_model == 'ideal'

    def apply(self, ranges, laser, std, rng):
        """The scan the laser reports for an exact cast.

        Args:
            ranges: exact ranges [m] of the world alone (``inf`` for nothing hit), one per beam
                of ``laser.angles()``, as :meth:`tiago_nav.sim.scene.Scene.cast` returns them.
            laser: the :class:`tiago_nav.sim.scene.LaserConfig` (beam angles, range limits, the
                laser's offset ahead of base_footprint).
            std: [m] the constant part of the Gaussian range noise (``laser_noise``).
            rng: numpy Generator; all randomness is drawn from it.

        Returns:
            :class:`LaserReading`. For ``ideal`` the ranges are exactly
            ``noisy(ranges, std, rng, laser.range_min, laser.range_max)``.
        """
        if self.is_ideal:
            r = noisy(ranges, std, rng, laser.range_min, laser.range_max)
            return LaserReading(r, np.zeros(r.shape, dtype=np.int8))
        angles = laser.angles()
        exact = np.array(ranges, dtype=float)
        effect = np.zeros(exact.shape, dtype=np.int8)
        body = body_ranges(angles, laser.offset, self.self_hit_radius,
                           math.radians(self.self_hit_angle))
        self_hit = body < exact
        exact[self_hit] = body[self_hit]
        effect[self_hit] = SELF_HIT
        r = exact.copy()
        mixed = self._mixed_pixels(exact, r, rng)
        effect[mixed] = MIXED
        if self.noise_per_metre > 0:
            finite = np.isfinite(r)
            r[finite] += rng.normal(0.0, 1.0, int(finite.sum())) * self.noise_per_metre * r[finite]
        r = noisy(r, std, rng, laser.range_min, laser.range_max)
        if self.range_resolution > 0:
            finite = np.isfinite(r)
            r[finite] = np.round(r[finite] / self.range_resolution) * self.range_resolution
        grazing = incidence_angles(exact, angles) > math.radians(self.grazing_angle)
        p = np.where(grazing, self.grazing_dropout_rate, self.dropout_rate)
        dropped = rng.random(r.shape) < p
        r[dropped] = np.nan
        effect[dropped] = DROPOUT
        return LaserReading(r, effect)

    def _mixed_pixels(self, exact, r, rng):
        """Blend the straddling beam's range in ``r`` at each depth edge of ``exact`` (both
        sides hits); returns the mask of blended beams."""
        near, far = np.minimum(exact[:-1], exact[1:]), np.maximum(exact[:-1], exact[1:])
        with np.errstate(invalid='ignore'):
            edge = np.isfinite(far) & (far - near > self.mixed_pixel_min_jump)
        edges = np.flatnonzero(edge)
        hit = rng.random(edges.size) < self.mixed_pixel_probability
        side = rng.integers(0, 2, edges.size)
        u = rng.random(edges.size)
        mixed = np.zeros(r.shape, dtype=bool)
        for k in np.flatnonzero(hit):
            i = edges[k]
            beam = i + side[k]
            r[beam] = near[i] + u[k] * (far[i] - near[i])
            mixed[beam] = True
        return mixed


def body_ranges(angles, offset, radius, window):
    """Range [m] from the laser to the robot's shell along each beam, ``inf`` for the beams
    that leave through the laser's window.

    Args:
        angles: beam angles [rad] in base_laser_link.
        offset: [m] the laser's position ahead of base_footprint's origin (on its x axis).
        radius: [m] the shell, a circle about base_footprint's origin enclosing the laser.
        window: [rad] beams within this of the laser's forward axis leave the body.

    Returns:
        ``(n,)`` ranges: where the beam from the laser leaves the circle (the laser is inside).
    """
    a = np.asarray(angles, dtype=float)
    c, s = np.cos(a), np.sin(a)
    r = -offset * c + np.sqrt(radius * radius - (offset * s) ** 2)
    return np.where(np.abs(a) > window, r, np.inf)


def incidence_angles(ranges, angles):
    """Angle [rad] between each beam and the normal of the surface it hits, in [0, pi/2].

    The surface's direction at a hit is the segment to a neighbouring beam's hit; of the two
    neighbours, the one giving the smaller angle is taken (at a depth edge the other one
    belongs to another surface). Beams with no neighbouring hit (or no hit) get 0.
    """
    r = np.asarray(ranges, dtype=float)
    a = np.asarray(angles, dtype=float)
    ok = np.isfinite(r)
    d = np.column_stack((np.cos(a), np.sin(a)))
    p = np.where(ok[:, None], r[:, None] * d, 0.0)
    best = np.full(r.shape, -1.0)       # cos(incidence) of the best neighbour so far
    for shift in (-1, 1):
        j = np.arange(r.size) + shift
        valid = ok & (j >= 0) & (j < r.size)
        j = np.clip(j, 0, r.size - 1)
        valid &= ok[j]
        t = p[j] - p
        norm = np.hypot(t[:, 0], t[:, 1])
        valid &= norm > 0
        with np.errstate(invalid='ignore', divide='ignore'):
            cos_inc = np.abs(t[:, 0] * d[:, 1] - t[:, 1] * d[:, 0]) / norm
        best = np.where(valid, np.maximum(best, cos_inc), best)
    best = np.where(best >= 0, best, 1.0)
    return np.arccos(np.clip(best, 0.0, 1.0))
