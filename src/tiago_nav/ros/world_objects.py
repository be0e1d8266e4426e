"""The simulator's ground truth of movable things as ROS messages: ``tiago_nav/SimObjects``
(/sim/objects) and its RViz drawing (visualization_msgs/MarkerArray, /sim/markers).

Everything is in the world (= map) frame; lengths in metres, angles in radians.
"""
import math

from geometry_msgs.msg import Point, Pose2D, Vector3
from visualization_msgs.msg import Marker, MarkerArray

from tiago_nav.msg import SimObject, SimObjects
from tiago_nav.sim.scene import TOP_HEIGHT, TOP_THICKNESS, WALKER_HEIGHT, WALL_HEIGHT
from tiago_nav.sim.walkers import LEG_RADIUS

OBSTACLE_RGBA = (0.9, 0.3, 0.2, 0.8)
WALKER_RGBA = (0.95, 0.7, 0.1, 0.9)


def _points(xy):
    return [Point(float(x), float(y), 0.0) for x, y in xy]


def obstacle_object(i, o):
    """The ``SimObject`` of movable obstacle ``i`` (:mod:`tiago_nav.sim.world`, any shape)."""
    m = SimObject(name='movable_obstacles[%d]' % i, shape=o.shape,
                  pose=Pose2D(float(o.x), float(o.y), float(o.yaw)), radius=float(o.radius),
                  leg_radius=float(o.leg_radius), legs=_points(o.legs()),
                  outline=_points(o.outline()), velocity=Vector3(), state='')
    if o.shape != 'cylinder':
        m.length, m.width = float(o.length), float(o.width)
    return m


def walker_object(i, walkers, time):
    """The ``SimObject`` of walker ``i`` of a :class:`tiago_nav.sim.walkers.Walkers` at
    simulated ``time`` [s]."""
    x, y, heading = walkers.pose(i)
    vx, vy = walkers.velocity[i]
    return SimObject(name='walkers[%d]' % i, shape='walker', pose=Pose2D(x, y, heading),
                     radius=0.0, leg_radius=LEG_RADIUS, legs=_points(walkers.legs(i)),
                     outline=[], velocity=Vector3(vx, vy, 0.0), state=walkers.state(i, time))


def objects_msg(obstacles, walkers, time, frame_id, stamp):
    """``tiago_nav/SimObjects``: the world's movable ``obstacles`` (they never move: the
    simulator's bodies are kinematic and a bump stops the robot) then its ``walkers``."""
    msg = SimObjects()
    msg.header.frame_id, msg.header.stamp = frame_id, stamp
    msg.objects = [obstacle_object(i, o) for i, o in enumerate(obstacles)] + \
        [walker_object(i, walkers, time) for i in range(len(walkers))]
    return msg


def _marker(ns, i, kind, frame_id, stamp, rgba):
    m = Marker(ns=ns, id=i, type=kind, action=Marker.ADD)
    m.header.frame_id, m.header.stamp = frame_id, stamp
    m.pose.orientation.w = 1.0
    m.color.r, m.color.g, m.color.b, m.color.a = rgba
    return m


def objects_markers(msg):
    """A MarkerArray drawing a ``SimObjects`` message: cylinders and boxes as solids, tables
    and chairs as their legs and top, walkers as their legs and an arrow of their velocity;
    it replaces what was drawn before (DELETEALL first)."""
    h = msg.header
    arr = MarkerArray()
    clear = Marker(action=Marker.DELETEALL)
    clear.header = h
    arr.markers.append(clear)
    n = 0
    for o in msg.objects:
        walker = o.shape == 'walker'
        rgba = WALKER_RGBA if walker else OBSTACLE_RGBA
        parts = []
        if o.shape == 'cylinder':
            parts.append((Marker.CYLINDER, o.pose.x, o.pose.y, 0.0, 2 * o.radius, 2 * o.radius,
                          WALL_HEIGHT / 2, WALL_HEIGHT))
        elif o.shape == 'box':
            parts.append((Marker.CUBE, o.pose.x, o.pose.y, o.pose.theta, o.length, o.width,
                          WALL_HEIGHT / 2, WALL_HEIGHT))
        else:
            top = WALKER_HEIGHT if walker else TOP_HEIGHT[o.shape]
            for p in o.legs:
                parts.append((Marker.CYLINDER, p.x, p.y, 0.0, 2 * o.leg_radius, 2 * o.leg_radius,
                              top / 2, top))
            if not walker:
                parts.append((Marker.CUBE, o.pose.x, o.pose.y, o.pose.theta,
                              o.length + 2 * o.leg_radius, o.width + 2 * o.leg_radius,
                              top - TOP_THICKNESS / 2, TOP_THICKNESS))
        for kind, x, y, yaw, sx, sy, z, sz in parts:
            m = _marker('sim_objects', n, kind, h.frame_id, h.stamp, rgba)
            m.pose.position.x, m.pose.position.y, m.pose.position.z = x, y, z
            m.pose.orientation.z, m.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
            m.scale.x, m.scale.y, m.scale.z = sx, sy, sz
            arr.markers.append(m)
            n += 1
        if walker and (o.velocity.x or o.velocity.y):
            m = _marker('sim_objects', n, Marker.ARROW, h.frame_id, h.stamp, rgba)
            m.points = [Point(o.pose.x, o.pose.y, WALKER_HEIGHT),
                        Point(o.pose.x + o.velocity.x, o.pose.y + o.velocity.y, WALKER_HEIGHT)]
            m.scale.x, m.scale.y, m.scale.z = 0.05, 0.1, 0.1
            arr.markers.append(m)
            n += 1
    return arr
