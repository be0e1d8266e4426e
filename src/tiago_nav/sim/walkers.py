"""People who walk (the world file's ``walkers``): where each one is, and where its legs are.

A walker is a point moving along its polyline (:class:`tiago_nav.sim.world.Walker`) at its
speed once its ``start_delay`` has passed; its state is the distance ``s`` [m] walked along
its path (and, while it walks round the robot, its place off the path), so a walker is a
function of the world and of simulated time, except that one about to step into the robot
stops and waits (:class:`Walkers`), as a person does, and one kept waiting :data:`PATIENCE`
walks round the robot where the room allows: then it is also a function of the robot's path,
which in lockstep is itself a function of world and seed.

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
PATIENCE = 2.0          # [s] a walker kept waiting this long by the robot walks round it
LEG_REACH = 0.3         # [m] walking round, a walker's centre keeps this far from walls and
                        # obstacles (its legs reach 0.28 m from it)
ROUND_STEP = 0.05       # [m] spacing of the points checked along a way round
RETRY = 1.0             # [s] a walker that found no way round looks again after this long


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


def _segment_distance(px, py, ax, ay, bx, by):
    """Distance [m] from the point ``(px, py)`` to the segment from ``(ax, ay)`` to ``(bx, by)``."""
    dx, dy = bx - ax, by - ay
    t = ((px - ax) * dx + (py - ay) * dy) / max(dx * dx + dy * dy, 1e-12)
    t = min(max(t, 0.0), 1.0)
    return math.hypot(px - ax - t * dx, py - ay - t * dy)


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
    :data:`KEEPOUT` to the robot's centre: it then waits where it is (velocity 0, state
    ``yielding``) until the robot has moved away or out of its path. A walker moving away from
    the robot is never held. One kept waiting :data:`PATIENCE` walks round the robot, as a
    person does: along the circle of radius ``robot_radius +`` :data:`KEEPOUT` about the
    robot's centre (first stepping back to it, facing as it stood, where the robot came
    nearer), on the side of the shorter way whose points all keep :data:`LEG_REACH` from walls
    and obstacles (``clearance``), at its speed, to the first point of its path beyond the
    robot, where it walks on; with no room either side it waits and looks again every
    :data:`RETRY`; where the robot moves and its way round runs out of room, it goes back the
    way it came to where it left its path. A walker walking round never steps nearer to the
    robot than that circle (it steps back out when the robot comes nearer), so, as on its path,
    its legs alone never come within 0.4 m of the robot's body.

    ``clearance``: a function of ``(N, 2)`` map positions [m] returning the least gap [m]
    between them and the world's walls and obstacles (:func:`tiago_nav.sim.world.clearance`);
    None: nothing is in the way."""

    def __init__(self, walkers, clearance=None):
        self.walkers = list(walkers)
        self.paths = [Path(w.path, w.loop) for w in self.walkers]
        self.clearance = clearance
        self.s = [0.0] * len(self.walkers)
        self.walked = [0.0] * len(self.walkers)   # [m] all steps, round the robot too (gait)
        self.poses = [p.at(0.0) for p in self.paths]
        self.velocity = [(0.0, 0.0)] * len(self.walkers)
        self.waiting = [False] * len(self.walkers)
        self.waited = [0.0] * len(self.walkers)   # [s] kept waiting by the robot so far
        self.rounding = [None] * len(self.walkers)  # (s where it rejoins its path, +1 ccw / -1 cw,
                                                    #  going back to where it left its path)

    def __len__(self):
        return len(self.walkers)

    def pose(self, i):
        """``(x, y, heading)`` of walker ``i``."""
        return self.poses[i]

    def legs(self, i):
        """``(2, 2)`` leg centres [m] of walker ``i``."""
        x, y, h = self.pose(i)
        return legs_at(x, y, h, self.walked[i])

    def state(self, i, time):
        """``'waiting'`` (for its start_delay), ``'walking'`` (round the robot too),
        ``'yielding'`` (stopped for the robot) or ``'arrived'`` (at the end of a path without
        loop) at simulated ``time`` [s]."""
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
            if self.rounding[i] is not None:
                pose, s1 = self._round(i, dt, rx, ry, near)
            else:
                s1 = s + w.speed * dt
                if not path.loop:
                    s1 = min(s1, path.total)
                pose = path.at(s1)
                d0, d1 = math.hypot(x0 - rx, y0 - ry), math.hypot(pose[0] - rx, pose[1] - ry)
                if d1 < near and d1 <= d0:
                    pose = None
                    self.waited[i] += dt
                    if self.waited[i] >= PATIENCE:
                        self.rounding[i] = self._way_round(i, rx, ry, near)
                        if self.rounding[i] is None:
                            self.waited[i] -= RETRY
            if pose is None:
                self.velocity[i], self.waiting[i] = (0.0, 0.0), True
                continue
            x1, y1, _ = pose
            self.s[i], self.poses[i] = s1, pose
            self.walked[i] += math.hypot(x1 - x0, y1 - y0)
            self.velocity[i] = ((x1 - x0) / dt, (y1 - y0) / dt)
            self.waiting[i], self.waited[i] = False, 0.0
            moved.append(i)
        return moved

    def _round(self, i, dt, rx, ry, near):
        """One step of walker ``i`` round the robot at ``(rx, ry)``: ``(pose, s)``, or
        ``(None, s)`` when it waits (the robot stands at the way back, or the next point has no
        room). Nearer than ``near`` to the robot's centre it steps straight back from it, facing
        as it stood (its legs, swinging slower than it walks, draw away too); then it walks
        straight to where it rejoins its path once that line keeps ``near`` from the robot's
        centre, else along the circle of radius ``near``. Where the robot moved and the next
        point has no room, it turns back the way it came, to where it left its path."""
        exit_s, turn, back = self.rounding[i]
        x0, y0, h0 = self.poses[i]
        ex, ey, _ = self.paths[i].at(exit_s)
        r = math.hypot(x0 - rx, y0 - ry)
        step = self.walkers[i].speed * dt
        stepping_back = r < near - 1e-9
        if stepping_back:
            if r <= 0.0:
                return None, self.s[i]
            x1, y1, heading = x0 + step * (x0 - rx) / r, y0 + step * (y0 - ry) / r, h0
        elif math.hypot(ex - rx, ey - ry) < near:
            return None, self.s[i]
        elif _segment_distance(rx, ry, x0, y0, ex, ey) >= near - 1e-9:
            dx, dy = ex - x0, ey - y0
            gap = math.hypot(dx, dy)
            if gap <= step:
                self.rounding[i] = None
                return self.paths[i].at(exit_s), exit_s
            x1, y1, heading = x0 + step * dx / gap, y0 + step * dy / gap, math.atan2(dy, dx)
        else:
            a1 = math.atan2(y0 - ry, x0 - rx) + turn * step / r
            x1, y1, heading = rx + r * math.cos(a1), ry + r * math.sin(a1), a1 + turn * math.pi / 2
        if not self._room(np.array([[x1, y1]]), np.array([[x0, y0]])):
            if not (stepping_back or back):
                # the robot moved and the way round has no room now: back the way it came, to
                # where it left its path
                self.rounding[i] = (self.s[i], -turn, True)
            return None, self.s[i]
        return (x1, y1, heading), self.s[i]

    def _way_round(self, i, rx, ry, near):
        """``(s, turn, False)``: where walker ``i`` rejoins its path beyond the robot at
        ``(rx, ry)`` (its first point at least ``near`` + :data:`ROUND_STEP` from the robot's
        centre after one nearer) and the side (+1 counter-clockwise, -1 clockwise) of the
        shorter way round with room along the circle of radius ``near`` about the robot's
        centre; None when there is no such point within reach or no room either side."""
        path, s = self.paths[i], self.s[i]
        end = s + 2.0 * near + 4.0
        if not path.loop:
            end = min(end, path.total)
        exit_s, inside = None, False
        for q in np.arange(s + ROUND_STEP, end + 1e-9, ROUND_STEP):
            x, y, _ = path.at(q)
            d = math.hypot(x - rx, y - ry)
            if d < near:
                inside = True
            elif inside and d >= near + ROUND_STEP:
                exit_s = float(q)
                break
        if exit_s is None:
            return None
        x0, y0, _ = self.poses[i]
        ex, ey, _ = path.at(exit_s)
        a0 = math.atan2(y0 - ry, x0 - rx)
        ccw = (math.atan2(ey - ry, ex - rx) - a0) % (2.0 * math.pi)
        for turn, angle in sorted(((1, ccw), (-1, 2.0 * math.pi - ccw)), key=lambda t: t[1]):
            n = max(2, int(math.ceil(angle * near / ROUND_STEP)) + 1)
            a = a0 + turn * np.linspace(0.0, angle, n)
            if self._room(np.column_stack((rx + near * np.cos(a), ry + near * np.sin(a)))):
                return exit_s, turn, False
        return None

    def _room(self, xy, here=None):
        """Do all the ``(N, 2)`` positions keep :data:`LEG_REACH` from walls and obstacles, or
        at least the gap ``here`` ``(1, 2)`` has (a step along a narrow way that its path takes
        anyway)?"""
        if self.clearance is None:
            return True
        gap = self.clearance(xy)
        return gap >= LEG_REACH or (here is not None and gap >= self.clearance(here))
