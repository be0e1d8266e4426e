"""World generators for tests and benchmarks: world dicts for
:meth:`tiago_nav.sim.world.World.from_dict` (metres, degrees where a name says ``_deg``)."""
import math


def corridor_world(width, length=5.0, bend_deg=0.0, bend_at=None, start=(-1.0, 0.0, 0.0),
                   wall=0.15, obstacle=None, name='corridor'):
    """A test and benchmark world (a dict for :meth:`tiago_nav.sim.world.World.from_dict`): a
    closed room (x < 0) whose doorway at x = 0 opens into a corridor of ``width`` [m] whose
    centre line runs from (0, 0) along +x for ``bend_at`` (default ``length``) metres, then
    turns by ``bend_deg`` [deg] for the rest of ``length``; open floor after it (the corridor is
    the only way out of the room). ``start`` is ``(x, y, yaw_deg)``; ``obstacle`` an optional ``(x, y, radius)`` movable cylinder."""
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
