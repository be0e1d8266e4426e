"""The command-line client's ROS-free parts: its arguments, its feedback lines and the obstacle
table (the node, with the run loop, is :mod:`tiago_nav.nodes.client`).

``rosrun tiago_nav client X Y YAW_DEG [--corridor | --no-corridor] [--server-timeout S]
[--frame FRAME]``
Exit codes: 0 the task succeeded, 1 it was aborted or preempted (or the server never came),
2 bad input (nothing was sent), including a ``--frame`` that tf does not know.
The obstacle table shows the centres in ``--frame`` (``map`` by default; e.g. ``base_footprint``
or a world file's ``world_frame``): :func:`centres_in_frame` moves them there.
"""
import argparse
import math

from tiago_nav.geometry import inverse, transform_points
from tiago_nav.mission.goals import GoalError, parse_number, validate_goal
from tiago_nav.mission.runner import STATE_NAMES
from tiago_nav.mission.sentences import fmt_pose

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2
SERVER_TIMEOUT = 15.0        # [s wall] default wait for the tiago_controller server
MAP_FRAME = 'map'            # the frame of the result's obstacle centres (and default --frame)
PROMPTS = ('x [m]: ', 'y [m]: ', 'yaw [deg]: ')
_TRUE, _FALSE = ('true', '1', 'yes', 'on'), ('false', '0', 'no', 'off')


class UsageError(ValueError):
    """Bad command-line input; the message says what is wrong."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):        # argparse would print and exit; the caller decides
        raise UsageError(message)


def _server_timeout(text):
    try:
        value = parse_number(text, '--server-timeout')
    except GoalError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    if value <= 0:
        raise argparse.ArgumentTypeError('must be > 0 s, got %g' % value)
    return value


def _frame(text):
    """A tf frame name: not empty, no spaces (a leading '/' is dropped, as tf2 wants)."""
    name = text.strip()
    name = name[1:] if name.startswith('/') else name
    if not name or any(c.isspace() for c in name) or name.startswith('/'):
        raise argparse.ArgumentTypeError('expected a tf frame name (e.g. map, base_footprint, '
                                         'world), got %r' % text)
    return name


def _parser():
    p = _Parser(prog='rosrun tiago_nav client', add_help=False, allow_abbrev=False, usage=(
                '%(prog)s X Y YAW_DEG [--corridor | --no-corridor] [--server-timeout SECONDS] '
                '[--frame FRAME]'),
                description='Send pose B to the tiago_controller proxy, print its feedback and '
                'the obstacles it found.')
    p.add_argument('values', nargs='*', metavar='X Y YAW_DEG',
                   help='pose B: X, Y in the map frame [m]; YAW_DEG the heading at pose B [deg], '
                   'between -360 and 360 (asked for when missing and stdin is a terminal)')
    p.add_argument('--corridor', dest='use_corridor_law', action='store_true', default=True,
                   help='drive a corridor with the laser-only law first when one leads toward '
                   'pose B (default; --corridor=true|false also works, e.g. from a launch file)')
    p.add_argument('--no-corridor', dest='use_corridor_law', action='store_false',
                   help='go straight to move_base')
    p.add_argument('--server-timeout', type=_server_timeout, default=SERVER_TIMEOUT,
                   metavar='SECONDS', help='how long to wait for the tiago_controller server [s] '
                   '(default %g)' % SERVER_TIMEOUT)
    p.add_argument('--frame', type=_frame, default=MAP_FRAME, metavar='FRAME',
                   help='show the obstacles\' centres in this tf frame (default %s; e.g. '
                   'base_footprint, or the world file\'s world_frame such as world)' % MAP_FRAME)
    p.add_argument('-h', '--help', action='store_true', help='show this help and exit')
    return p


USAGE = _parser().format_help().rstrip()


def _is_number(arg):
    try:
        float(arg)
        return True
    except ValueError:
        return False


def _prepare(argv):
    """argparse takes ``-45`` and ``-inf`` for options and has no ``--flag=value`` for a
    switch: a leading space keeps a number positional (:func:`parse_number` strips it), and
    ``--corridor=true|false`` becomes ``--corridor`` or ``--no-corridor``."""
    out = []
    for a in argv:
        if a.startswith('--corridor='):
            value = a.split('=', 1)[1]
            if value.strip().lower() in _TRUE:
                a = '--corridor'
            elif value.strip().lower() in _FALSE:
                a = '--no-corridor'
            else:
                raise UsageError('--corridor=%s: expected true or false' % value)
        elif a.startswith('-') and _is_number(a):
            a = ' ' + a
        out.append(a)
    return out


def parse_client_args(argv, interactive=False, ask=input):
    """Parse the client's arguments (``argv`` without the program name and without ROS
    remappings, see ``rospy.myargv``).

    Missing X/Y/YAW are asked for with ``ask(prompt)`` when ``interactive`` (a terminal);
    otherwise they are a :class:`UsageError`. Every value is validated
    (:func:`tiago_nav.mission.goals.validate_goal`). Returns a dict with ``x``, ``y``,
    ``yaw_deg``, ``use_corridor_law``, ``server_timeout``, ``frame`` or ``{'help': True}``.
    """
    args, unknown = _parser().parse_known_intermixed_args(_prepare(argv))
    if args.help:
        return {'help': True}
    if unknown:
        raise UsageError('unknown option %s' % unknown[0])
    positional = list(args.values)
    if len(positional) > 3:
        raise UsageError('too many values: %s (expected X Y YAW_DEG)'
                         % ' '.join(v.strip() for v in positional))
    if len(positional) < 3:
        if not interactive:
            raise UsageError('missing %s (expected X Y YAW_DEG)'
                             % ', '.join(('X', 'Y', 'YAW_DEG')[len(positional):]))
        for prompt in PROMPTS[len(positional):]:
            try:
                positional.append(ask(prompt))
            except EOFError:
                raise UsageError('input ended before %s was given' % prompt.split(' ')[0]) from None
    try:
        x, y, yaw = validate_goal(*positional)
    except GoalError as e:
        raise UsageError(str(e)) from None
    return {'x': x, 'y': y, 'yaw_deg': yaw, 'use_corridor_law': args.use_corridor_law,
            'server_timeout': args.server_timeout, 'frame': args.frame}


def feedback_line(t, state, status, pose=None):
    """One line per feedback change: sim time ``t`` [s], state name, sentence, pose in map."""
    name = STATE_NAMES[state] if 0 <= state < len(STATE_NAMES) else 'STATE_%d' % state
    return '[%7.2f s] %-14s %s%s' % (t, name, status, '   @ %s' % fmt_pose(pose) if pose else '')


def largest_std(cov4):
    """[m] the standard deviation along the least certain direction of a row-major 2 × 2
    covariance [m²] (None when it is not finite)."""
    c = [float(v) for v in cov4]
    if len(c) != 4 or not all(math.isfinite(v) for v in c):
        return None
    mean, half = (c[0] + c[3]) / 2.0, math.hypot((c[0] - c[3]) / 2.0, (c[1] + c[2]) / 2.0)
    return math.sqrt(max(mean + half, 0.0))


def obstacle_rows(obstacles):
    """tiago_nav/Obstacle messages → rows of :func:`obstacle_table` (with their stds: the
    centre's in the map frame, the radius's, the centre's in the robot frame)."""
    return [(o.center.x, o.center.y, o.center_robot.x, o.center_robot.y, o.radius, o.num_points,
             o.center_std, o.radius_std, largest_std(o.center_robot_covariance))
            for o in obstacles]


def centres_in_frame(rows, frame_pose):
    """Rows of :func:`obstacle_rows` with their map-frame centres moved into another frame.

    ``frame_pose``: ``(x, y, yaw)`` [m, m, rad], the pose of that frame's origin in the map
    (what tf's ``lookup_transform('map', frame)`` gives), so a centre ``p_map`` becomes
    ``inverse(frame_pose) ∘ p_map``. The robot-frame columns are kept.
    """
    if not rows:
        return []
    for v in frame_pose:
        if not math.isfinite(v):
            raise ValueError('frame pose %r is not finite' % (frame_pose,))
    xy = transform_points(inverse(frame_pose), [(r[0], r[1]) for r in rows])
    return [(float(p[0]), float(p[1])) + tuple(r[2:]) for p, r in zip(xy, rows)]


def table_title(frame=MAP_FRAME):
    """The line above the obstacle table."""
    return 'obstacles (%s frame, and robot frame base_footprint at scan time):' % frame


def _std(v):
    """A standard deviation [m] for the table: ``±0.004``, ``?`` when not known (inf, NaN)."""
    return '±%.3f' % v if v is not None and math.isfinite(v) else '?'


def obstacle_table(rows):
    """Format obstacles as a text table.

    ``rows``: sequence of ``(x, y, x_robot, y_robot, radius, num_points[, center_std,
    radius_std[, robot_std]])`` [m, m, m, m, m, -, m, m, m] (map frame, or the frame of
    :func:`centres_in_frame`; then base_footprint at scan time). ``center_std``: the centre's
    standard deviation along its least certain direction in the map frame (the laser pose's
    error included), ``radius_std`` the radius's, ``robot_std`` the centre's in the robot frame
    (the fit's alone; tiago_nav/Obstacle); rows without them show ``?``.
    Returns the lines (header first).
    """
    lines = [' #   x [m]   y [m]  x_robot  y_robot  radius [m]  points  centre std  radius std'
             '  robot std',
             '--  ------  ------  -------  -------  ----------  ------  ----------  ----------'
             '  ---------']
    for i, row in enumerate(rows, 1):
        x, y, xr, yr, r, n = row[:6]
        cs, rs, ws = (tuple(row[6:9]) + (None, None, None))[:3]
        lines.append('%2d  %6.2f  %6.2f  %7.2f  %7.2f  %10.3f  %6d  %10s  %10s  %9s'
                     % (i, x, y, xr, yr, r, n, _std(cs), _std(rs), _std(ws)))
    if not rows:
        lines.append('    (no obstacles)')
    return lines


def _num(v, fmt):
    """``fmt % v``, ``?`` when not known (NaN, inf)."""
    return fmt % v if v is not None and math.isfinite(v) else '?'


def shape_lines(obstacles):
    """One line per tiago_nav/Obstacle (``#N``, N as in :func:`obstacle_table`): its shape, extent
    [m] and orientation [deg] with their stds, whether its centre is fixed, its motion and
    velocity [m/s] (map frame), and the note of what was seen. Messages without the shape
    fields (older recordings) give ``circle``."""
    out = []
    for i, o in enumerate(obstacles, 1):
        shape = getattr(o, 'shape', '') or 'circle'
        ext = list(getattr(o, 'extent', ()) or ())
        estd = list(getattr(o, 'extent_std', ()) or ())
        ext += [math.nan] * (2 - len(ext))
        estd += [math.nan] * (2 - len(estd))
        yaw = getattr(o, 'orientation', math.nan)
        ystd = getattr(o, 'orientation_std', math.nan)
        line = '#%d  %-9s  %s x %s m' % (i, shape, _num(ext[0], '%.2f'), _num(ext[1], '%.2f'))
        if any(math.isfinite(v) for v in estd):
            line += ' (±%s, ±%s)' % (_num(estd[0], '%.3f'), _num(estd[1], '%.3f'))
        if math.isfinite(yaw):
            line += ', heading %.1f deg (±%s)' % (math.degrees(yaw),
                                                  _num(math.degrees(ystd), '%.1f'))
        if not getattr(o, 'center_fixed', True):
            line += ', centre bounded, not fixed'
        motion = getattr(o, 'motion', '') or 'unknown'
        line += ', %s' % motion
        v = getattr(o, 'velocity', None)
        if motion == 'moving' and v is not None:
            line += ' at (%s, %s) m/s (±%s)' % (_num(v.x, '%+.2f'), _num(v.y, '%+.2f'),
                                                 _num(getattr(o, 'velocity_std', math.nan),
                                                      '%.2f'))
        note = getattr(o, 'note', '')
        if note:
            line += ': ' + note
        out.append(line)
    return out
