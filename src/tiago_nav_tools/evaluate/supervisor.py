"""One evaluation run's supervisor: ``python3 -m tiago_nav_tools.evaluate.supervisor RUN_DIR``.

Started by :mod:`tiago_nav_tools.evaluate.run` as the leader of a session of its own, with the run's
environment (ROS_MASTER_URI on 127.0.0.1 and the slot's port, ROS_HOME, ROS_LOG_DIR, loopback
ROS_IP/ROS_HOSTNAME). It reads ``RUN_DIR/spec.json`` and, as children in its session:
starts roscore, waits for the master; starts demo.launch (the run's world, seed and launch
args; built-in nodes a candidate replaces switched off), waits for its ``/use_sim_time``, then
starts the candidate's command or launch file; waits for readiness (every action server and
the detection service, a candidate's interface within its ``check_timeout``, ``/clock``,
``/map``, ``/sim/ground_truth``); checks that the scenario loaded as specified (map and start pose);
sends the mission with a plain actionlib SimpleActionClient; watches the ground truth, the
localisation's estimate, ``/sim/collisions`` and the walkers on ``/sim/objects`` (among them
also move_base's published costmap and the scans, for the ghosts: ghosts.py) until a result or
the simulated-time limit;
writes ``RUN_DIR/raw.json`` (atomically); stops its children. Stages go to
``RUN_DIR/stage`` so that a watchdog kill can tell start-up from mission.
"""
import json
import math
import os
import re
import shlex
import signal
import subprocess
import sys
import threading
import time

from tiago_nav_tools.evaluate.run import write_json

STARTED_MARK = '__tiago_nav_eval__'
LOC_SAMPLES_PER_S = 10      # localisation error: one sample per 0.1 s of simulated time
LOC_TAIL = 0.5              # [s sim] the last samples before the result, which tf may not reach
END_WAIT = 10.0             # [s wall] the longest wait for the mission's last messages
STILL_SAY = 10.0            # [s wall] simulated time standing still this long in a mission is logged
LOC_POSE_TOPIC = '/amcl_pose'   # the localisation's estimate with its covariance
# roslaunch's line for a node that exited with an error (in its output, in colour on a terminal)
DIED = re.compile(r'\[([^\[\]\s]+)\] process has died \[pid (\d+), exit code (-?\d+)')


def died_nodes(text):
    """The nodes a roslaunch output ``text`` reports dead: ``[(name, exit code)]`` in the order
    they died (``name`` as roslaunch prints it, e.g. ``move_base-5``)."""
    return [(m.group(1), int(m.group(3))) for m in DIED.finditer(text)]


def message_fields(msg):
    """A ROS message as plain JSON values, every field of it (nested messages as dicts, arrays
    as lists), whatever fields its type has."""
    if hasattr(msg, '_slot_types') or hasattr(msg, 'secs'):     # a message, a time or duration
        return {k: message_fields(getattr(msg, k)) for k in msg.__slots__}
    if isinstance(msg, (list, tuple)):
        return [message_fields(v) for v in msg]
    if isinstance(msg, bytes):
        return list(msg)
    if hasattr(msg, 'tolist'):          # a numpy array or scalar
        return msg.tolist()
    return msg


def pose_covariance(msg):
    """``[stamp s, xx, xy, xyaw, yy, yyaw, yawyaw]`` of a PoseWithCovarianceStamped: the
    upper triangle of its (x, y, yaw) covariance [m², m², m·rad, m², m·rad, rad²]."""
    c = msg.pose.covariance
    return [msg.header.stamp.to_sec(), c[0], c[1], c[5], c[7], c[11], c[35]]


def mission_over(client, ended_since, now):
    """Is the goal of SimpleActionClient ``client`` over: ``(over, ended_since)``. Over once its
    result has come (the client is DONE): the status topic can name the end state before the
    result topic delivers the result, which carries the obstacles. A goal whose status ended
    but whose result has not come within :data:`END_WAIT` wall seconds of ``ended_since`` is
    over too (its result is judged as missing)."""
    from actionlib import SimpleGoalState
    from actionlib_msgs.msg import GoalStatus
    if client.simple_state == SimpleGoalState.DONE:
        return True, ended_since
    if client.get_state() in (GoalStatus.PENDING, GoalStatus.ACTIVE):
        return False, None
    ended_since = now if ended_since is None else ended_since
    return now - ended_since > END_WAIT, ended_since


def _has_param(master, name):
    """Whether the master holds the parameter ``name`` (False while it does not answer)."""
    import rosgraph
    try:
        return bool(master.hasParam(name))
    except (OSError, rosgraph.MasterException):
        return False


class ClockWatch:
    """Watches simulated time during a mission against the wall clock: how long [s wall] it has
    stood still, said once per stand-still of :data:`STILL_SAY` or more (in lockstep it stands
    still while no node works, e.g. a goal nobody received), and whether the mission has used
    up ``wall_limit`` [s wall]."""

    def __init__(self, sim, wall, wall_limit):
        self.start, self.limit = wall, wall_limit
        self.sim, self.since = sim, wall
        self.said = False

    def update(self, sim, wall):
        """Simulated time ``sim`` [s] at wall time ``wall`` [s]: a sentence to log when it has
        just stood still for :data:`STILL_SAY` (else None)."""
        if sim != self.sim:
            self.sim, self.since, self.said = sim, wall, False
            return None
        if self.said or wall - self.since < STILL_SAY:
            return None
        self.said = True
        return 'simulated time has stood still at %.3f s for %.0f s of wall time' % (sim, wall - self.since)

    def over(self, wall):
        """Has the mission used up its wall limit: None, or why it ends."""
        if wall - self.start <= self.limit:
            return None
        still = wall - self.since
        return 'no result within %g s of wall time (wall_time_limit; simulated time %.3f s%s)' % (
            self.limit, self.sim, ', standing still for the last %.0f s' % still if still >= STILL_SAY else '')


class Infra(Exception):
    """An infrastructure error: ``code`` (INFRA_LAUNCH, INFRA_NODE_DIED, INFRA_SCENARIO,
    INFRA_CONTRACT) and a reason."""

    def __init__(self, code, reason):
        super().__init__(reason)
        self.code = code


class Supervisor:
    def __init__(self, run_dir):
        self.dir = run_dir
        with open(os.path.join(run_dir, 'spec.json')) as f:
            self.spec = json.load(f)
        self.procs = {}
        self.logs = []
        self.uri = os.environ['ROS_MASTER_URI']
        self.port = int(self.uri.rsplit(':', 1)[1])
        self.truth = None
        self.truth_msg = None
        self.path = []
        self.loc_err = []
        self.loc_due = []           # [(stamp, true pose)] of the 0.1 s grid, to compare with tf
        self.loc_bucket = None      # the 0.1 s bucket of the last sample (None: not sampling)
        self.loc_from = None        # samples after this stamp (the goal's)
        self.loc_until = None       # ... up to this one (None: the mission has not ended)
        self.loc_missing = 0
        self.loc_cov = []           # pose_covariance of each estimate after the goal (None: off)
        self.loc_cov_on = False
        self.loc_pose_sub = None
        self.collisions = None
        self.people_on = False      # recording the true poses and the walkers (the mission)
        self.truth_log = []         # [t, x, y, yaw, v, w] of every true pose in the mission
        self.walker_log = []        # [t, walkers] of every /sim/objects with walkers in it
        self.ghosts = None          # the GhostWatch of a mission among walkers (ghosts.py)
        self.world = None
        self.clock = None
        self.grid_msg = None
        self.lock = threading.Lock()

    def stage(self, name):
        with open(os.path.join(self.dir, 'stage'), 'w') as f:
            f.write(name)
        # the time and the run's CPU at each stage, for the time breakdown
        from tiago_nav_tools.evaluate.run import TOKEN_VAR
        from tiago_nav_tools.evaluate.timing import mark
        mark(self.dir, name, os.environ.get(TOKEN_VAR), TOKEN_VAR)

    def start(self, name, cmd):
        log = open(os.path.join(self.dir, name + '.log'), 'w')
        self.logs.append(log)
        self.procs[name] = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT,
                                            stdin=subprocess.DEVNULL)

    def check_alive(self, what):
        for name, p in self.procs.items():
            if p.poll() is not None:
                code = 'INFRA_LAUNCH' if name in ('roscore', 'roslaunch') else 'INFRA_CONTRACT'
                raise Infra(code, '%s exited with %s while waiting for %s (see %s.log): %s'
                            % (name, p.returncode, what, name, self.tail(name)))

    def tail(self, name, n=3):
        try:
            with open(os.path.join(self.dir, name + '.log')) as f:
                lines = [ln.strip() for ln in f if ln.strip()]
            return ' | '.join(lines[-n:])
        except OSError:
            return ''

    def not_up(self, what, timeout):
        """The verdict on ``what`` not there within ``timeout`` [s wall] of start-up, by what
        died: INFRA_NODE_DIED naming the nodes roslaunch reports dead, or, when every process is
        alive and no node died, INFRA_LAUNCH (not up in time: a slow or loaded machine)."""
        self.check_alive(what)
        dead = self.dead_note()
        if dead:
            return Infra('INFRA_NODE_DIED', 'no %s within %g s%s' % (what, timeout, dead))
        return Infra('INFRA_LAUNCH', 'no %s within %g s, with every process alive and no node '
                     'dead' % (what, timeout))

    def dead_note(self):
        """``'; X died with exit code N (see P.log)'`` for each node the run's roslaunch
        processes (demo.launch's, a candidate's) report dead, for a reason's end."""
        out = ''
        for proc in ('roslaunch', 'candidate'):
            try:
                with open(os.path.join(self.dir, proc + '.log'), errors='replace') as f:
                    text = f.read()
            except OSError:
                continue
            out += ''.join('; %s died with exit code %d (see %s.log)' % (node, code, proc)
                           for node, code in died_nodes(text))
        return out

    def wait(self, what, pred, timeout):
        t0 = time.monotonic()
        while not pred():
            self.check_alive(what)
            if time.monotonic() - t0 > timeout:
                raise self.not_up(what, timeout)
            time.sleep(0.05)

    # --- start-up ----------------------------------------------------------------------------
    def launch(self):
        import rosgraph
        spec, lim = self.spec, self.spec['limits']
        t0 = time.monotonic()
        # the slot's port must be free (the last run's master gone)
        self.wait('free port %d' % self.port, lambda: not rosgraph.is_master_online(self.uri), 15.0)
        self.start('roscore', ['roscore', '-p', str(self.port)])
        self.wait('ROS master at %s' % self.uri, lambda: rosgraph.is_master_online(self.uri),
                  lim['startup_timeout'])
        args = ['roslaunch', '-p', str(self.port), 'tiago_nav', 'demo.launch',
                'world:=' + spec['world_path'], 'seed:=%d' % spec['seed'],
                'real_time_factor:=%g' % lim['real_time_factor'], 'client:=false',
                'rviz:=false', 'gui:=false']
        args += ['%s:=%s' % (k, v) for k, v in sorted(spec['launch_args'].items())]
        cand = spec.get('candidate_spec') or {}
        for role in cand.get('replaces', []):
            args.append('%s:=false' % role)
        if spec.get('record'):
            args += ['record:=true', 'bag:=' + os.path.join(self.dir, 'run.bag')]
        self.start('roslaunch', args)
        # demo.launch's /use_sim_time, before the probe and the candidate start: a node reads it
        # once, at its start, and one started before it is set follows wall time for good
        master = rosgraph.Master('/tiago_nav_evaluate', master_uri=self.uri)
        self.wait('/use_sim_time from demo.launch', lambda: _has_param(master, '/use_sim_time'),
                  lim['startup_timeout'])
        if cand:
            if 'command' in cand:
                self.start('candidate', shlex.split(cand['command']))
            else:
                self.start('candidate', ['roslaunch', '-p', str(self.port)] + shlex.split(cand['launch']))
        return t0

    def ready(self, t0):
        import actionlib
        import rospy
        from move_base_msgs.msg import MoveBaseAction
        from nav_msgs.msg import OccupancyGrid, Odometry
        from rosgraph_msgs.msg import Clock
        from std_msgs.msg import UInt32
        from tiago_nav.msg import CorridorAction, TiagoTaskAction
        from tiago_nav.ros.actions import wait_server
        lim = self.spec['limits']
        deadline = t0 + lim['startup_timeout']
        rospy.init_node('evaluate_probe', disable_signals=True)
        rospy.Subscriber('/clock', Clock, lambda m: setattr(self, 'clock', m.clock.to_sec()), queue_size=1)
        rospy.Subscriber('/map', OccupancyGrid, lambda m: setattr(self, 'grid_msg', m), queue_size=1)
        rospy.Subscriber('/sim/collisions', UInt32, lambda m: setattr(self, 'collisions', m.data), queue_size=1)
        # every message, none dropped (queue_size None): the path and the localisation's samples
        # are then the same whatever the load
        rospy.Subscriber('/sim/ground_truth', Odometry, self.on_truth, queue_size=None)
        from tiago_nav.msg import SimObjects
        self.objects_sub = rospy.Subscriber('/sim/objects', SimObjects, self.on_objects,
                                            queue_size=None)
        from geometry_msgs.msg import PoseWithCovarianceStamped
        self.loc_pose_sub = rospy.Subscriber(LOC_POSE_TOPIC, PoseWithCovarianceStamped,
                                             self.on_loc_pose, queue_size=None)
        cand = self.spec.get('candidate_spec') or {}
        roles = cand.get('replaces', [])
        check = cand.get('check_timeout', lim['check_timeout'])
        servers = [('tiago_controller', TiagoTaskAction, None), ('move_base', MoveBaseAction, 'navigation'),
                   ('corridor_controller', CorridorAction, 'corridor')]
        for name, kind, role in servers:
            c = actionlib.SimpleActionClient(name, kind)
            if role in roles:       # the candidate's interface: its own, shorter, bound
                if not wait_server(c, check):
                    self.check_alive('the candidate')
                    raise Infra('INFRA_CONTRACT', 'candidate %s: no %s action server (%s) advertised '
                                'within %g s%s' % (self.spec['candidate'], name, kind.__name__, check,
                                                   self.dead_note()))
            elif not wait_server(c, max(1.0, deadline - time.monotonic())):
                raise self.not_up('%s action server' % name, lim['startup_timeout'])
            c.action_client.stop()
        timeout = check if 'detection' in roles else max(1.0, deadline - time.monotonic())
        try:
            rospy.wait_for_service('obstacle_detection', timeout)
        except rospy.ROSException:
            self.check_alive('the obstacle_detection service')
            if 'detection' in roles:
                raise Infra('INFRA_CONTRACT', 'candidate %s: no obstacle_detection service '
                            '(tiago_nav/DetectObstacles) advertised within %g s%s'
                            % (self.spec['candidate'], check, self.dead_note())) from None
            raise self.not_up('obstacle_detection service', lim['startup_timeout']) from None
        if 'detection' in roles:
            import rosservice
            kind = rosservice.get_service_type('/obstacle_detection')
            if kind != 'tiago_nav/DetectObstacles':
                raise Infra('INFRA_CONTRACT', 'candidate %s: /obstacle_detection is a %s, not a '
                            'tiago_nav/DetectObstacles' % (self.spec['candidate'], kind))
        self.wait('/clock, /map and /sim/ground_truth',
                  lambda: self.clock is not None and self.grid_msg is not None and self.truth is not None,
                  max(1.0, deadline - time.monotonic()))

    def on_truth(self, m):
        p = m.pose.pose
        pose = (p.position.x, p.position.y, 2 * math.atan2(p.orientation.z, p.orientation.w))
        with self.lock:
            self.truth, self.truth_msg = (m.header.stamp, pose), m
            if not self.path or abs(pose[0] - self.path[-1][0]) + abs(pose[1] - self.path[-1][1]) > 0.01:
                self.path.append(pose)
            if self.people_on:
                self.truth_log.append([m.header.stamp.to_sec()] + [round(v, 4) for v in pose] +
                                      [round(m.twist.twist.linear.x, 4), round(m.twist.twist.angular.z, 4)])
                if self.ghosts is not None:
                    self.ghosts.pose(m.header.stamp.to_sec(), pose)
            if self.loc_bucket is not None and m.header.stamp > self.loc_from and \
                    (self.loc_until is None or m.header.stamp <= self.loc_until):
                # the first true pose of each 0.1 s of simulated time after the goal
                bucket = math.floor(m.header.stamp.to_sec() * LOC_SAMPLES_PER_S + 1e-6)
                if bucket != self.loc_bucket:
                    self.loc_bucket = bucket
                    self.loc_due.append((m.header.stamp, pose))

    def on_objects(self, m):
        """The walkers of a /sim/objects message during the mission: ``[t, [[x, y, vx, vy,
        leg_radius, legs, state], ...]]`` (metrics.closest_walker)."""
        people = [[round(o.pose.x, 4), round(o.pose.y, 4), round(o.velocity.x, 4),
                   round(o.velocity.y, 4), o.leg_radius,
                   [[round(p.x, 4), round(p.y, 4)] for p in o.legs], o.state]
                  for o in m.objects if o.shape == 'walker']
        with self.lock:
            if self.people_on and people:
                self.walker_log.append([m.header.stamp.to_sec(), people])
                if self.ghosts is not None:
                    self.ghosts.walkers(m.header.stamp.to_sec(), [q for w in people for q in w[5]],
                                        max(w[4] for w in people))

    def on_costmap(self, m):
        """move_base's published costmap, for the ghosts (among walkers)."""
        import numpy as np
        values = np.asarray(m.data, dtype=np.int8).reshape(m.info.height, m.info.width)
        with self.lock:
            if self.people_on and self.ghosts is not None:
                self.ghosts.costmap(m.header.stamp.to_sec(), values)

    def on_scan(self, m):
        with self.lock:
            if self.people_on and self.ghosts is not None:
                self.ghosts.scan(m.header.stamp.to_sec(), m.ranges, m.angle_min, m.angle_increment,
                                 m.range_min, m.range_max)

    def watch_ghosts(self, tf):
        """Among walkers: a :class:`~tiago_nav_tools.evaluate.ghosts.GhostWatch` fed by
        move_base's published costmap, the scans, the true poses and the walkers; its
        subscribers (None elsewhere)."""
        import rospy
        from nav_msgs.msg import OccupancyGrid
        from sensor_msgs.msg import LaserScan
        from tiago_nav.nav.people import person_keep_out
        from tiago_nav.robot import LASER_OFFSET, ROBOT_RADIUS
        from tiago_nav.ros.conversions import gridmap_from_msg
        from tiago_nav_tools.evaluate.ghosts import GhostWatch
        if not self.world.walkers:
            return None
        # where the laser sits on the base (tf, static), as the navigation places scans; polled
        # in wall time (simulated time stands still until the goal), else the mock's own
        offset, end = LASER_OFFSET, time.monotonic() + 5.0
        while time.monotonic() < end:
            if tf.can_transform('base_footprint', 'base_laser_link', rospy.Time(0)):
                t = tf.lookup_transform('base_footprint', 'base_laser_link',
                                        rospy.Time(0)).transform.translation
                offset = math.hypot(t.x, t.y)
                break
            time.sleep(0.01)
        grid = gridmap_from_msg(self.grid_msg)
        keep_out = person_keep_out(rospy.get_param('/move_base/person_clearance', 0.0),
                                   rospy.get_param('/move_base/safety_margin', 0.0),
                                   grid.resolution)
        self.ghosts = GhostWatch(grid, self.world.movable_obstacles,
                                 rospy.get_param('/move_base/robot_radius', ROBOT_RADIUS), offset,
                                 rospy.get_param('/move_base/raytrace_range', 5.0), keep_out)
        return [rospy.Subscriber('/move_base/global_costmap/costmap', OccupancyGrid,
                                 self.on_costmap, queue_size=None),
                rospy.Subscriber('/scan', LaserScan, self.on_scan, queue_size=None)]

    def on_loc_pose(self, m):
        with self.lock:
            if self.loc_cov_on:
                self.loc_cov.append(pose_covariance(m))

    def loc_cov_until(self, until):
        """The localisation's covariances after the goal up to ``until`` (rospy.Time), or None
        while one stamped after it has not come from a connected publisher."""
        sub = self.loc_pose_sub
        with self.lock:
            cov = list(self.loc_cov)
        t = until.to_sec()
        if sub is not None and sub.get_num_connections() > 0 and not any(c[0] > t for c in cov):
            return None
        return [c for c in cov if c[0] <= t]

    def sample_localisation(self, tf, until=None):
        """Compares each due true pose with tf's ``map → base_footprint`` at its stamp, in
        stamp order, as far as tf has the data (all of them up to ``until``, a rospy.Time, when
        given: later ones are dropped). A stamp tf can no longer give counts as missing."""
        import tf2_ros
        from tiago_nav.ros.conversions import pose_from_transform
        while True:
            with self.lock:
                if not self.loc_due:
                    return True
                stamp, (tx, ty, tyaw) = self.loc_due[0]
                if until is not None and stamp > until:
                    del self.loc_due[:]
                    return True
            try:
                t = tf.lookup_transform('map', 'base_footprint', stamp)
            except tf2_ros.ExtrapolationException as e:
                if 'past' not in str(e):
                    return False            # not there yet
                self.loc_missing += 1
            except (tf2_ros.LookupException, tf2_ros.ConnectivityException):
                return False
            else:
                ex, ey, eyaw = pose_from_transform(t.transform)
                self.loc_err.append((math.hypot(ex - tx, ey - ty),
                                     abs((eyaw - tyaw + math.pi) % (2 * math.pi) - math.pi),
                                     stamp.to_sec()))
            with self.lock:
                self.loc_due.pop(0)

    def scenario(self):
        """The scenario loaded as specified: the map is the world's, the robot at its start."""
        from tiago_nav.sim.raster import rasterise_world
        from tiago_nav.sim.world import load_world
        world = self.world = load_world(self.spec['world_path'])
        grid = rasterise_world(world)
        info = self.grid_msg.info
        if (info.width, info.height) != (grid.width, grid.height) or \
                abs(info.resolution - grid.resolution) > 1e-6 or \
                abs(info.origin.position.x - grid.origin[0]) > 1e-3 or \
                abs(info.origin.position.y - grid.origin[1]) > 1e-3:
            raise Infra('INFRA_SCENARIO', '/map is %dx%d cells of %g m at (%g, %g), the world %s '
                        'gives %dx%d of %g m at (%g, %g)' % (info.width, info.height, info.resolution,
                                                           info.origin.position.x, info.origin.position.y,
                                                           world.name, grid.width, grid.height,
                                                           grid.resolution, *grid.origin))
        x, y, yaw = self.truth[1]
        sx, sy, syaw = world.start_pose
        dyaw = abs((yaw - syaw + math.pi) % (2 * math.pi) - math.pi)
        if math.hypot(x - sx, y - sy) > 0.05 or dyaw > math.radians(3):
            raise Infra('INFRA_SCENARIO', 'the robot is at (%.3f, %.3f, %.1f deg), the world starts '
                        'it at (%.3f, %.3f, %.1f deg)' % (x, y, math.degrees(yaw), sx, sy, math.degrees(syaw)))

    # --- the mission -------------------------------------------------------------------------
    def mission(self):
        """Sends the goal with a plain SimpleActionClient and watches it to its end. What it
        records depends on simulated time only, not on when this process gets the processor:
        feedback from the topic with its stamps (SimpleActionClient drops feedback that comes
        before ``send_goal`` returns or after the result), the duration from the result's stamp,
        every true pose (the path), the localisation error on a 0.1 s grid of simulated time,
        and the final pose once the base is at rest after the result."""
        import actionlib
        import rospy
        import tf2_ros
        from actionlib import SimpleGoalState
        from actionlib_msgs.msg import GoalStatus
        from tiago_nav.msg import TiagoTaskAction, TiagoTaskActionFeedback, TiagoTaskGoal
        from tiago_nav.ros.actions import wait_server
        lim = self.spec['limits']
        tf = tf2_ros.Buffer(rospy.Duration(2 * lim['sim_time_limit'] + 60))
        tf2_ros.TransformListener(tf)
        published = []             # (goal id, stamp, state, status) of every feedback message
        sub = rospy.Subscriber('/tiago_controller/feedback', TiagoTaskActionFeedback,
                               lambda m: published.append((m.status.goal_id.id, m.header.stamp.to_sec(),
                                                           int(m.feedback.state), m.feedback.status)),
                               queue_size=None)
        ghost_subs = self.watch_ghosts(tf)
        client = actionlib.SimpleActionClient('tiago_controller', TiagoTaskAction)
        if not wait_server(client, 30.0):
            raise Infra('INFRA_NODE_DIED', 'the tiago_controller action server went away before the goal')
        # what is recorded from the goal on comes from its first message: wait until each of
        # these subscriptions is connected (the walkers' had missed their first 3 s, in one
        # run of twenty on a busy machine), those of topics nobody publishes excepted (a
        # candidate's move_base may publish no costmap)
        advertised = {name for name, _ in rospy.get_published_topics()}
        subs = [sub] + ([self.objects_sub] + ghost_subs if ghost_subs else [])
        subs = [s for s in subs if s is sub or s.resolved_name in advertised]
        end = time.monotonic() + 30.0
        while any(s.get_num_connections() == 0 for s in subs) and time.monotonic() < end:
            time.sleep(0.01)
        x, y, yaw = self.spec['goal']
        c0, s0, w0 = self.collisions or 0, rospy.get_time(), time.monotonic()
        with self.lock:
            self.path = [self.truth[1]]
            self.loc_bucket, self.loc_from = -1, rospy.Time.from_sec(s0)
            self.loc_cov, self.loc_cov_on = [], True
            self.truth_log, self.walker_log, self.people_on = [], [], True
        client.send_goal(TiagoTaskGoal(x=x, y=y, yaw_deg=yaw, use_corridor_law=self.spec['use_corridor_law']))
        timed_out, ended_since, why = False, None, None
        watch = ClockWatch(s0, w0, lim['wall_time_limit'])
        while True:
            now = time.monotonic()
            over, ended_since = mission_over(client, ended_since, now)
            if over:
                break
            self.check_alive_mission()
            t = rospy.get_time()
            said = watch.update(t, now)
            if said:
                sys.stderr.write('supervisor: %s, the goal %s\n' % (said, client.get_goal_status_text()
                                                                     or 'in state %d' % client.get_state()))
                sys.stderr.flush()
            why = watch.over(now)
            if t - s0 > lim['sim_time_limit'] or why:
                timed_out = True
                client.cancel_all_goals()
                # (in wall time: simulated time may be what stands still)
                end = time.monotonic() + 5.0
                while client.simple_state != SimpleGoalState.DONE and time.monotonic() < end:
                    time.sleep(0.01)
                break
            self.sample_localisation(tf)
            time.sleep(0.1)
        wall = time.monotonic() - w0
        result = client.get_result()
        latest = client.gh.comm_state_machine.latest_result if client.gh else None
        ended = latest.header.stamp if latest is not None and not timed_out else rospy.Time.from_sec(rospy.get_time())
        goal_id = client.gh.comm_state_machine.action_goal.goal_id.id if client.gh else None
        until = ended - rospy.Duration(LOC_TAIL)
        with self.lock:
            # sampling ends by stamp, not by when this loop noticed the end: true poses up to
            # ``until`` may still be queued (the wait for the base at rest below receives them)
            self.loc_until = until
        # the mission's last messages: the feedback the result names, the base at rest, and
        # tf up to the result (each bounded: a run that ends badly may never give them)
        wanted = getattr(result, 'state', None)
        scan_period = 1.0 / float(rospy.get_param('/simulator/scan_rate', 15.0))
        deadline = time.monotonic() + END_WAIT
        while True:
            fed = wanted is None or any(g == goal_id and st == wanted for g, _, st, _ in list(published))
            m = self.truth_msg
            rest = m is not None and m.header.stamp >= ended and m.twist.twist.linear.x == 0.0 \
                and m.twist.twist.angular.z == 0.0
            with self.lock:     # (the walkers of the last scan up to the result, if any: they
                # come with each scan, so the last one at or before it is less than a scan
                # period before it; a scan after it may never come, time standing still once
                # the mission's nodes have no more work)
                walked = not self.walker_log \
                    or self.walker_log[-1][0] > ended.to_sec() - scan_period + 1e-6
            got = {'feedback': fed, 'base_at_rest': rest, 'walkers': walked,
                   'localisation': self.sample_localisation(tf, until=until),
                   'covariance': self.loc_cov_until(until) is not None}
            # what had not come by the deadline stays in the record: the logs it ends are short
            end_missing = [k for k, v in got.items() if not v]
            if not end_missing or time.monotonic() >= deadline:
                break
            time.sleep(0.01)
        loc_err = [e for e in self.loc_err if e[2] <= until.to_sec()]
        loc_cov = self.loc_cov_until(until)
        with self.lock:
            self.loc_cov_on = self.people_on = False
            self.loc_bucket, self.loc_until = None, None
            # the walkers and true poses up to the result (the base at rest after it is not the
            # mission's)
            t_end = ended.to_sec()
            truth_log = [r for r in self.truth_log if s0 <= r[0] <= t_end]
            walker_log = [r for r in self.walker_log if s0 <= r[0] <= t_end]
            ghosts = []
            if self.ghosts is not None:
                self.ghosts.flush(t_end)
                ghosts = [r for r in self.ghosts.records if s0 <= r[0] <= t_end]
        sub.unregister()
        for g in ghost_subs or []:
            g.unregister()
        feedback = []
        for g, stamp, st, status in published:
            if g == goal_id and (not feedback or feedback[-1][1] != st):
                feedback.append((stamp, st, status))
        with self.lock:
            final = self.truth[1]
            path = list(self.path) + [final]
        names = {v: k for k, v in vars(GoalStatus).items() if k.isupper() and isinstance(v, int)}
        return {'state': client.get_state(), 'state_name': names.get(client.get_state(), '?'),
                'status_text': client.get_goal_status_text(), 'timed_out': timed_out,
                **({'reason': why} if why else {}),
                'message': result.message if result else '',
                'obstacles': [[o.center.x, o.center.y, o.radius] for o in result.obstacles] if result else [],
                'obstacles_detail': [message_fields(o) for o in result.obstacles] if result else [],
                'loc_covariance': [c for c in (loc_cov or []) if c[0] > s0],
                'sim_s': ended.to_sec() - s0, 'wall_s': wall,
                'collisions': (self.collisions or 0) - c0, 'final_pose': list(final),
                'path': [[round(v, 4) for v in p] for p in path], 'feedback': feedback,
                'loc_errors': loc_err, 'loc_missing': self.loc_missing,
                'truth_log': truth_log if walker_log else [], 'walkers': walker_log,
                'ghosts': ghosts, 'end_missing': end_missing}

    def check_alive_mission(self):
        for name in ('roscore', 'roslaunch', 'candidate'):
            p = self.procs.get(name)
            if p is not None and p.poll() is not None:
                raise Infra('INFRA_NODE_DIED', '%s exited with %s during the mission (see %s.log): %s'
                            % (name, p.returncode, name, self.tail(name)))

    def stop(self):
        for name in ('candidate', 'roslaunch', 'roscore'):
            p = self.procs.get(name)
            if p is None or p.poll() is not None:
                continue
            # roslaunch escalates SIGINT -> SIGTERM on a slow node itself after 15 s
            for sig, wait in ((signal.SIGINT, 20.0), (signal.SIGTERM, 3.0), (signal.SIGKILL, 3.0)):
                try:
                    p.send_signal(sig)
                    p.wait(wait)
                    break
                except subprocess.TimeoutExpired:
                    continue
        for log in self.logs:
            log.close()
        # whatever outlived roslaunch (each node has a session of its own): by the run's token
        from tiago_nav_tools.evaluate.run import TOKEN_VAR, tagged_pids
        token = os.environ.get(TOKEN_VAR)
        for pid in tagged_pids(token) if token else []:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass


def watch_parent(sup):
    """When the worker that started this run dies (a killed Dask worker), stop the run's
    processes and exit: the run is rescheduled elsewhere and must not hold the slot's port."""
    parent = os.getppid()

    def loop():
        while os.getppid() == parent:
            time.sleep(0.5)
        sup.stage('orphaned')
        sup.stop()
        os._exit(3)
    threading.Thread(target=loop, daemon=True).start()


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    run_dir = argv[0]
    sup = Supervisor(run_dir)
    watch_parent(sup)
    raw = {'schema': 1, 'id': sup.spec['id']}
    try:
        sup.stage('startup')
        t0 = sup.launch()
        sup.ready(t0)
        sup.scenario()
        raw['startup_wall_s'] = time.monotonic() - t0
        sup.stage('mission')
        raw.update(sup.mission())
    except Infra as e:
        raw.update(infra=e.code, reason=str(e))
    except Exception as e:      # noqa: BLE001  (the supervisor's own failure is the run's)
        raw.update(infra='INFRA_LAUNCH', reason='supervisor: %s: %s' % (type(e).__name__, e))
    finally:
        sup.stage('teardown')
        try:
            import rospy
            rospy.signal_shutdown('run done')
        except Exception:       # noqa: BLE001
            pass
        sup.stop()
    write_json(os.path.join(run_dir, 'raw.json'), raw)
    sup.stage('done')
    return 0


if __name__ == '__main__':
    sys.exit(main())
