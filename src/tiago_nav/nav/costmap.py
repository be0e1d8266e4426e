"""A 2-D costmap in the map frame: the static map plus a rolling obstacle layer from the laser,
inflated by the robot radius with an exponential cost gradient (as costmap_2d does).

Frames and units: everything is in the ``map`` frame, metres and radians. The grid layout is
:class:`tiago_nav.gridmap.GridMap`'s (``[row=y, col=x]``).

Costs: ``LETHAL`` (254) where the robot centre would overlap an obstacle (within
``robot_radius`` of an occupied cell), ``INSCRIBED`` (253) on the boundary, then
``252 * exp(-cost_scaling_factor * (d - robot_radius))`` out to ``inflation_radius``, 0 beyond.
"""
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from tiago_nav.geometry import transform_points
from tiago_nav.gridmap import distance_to_mask
from tiago_nav.robot import ROBOT_RADIUS
from tiago_nav.scan import HIT, beam_angles, classify, scan_to_points

LETHAL = 254
INSCRIBED = 253
MAX_NON_LETHAL = 252


@dataclass(frozen=True)
class MapScan:
    """One laser scan placed in the map: the laser's pose ``(x, y, yaw)`` in ``map`` at the
    scan's stamp, the ranges [m] and the LaserScan's angle and range limits (laser frame, rad
    and m), and the stamp [s, ROS time]."""
    laser_pose: tuple
    ranges: np.ndarray
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    stamp: float = 0.0

    @cached_property
    def kinds(self):
        """Per beam, :data:`~tiago_nav.scan.HIT`, ``NO_RETURN``, ``TOO_CLOSE`` or ``INVALID``."""
        return classify(self.ranges, self.range_min, self.range_max)

    def angles(self):
        """Beam directions [rad] in ``map``."""
        return self.laser_pose[2] + beam_angles(self.angle_min, self.angle_increment, len(self.ranges))

    @cached_property
    def obstacles(self):
        """``(points (M, 2) in map, range [m] of each)``: the hits."""
        pts, idx = scan_to_points(self.ranges, self.angle_min, self.angle_increment,
                                  self.range_min, self.range_max)
        return transform_points(self.laser_pose, pts), np.asarray(self.ranges, dtype=float)[idx]


def inflate(occupied, resolution, robot_radius, inflation_radius, cost_scaling_factor):
    """Boolean ``(rows, cols)`` obstacles → ``(cost uint8, distance float [m])``.

    ``distance`` is each cell centre's Euclidean distance to the nearest occupied cell centre
    (:func:`tiago_nav.gridmap.distance_to_mask`), ``cost`` as in the module docstring."""
    dist = distance_to_mask(occupied, resolution)
    cost = np.zeros(occupied.shape, dtype=np.uint8)
    band = (dist >= robot_radius) & (dist <= inflation_radius)
    cost[band] = np.minimum(
        MAX_NON_LETHAL,
        np.round(MAX_NON_LETHAL * np.exp(-cost_scaling_factor * (dist[band] - robot_radius)))).astype(np.uint8)
    cost[dist < robot_radius] = LETHAL
    return cost, dist


class Costmap:
    """Static layer + obstacle layer, inflated on :meth:`update` (cheap: one EDT).

    ``obstacle_range`` [m]: laser returns farther than this are not marked;
    ``raytrace_range`` [m]: beams clear the obstacle layer up to this range (or their hit).
    """

    def __init__(self, grid, robot_radius=ROBOT_RADIUS, inflation_radius=0.8, cost_scaling_factor=4.0,
                 obstacle_range=4.0, raytrace_range=5.0):
        if robot_radius <= 0 or inflation_radius < robot_radius:
            raise ValueError('need 0 < robot_radius <= inflation_radius, got %r, %r'
                             % (robot_radius, inflation_radius))
        self.grid = grid
        self.robot_radius = float(robot_radius)
        self.inflation_radius = float(inflation_radius)
        self.cost_scaling_factor = float(cost_scaling_factor)
        self.obstacle_range = float(obstacle_range)
        self.raytrace_range = float(raytrace_range)
        self.static = grid.occupied()
        self.obstacles = np.zeros(grid.shape, dtype=bool)
        self.update()

    @property
    def resolution(self):
        return self.grid.resolution

    def clear_obstacles(self):
        """Forget everything the laser marked (``clear_costmaps``)."""
        self.obstacles[:] = False
        self.update()

    def add_scan(self, scan):
        """Mark and clear the obstacle layer with one :class:`MapScan`: each beam clears the
        cells it passes through (up to its hit or ``raytrace_range``; a beam without a hit counts
        as no return), then hits within ``obstacle_range`` are marked. Does not re-inflate: call
        :meth:`update`."""
        r = np.asarray(scan.ranges, dtype=float)
        hit = scan.kinds == HIT
        reach = np.where(hit, np.minimum(r, self.raytrace_range), self.raytrace_range)
        angles = scan.angles()
        origin = scan.laser_pose
        res = self.resolution
        step = res * 0.5
        n = int(np.ceil(self.raytrace_range / step))
        s = np.arange(1, n + 1) * step                                  # (n,)
        # sample along each beam, stopping one cell short of its hit
        keep = s[None, :] < (reach[:, None] - res)                       # (B, n)
        c, sn = np.cos(angles), np.sin(angles)
        px = origin[0] + c[:, None] * s[None, :]
        py = origin[1] + sn[:, None] * s[None, :]
        self._set(np.column_stack((px[keep], py[keep])), False)
        pts, ranges = scan.obstacles
        self._set(pts[ranges <= self.obstacle_range], True)

    def _set(self, xy, value):
        rc = self.grid.world_to_cell(xy)
        inb = self.grid.in_bounds(rc)
        self.obstacles[rc[inb, 0], rc[inb, 1]] = value

    def update(self):
        """Recompute ``cost`` and ``distance`` from both layers."""
        self.cost, self.distance = inflate(self.static | self.obstacles, self.resolution,
                                           self.robot_radius, self.inflation_radius,
                                           self.cost_scaling_factor)

    def cost_at(self, xy):
        """Costs at ``(N, 2)`` map points; ``LETHAL`` outside the grid."""
        rc = self.grid.world_to_cell(xy)
        inb = self.grid.in_bounds(rc)
        out = np.full(len(rc), LETHAL, dtype=np.uint8)
        out[inb] = self.cost[rc[inb, 0], rc[inb, 1]]
        return out
