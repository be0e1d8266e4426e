"""Wheel odometry of the mock TIAGo: exact (``ideal``) or drifting (``drift``).

The odom frame is the robot's start pose (REP 105). ``ideal`` odometry is the true pose seen
from the start pose, so ``map → odom`` is the start pose. ``drift`` odometry integrates the
base's true motion, step by step, with the errors of wheel odometry, so it drifts away from the
truth; then the ground-truth ``map → odom`` is ``pose ∘ inverse(odom_pose)`` (what the simulator
publishes when localisation is ground truth), no longer the start pose.

The error model is the odometry motion model of Thrun, Burgard & Fox, *Probabilistic Robotics*
(2005), §5.4, with two changes: (1) the noise's *variance* grows linearly with the distance and
the rotation of each increment (a random walk: the std after a path of length D is
``sigma * sqrt(D)`` whatever the step size; Thrun's alpha * delta**2 form would vanish as the
simulator's step shrinks), and (2) a systematic scale error per run, drawn once from the seed
(mis-calibrated wheel radius and wheel separation: Borenstein & Feng's UMBmark, 1996, shows
these dominate a differential drive's odometry error). TIAGo's base is a differential drive
(wheel separation about 0.40 m, wheel radius about 0.0985 m, PAL's PMB-2 description); the
defaults below are estimates for a calibrated base of that kind (no measured TIAGo figures are
published): about 1 % of distance and 1 % of rotation systematic, plus random noise.

For one step where the base truly moves by ``(dx, dy, dyaw)`` in its own frame (``ds`` =
``hypot(dx, dy)``), the odometry measures::

    dyaw' = dyaw * (1 + e_rot)   + N(0, rot_per_rad**2 * |dyaw| + rot_per_metre**2 * ds)
    dx'   = dx   * (1 + e_dist)  + N(0, dist_per_metre**2 * ds  + dist_per_rad**2 * |dyaw|)
    dy'   = dy   * (1 + e_dist)

with ``e_dist ~ N(0, distance_scale_error**2)`` and ``e_rot ~ N(0, rotation_scale_error**2)``
drawn once, and composes ``odom_pose ∘ (dx', dy', dyaw')``.
"""
import math
from dataclasses import dataclass

from tiago_nav.geometry import compose, inverse
from tiago_nav.params import param, validate


@dataclass(frozen=True)
class OdometryNoise:
    """The odometry model and its error parameters (estimates; see the module's docstring)."""
    odometry_model: str = param('drift', 'odometry model: drift (wheel odometry errors, odom '
                                'drifts from the truth) or ideal (exact)', choices=('drift', 'ideal'))
    distance_scale_error: float = param(0.01, '[1] std of the per-run systematic distance scale '
                                        'error (wheel radius calibration; estimate)', ge=0, lt=0.5)
    rotation_scale_error: float = param(0.01, '[1] std of the per-run systematic rotation scale '
                                        'error (wheel separation calibration; estimate)', ge=0, lt=0.5)
    dist_per_metre: float = param(0.01, '[m/sqrt(m)] random distance error: its std after a path '
                                  'of D m is this * sqrt(D) (wheel slip; estimate)', ge=0, lt=1)
    dist_per_rad: float = param(0.002, '[m/sqrt(rad)] random distance error from rotation '
                                '(estimate)', ge=0, lt=1)
    rot_per_rad: float = param(0.02, '[rad/sqrt(rad)] random heading error from rotation: its '
                               'std after turning A rad is this * sqrt(A) (estimate)', ge=0, lt=1)
    rot_per_metre: float = param(0.005, '[rad/sqrt(m)] random heading error from distance '
                                 '(unequal wheel slip; estimate)', ge=0, lt=1)

    def __post_init__(self):
        validate(self)

    @property
    def is_ideal(self):
        return self.odometry_model == 'ideal'


class Odometry:
    """The odometry of one run: call :meth:`advance` with the true pose before and after each
    simulator step.

    Args:
        noise: :class:`OdometryNoise`.
        start_pose: ``(x, y, yaw)`` the true pose at start, in map (the odom frame's origin).
        rng: numpy Generator for every draw (its own, so the laser's draws do not change).
    """

    def __init__(self, noise, start_pose, rng):
        self.noise = noise
        self.start_pose = tuple(start_pose)
        self.rng = rng
        self._odom = (0.0, 0.0, 0.0)
        if noise.is_ideal:
            self.dist_scale = self.rot_scale = 1.0
        else:
            self.dist_scale = 1.0 + rng.normal(0.0, noise.distance_scale_error)
            self.rot_scale = 1.0 + rng.normal(0.0, noise.rotation_scale_error)

    def advance(self, before, after):
        """Integrate the true motion from pose ``before`` to pose ``after`` (map frame). A base
        that did not move adds nothing (wheels that do not turn give no encoder ticks): the
        relative motion of a pose to itself is not exactly zero in floating point, and its
        noise made a standing robot's odometry wander by 10⁻¹⁰ m per step."""
        if self.noise.is_ideal or tuple(before) == tuple(after):
            return
        n = self.noise
        dx, dy, dyaw = compose(inverse(before), after)
        ds, da = math.hypot(dx, dy), abs(dyaw)
        e_rot, e_dist = self.rng.normal(0.0, 1.0, 2)
        dyaw = dyaw * self.rot_scale + e_rot * math.sqrt(n.rot_per_rad ** 2 * da + n.rot_per_metre ** 2 * ds)
        dx = dx * self.dist_scale + e_dist * math.sqrt(n.dist_per_metre ** 2 * ds + n.dist_per_rad ** 2 * da)
        self._odom = compose(self._odom, (dx, dy * self.dist_scale, dyaw))

    def odom_pose(self, pose):
        """The base's pose in the odom frame, given its true pose ``pose`` in map."""
        if self.noise.is_ideal:
            return compose(inverse(self.start_pose), pose)
        return self._odom

    def map_to_odom(self, pose):
        """The ground-truth transform map → odom, given the true pose: the start pose with
        ideal odometry, ``pose ∘ inverse(odom_pose)`` with drift (so that map → odom →
        base_footprint is the true pose)."""
        if self.noise.is_ideal:
            return self.start_pose
        return compose(pose, inverse(self._odom))

