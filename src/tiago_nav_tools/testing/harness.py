"""Running whole missions from a script (scripts/run_demo.py, bench/bench_mission.py): start
demo.launch on a private master, watch the robot (true path from /sim/ground_truth, the
localisation's error against it, last scan, /map, /sim/collisions),
send TiagoTask goals through the client node's run loop (:func:`tiago_nav.nodes.client.run`),
shut everything down.

A process can join one ROS master only: use one :class:`Harness` per process. The benchmarks
use :func:`free_port` and :func:`stop_process` for their own private launches too.
"""
import math
import os
import signal
import socket
import subprocess
import tempfile
import threading
import time

from tiago_nav.geometry import compose, transform_points


MISSION_NODES = ('/simulator', '/move_base', '/corridor_controller', '/obstacle_detection',
                 '/tiago_controller')
STARVED = ('/simulator', '/localisation', '/move_base', '/corridor_controller', '/tiago_controller',
           '/obstacle_detection')       # the nodes :meth:`Starver.of_nodes` stops, in this order


def node_pid(name, caller='/mission_harness'):
    """The pid of the running node ``name``, asked over its XML-RPC API (as ``caller``)."""
    import rosgraph
    import xmlrpc.client
    uri = rosgraph.Master(caller).lookupNode(name)
    code, _, pid = xmlrpc.client.ServerProxy(uri).getPid(caller)
    if code != 1:
        raise RuntimeError('cannot get the pid of %s' % name)
    return pid


class Starver(threading.Thread):
    """Starves a running stack as a loaded machine does, only harder and the same way in every
    run: stops each of the processes ``pids`` in turn (SIGSTOP) for ``stop`` wall seconds, then
    lets it go on (SIGCONT), ``gap`` wall seconds apart, until :meth:`finish`. ``stops``
    counts them."""

    def __init__(self, pids, stop, gap=0.2):
        super().__init__(name='starver', daemon=True)
        self.pids, self.stop, self.gap = list(pids), float(stop), float(gap)
        self.done = threading.Event()
        self.stops = 0

    @classmethod
    def of_nodes(cls, stop, nodes=STARVED):
        """A started Starver of the running nodes ``nodes`` (names), ``stop`` [s wall] each."""
        starver = cls([node_pid(n) for n in nodes], stop)
        starver.start()
        return starver

    def run(self):
        while not self.done.wait(self.gap):
            pid = self.pids[self.stops % len(self.pids)]
            try:
                os.kill(pid, signal.SIGSTOP)
            except ProcessLookupError:
                return
            self.stops += 1
            try:
                self.done.wait(self.stop)
            finally:
                try:
                    os.kill(pid, signal.SIGCONT)
                except ProcessLookupError:
                    return          # it died while stopped (the launch is closing)

    def finish(self):
        """Ends the starving once the process stopped now goes on again."""
        self.done.set()
        self.join()


def free_port():
    """A TCP port on localhost that is free now (for a private ROS master)."""
    with socket.socket() as s:
        s.bind(('localhost', 0))
        return s.getsockname()[1]


class HarnessError(RuntimeError):
    """The launch did not come up (no master, no server, roslaunch exited); the message names
    what is missing and the log file."""


class Harness:
    """demo.launch (without its client) on a private master; this process becomes a node of it
    once :meth:`connect` is called.

    Args:
        world: path of the world file.
        real_time_factor, laser_noise: passed to the launch file (0 = as fast as possible;
            [m] laser noise sigma).
        port: the master's port (default: a free one).
        robot_start: ``(x, y, yaw_deg)`` to start from instead of the world's start.
        log_path: where roscore and roslaunch write (default: a file in the temp directory).
        extra_args: further ``name:=value`` launch arguments.
        launch: the roslaunch arguments naming the launch file (package and file, or a path).
        observe: take in /scan and /tf and track the path and the localisation error (for
            plots and the demo's summary); False leaves this process a client like
            ``rosrun tiago_nav client`` (plus the collision count) once :meth:`connect` has
            seen everything up: it then drops its ground-truth subscription and the action
            clients it probed the servers with, so that a benchmark does not time its own
            observing (:attr:`truth` and :meth:`pose` are then not updated).
    """

    def __init__(self, world, real_time_factor=5.0, laser_noise=0.01, port=None, robot_start=None,
                 log_path=None, extra_args=(), launch=('tiago_nav', 'demo.launch'), observe=True):
        self.port = port or free_port()
        self.uri = 'http://localhost:%d' % self.port
        self.log_path = log_path or os.path.join(tempfile.gettempdir(),
                                                 'tiago_nav_demo_%d.log' % self.port)
        args = ['roslaunch', '-p', str(self.port), '--wait'] + list(launch) + [
                'world:=' + os.path.abspath(world), 'real_time_factor:=%g' % real_time_factor,
                'laser_noise:=%g' % laser_noise, 'client:=false', 'rviz:=false', 'gui:=false']
        if robot_start is not None:
            args.append('robot_start:=[%g, %g, %g]' % tuple(robot_start))
        args += list(extra_args)
        # the laser profile it runs (the launch file's default: tiago), for the ground truth
        self.laser_model = ([a.split(':=', 1)[1] for a in args if a.startswith('laser_model:=')]
                            or ['tiago'])[-1]
        self.env = dict(os.environ, ROS_MASTER_URI=self.uri)
        self.log = open(self.log_path, 'w')
        # roscore first (roslaunch --wait), in its own session so that it can be stopped as a group
        self.core = subprocess.Popen(['roscore', '-p', str(self.port)], env=self.env,
                                     stdout=self.log, stderr=subprocess.STDOUT,
                                     start_new_session=True)
        self.launch = subprocess.Popen(args, env=self.env, stdout=self.log,
                                       stderr=subprocess.STDOUT, start_new_session=True)
        self.path = []
        self.scan = None
        self.grid = None
        self.collisions = None
        self.truth = None
        self.loc_errors = []        # [(position m, |yaw| rad)] of the estimate against the truth
        self.lock = threading.Lock()
        self._node = False
        self.observe = observe
        self.tf = None

    # --- ROS side ------------------------------------------------------------------------------
    def connect(self, timeout=60.0):
        """Join the master, subscribe, and wait (wall ``timeout``) for /clock, /map and every
        server of the mission."""
        os.environ['ROS_MASTER_URI'] = self.uri
        import rosgraph
        t0 = time.monotonic()
        while not rosgraph.is_master_online(self.uri):
            self._check_alive()
            if time.monotonic() - t0 > timeout:
                raise HarnessError('no ROS master at %s after %g s' % (self.uri, timeout))
            time.sleep(0.2)
        master = rosgraph.Master('/mission_harness')
        while not master.hasParam('/use_sim_time'):      # set by sim.launch before any node
            self._check_alive()
            if time.monotonic() - t0 > timeout:
                raise HarnessError('/use_sim_time never set (see %s)' % self.log_path)
            time.sleep(0.1)
        import rospy
        import tf2_ros
        from nav_msgs.msg import OccupancyGrid, Odometry
        from sensor_msgs.msg import LaserScan
        from std_msgs.msg import UInt32
        rospy.init_node('mission_harness', anonymous=True, disable_signals=True)
        self._node = True
        if self.observe:
            self.tf = tf2_ros.Buffer(rospy.Duration(30))
            self.tf_listener = tf2_ros.TransformListener(self.tf)
            rospy.Subscriber('/scan', LaserScan, self._on_scan, queue_size=1)
        rospy.Subscriber('/map', OccupancyGrid, self._on_map, queue_size=1)
        rospy.Subscriber('/sim/collisions', UInt32, self._on_collisions, queue_size=1)
        truth = rospy.Subscriber('/sim/ground_truth', Odometry, self._on_truth, queue_size=1)
        self.wait_servers(timeout - (time.monotonic() - t0))
        if self.observe:
            threading.Thread(target=self._track, daemon=True).start()
        else:
            truth.unregister()

    def wait_servers(self, timeout):
        """Wait (wall ``timeout`` [s]) for every server of the mission, /map and the robot's tf;
        :class:`HarnessError` naming the missing one otherwise."""
        import actionlib
        import rospy
        from move_base_msgs.msg import MoveBaseAction
        from tiago_nav.ros.actions import wait_server
        from tiago_nav.msg import CorridorAction, TiagoTaskAction
        t0 = time.monotonic()
        for name, kind in (('tiago_controller', TiagoTaskAction), ('move_base', MoveBaseAction),
                           ('corridor_controller', CorridorAction)):
            c = actionlib.SimpleActionClient(name, kind)
            up = wait_server(c, max(1.0, timeout - (time.monotonic() - t0)))
            c.action_client.stop()      # a probe: its status and feedback are not read
            if not up:
                self._check_alive()
                raise HarnessError('no %s action server (see %s)' % (name, self.log_path))
        try:
            rospy.wait_for_service('obstacle_detection', max(1.0, timeout - (time.monotonic() - t0)))
        except rospy.ROSException:
            raise HarnessError('no obstacle_detection service (see %s)' % self.log_path) from None
        while self.grid is None or self.pose() is None:
            if time.monotonic() - t0 > timeout:
                raise HarnessError('no /map or no /sim/ground_truth (see %s)' % self.log_path)
            time.sleep(0.1)

    def _check_alive(self):
        if self.launch.poll() is not None:
            raise HarnessError('roslaunch exited with %s (see %s)' % (self.launch.returncode,
                                                                    self.log_path))

    def _on_scan(self, msg):
        self.scan = msg

    def _on_map(self, msg):
        from tiago_nav.ros.conversions import gridmap_from_msg
        self.grid = gridmap_from_msg(msg)

    def _on_collisions(self, msg):
        self.collisions = msg.data

    def _on_truth(self, msg):
        self.truth = msg

    def pose(self):
        """Ground-truth base pose ``(x, y, yaw)`` in map from /sim/ground_truth, or None (tf
        map -> base_footprint is the localisation's estimate)."""
        from tiago_nav.ros.conversions import pose_from_msg
        msg = self.truth
        return None if msg is None else pose_from_msg(msg.pose.pose)

    def estimate(self):
        """The localisation's estimate of the base pose (tf map -> base_footprint) or None."""
        import rospy
        from tiago_nav.ros.conversions import pose_from_transform
        try:
            t = self.tf.lookup_transform('map', 'base_footprint', rospy.Time(0))
        except Exception:
            return None
        return pose_from_transform(t.transform)

    def localisation_error(self):
        """``(position [m], |yaw| [rad])`` of tf map -> base_footprint (the estimate) against
        the latest /sim/ground_truth at its stamp, or None when either is missing."""
        import rospy
        from tiago_nav.geometry import wrap_angle
        from tiago_nav.ros.conversions import pose_from_msg, pose_from_transform
        msg = self.truth
        if msg is None:
            return None
        try:
            t = self.tf.lookup_transform('map', 'base_footprint', msg.header.stamp, rospy.Duration(0.2))
        except Exception:
            return None
        (x, y, yaw), (ex, ey, eyaw) = pose_from_msg(msg.pose.pose), pose_from_transform(t.transform)
        return math.hypot(ex - x, ey - y), abs(wrap_angle(eyaw - yaw))

    def localisation_summary(self):
        """p95 / max of :attr:`loc_errors` as ``{'samples', 'p95_m', 'max_m', 'p95_deg',
        'max_deg'}`` (None without samples)."""
        with self.lock:
            e = list(self.loc_errors)
        if not e:
            return None
        d = sorted(v[0] for v in e)
        a = sorted(math.degrees(v[1]) for v in e)
        p95 = max(0, int(math.ceil(0.95 * len(e))) - 1)
        return {'samples': len(e), 'p95_m': d[p95], 'max_m': d[-1], 'p95_deg': a[p95], 'max_deg': a[-1]}

    def _track(self):
        import rospy
        while not rospy.is_shutdown():
            p = self.pose()
            if p is not None:
                with self.lock:
                    if not self.path or abs(p[0] - self.path[-1][0]) + abs(p[1] - self.path[-1][1]) > 0.01:
                        self.path.append(p)
            err = self.localisation_error()
            if err is not None:
                with self.lock:
                    self.loc_errors.append(err)
            time.sleep(0.05)

    def scan_points_map(self, timeout=5.0):
        """The latest scan's points in the map frame (laser pose from tf at the scan's stamp)."""
        from tiago_nav.ros.conversions import pose_from_transform, scan_points
        t0 = time.monotonic()
        s0 = self.scan
        while self.scan is s0 and time.monotonic() - t0 < timeout:
            time.sleep(0.05)
        scan = self.scan
        if scan is None:
            return None
        try:
            t = self.tf.lookup_transform('map', scan.header.frame_id, scan.header.stamp)
            laser = pose_from_transform(t.transform)
        except Exception:
            laser = compose(self.pose(), (0.2, 0.0, 0.0))
        pts, _ = scan_points(scan)
        return transform_points(laser, pts)

    def mission(self, x, y, yaw_deg, use_corridor_law, out=print, limit=None):
        """Run one TiagoTask to pose B (``x``, ``y`` [m] in map, ``yaw_deg``) as the client
        does, printing its lines with ``out``; return ``(exit code, GoalStatus, TiagoTaskResult,
        wall seconds)``. With ``limit`` [s wall]: a task with no terminal state by then is a
        hang: it is cancelled (every goal of the action) and the exit code is None."""
        from tiago_nav.nodes.client import run
        box = {}

        def on_result(state, result):
            box['state'], box['result'] = state, result

        def go():
            box['code'] = run(goal, out=out, server_timeout=10.0, on_result=on_result)
        goal = {'x': x, 'y': y, 'yaw_deg': yaw_deg, 'use_corridor_law': use_corridor_law}
        t0 = time.monotonic()
        worker = threading.Thread(target=go, daemon=True)
        worker.start()
        worker.join(limit)
        if worker.is_alive():
            self._cancel_all()
            worker.join(30.0)
            return None, box.get('state'), box.get('result'), time.monotonic() - t0
        return box.get('code'), box.get('state'), box.get('result'), time.monotonic() - t0

    def _cancel_all(self):
        """Cancel every goal of the tiago_controller action (an empty GoalID)."""
        import rospy
        from actionlib_msgs.msg import GoalID
        pub = rospy.Publisher('/tiago_controller/cancel', GoalID, queue_size=1, latch=True)
        pub.publish(GoalID())

    def dead_nodes(self, names=MISSION_NODES):
        """Which of the nodes ``names`` are gone: not registered with the master, or registered
        but not answering (a crashed process leaves its registration behind)."""
        import rosgraph
        import xmlrpc.client
        master = rosgraph.Master('/mission_harness')
        dead = []
        for name in names:
            try:
                uri = master.lookupNode(name)
                proxy = xmlrpc.client.ServerProxy(uri)
                code, _, _ = proxy.getPid('/mission_harness')
                if code != 1:
                    dead.append(name)
            except Exception:           # unknown to the master, or its process gone
                dead.append(name)
        return dead

    def cpu_by_process(self):
        """CPU time [s] used so far by each process of the launch, by node name
        (:func:`tree_cpu_by_process`)."""
        return tree_cpu_by_process((self.core.pid, self.launch.pid))

    def cpu_seconds(self):
        """CPU time [s] used so far by roscore and by roslaunch and its nodes (Linux only: see
        :func:`tree_cpu_seconds`). Over a mission, its difference is the work the mission cost:
        on ``n`` cores no mission can take less wall time than that divided by ``n``."""
        return tree_cpu_seconds((self.core.pid, self.launch.pid))

    # --- shutdown ------------------------------------------------------------------------------
    def close(self):
        """Leave the master and stop roslaunch and roscore (SIGINT, then SIGTERM, SIGKILL)."""
        if self._node:
            import rospy
            rospy.signal_shutdown('harness done')
        for p in (self.launch, self.core):
            stop_process(p)
        self.log.close()


def mission_record(h, world, goal, use_corridor_law, limit=None):
    """Run one mission through the :class:`Harness` ``h`` (connected) and judge it against
    ``world`` (:class:`tiago_nav.sim.world.World`, ground truth from the simulator's tf).

    Args:
        h: the harness.
        world: the world it runs.
        goal: pose B ``(x, y, yaw_deg)`` [m, m, deg] in map.
        use_corridor_law: the goal's flag.
        limit: [s wall] a mission without a terminal state by then is a hang (None: no bound).

    Ground truth: the obstacles in view from the final pose for the harness's laser profile
    (:mod:`tiago_nav_tools.evaluate.inview`); a found centre on a glimpsed obstacle is no false positive,
    and its error counts with the others.

    Returns a dict: goal, ``succeeded``, ``hang``, ``message`` (the client's last line on
    failure, else the result's message), wall and simulated seconds, ``collisions`` during the
    mission, detection figures (``in_view``, ``glimpsed``, ``found``, ``matched``,
    ``matched_glimpsed``, ``recall``, ``false_positives``, ``rms_error_m``, ``max_error_m``,
    ``errors_m``: of every matched obstacle), ``final_pose`` and
    ``lines`` (everything the client printed).
    """
    import rospy
    from tiago_nav_tools.evaluate.metrics import detection_score
    from tiago_nav_tools.evaluate.inview import truth as view_truth
    x, y, yaw = goal
    c0 = h.collisions or 0
    t_sim = rospy.get_time()
    lines = []
    code, state, result, wall = h.mission(x, y, yaw, use_corridor_law, out=lines.append,
                                          limit=limit)
    sim = rospy.get_time() - t_sim
    final = h.pose()
    truth, glimpsed = view_truth(world, final, h.laser_model) if final else ([], [])
    found = [(o.center.x, o.center.y) for o in result.obstacles] if result else []
    s = detection_score([(tx, ty) for _, tx, ty, _ in truth], found,
                        [(gx, gy) for _, gx, gy, _ in glimpsed])
    message = (result.message if result else '') if code == 0 else (lines[-1] if lines else '')
    return {'world': world.name, 'goal': [x, y, yaw], 'use_corridor_law': use_corridor_law,
            'succeeded': code == 0, 'hang': code is None, 'message': message,
            'wall_s': wall, 'sim_s': sim, 'collisions': (h.collisions or 0) - c0,
            'in_view': s['true'], 'glimpsed': s['glimpsed'], 'found': s['found'],
            'matched': s['matched'], 'matched_glimpsed': s['matched_glimpsed'],
            'recall': s['recall'], 'false_positives': s['false_positives'],
            'rms_error_m': s['rms_error'], 'max_error_m': s['max_error'],
            'errors_m': [e['error'] for e in s['errors']],
            'final_pose': list(final) if final else None, 'lines': lines}


def tree_cpu_seconds(roots):
    """CPU time [s] (user + system) used so far by the live processes ``roots`` (pids) and all
    their descendants (roslaunch and every node it started, each in a session of its own), read
    from Linux's ``/proc``. Processes that have exited are not counted: take differences over a
    window in which they all run."""
    return sum(tree_cpu_by_process(roots).values())


def _process_name(pid):
    """A process's ROS node name (its ``__name:=`` argument) or its program's name."""
    try:
        with open('/proc/%d/cmdline' % pid, 'rb') as f:
            args = [a.decode(errors='replace') for a in f.read().split(b'\0') if a]
    except OSError:
        return str(pid)
    for a in args:
        if a.startswith('__name:='):
            return a[len('__name:='):]
    for a in args:                  # python3 /path/rosmaster ...: the script's name
        base = os.path.basename(a)
        if base and not base.startswith('python'):
            return base
    return os.path.basename(args[0]) if args else str(pid)


def tree_cpu_by_process(roots):
    """CPU time [s] so far of each live process under ``roots`` (see
    :func:`tree_cpu_seconds`), by node name (processes of the same name added up)."""
    tick = os.sysconf('SC_CLK_TCK')
    parent, cpu = {}, {}
    for pid in os.listdir('/proc'):
        if not pid.isdigit():
            continue
        try:
            with open('/proc/%s/stat' % pid) as f:
                # after the command name (which may hold spaces and parentheses): state, ppid,
                # ..., utime and stime (the 14th and 15th fields overall)
                fields = f.read().rsplit(')', 1)[1].split()
        except OSError:         # gone meanwhile
            continue
        parent[int(pid)] = int(fields[1])
        cpu[int(pid)] = int(fields[11]) + int(fields[12])
    roots = set(roots)
    out = {}
    for pid, ticks in cpu.items():
        p = pid
        while p not in roots and p in parent:    # up the tree to a root, or past init (ppid 0)
            p = parent[p]
        if p in roots:
            name = _process_name(pid)
            out[name] = out.get(name, 0.0) + ticks / tick
    return out


def stop_process(proc):
    """Stop a process started with ``start_new_session=True`` and everything it started:
    SIGINT (roslaunch shuts its nodes down cleanly), then SIGTERM, then SIGKILL."""
    if proc is None or proc.poll() is not None:
        return
    for sig, wait in ((signal.SIGINT, 15.0), (signal.SIGTERM, 5.0), (signal.SIGKILL, 5.0)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            return
        try:
            proc.wait(wait)
            return
        except subprocess.TimeoutExpired:
            continue
