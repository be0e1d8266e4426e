"""The mock TIAGo without ROS: a :class:`Scene`, a :class:`DiffDrive` base and a noisy laser,
stepped at a fixed rate of simulated time. :mod:`tiago_nav.nodes.simulator` wires it to ROS.

Ground truth (:attr:`Simulator.pose`) lives in the world (map) frame. Odometry is expressed in
the odom frame, whose origin is the robot's start pose (REP 105); it is exact or drifts
(:mod:`tiago_nav.sim.odometry`). The laser is modelled by a profile (:mod:`tiago_nav.sim.laser`).
The world's walkers (:mod:`tiago_nav.sim.walkers`) move with each step, before the base.
"""
import math
from dataclasses import dataclass

import numpy as np

from tiago_nav.params import ParamError, nested, param, validate
from tiago_nav.robot import ROBOT_RADIUS
from tiago_nav.sim.diffdrive import BaseLimits, DiffDrive
from tiago_nav.sim.laser import LaserModel
from tiago_nav.sim.odometry import Odometry, OdometryNoise
from tiago_nav.sim.scene import LaserConfig, Scene
from tiago_nav.sim.walkers import Walkers
from tiago_nav.sim.world import clearance


CONTACT_CLEARANCE = 0.02   # [m] a contact event ends when the base is this far from what it hit


@dataclass(frozen=True)
class SimConfig:
    """Simulator settings. Rates are in Hz of simulated time; ``scan_rate`` and ``odom_rate``
    must divide ``rate``. ``laser_noise`` is the range noise's std [m]; ``cmd_timeout`` [s]
    stops the base when no command arrives for that long. ``laser_model`` and ``odometry``
    default to the exact models here, for tests; the simulator node's parameters default to
    ``tiago`` and ``drift``."""
    rate: float = param(60.0, '[Hz] physics steps per simulated second; scan_rate and odom_rate divide it',
                        gt=0)
    scan_rate: float = param(15.0, '[Hz] /scan', gt=0)
    odom_rate: float = param(30.0, '[Hz] odometry, tf and ground truth', gt=0)
    laser_noise: float = param(0.01, '[m] Gaussian range noise std', ge=0, lt=1)
    cmd_timeout: float = param(0.5, '[s] the base brakes to a stop when no cmd_vel arrives for this long',
                               gt=0)
    cmd_resolution: float = param(1e-6, '[m/s, rad/s] velocity commands are rounded to this, '
                                  'as a motor driver takes fixed-point setpoints (keeps the '
                                  'controllers\' last-bit floating-point differences out of the '
                                  'motion, so lockstep runs repeat exactly); 0 = exact',
                                  ge=0, lt=0.01)
    robot_radius: float = param(ROBOT_RADIUS, "[m] the base's footprint", gt=0)
    seed: int = param(0, 'seed of the laser noise and of the odometry drift', ge=0)
    limits: BaseLimits = nested(BaseLimits)
    laser: LaserConfig = nested(LaserConfig)
    laser_model: LaserModel = nested(LaserModel, laser_model='ideal')
    odometry: OdometryNoise = nested(OdometryNoise, odometry_model='ideal')

    def __post_init__(self):
        validate(self)
        for k in ('scan_rate', 'odom_rate'):
            n = self.rate / getattr(self, k)
            if abs(n - round(n)) > 1e-6 or round(n) < 1:
                raise ParamError('%g Hz must divide rate (%g Hz)' % (getattr(self, k), self.rate), k)

    @property
    def dt(self):
        return 1.0 / self.rate


class Simulator:
    """Steps the world by ``config.dt`` of simulated time per :meth:`step`."""

    def __init__(self, world, config=SimConfig(), start_pose=None, gui=False):
        self.world = world
        self.config = config
        self.scene = Scene(world, robot_radius=config.robot_radius, laser=config.laser, gui=gui)
        self.start_pose = tuple(start_pose) if start_pose is not None else world.start_pose
        self.scene.set_robot_pose(self.start_pose)
        self.walkers = Walkers(world.walkers, lambda xy: clearance(world, xy))
        for i in range(len(self.walkers)):
            self.scene.set_walker_legs(i, self.walkers.legs(i))
        touching = self.scene.robot_contacts()
        if touching:
            self.scene.close()
            raise ValueError('%s: the robot at its start pose (%.3f, %.3f) overlaps an obstacle'
                             % (world.source, self.start_pose[0], self.start_pose[1]))
        self.base = DiffDrive(self.start_pose, config.limits)
        self.rng = np.random.default_rng(config.seed)
        self.odometry = Odometry(config.odometry, self.start_pose,
                                 np.random.default_rng((config.seed, 1)))
        self.steps = 0
        self.collisions = 0
        self._touching = ()
        self._cmd = (0.0, 0.0)
        self._cmd_time = -math.inf
        self._scan_every = int(round(config.rate / config.scan_rate))
        self._odom_every = int(round(config.rate / config.odom_rate))

    # --- time -----------------------------------------------------------------------------
    @property
    def time(self):
        """Simulated time [s] since start."""
        return self.steps / self.config.rate

    @property
    def time_ns(self):
        """Simulated time [ns] since start, exact (no accumulated rounding)."""
        return self.steps * 10**9 // int(round(self.config.rate)) if float(self.config.rate).is_integer() \
            else int(round(self.time * 1e9))

    # --- commands and stepping ------------------------------------------------------------
    def command(self, v, w):
        """A velocity command ``v`` [m/s], ``w`` [rad/s] in base_footprint, held for
        ``cmd_timeout`` of simulated time and rounded to ``cmd_resolution``: the controllers'
        numpy/BLAS reductions can differ in the last bit from run to run (their summation
        order follows the arrays' memory alignment), and without the rounding those 10⁻¹⁶
        differences reached the robot's path (final poses 10⁻⁹ m apart)."""
        if not (math.isfinite(v) and math.isfinite(w)):
            return False
        q = self.config.cmd_resolution
        self._cmd = (round(v / q) * q, round(w / q) * q) if q > 0 else (float(v), float(w))
        self._cmd_time = self.time
        return True

    def _command_in_force(self):
        """The command ``(v, w)`` the next step applies: the last one, until ``cmd_timeout``."""
        return self._cmd if self.time - self._cmd_time <= self.config.cmd_timeout else (0.0, 0.0)

    def step(self):
        """Advance one step: the walkers (each yields to the base where it stands now), then
        the base (a contact with anything, a walker's leg too, is a collision). Returns
        ``(scan_due, odom_due)`` for the new time."""
        dt = self.config.dt
        if len(self.walkers):
            for i in self.walkers.step(self.time, dt, self.base.pose[:2], self.config.robot_radius):
                self.scene.set_walker_legs(i, self.walkers.legs(i))
        v, w = self._command_in_force()
        before = self.base.pose
        pose = self.base.step(v, w, dt)
        self.scene.set_robot_pose(pose)
        touching = self.scene.robot_contacts()
        if touching:
            # a bump: the base stays where it was and stops. One contact event lasts until the
            # base has moved clear (CONTACT_CLEARANCE) of what it touched.
            if not self._touching:
                self.collisions += 1
            self._touching = set(self._touching) | set(touching)
            self.base.pose = before
            self.base.stop()
            self.scene.set_robot_pose(before)
        elif self._touching and self.scene.robot_clear_of(self._touching, CONTACT_CLEARANCE):
            self._touching = ()
        self.odometry.advance(before, self.base.pose)
        self.steps += 1
        return (self.steps % self._scan_every == 0, self.steps % self._odom_every == 0)

    # --- sensing --------------------------------------------------------------------------
    @property
    def pose(self):
        """Ground-truth base pose ``(x, y, yaw)`` in the map frame."""
        return self.base.pose

    @property
    def odom_pose(self):
        """Base pose in the odom frame (the start pose is the odom origin): exact, or drifting
        from the truth with ``config.odometry``."""
        return self.odometry.odom_pose(self.base.pose)

    @property
    def map_to_odom(self):
        """The ground-truth transform map → odom as a pose ``(x, y, yaw)``: the start pose with
        exact odometry; with drift, ``pose ∘ inverse(odom_pose)`` (so that map → odom →
        base_footprint is the true pose)."""
        return self.odometry.map_to_odom(self.base.pose)

    @property
    def velocity(self):
        """Current ``(v, w)`` [m/s, rad/s] of the base."""
        return (self.base.v, self.base.w)

    @property
    def in_motion(self):
        """True while the base moves or a non-zero command is in force (the next step would
        move it)."""
        v, w = self._command_in_force()
        return bool(self.base.v or self.base.w or v or w)

    def scan(self):
        """One laser scan from the current pose: ranges [m] (REP 117 values) as
        ``config.laser_model`` reports them; beam angles are ``config.laser.angles()``."""
        ranges, _ = self.scene.cast()
        c = self.config
        return c.laser_model.apply(ranges, c.laser, c.laser_noise, self.rng).ranges

    def close(self):
        self.scene.close()
