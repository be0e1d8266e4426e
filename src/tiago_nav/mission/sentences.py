"""The human sentences of the mission's feedback and result, and how far the robot still has to
go (no ROS here). Poses are ``(x, y, yaw)`` [m, m, rad] in ``map``."""
import math


def fmt_pose(pose):
    """``(x, y, yaw)`` → ``'(1.00, 2.00, -45 deg)'``."""
    return '(%.2f, %.2f, %.0f deg)' % (pose[0], pose[1], math.degrees(pose[2]))


def goal_sentence(x, y, yaw_deg, use_corridor_law):
    """The GOAL_RECEIVED sentence for pose B (``x``, ``y`` [m], ``yaw_deg`` [deg])."""
    return 'goal received: go to (%.2f, %.2f, %.0f deg)%s' % (
        x, y, yaw_deg, ', through a corridor with the laser-only law first if one leads there'
        if use_corridor_law else '')


def corridor_sentence(distance=None, lateral_offset=None, left=None, right=None):
    """A sentence about the corridor law's progress (feedback of corridor_controller) [m]."""
    if distance is None:
        return 'driving the corridor with the laser-only law'
    s = 'in the corridor, %.1f m driven' % distance
    if lateral_offset is not None and math.isfinite(lateral_offset):
        side = 'left' if lateral_offset >= 0 else 'right'
        s += ', %.2f m %s of the centre line' % (abs(lateral_offset), side)
    if left is not None and right is not None and math.isfinite(left) and math.isfinite(right):
        s += ' (walls %.2f m left, %.2f m right)' % (left, right)
    return s


def corridor_done_sentence(distance=None, reason=''):
    """The last CORRIDOR sentence when the law succeeded: how far it drove [m] and why it
    stopped (corridor_controller's result), before move_base drives on to pose B."""
    s = 'corridor law done'
    if distance is not None and math.isfinite(distance):
        s += ' after %.1f m' % distance
    if reason:
        s += ': %s' % reason
    return s + '; navigating on to pose B'


def handoff_sentence(reason):
    """The NAVIGATING sentence when corridor_controller aborted (``reason``, its status text)
    and move_base drives the rest of the way."""
    return 'the corridor law stopped (%s): move_base drives the rest of the way' % reason


def motion_sentence(moving, to_go):
    """``'moving, 3.2 m to go'`` / ``'stopped, 0.4 m to go'`` (``to_go`` [m] or None)."""
    word = 'moving' if moving else 'stopped'
    return word if to_go is None else '%s, %.1f m to go' % (word, to_go)


def plural(n, word):
    """``plural(2, 'obstacle')`` → ``'2 obstacles'``."""
    return '%d %s%s' % (n, word, '' if n == 1 else 's')


def remaining_path_length(path, position):
    """Length [m] of ``path`` (a sequence of ``(x, y)``, map frame) from the point nearest to
    ``position`` to its end, plus the distance from ``position`` to that point. None if the path
    is empty."""
    if path is None or len(path) == 0:
        return None
    px, py = position[0], position[1]
    if len(path) == 1:
        return math.hypot(px - path[0][0], py - path[0][1])
    best, best_i, best_pt = math.inf, 0, tuple(path[0][:2])
    for i in range(len(path) - 1):
        ax, ay = path[i][0], path[i][1]
        bx, by = path[i + 1][0], path[i + 1][1]
        dx, dy = bx - ax, by - ay
        L2 = dx * dx + dy * dy
        u = 0.0 if L2 == 0 else max(0.0, min(1.0, ((px - ax) * dx + (py - ay) * dy) / L2))
        qx, qy = ax + u * dx, ay + u * dy
        d = math.hypot(px - qx, py - qy)
        if d < best:
            best, best_i, best_pt = d, i, (qx, qy)
    rest = math.hypot(path[best_i + 1][0] - best_pt[0], path[best_i + 1][1] - best_pt[1])
    for i in range(best_i + 1, len(path) - 1):
        rest += math.hypot(path[i + 1][0] - path[i][0], path[i + 1][1] - path[i][1])
    return best + rest
