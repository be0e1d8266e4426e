"""RViz markers of found obstacles (visualization_msgs/MarkerArray)."""
from visualization_msgs.msg import Marker, MarkerArray

HEIGHT = 1.0        # [m] drawn height of an obstacle (the world's bodies span 0-1 m)


def obstacle_markers(obstacles, frame_id, stamp=None, rgba=(0.1, 0.8, 0.2, 0.7), labels=False):
    """A MarkerArray that replaces whatever was drawn before (DELETEALL first) with one cylinder
    per ``tiago_nav/Obstacle`` (its ``center`` in ``frame_id``, its radius) and, with
    ``labels``, a text ``"i: (x, y)"`` above each."""
    arr = MarkerArray()
    clear = Marker(action=Marker.DELETEALL)
    clear.header.frame_id = frame_id
    arr.markers.append(clear)
    for i, o in enumerate(obstacles):
        m = Marker(ns='obstacles', id=i, type=Marker.CYLINDER, action=Marker.ADD)
        m.header.frame_id = frame_id
        if stamp is not None:
            m.header.stamp = stamp
        m.pose.position.x, m.pose.position.y, m.pose.position.z = o.center.x, o.center.y, HEIGHT / 2
        m.pose.orientation.w = 1.0
        m.scale.x = m.scale.y = 2.0 * max(o.radius, 0.02)
        m.scale.z = HEIGHT
        m.color.r, m.color.g, m.color.b, m.color.a = rgba
        arr.markers.append(m)
        if labels:
            t = Marker(ns='obstacle_labels', id=i, type=Marker.TEXT_VIEW_FACING, action=Marker.ADD)
            t.header = m.header
            t.pose.position.x, t.pose.position.y = o.center.x, o.center.y
            t.pose.position.z = HEIGHT + 0.2
            t.pose.orientation.w = 1.0
            t.scale.z = 0.3
            t.color.r = t.color.g = t.color.b = t.color.a = 1.0
            t.text = '%d: (%.2f, %.2f)' % (i + 1, o.center.x, o.center.y)
            arr.markers.append(t)
    return arr
