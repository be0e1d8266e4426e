"""People who walk (the world file's ``walkers``): where each one is, and where its legs are.

A walker is a point moving along its polyline (:class:`tiago_nav.sim.world.Walker`) at its
speed once its ``start_delay`` has passed; its state is the distance ``s`` [m] walked so far,
so a walker is a function of the world and of simulated time, except that one about to step
into the robot stops and waits (:class:`Walkers`), as a person does: then it is also a
function of the robot's path, which in lockstep is itself a function of world and seed.

The laser sees a walker as two legs, not as a body: TIAGo's laser is about 0.1 m above the
floor (0.3 m in this mock, :data:`tiago_nav.robot.LASER_HEIGHT`), below the knees, where a
person is two round legs about 0.2 m apart that swing forwards and back with each stride.
Each leg is a vertical cylinder of :data:`LEG_RADIUS`; the legs stand :data:`HIP_HALF_WIDTH`
either side of the walker's line and swing :data:`SWING` ahead of and behind it, in opposite
phase, one gait cycle per :data:`STRIDE` walked; a walker that stops keeps its legs where they
are. Lengths are metres, angles radians, in the map frame.
"""
import bisect
import math

import numpy as np

LEG_RADIUS = 0.06       # [m] a calf about 0.12 m across
HIP_HALF_WIDTH = 0.1    # [m] each leg's centre this far to the side of the walking line
SWING = 0.2             # [m] the legs swing this far ahead of and behind the walker's centre
STRIDE = 1.4            # [m] walked per gait cycle (two steps of 0.7 m)
KEEPOUT = 0.7           # [m] a walker does not step with its centre nearer than this to the
                        # robot's footprint: its legs (within hypot(SWING, HIP_HALF_WIDTH) +
                        # LEG_RADIUS = 0.28 m of its centre) stay >= 0.4 m from the robot's body,
                        # so a walker alone never brings a leg within 0.3 m of it: nearer is the
                        # robot's doing


class Path:
    """The polyline of a walker, closed back to its first point with ``loop``: the point and
    heading at a distance ``s`` [m] along it."""

    def __init__(self, points, loop):
        p = np.asarray(points, dtype=float)
        if loop and not np.array_equal(p[0], p[-1]):
            p = np.vstack((p, p[:1]))
        seg = np.diff(p, axis=0)
        keep = np.hypot(seg[:, 0], seg[:, 1]) > 0
        self.points = np.vstack((p[:1], p[1:][keep]))
        self.seg = seg[keep]
        self.len = np.hypot(self.seg[:, 0], self.seg[:, 1])
        self.cum = np.concatenate(([0.0], np.cumsum(self.len)))
        self.total = float(self.cum[-1])
        self.loop = bool(loop)
        # plain floats for at(), called for every walker at every physics step
        self._cum = self.cum.tolist()
        self._rows = [(float(p0[0]), float(p0[1]), float(d[0]), float(d[1]), float(n),
                       math.atan2(d[1], d[0])) for p0, d, n in zip(self.points, self.seg, self.len)]

    def at(self, s):
        """``(x, y, heading)`` at distance ``s`` [m] along the path (wrapped with ``loop``,
        else held at the last point, heading along the last segment)."""
        s = s % self.total if self.loop else min(max(s, 0.0), self.total)
        k = min(bisect.bisect_right(self._cum, s) - 1, len(self._rows) - 1)
        x0, y0, dx, dy, n, heading = self._rows[k]
        f = (s - self._cum[k]) / n
        return x0 + f * dx, y0 + f * dy, heading

    def finished(self, s):
        """True when a walker that has walked ``s`` [m] is at the end (never with ``loop``)."""
        return not self.loop and s >= self.total


def legs_at(x, y, heading, s):
    """``(2, 2)`` centres [m] of the two legs of a walker at ``(x, y)`` heading ``heading``
    [rad] that has walked ``s`` [m]."""
    ux, uy = math.cos(heading), math.sin(heading)
    swing = SWING * math.sin(2.0 * math.pi * s / STRIDE)
    ax, ay = swing * ux - HIP_HALF_WIDTH * uy, swing * uy + HIP_HALF_WIDTH * ux
    return np.array([[x + ax, y + ay], [x - ax, y - ay]])


class Walkers:
    """The walkers of a world, stepped with the simulator.

    :meth:`step` advances each walker that has started and is not at its end by ``speed × dt``
    along its path, unless that step would bring its centre nearer than ``robot_radius +``
    :data:`KEEPOUT` to the robot's centre (it then waits where it is, velocity 0, until the
    robot has moved away or out of its path). A walker moving away from the robot is never
    held."""

    def __init__(self, walkers):
        self.walkers = list(walkers)
        self.paths = [Path(w.path, w.loop) for w in self.walkers]
        self.s = [0.0] * len(self.walkers)
        self.poses = [p.at(0.0) for p in self.paths]
        self.velocity = [(0.0, 0.0)] * len(self.walkers)
        self.waiting = [False] * len(self.walkers)

    def __len__(self):
        return len(self.walkers)

    def pose(self, i):
        """``(x, y, heading)`` of walker ``i``."""
        return self.poses[i]

    def legs(self, i):
        """``(2, 2)`` leg centres [m] of walker ``i``."""
        x, y, h = self.pose(i)
        return legs_at(x, y, h, self.s[i])

    def state(self, i, time):
        """``'waiting'`` (for its start_delay), ``'walking'``, ``'yielding'`` (stopped for the
        robot) or ``'arrived'`` (at the end of a path without loop) at simulated ``time`` [s]."""
        if self.waiting[i]:
            return 'yielding'
        if self.paths[i].finished(self.s[i]):
            return 'arrived'
        return 'walking' if time >= self.walkers[i].start_delay else 'waiting'

    def step(self, time, dt, robot_xy, robot_radius):
        """Advance every walker from simulated ``time`` [s] by ``dt`` [s], the robot's centre
        at ``robot_xy`` [m] with footprint radius ``robot_radius`` [m]. Returns the indices of
        the walkers that moved."""
        moved = []
        rx, ry = robot_xy
        near = robot_radius + KEEPOUT
        for i, (w, path) in enumerate(zip(self.walkers, self.paths)):
            s = self.s[i]
            if time < w.start_delay or path.finished(s):
                self.velocity[i], self.waiting[i] = (0.0, 0.0), False
                continue
            x0, y0, _ = self.poses[i]
            s1 = s + w.speed * dt
            if not path.loop:
                s1 = min(s1, path.total)
            pose = path.at(s1)
            x1, y1, _ = pose
            d0, d1 = math.hypot(x0 - rx, y0 - ry), math.hypot(x1 - rx, y1 - ry)
            if d1 < near and d1 <= d0:
                self.velocity[i], self.waiting[i] = (0.0, 0.0), True
                continue
            self.s[i], self.poses[i] = s1, pose
            self.velocity[i] = ((x1 - x0) / dt, (y1 - y0) / dt)
            self.waiting[i] = False
            moved.append(i)
        return moved
