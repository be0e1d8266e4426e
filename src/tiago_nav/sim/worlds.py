"""World generators for tests and benchmarks: world dicts for
:meth:`tiago_nav.sim.world.World.from_dict` (metres, degrees where a name says ``_deg``)."""
import math


def corridor_world(width, length=5.0, bend_deg=0.0, bend_at=None, start=(-1.0, 0.0, 0.0),
                   wall=0.15, obstacle=None, name='corridor', mitre=False):
    """A test and benchmark world (a dict for :meth:`tiago_nav.sim.world.World.from_dict`): a
    closed room (x < 0) whose doorway at x = 0 opens into a corridor of ``width`` [m] whose
    centre line runs from (0, 0) along +x for ``bend_at`` (default ``length``) metres, then
    turns by ``bend_deg`` [deg] for the rest of ``length``; open floor after it (the corridor is
    the only way out of the room). ``start`` is ``(x, y, yaw_deg)``; ``obstacle`` an optional ``(x, y, radius)`` movable cylinder.

    At a bend, by default each leg's walls run the leg's full length (plus 0.1 m), so the inner
    walls of the two legs cross into each other's corridor: a protruding inner corner, harmless
    for the slight bends of :func:`rooms_world` but a wall across the way at sharp ones. With
    ``mitre=True`` the wall faces meet at the mitre points (the corners of a corridor of
    constant ``width``, up to 90 deg): the inner faces end exactly there, the outer walls run
    ``wall`` past it to close the outer corner."""
    if mitre and bend_deg and bend_at is not None and length > bend_at:
        return _mitred_corridor_world(width, length, bend_deg, bend_at, start, wall, obstacle, name)
    bend_at = length if bend_at is None else bend_at
    h = width / 2.0 + wall / 2.0
    walls = []
    b = math.radians(bend_deg)
    segments = [((0.0, 0.0), 0.0, bend_at)]
    if length > bend_at:
        segments.append(((bend_at, 0.0), b, length - bend_at))
    for (x0, y0), th, ln in segments:
        for side in (1, -1):
            # each wall segment's inner face follows the centre line at +-width/2; overlap 0.1 m
            # at the bend so the outer side has no gap
            cx = x0 + 0.5 * ln * math.cos(th) - side * h * math.sin(th)
            cy = y0 + 0.5 * ln * math.sin(th) + side * h * math.cos(th)
            walls.append({'x': cx, 'y': cy, 'length': ln + (0.1 if len(segments) > 1 else 0.0),
                          'width': wall, 'yaw_deg': math.degrees(th)})
    # a closed room before the corridor: the doorway wall across x = 0 (faces at x = -wall..0)
    # and walls around; the corridor is the only way out of it
    half_room = max(2.0, width / 2.0 + 1.0)
    back = min(start[0], 0.0) - 1.5
    piece = half_room - width / 2.0
    for side in (1, -1):
        walls.append({'x': -wall / 2.0, 'y': side * (width / 2.0 + piece / 2.0), 'length': piece,
                      'width': wall, 'yaw_deg': 90.0})
        walls.append({'x': back / 2.0, 'y': side * (half_room + wall / 2.0), 'length': -back + wall,
                      'width': wall, 'yaw_deg': 0.0})
    walls.append({'x': back - wall / 2.0, 'y': 0.0, 'length': 2 * half_room + 2 * wall, 'width': wall,
                  'yaw_deg': 90.0})
    ex = bend_at + (length - bend_at) * math.cos(b)
    ey = (length - bend_at) * math.sin(b)
    d = {'name': name, 'resolution': 0.05,
         'bounds': [back - 0.5, min(ey, 0.0) - half_room - 1.0, ex + 3.0, max(ey, 0.0) + half_room + 1.0],
         'robot_start': list(start), 'walls': walls,
         'corridor': {'entry': [0.0, 0.0], 'exit': [ex, ey], 'width': width}}
    if obstacle is not None:
        d['movable_obstacles'] = [{'x': obstacle[0], 'y': obstacle[1], 'radius': obstacle[2]}]
    return d


def _mitred_corridor_world(width, length, bend_deg, bend_at, start, wall, obstacle, name):
    """:func:`corridor_world` with ``mitre=True`` and a bend (|bend_deg| <= 90)."""
    if not 0.0 < abs(bend_deg) <= 90.0:
        raise ValueError('mitre: the bend must be within +-90 deg, not %g' % bend_deg)
    # the straight world gives the start room, the doorway and the dict's other keys
    d = corridor_world(width, length=length, bend_deg=bend_deg, bend_at=bend_at, start=start,
                       wall=wall, obstacle=obstacle, name=name)
    b = math.radians(bend_deg)
    d1, d2 = (1.0, 0.0), (math.cos(b), math.sin(b))
    n1, n2 = (0.0, 1.0), (-math.sin(b), math.cos(b))
    bx, by = bend_at, 0.0
    ex, ey = bx + (length - bend_at) * d2[0], by + (length - bend_at) * d2[1]
    walls = []
    for side in (1, -1):
        f = side * width / 2.0
        # the mitre point of this side's face: B + f (n1 + n2) / (1 + cos b)
        k = f / (1.0 + math.cos(b))
        mx, my = bx + k * (n1[0] + n2[0]), by + k * (n1[1] + n2[1])
        outer = side * b < 0            # the side away from the turn
        ext = wall if outer else 0.0
        faces = (((0.0, f), (mx + ext * d1[0], my + ext * d1[1]), n1),
                 ((mx - ext * d2[0], my - ext * d2[1]), (ex + f * n2[0], ey + f * n2[1]), n2))
        for (ax, ay), (cx, cy), n in faces:
            ln = math.hypot(cx - ax, cy - ay)
            walls.append({'x': (ax + cx) / 2.0 + side * n[0] * wall / 2.0,
                          'y': (ay + cy) / 2.0 + side * n[1] * wall / 2.0,
                          'length': ln, 'width': wall,
                          'yaw_deg': math.degrees(math.atan2(cy - ay, cx - ax))})
    # keep the start room's walls (the straight world's last five)
    d['walls'] = walls + d['walls'][4:]
    return d


def enclosure(bounds, wall=0.15):
    """Walls (world-file dicts) just inside ``bounds`` [xmin, ymin, xmax, ymax] [m]: a generated
    world's open floor ends at a wall, not at the map's edge (a robot that leaves the map can
    plan no more)."""
    x0, y0, x1, y1 = bounds
    x0, y0, x1, y1 = x0 + wall, y0 + wall, x1 - wall, y1 - wall
    cx, cy, lx, ly = (x0 + x1) / 2, (y0 + y1) / 2, x1 - x0 + wall, y1 - y0 + wall
    return [{'x': cx, 'y': y0, 'length': lx, 'width': wall, 'yaw_deg': 0.0},
            {'x': cx, 'y': y1, 'length': lx, 'width': wall, 'yaw_deg': 0.0},
            {'x': x0, 'y': cy, 'length': ly, 'width': wall, 'yaw_deg': 90.0},
            {'x': x1, 'y': cy, 'length': ly, 'width': wall, 'yaw_deg': 90.0}]


def rooms_world(seed, movable=(2, 5), static=(0, 2), partition_probability=0.5, name=None):
    """A seeded random walled world of the course's class (a dict for
    :meth:`tiago_nav.sim.world.World.from_dict`): the robot starts in a small closed room whose
    only way out is a corridor (0.95-1.4 m wide, 2.5-4.5 m long, bent by up to 30 deg half the
    time) into a walled room of 5-7 m by 6-8 m, split by a partition with a 1.3-1.8 m door with
    probability ``partition_probability``, holding ``movable`` (min, max) unmapped cylinders
    (what detection must find) and ``static`` (min, max) mapped ones, each at least 0.9 m from
    the others and 0.7 m from any wall. The same ``seed`` gives the same world."""
    import numpy as np
    rng = np.random.default_rng(seed)
    width = float(rng.uniform(0.95, 1.4))
    length = float(rng.uniform(2.5, 4.5))
    bend = float(rng.choice([-1.0, 1.0]) * rng.uniform(15.0, 30.0)) if rng.random() < 0.5 else 0.0
    world = corridor_world(width, length=length, bend_deg=bend,
                           bend_at=length / 2.0 if bend else None,
                           name=name or 'rooms_%d' % seed)
    ex, ey = world['corridor']['exit']
    room_x, half_y = float(rng.uniform(5.0, 7.0)), float(rng.uniform(3.0, 4.0))
    x0 = world['bounds'][0]
    bounds = [x0, min(ey, 0.0) - half_y, ex + room_x, max(ey, 0.0) + half_y]
    world['bounds'] = [round(v, 3) for v in bounds]
    world['walls'] += enclosure(bounds)
    if rng.random() < partition_probability:
        # a partition across the room (parallel to y) with a door
        px = ex + room_x * float(rng.uniform(0.45, 0.65))
        door = float(rng.uniform(1.3, 1.8))
        y_lo, y_hi = bounds[1] + 0.15, bounds[3] - 0.15
        dc = float(rng.uniform(y_lo + 0.5 + door / 2, y_hi - 0.5 - door / 2))
        for a, b in ((y_lo, dc - door / 2), (dc + door / 2, y_hi)):
            world['walls'].append({'x': px, 'y': (a + b) / 2, 'length': b - a, 'width': 0.15,
                                   'yaw_deg': 90.0})
    from tiago_nav.gridmap import distance_to_mask
    from tiago_nav.sim.raster import rasterise_world
    from tiago_nav.sim.world import World
    grid = rasterise_world(World.from_dict(world))
    dist = distance_to_mask(grid.occupied(), grid.resolution)
    placed = []

    def place(radius):
        for _ in range(400):
            x = float(rng.uniform(ex + 1.0, bounds[2] - 0.5))
            y = float(rng.uniform(bounds[1] + 0.5, bounds[3] - 0.5))
            (r, c), = grid.world_to_cell([[x, y]])
            if dist[r, c] - radius < 0.7 or math.hypot(x - ex, y - ey) < 1.5:
                continue
            if any(math.hypot(x - px_, y - py_) - radius - pr < 0.9 for px_, py_, pr in placed):
                continue
            placed.append((x, y, radius))
            return {'x': round(x, 3), 'y': round(y, 3), 'radius': round(radius, 3)}
        return None
    n_static = int(rng.integers(static[0], static[1] + 1))
    n_movable = int(rng.integers(movable[0], movable[1] + 1))
    world['static_cylinders'] = [c for c in (place(float(rng.uniform(0.1, 0.3)))
                                             for _ in range(n_static)) if c]
    world['movable_obstacles'] = [c for c in (place(float(rng.uniform(0.15, 0.25)))
                                              for _ in range(n_movable)) if c]
    return world


def cluttered_room(radius=0.15, gaps=(0.3, 0.4, 0.5), wall_gaps=(0.15, 0.2, 0.3), door=1.0,
                   room=(6.0, 5.0), wall=0.15, name='clutter_room'):
    """A cluttered room (a dict for :meth:`tiago_nav.sim.world.World.from_dict`): the robot
    starts in a closed 3 m x 3 m room facing +x, whose only way out is a ``door`` [m] wide
    opening in the wall at x = 0 (centred on y = 0), into a walled room of ``room`` (x, y) [m]
    holding unmapped cylinders of ``radius`` [m] in three groups, each close to a wall:

    * a row of four along the far wall (x = room x), centred on y = 0, the gaps between
      neighbours' surfaces ``gaps`` in turn, each ``wall_gaps[k]`` from that wall in turn;
    * a pair along the north wall near the far corner: surfaces ``gaps[-1]`` apart,
      ``wall_gaps[0]`` from the north wall;
    * a pair in the south-east corner: surfaces ``gaps[0]`` apart, both ``wall_gaps[-1]`` from
      the south wall, the eastern one ``wall_gaps[1]`` from the east (far) wall.

    Gaps are between surfaces [m] (the robot, 0.54 m across, fits through none of them);
    ``gaps`` and ``wall_gaps`` are used in turn when shorter than the row. A pose B is not part
    of the world format: :func:`cluttered_room_pose_b` gives the one from where all eight are
    in the laser's view."""
    from tiago_nav.robot import ROBOT_RADIUS
    if radius <= 0 or door <= 2 * ROBOT_RADIUS or min(gaps) <= 0 or min(wall_gaps) <= 0:
        raise ValueError('need radius > 0, door > 0.54 m (the robot), gaps and wall_gaps > 0; '
                         'got radius=%r door=%r gaps=%r wall_gaps=%r' % (radius, door, gaps, wall_gaps))
    lx, ly = room
    hy = ly / 2.0
    back, half_start = -3.0, 1.5
    h = wall / 2.0
    walls = [
        # the start room: west, north, south; the door wall at x = 0 in two pieces
        {'x': back - h, 'y': 0.0, 'length': 2 * half_start + 2 * wall, 'width': wall, 'yaw_deg': 90.0},
        {'x': back / 2.0, 'y': half_start + h, 'length': -back, 'width': wall, 'yaw_deg': 0.0},
        {'x': back / 2.0, 'y': -half_start - h, 'length': -back, 'width': wall, 'yaw_deg': 0.0},
    ]
    for side in (1, -1):
        a, b = door / 2.0, hy
        walls.append({'x': -h, 'y': side * (a + b + wall) / 2.0, 'length': b - a + wall, 'width': wall,
                      'yaw_deg': 90.0})
    # the cluttered room: north, south, east (far) walls; inner faces at y = +-hy, x = lx
    walls += [
        {'x': lx / 2.0, 'y': hy + h, 'length': lx + 2 * wall, 'width': wall, 'yaw_deg': 0.0},
        {'x': lx / 2.0, 'y': -hy - h, 'length': lx + 2 * wall, 'width': wall, 'yaw_deg': 0.0},
        {'x': lx + h, 'y': 0.0, 'length': ly + 2 * wall, 'width': wall, 'yaw_deg': 90.0},
    ]
    r = radius
    cyl = []
    xs = [lx - wall_gaps[k % len(wall_gaps)] - r for k in range(4)]
    ys = [0.0]
    for k in range(3):
        # neighbours' centres 2 r + gap apart, whatever their offsets from the wall
        d, dx = 2 * r + gaps[k % len(gaps)], xs[k + 1] - xs[k]
        ys.append(ys[-1] + math.sqrt(d * d - dx * dx))
    off = (ys[0] + ys[-1]) / 2.0
    cyl += [(x, y - off) for x, y in zip(xs, ys)]
    yn = hy - wall_gaps[0] - r
    cyl += [(lx - 1.2, yn), (lx - 1.2 - 2 * r - gaps[-1], yn)]
    cx, cy = lx - wall_gaps[1 % len(wall_gaps)] - r, -hy + wall_gaps[-1] + r
    cyl += [(cx - 2 * r - gaps[0], cy), (cx, cy)]
    return {'name': name, 'resolution': 0.05,
            'bounds': [back - wall - 0.5, -hy - wall - 0.5, lx + wall + 0.5, hy + wall + 0.5],
            'robot_start': [back / 2.0, 0.0, 0.0], 'walls': walls,
            'movable_obstacles': [{'x': round(x, 3), 'y': round(y, 3), 'radius': r} for x, y in cyl]}


def cluttered_room_pose_b(world):
    """The pose B ``(x [m], y [m], yaw [deg])`` of a :func:`cluttered_room` world: on the
    room's centre line 2.2 m short of the far wall, facing it (the row along it ahead, the
    north and south-east pairs to the sides, within the laser's fan)."""
    east = max(w['x'] for w in world['walls'])
    return (round(east - 0.075 - 2.2, 3), 0.0, 0.0)
