"""One run of a localisation node on a log's bag, as a user runs it: a private ROS master with
``/use_sim_time``, the map published latched on ``/map`` (as map_server does), the node
started at a given pose and, once it has taken the map in, the bag played with ``rosbag play
--clock``; every ``/amcl_pose`` is recorded, with the node's CPU time over the playback and its
peak resident memory (Linux ``/proc``).

The localisers:

- ``tiago_nav``: ``roslaunch tiago_nav localisation.launch initial_pose:=[x, y, yaw_deg]``
  (ready once it logs that it took the map in);
- ``amcl``: ROS's amcl (ros-planning/navigation), from the workspace whose ``setup.bash`` is
  given: ``rosrun amcl amcl`` with the frames, the initial pose, ``use_map_topic`` and the given
  parameters (ready once it logs its likelihood field done).

Run as ``python3 -m tiago_nav_tools.testing.realdata.play CONFIG_JSON``: one run per process (a process joins
one master); it prints ``RESULT <json>`` last. :func:`run_child` does that from another process.
"""
import json
import math
import os
import subprocess
import sys
import tempfile
import threading
import time

READY = {'tiago_nav': ('/localisation', 'localisation: map '),
         'amcl': ('/amcl', 'Done initializing likelihood field model')}
NODE_NAME = {'tiago_nav': 'localisation', 'amcl': 'amcl'}


class PlayError(RuntimeError):
    """The run could not be made (no master, the node died or never got ready, the player
    hung); the message says which and where the log is."""


def node_pid(roots, name):
    """The pid of the process named ``name`` (its ``__name:=`` or program) under ``roots``."""
    from tiago_nav_tools.testing.harness import _process_name
    parent = {}
    for pid in os.listdir('/proc'):
        if pid.isdigit():
            try:
                with open('/proc/%s/stat' % pid) as f:
                    parent[int(pid)] = int(f.read().rsplit(')', 1)[1].split()[1])
            except OSError:
                continue
    for pid in sorted(parent):
        p = pid
        while p not in roots and p in parent:
            p = parent[p]
        if p in roots and _process_name(pid) == name:
            return pid
    return None


def cpu_seconds(pid):
    """User + system CPU time [s] of process ``pid`` (all its threads)."""
    with open('/proc/%d/stat' % pid) as f:
        fields = f.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def peak_rss_mb(pid):
    """Peak resident memory (VmHWM) [MB] of process ``pid``."""
    with open('/proc/%d/status' % pid) as f:
        for line in f:
            if line.startswith('VmHWM:'):
                return int(line.split()[1]) / 1024.0
    return None


def amcl_params(start, extra, cov=None):
    """amcl's private parameters for a run: the bag's frames, the initial pose ``start`` ``(x,
    y, yaw)``, the map from ``/map``, then ``extra`` (e.g. the tuned set)."""
    p = {'base_frame_id': 'base_footprint', 'odom_frame_id': 'odom', 'global_frame_id': 'map',
         'use_map_topic': True, 'initial_pose_x': float(start[0]),
         'initial_pose_y': float(start[1]), 'initial_pose_a': float(start[2])}
    p.update(extra or {})
    return p


def run(cfg):
    """One run (``cfg``: ``localiser``, ``bag``, ``map``, ``start`` ``[x, y, yaw]``,
    ``rate``, ``duration`` [s of the bag], ``last_stamp``, ``global_localization``,
    ``amcl_setup``, ``amcl_params``, ``log``); returns the record."""
    import rosgraph
    from tiago_nav_tools.testing.harness import free_port, stop_process
    port = free_port()
    uri = 'http://localhost:%d' % port
    env = dict(os.environ, ROS_MASTER_URI=uri)
    os.environ['ROS_MASTER_URI'] = uri
    log_path = cfg.get('log') or os.path.join(tempfile.gettempdir(), 'realdata_%d.log' % port)
    log = open(log_path, 'w')
    procs = []
    try:
        core = subprocess.Popen(['roscore', '-p', str(port)], env=env, stdout=log,
                                stderr=subprocess.STDOUT, start_new_session=True)
        procs.append(core)
        end = time.monotonic() + 60.0
        while not rosgraph.is_master_online(uri):
            if time.monotonic() > end or core.poll() is not None:
                raise PlayError('no ROS master at %s within 60 s (see %s)' % (uri, log_path))
            time.sleep(0.2)
        master = rosgraph.Master('/realdata_player')
        master.setParam('/use_sim_time', True)
        return _run(cfg, env, log, log_path, procs)
    finally:
        for p in reversed(procs):
            stop_process(p)
        log.close()


class Recorder:
    """This process's subscriptions of a run (it must be a node already): every
    ``/amcl_pose`` as ``(stamp [s], x, y, yaw, var x, var y, var yaw, wall time received)``,
    every ``/diagnostics`` of the node as ``(stamp [s], highest level, scans it says it skipped
    or None)``, and the node's readiness, seen on ``/rosout`` (the message of
    ``READY[kind]``)."""

    def __init__(self, kind):
        import rospy
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import PoseWithCovarianceStamped
        from rosgraph_msgs.msg import Log
        self.ready_node, self.ready_text = READY[kind]
        self.ready = threading.Event()
        self.lock = threading.Lock()
        self._estimates = []
        self._diagnostics = []
        self.subs = [rospy.Subscriber('/rosout', Log, self._on_log, queue_size=50),
                     rospy.Subscriber('/amcl_pose', PoseWithCovarianceStamped, self._on_pose,
                                      queue_size=100),
                     rospy.Subscriber('/diagnostics', DiagnosticArray, self._on_diagnostics,
                                      queue_size=100)]

    def _on_diagnostics(self, msg):
        if msg._connection_header.get('callerid') != self.ready_node or not msg.status:
            return
        skipped = None
        for st in msg.status:
            for kv in st.values:
                if kv.key == 'skipped scans':
                    skipped = int(kv.value)
        with self.lock:
            self._diagnostics.append((msg.header.stamp.to_sec(),
                                      max(ord(st.level) if isinstance(st.level, bytes) else
                                          int(st.level) for st in msg.status), skipped))

    def diagnostics(self):
        """``[(stamp, level, skipped)]`` so far."""
        with self.lock:
            return list(self._diagnostics)

    def _on_pose(self, msg):
        from tiago_nav.geometry import quaternion_to_yaw
        q, c = msg.pose.pose.orientation, msg.pose.covariance
        with self.lock:
            self._estimates.append((msg.header.stamp.to_sec(), msg.pose.pose.position.x,
                                    msg.pose.pose.position.y,
                                    quaternion_to_yaw(q.x, q.y, q.z, q.w), c[0], c[7], c[35],
                                    time.monotonic()))

    def _on_log(self, msg):
        if msg.name == self.ready_node and msg.msg.startswith(self.ready_text):
            self.ready.set()

    def wait_connected(self, limit, node=None):
        """Wait (wall ``limit`` s) until the localiser's ``/rosout`` is connected to this
        process, so that its readiness message cannot pass unheard (PlayError when the time runs
        out or the process ``node`` (Popen, optional) exits)."""
        import rosgraph
        import rospy
        master = rosgraph.Master(rospy.get_name())
        end = time.monotonic() + limit
        while True:
            try:
                uri = master.lookupNode(self.ready_node)
            except rosgraph.MasterError:
                uri = None
            if uri and any(c.endpoint_id == uri for c in self.subs[0].impl.connections):
                return
            if node is not None and node.poll() is not None:
                raise PlayError('%s exited with %s' % (self.ready_node, node.returncode))
            if time.monotonic() > end:
                raise PlayError('%s: its /rosout not connected within %g s'
                                % (self.ready_node, limit))
            time.sleep(0.05)

    def wait_ready(self, limit, node, what):
        """Wait (wall ``limit`` s) until the node said it took the map in; PlayError if the
        process ``node`` (Popen) exits first or the time runs out. Returns the seconds waited."""
        t0 = time.monotonic()
        while not self.ready.wait(0.5):
            if node.poll() is not None:
                raise PlayError('%s exited with %s before it was ready' % (what, node.returncode))
            if time.monotonic() - t0 > limit:
                raise PlayError('%s not ready within %g s' % (what, limit))
        return time.monotonic() - t0

    def drain(self, last_stamp, since, quiet=3.0, limit=60.0):
        """After the bag: wait until the estimate of the scan stamped ``last_stamp`` [s] has
        come, or none has come for ``quiet`` s of wall time (a node that publishes only after
        motion, or dropped that scan), at most ``limit`` s."""
        end = time.monotonic() + limit
        while time.monotonic() < end:
            with self.lock:
                latest = max((e[0] for e in self._estimates), default=0.0)
                heard = max((e[7] for e in self._estimates), default=since)
            if latest >= last_stamp - 1e-4 or time.monotonic() - heard > quiet:
                return
            time.sleep(0.1)

    def estimates(self):
        """``[(stamp, x, y, yaw, var x, var y, var yaw)]`` so far."""
        with self.lock:
            return [e[:7] for e in self._estimates]


def play_bag(bag, rate, duration, env, log):
    """``rosbag play --clock -q -r rate bag`` to its end (PlayError when it fails or takes more
    than three times its playing time plus two minutes)."""
    from tiago_nav_tools.testing.harness import stop_process
    player = subprocess.Popen(['rosbag', 'play', '--clock', '-q', '-r', '%g' % rate, bag],
                              env=env, stdout=log, stderr=subprocess.STDOUT,
                              start_new_session=True)
    limit = duration / rate * 3.0 + 120.0
    try:
        player.wait(limit)
    except subprocess.TimeoutExpired:
        stop_process(player)
        raise PlayError('rosbag play did not finish within %.0f s' % limit)
    if player.returncode:
        raise PlayError('rosbag play exited with %d' % player.returncode)


def publish_map(path_yaml):
    """Publish the map file latched on ``/map`` (as map_server does); returns the publisher."""
    import rospy
    from nav_msgs.msg import OccupancyGrid
    from tiago_nav.ros.conversions import gridmap_to_msg
    from tiago_nav_tools.testing.realdata.mapping import load_map
    pub = rospy.Publisher('/map', OccupancyGrid, queue_size=1, latch=True)
    pub.publish(gridmap_to_msg(load_map(path_yaml)))
    return pub


def _run(cfg, env, log, log_path, procs):
    import rosgraph
    import rospy

    kind = cfg['localiser']
    rospy.init_node('realdata_player', disable_signals=True)
    rec = Recorder(kind)

    x, y, yaw = cfg['start']
    if kind == 'tiago_nav':
        cmd = ['roslaunch', 'tiago_nav', 'localisation.launch',
               'initial_pose:=[%r, %r, %r]' % (x, y, math.degrees(yaw))]
    else:
        setup = cfg.get('amcl_setup')
        if not setup or not os.path.exists(setup):
            raise PlayError('amcl: no workspace setup.bash at %r' % setup)
        for k, v in amcl_params(cfg['start'], cfg.get('amcl_params')).items():
            rospy.set_param('/amcl/' + k, v)
        cmd = ['bash', '-c', 'source "$0" --extend && exec rosrun amcl amcl', setup]
    node = subprocess.Popen(cmd, env=env, stdout=log, stderr=subprocess.STDOUT,
                            start_new_session=True)
    procs.append(node)
    try:
        rec.wait_connected(60.0, node)
        map_pub = publish_map(cfg['map'])       # noqa: F841 (kept: the latched map)
        ready_s = rec.wait_ready(cfg.get('ready_timeout', 600.0), node, kind)
    except PlayError as e:
        raise PlayError('%s (see %s)' % (e, log_path))
    pid = node_pid({node.pid}, NODE_NAME[kind])
    if pid is None:
        raise PlayError('no %s process under %d' % (NODE_NAME[kind], node.pid))
    cpu_map = cpu_seconds(pid)

    pubs, _, services = rosgraph.Master('/realdata_player').getSystemState()
    diagnostics = any(t == '/diagnostics' and rec.ready_node in nodes for t, nodes in pubs)
    offered = None
    if cfg.get('global_localization'):
        offered = any(name == '/global_localization' for name, _ in services)
        if not offered:
            return {'localiser': kind, 'global_localization_offered': False,
                    'diagnostics_published': diagnostics, 'log': log_path}
        from std_srvs.srv import Empty
        rospy.wait_for_service('/global_localization', 10.0)
        rospy.ServiceProxy('/global_localization', Empty)()

    cpu0, w0 = cpu_seconds(pid), time.monotonic()
    try:
        play_bag(cfg['bag'], cfg['rate'], cfg['duration'], env, log)
    except PlayError as e:
        raise PlayError('%s (see %s)' % (e, log_path))
    rec.drain(cfg['last_stamp'], w0)
    wall = time.monotonic() - w0
    cpu1 = cpu_seconds(pid)
    rss = peak_rss_mb(pid)
    return {'localiser': kind, 'estimates': rec.estimates(), 'diagnostics': rec.diagnostics(),
            'cpu_s': cpu1 - cpu0,
            'cpu_map_s': cpu_map, 'ready_s': ready_s, 'wall_s': wall, 'peak_rss_mb': rss,
            'node_alive_at_end': node.poll() is None, 'global_localization_offered': offered,
            'diagnostics_published': diagnostics, 'log': log_path}


def run_child(cfg, timeout):
    """:func:`run` in a new process (``python3 -m tiago_nav_tools.testing.realdata.play``); its record, or
    ``{'error': message}``."""
    with tempfile.NamedTemporaryFile('w', suffix='.json', delete=False) as f:
        json.dump(cfg, f)
    try:
        out = subprocess.run([sys.executable, '-m', 'tiago_nav_tools.testing.realdata.play', f.name],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             timeout=timeout)
    except subprocess.TimeoutExpired:
        return {'error': 'run did not finish within %.0f s' % timeout}
    finally:
        os.unlink(f.name)
    for line in reversed(out.stdout.splitlines()):
        if line.startswith('RESULT '):
            return json.loads(line[len('RESULT '):])
    return {'error': 'no result (exit %d): %s' % (out.returncode, out.stderr.strip()[-600:])}


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    with open(argv[0]) as f:
        cfg = json.load(f)
    try:
        rec = run(cfg)
    except PlayError as e:
        rec = {'error': str(e)}
    print('RESULT ' + json.dumps(rec), flush=True)
    return 0 if 'error' not in rec else 1


if __name__ == '__main__':
    sys.exit(main())
