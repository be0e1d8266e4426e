#!/usr/bin/python3
"""obstacle_detection: recall, false positives, centre error and latency of the three methods,
and map subtraction by distance transform against the brute-force comparison.

Over seeded random robot poses (reachable, clear of every body) in the shipped worlds
(ias_lab_room_full: cylinders of r = 0.183 m; open_hall: r = 0.10-0.30 m), each scan is the
pybullet ray cast plus seeded 0.01 m Gaussian range noise, exactly what the simulator publishes.
Ground truth: the world file's movable obstacles; "in view" is the one definition the
evaluator and the tests use (tiago_nav_tools.evaluate.inview: >= 7 usable beams
of the noise-free cast for the laser profile); a found centre on a glimpsed obstacle (reached by
a beam, not in view) is no false positive. "In clear view" also asks the obstacle to be within
the detector's max_range and unoccluded (hit by >= 80 % of the beams its silhouette spans).
The scans are placed with their exact poses, so the pose correction is off unless
--correct-pose (bench_detection_sensing.py measures it under the localisation's error).
Latency is one library call (scan ranges -> obstacles in the map frame); the service round trip
(ROS, the wait for a fresh scan, tf) is measured separately with the node on its own master.
With tysik/obstacle_detector installed (``make obstacle-detector`` builds it in .od_ws; else it
is skipped, saying so), the live comparison on the course mission (:func:`live_comparison`).
Writes bench/results/detection.json and detection.png.
Usage: bench/bench_detection.py [--quick] [--no-service] [--laser-model ideal|tiago] [--correct-pose]
"""
import argparse
import dataclasses
import json
import math
import os
import subprocess
import sys
import time

import numpy as np
from scipy import ndimage

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if os.path.join(ROOT, 'src') not in sys.path:
    sys.path.append(os.path.join(ROOT, 'src'))   # after the workspace's (which has the messages)
RESULTS = os.path.join(ROOT, 'bench', 'results')

from tiago_nav_tools.testing.harness import Harness, free_port, stop_process  # noqa: E402
from tiago_nav.detection import METHODS, DetectionParams, ObstacleDetector  # noqa: E402
from tiago_nav.detection.subtraction import MapDistance, brute_force_distance  # noqa: E402
from tiago_nav import robot  # noqa: E402
from tiago_nav_tools.benchmarks import meta  # noqa: E402
from tiago_nav_tools.evaluate.inview import view_from  # noqa: E402
from tiago_nav.geometry import compose, inverse, transform_points, wrap_angle  # noqa: E402
from tiago_nav.scan import scan_to_points  # noqa: E402
from tiago_nav.sim.laser import LaserModel  # noqa: E402
from tiago_nav.sim.raster import rasterise_world  # noqa: E402
from tiago_nav.sim.scene import LaserConfig, Scene, noisy  # noqa: E402
from tiago_nav.sim.world import load_world  # noqa: E402

WORLDS = ['ias_lab_room_full.yaml', 'open_hall.yaml']
NOISE = 0.01            # [m] range noise std, as the simulator's default
ROBOT_RADIUS = robot.ROBOT_RADIUS  # [m] the simulator's default base
CLEARANCE = 0.1         # [m] extra free space around the sampled base
MATCH_GATE = 0.05       # [m] a found centre matches an obstacle within its radius + this
# circle_fit's targets: recall and RMS error over the obstacles in clear view, false positives
# over everything found, latency as the median library call
TARGETS = {'recall_clear': 1.0, 'false_positives': 0, 'rms_error_m': 0.01, 'latency_ms': 5.0,
           'subtraction_speedup': 100.0}


# --- poses and ground truth ---------------------------------------------------------------
def sample_poses(world, grid, n, rng, max_tries):
    """Up to ``n`` random base poses ``(x, y, yaw)`` reachable from the world's start (same
    connected free space), ``ROBOT_RADIUS + CLEARANCE`` clear of the map and of every movable
    obstacle, from which at least one movable obstacle is in view."""
    clear = ROBOT_RADIUS + CLEARANCE
    free = grid.distance_field() > clear
    xs, ys = grid.cell_centres()
    for c in world.movable_obstacles:
        free &= np.hypot(xs - c.x, ys - c.y) > c.radius + clear
    labels, _ = ndimage.label(free)
    (r0, c0), = grid.world_to_cell([world.start_pose[:2]])
    start_label = labels[r0, c0] if grid.in_bounds([[r0, c0]])[0] else 0
    cells = np.argwhere(labels == start_label) if start_label else np.argwhere(free)
    poses, tried = [], 0
    with Scene(world, robot_radius=ROBOT_RADIUS) as scene:
        while len(poses) < n and tried < max_tries:
            tried += 1
            rc = cells[rng.integers(len(cells))]
            (x, y), = grid.cell_to_world([rc])
            x += rng.uniform(-0.5, 0.5) * grid.resolution
            y += rng.uniform(-0.5, 0.5) * grid.resolution
            pose = (float(x), float(y), float(rng.uniform(-math.pi, math.pi)))
            if view_from(scene, pose).in_view:
                poses.append(pose)
    return poses, tried


def clear_view(world, scene, pose, ids, max_range, visible):
    """Indices of the movable obstacles in clear view from ``pose`` (see the module doc): of
    those in view (``visible``), the ones within ``max_range`` [m] and unoccluded."""
    lx, ly, lyaw = scene.laser_pose(pose)
    cfg = scene.laser
    ang = cfg.angles()
    out = []
    for i, (c, body) in enumerate(zip(world.movable_obstacles, scene.movable_ids)):
        hits = int(np.sum(ids == body))
        d = math.hypot(c.x - lx, c.y - ly)
        if i not in visible or d > max_range or d <= c.radius:
            continue
        bearing = wrap_angle(math.atan2(c.y - ly, c.x - lx) - lyaw)
        half = math.asin(c.radius / d)
        if bearing - half < cfg.angle_min or bearing + half > cfg.angle_max:
            continue                                   # cut by the edge of the field of view
        spanned = int(np.sum(np.abs(ang - bearing) <= half))
        if hits >= 0.8 * spanned:
            out.append(i)
    return out


def match(found, world, visible):
    """Assign found centres to true obstacles (nearest first, one each, within radius +
    MATCH_GATE). Returns ``(errors {index: metres}, false_positives, found_out_of_view)``."""
    pairs = []
    for k, d in enumerate(found):
        for i, c in enumerate(world.movable_obstacles):
            e = math.hypot(d.center[0] - c.x, d.center[1] - c.y)
            if e <= c.radius + MATCH_GATE:
                pairs.append((e, k, i))
    pairs.sort()
    used_f, errors = set(), {}
    for e, k, i in pairs:
        if k in used_f or i in errors:
            continue
        used_f.add(k)
        errors[i] = e
    unmatched = len(found) - len(used_f)
    out_of_view = sum(1 for i in errors if i not in visible)
    return {i: e for i, e in errors.items() if i in visible}, unmatched, out_of_view


# --- the measurement ----------------------------------------------------------------------
def evaluate_world(path, n_poses, seed, repeats, laser_model=LaserModel(laser_model='ideal'),
                   correct_pose=False):
    world = load_world(path)
    grid = rasterise_world(world)
    params = DetectionParams(correct_pose=correct_pose)
    t0 = time.perf_counter()
    detector = ObstacleDetector(grid, params)
    dt_build_ms = (time.perf_counter() - t0) * 1e3
    rng = np.random.default_rng(seed)
    poses, tried = sample_poses(world, grid, n_poses, rng, max_tries=40 * n_poses)
    cfg = LaserConfig()
    res = {m: {'in_view': 0, 'found_in_view': 0, 'clear': 0, 'found_clear': 0,
               'false_positives': 0, 'found_out_of_view': 0, 'errors_in_view': [],
               'errors_clear': [], 'latency_ms': [], 'misses': [], 'fp_poses': []}
           for m in METHODS}
    sub = {'points': [], 'transform_ms': [], 'brute_force_ms': [], 'max_abs_diff_m': 0.0}
    example = None
    with Scene(world, robot_radius=ROBOT_RADIUS) as scene:
        for k, pose in enumerate(poses):
            clean, ids = scene.cast(pose)
            ranges = laser_model.apply(clean, cfg, NOISE, rng).ranges     # ideal: noisy()
            laser = scene.laser_pose(pose)
            laser_in_base = compose(inverse(pose), laser)
            visible = view_from(scene, pose, laser_model.laser_model).in_view
            clear = clear_view(world, scene, pose, ids, params.max_range, visible)
            for m in METHODS:
                best = math.inf
                for _ in range(repeats):
                    t = time.perf_counter()
                    found = detector.detect(ranges, cfg.angle_min, cfg.angle_increment,
                                            cfg.range_min, cfg.range_max, laser, m,
                                            laser_in_base=laser_in_base)
                    best = min(best, time.perf_counter() - t)
                errors, fp, extra = match(found, world, visible)
                r = res[m]
                r['latency_ms'].append(best * 1e3)
                r['in_view'] += len(visible)
                r['found_in_view'] += len(errors)
                r['clear'] += len(clear)
                r['found_clear'] += sum(1 for i in clear if i in errors)
                r['false_positives'] += fp
                r['found_out_of_view'] += extra
                r['errors_in_view'] += list(errors.values())
                r['errors_clear'] += [errors[i] for i in clear if i in errors]
                r['misses'] += [(k, i) for i in clear if i not in errors]
                if fp:
                    r['fp_poses'].append(k)
                if m == 'circle_fit' and (example is None or len(visible) > example[1]):
                    example = (k, len(visible))
            # map subtraction: distance transform look-up vs every point against every cell
            local, _ = scan_to_points(ranges, cfg.angle_min, cfg.angle_increment,
                                      cfg.range_min, cfg.range_max)
            pts = transform_points(laser, local)
            t = time.perf_counter()
            fast = detector.distance(pts) > params.scan_minus_map_threshold
            t_fast = time.perf_counter() - t
            t = time.perf_counter()
            dist = brute_force_distance(pts, grid)
            slow = dist > params.scan_minus_map_threshold
            t_slow = time.perf_counter() - t
            sub['points'].append(len(pts))
            sub['transform_ms'].append(t_fast * 1e3)
            sub['brute_force_ms'].append(t_slow * 1e3)
            finite = np.isfinite(dist)
            sub['max_abs_diff_m'] = max(sub['max_abs_diff_m'], float(np.max(
                np.abs(detector.distance(pts)[finite] - dist[finite]), initial=0.0)))
            sub.setdefault('disagree', 0)
            sub['disagree'] += int(np.sum(fast != slow))
    summary = {'world': world.name, 'poses': len(poses), 'poses_tried': tried,
               'occupied_cells': int(grid.occupied().sum()),
               'map_cells': int(grid.data.size), 'distance_transform_build_ms': round(dt_build_ms, 2),
               'methods': {}}
    for m in METHODS:
        r = res[m]
        e_all = np.array(r['errors_in_view'])
        e_clear = np.array(r['errors_clear'])
        lat = np.array(r['latency_ms'])
        summary['methods'][m] = {
            'in_view': r['in_view'], 'found_in_view': r['found_in_view'],
            'recall_in_view': round(r['found_in_view'] / max(r['in_view'], 1), 4),
            'clear_view': r['clear'], 'found_clear': r['found_clear'],
            'recall_clear': round(r['found_clear'] / max(r['clear'], 1), 4),
            'false_positives': r['false_positives'], 'found_out_of_view': r['found_out_of_view'],
            'rms_error_m': round(float(np.sqrt(np.mean(e_all ** 2))), 4) if e_all.size else None,
            'rms_error_clear_m': round(float(np.sqrt(np.mean(e_clear ** 2))), 4) if e_clear.size else None,
            'max_error_m': round(float(e_all.max()), 4) if e_all.size else None,
            'latency_ms_median': round(float(np.median(lat)), 3),
            'latency_ms_p95': round(float(np.percentile(lat, 95)), 3),
            'latency_ms_max': round(float(lat.max()), 3),
            'missed_clear': r['misses'][:10], 'false_positive_poses': r['fp_poses'][:10]}
    p = np.array(sub['points'])
    tf, bf = np.array(sub['transform_ms']), np.array(sub['brute_force_ms'])
    summary['subtraction'] = {
        'points_median': int(np.median(p)), 'transform_ms_median': round(float(np.median(tf)), 4),
        'brute_force_ms_median': round(float(np.median(bf)), 3),
        'speedup_median': round(float(np.median(bf / tf)), 1),
        'max_abs_diff_m': round(sub['max_abs_diff_m'], 4), 'points_classified_differently': sub['disagree']}
    return summary, world, grid, poses, example


def scaling(path, rng):
    """Asymptotics: the same world rasterised at finer cells (more occupied cells M) and scans
    of N points. Brute force grows as N·M; the look-up as N (the transform is built once per map)."""
    world = load_world(path)
    rows = []
    for res in (0.1, 0.05, 0.025):
        w = dataclasses.replace(world, resolution=res)
        grid = rasterise_world(w)
        t = time.perf_counter()
        dist = MapDistance(grid)
        build = time.perf_counter() - t
        for n in (200, 666, 2000):
            x0, y0, x1, y1 = grid.bounds
            pts = rng.uniform((x0, y0), (x1, y1), (n, 2))
            t_fast = min(_timed(lambda: dist(pts)) for _ in range(5))
            t_slow = min(_timed(lambda: brute_force_distance(pts, grid)) for _ in range(2))
            rows.append({'resolution_m': res, 'occupied_cells': int(grid.occupied().sum()),
                         'points': n, 'transform_build_ms': round(build * 1e3, 2),
                         'transform_ms': round(t_fast * 1e3, 4),
                         'brute_force_ms': round(t_slow * 1e3, 3),
                         'speedup': round(t_slow / t_fast, 1)})
    return rows


def _timed(fn):
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


# --- the service round trip (ROS), in a child process on its own master ----------------------
def service_round_trip(world_path, pose, calls, rtf):
    out = subprocess.run([sys.executable, os.path.abspath(__file__), '--service-child', world_path,
                          json.dumps([pose[0], pose[1], math.degrees(pose[2])]), str(calls), str(rtf)],
                         stdout=subprocess.PIPE, text=True, timeout=180)
    lines = out.stdout.strip().splitlines()
    if out.returncode != 0 or not lines:
        raise RuntimeError('service measurement failed (exit %d)' % out.returncode)
    return json.loads(lines[-1])


def measure_service(world_path, start, calls, rtf):
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI='http://localhost:%d' % port)
    launch = subprocess.Popen(
        ['roslaunch', '-p', str(port), 'tiago_nav', 'sim.launch', 'world:=' + world_path,
         'real_time_factor:=%s' % rtf, 'robot_start:=%s' % start],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    node = None
    try:
        os.environ['ROS_MASTER_URI'] = env['ROS_MASTER_URI']
        deadline = time.time() + 60
        while subprocess.run(['rosparam', 'load', os.path.join(ROOT, 'config', 'detection.yaml'),
                              '/obstacle_detection'], env=env, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL).returncode != 0:
            if time.time() > deadline:
                raise RuntimeError('no ROS master on port %d' % port)
            time.sleep(0.5)
        node = subprocess.Popen(['rosrun', 'tiago_nav', 'obstacle_detection',
                                 '__name:=obstacle_detection'], env=env,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                start_new_session=True)
        import rospy
        from tiago_nav.srv import DetectObstacles, DetectObstaclesRequest
        deadline = time.time() + 60
        while True:
            try:
                rospy.init_node('bench_detection', anonymous=True, disable_signals=True)
                break
            except Exception:
                if time.time() > deadline:
                    raise
                time.sleep(0.5)
        rospy.wait_for_service('obstacle_detection', timeout=60)
        call = rospy.ServiceProxy('obstacle_detection', DetectObstacles, persistent=True)
        # the service comes with the map; the simulator's first scans and tf may still be on
        # their way (the node answers success=false until they are there)
        for _ in range(60):
            if call(DetectObstaclesRequest()).success:
                break
            time.sleep(0.5)
        rt, found = [], []
        for _ in range(calls):
            t = time.perf_counter()
            resp = call(DetectObstaclesRequest())
            rt.append((time.perf_counter() - t) * 1e3)
            found.append(len(resp.obstacles))
        return {'calls': calls, 'real_time_factor': rtf,
                'round_trip_ms_median': round(float(np.median(rt)), 2),
                'round_trip_ms_p95': round(float(np.percentile(rt, 95)), 2),
                'obstacles_found_median': int(np.median(found))}
    finally:
        for p in (node, launch):
            stop_process(p)


def obstacle_detector_available():
    """``(True, path)`` when tysik/obstacle_detector (not a Debian package) is installed in the
    ROS environment, found with ``rospack find obstacle_detector``; ``(False, why)`` otherwise."""
    try:
        out = subprocess.run(['rospack', 'find', 'obstacle_detector'], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, timeout=30)
    except FileNotFoundError:
        return False, 'rospack is not on PATH (source the workspace\'s devel/setup.bash)'
    except subprocess.TimeoutExpired:
        return False, 'rospack find obstacle_detector did not answer within 30 s'
    if out.returncode != 0:
        why = (out.stderr.strip().splitlines() or ['not found'])[-1]
        return False, ('obstacle_detector is not installed (rospack find obstacle_detector: %s); '
                       'it is not a Debian package: build tysik/obstacle_detector in a catkin '
                       'workspace and source it to compare' % why)
    return True, out.stdout.strip()


OD_SCANS = 20             # live scans at pose B compared
COURSE_B = (11.0, 0.0, -45.0)


def obstacle_detector_comparison(laser_model, quick=False):
    """The live-scan comparison with obstacle_detector under ``laser_model``: skipped, with the
    reason, when the package is not installed; else :func:`live_comparison` in a child process
    on its own master."""
    ok, info = obstacle_detector_available()
    if not ok:
        print('\nobstacle_detector comparison (%s laser): skipped: %s' % (laser_model, info))
        return {'skipped': True, 'reason': info, 'laser_model': laser_model}
    scans = 10 if quick else OD_SCANS
    try:
        out = subprocess.run([sys.executable, os.path.abspath(__file__), '--od-child',
                              laser_model, str(scans)],
                             stdout=subprocess.PIPE, text=True, timeout=600)
        lines = out.stdout.strip().splitlines()
        if out.returncode != 0 or not lines:
            raise RuntimeError('the comparison child failed (exit %d)' % out.returncode)
        res = json.loads(lines[-1])
    except (RuntimeError, subprocess.TimeoutExpired, ValueError) as e:
        print('\nobstacle_detector comparison (%s laser): failed: %s' % (laser_model, e))
        return {'skipped': True, 'reason': 'failed: %s' % e, 'laser_model': laser_model}
    res.update(skipped=False, installed_at=info, laser_model=laser_model)
    print('\nobstacle_detector comparison (%s laser, the course mission, then %d live scans at '
          'pose B; obstacle_detector reads the scan with the self-hits and veils set invalid):'
          % (laser_model, res['scans']))
    for k in ('tiago_nav_one_scan', 'tiago_nav', 'obstacle_detector'):
        m = res[k]
        print('  %-18s found %3d/%3d, RMS %.2f cm, max %.2f cm, %d false positives (%d off the '
              'static map)' % (k, m['found'], m['must_find'], 100 * (m['rms_error_m'] or 0),
                               100 * (m['max_error_m'] or 0), m['false_positives'],
                               m['false_positives_off_map']))
    print('  (tiago_nav: the service\'s median of the scans at rest, %s scans per call)'
          % sorted(set(res['rest_scans_used'])))
    if res.get('rms_ratio'):
        print('  obstacle_detector\'s centre RMS is %.1fx tiago_nav\'s on the one scan, %.1fx '
              'with the scans at rest' % (res['rms_ratio'], res['rms_ratio_rest'] or 0))
    return res


def _judge_centres(truth, found, near_map):
    """Errors of the found centres ``[(x, y)]`` matched one-to-one (Hungarian, within the
    evaluator's gate) to ``truth`` ``[(x, y)]``; unmatched ones are false positives, those
    ``near_map`` says are on the static map counted apart."""
    from tiago_nav_tools.evaluate.matching import match_obstacles
    pairs, missed, fps = match_obstacles(truth, found)
    off = [j for j in fps if not near_map(found[j])]
    return [e for _, _, e in pairs], len(missed), len(fps), len(off)


def live_comparison(laser_model, scans):
    """Run the course mission (demo.launch at real-time factor 2, seed 0, the default
    odometry and localisation, ``laser_model``), then, over ``scans`` scans at pose B (each the
    newest when the one before has been answered),
    ask this package's obstacle_detection for each scan (``scan_stamp``; ``tiago_nav``: the
    launch's node, which combines the scan with the scans at rest before it, ``rest_scans``;
    ``tiago_nav_one_scan``: a second node with ``rest_scans`` 1, the like-for-like comparison)
    and take obstacle_detector's obstacle_extractor's circles for the same scan (it reads /scan
    with the beams :func:`tiago_nav.scan.usable_ranges` drops set to NaN: the robot's own body and
    the veils, filtered for it as for this package; its circles come out in map through tf at
    the scan's stamp). All are judged against the world file: the movable obstacles in view
    from the true pose (:mod:`tiago_nav_tools.evaluate.inview`) must be found; a found centre matching
    none (within 0.3 m) is a false positive, counted apart when it lies on the static map (a wall or a
    mapped cylinder, which the map subtraction of this package removes by design)."""
    import rospy
    from obstacle_detector.msg import Obstacles
    from sensor_msgs.msg import LaserScan
    from tiago_nav.scan import usable_ranges
    from tiago_nav.srv import DetectObstacles, DetectObstaclesRequest
    world_path = os.path.join(ROOT, 'worlds', WORLDS[0])
    world = load_world(world_path)
    distance = MapDistance(rasterise_world(world))
    h = Harness(world_path, real_time_factor=2.0,
                extra_args=('laser_model:=' + laser_model, 'seed:=0'))
    extractor = one = None
    try:
        h.connect()
        # the extractor is given only the scans compared, one at a time, each once it has
        # answered the one before: fed every scan, it drops the scans its queue cannot hold
        # when the host is loaded, and the scan compared may be one of them
        relay = rospy.Publisher('/scan_usable', LaserScan, queue_size=100)
        stamps, usable, circles = [], {}, {}

        def on_scan(msg):
            msg.ranges = list(usable_ranges(msg.ranges, msg.angle_min, msg.angle_increment,
                                            msg.range_min, msg.range_max))
            usable[msg.header.stamp] = msg
            stamps.append(msg.header.stamp)

        def on_obstacles(msg):
            circles[msg.header.stamp] = [(c.center.x, c.center.y) for c in msg.circles]
        rospy.Subscriber('/scan', LaserScan, on_scan, queue_size=100)
        rospy.Subscriber('/raw_obstacles', Obstacles, on_obstacles, queue_size=100)
        # obstacle_extractor_node with its defaults, but reading the scan, circles in map, and
        # its window on them (default +-10 m about map's origin) wide enough for the world
        b = world.bounds
        extractor = _node(h, ['obstacle_detector', 'obstacle_extractor_node',
                              'scan:=/scan_usable', '__name:=obstacle_extractor',
                              '_frame_id:=map', '_use_scan:=true', '_use_pcl:=false',
                              '_min_x_limit:=%g' % b[0], '_min_y_limit:=%g' % b[1],
                              '_max_x_limit:=%g' % b[2], '_max_y_limit:=%g' % b[3]])
        one = _node(h, ['tiago_nav', 'obstacle_detection', '__name:=obstacle_detection_one',
                        'obstacle_detection:=obstacle_detection_one', '_rest_scans:=1'])
        detect = {}
        for k, name in (('tiago_nav', 'obstacle_detection'),
                        ('tiago_nav_one_scan', 'obstacle_detection_one')):
            rospy.wait_for_service(name, timeout=60)
            detect[k] = rospy.ServiceProxy(name, DetectObstacles, persistent=True)
        lines = []
        code, _, _, _ = h.mission(*COURSE_B, True, out=lines.append, limit=180.0)
        if code != 0:
            raise RuntimeError('the course mission failed: %s' % (lines[-1] if lines else code))
        # each row takes the newest scan, newer than the previous row's: the nodes hold the
        # last 4 s of scans, which a loaded host may take longer than to answer a row
        last = [stamps[-1] if stamps else None]
        with Scene(world) as scene:
            rows = []
            while len(rows) < scans:
                _wait(lambda: stamps and stamps[-1] != last[0], 'no scan at pose B')
                stamp = last[0] = stamps[-1]
                resp = {}
                for k, call in detect.items():
                    resp[k] = call(DetectObstaclesRequest(method='circle_fit', scan_stamp=stamp))
                    if not resp[k].success:
                        raise RuntimeError('%s failed: %s' % (k, resp[k].message))
                _wait(lambda: relay.get_num_connections() > 0,
                      'obstacle_detector did not subscribe to /scan_usable')
                relay.publish(usable[stamp])
                _wait(lambda: stamp in circles, 'obstacle_detector did not answer the scan at '
                      '%.3f' % stamp.to_sec())
                must = view_from(scene, h.pose(), laser_model).in_view
                rows.append({'truth': [(world.movable_obstacles[i].x,
                                        world.movable_obstacles[i].y) for i in must],
                             'rest_message': resp['tiago_nav'].message,
                             **{k: [(o.center.x, o.center.y) for o in r.obstacles]
                                for k, r in resp.items()},
                             'obstacle_detector': circles[stamp]})

        def near_map(xy):
            return bool(distance(np.array([xy]))[0] <= 0.3)
        out = {'scans': scans, 'world': world.name, 'pose_b': list(COURSE_B),
               'truth_pose': [round(v, 4) for v in h.pose()],
               'rest_scans_used': [int(m.split('the median of ')[1].split()[0])
                                   if 'the median of ' in m else 1
                                   for m in (r['rest_message'] for r in rows)]}
        for k in ('tiago_nav', 'tiago_nav_one_scan', 'obstacle_detector'):
            errs, missed, fps, off = [], 0, 0, 0
            for r in rows:
                e, m, f, o = _judge_centres(r['truth'], r[k], near_map)
                errs += e
                missed, fps, off = missed + m, fps + f, off + o
            errs = np.array(errs)
            must = sum(len(r['truth']) for r in rows)
            out[k] = {'must_find': must, 'found': must - missed,
                      'rms_error_m': (round(float(np.sqrt(np.mean(errs ** 2))), 4)
                                      if errs.size else None),
                      'max_error_m': round(float(errs.max()), 4) if errs.size else None,
                      'false_positives': fps, 'false_positives_off_map': off}
        b = out['obstacle_detector']['rms_error_m']
        for k, key in (('tiago_nav_one_scan', 'rms_ratio'), ('tiago_nav', 'rms_ratio_rest')):
            a = out[k]['rms_error_m']
            out[key] = round(b / a, 2) if a and b else None
        return out
    finally:
        for p in (one, extractor):
            stop_process(p)
        h.close()


def _node(h, args):
    """``rosrun ARGS`` on the harness ``h``'s master, in a session of its own."""
    return subprocess.Popen(['rosrun'] + args, env=h.env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)


def _wait(condition, failure, timeout=10.0):
    """Wait up to ``timeout`` wall seconds for ``condition()``; RuntimeError(``failure``)
    otherwise."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise RuntimeError(failure)
        time.sleep(0.01)


# --- the figure ---------------------------------------------------------------------------
def plot(path, runs, scale_rows):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig = plt.figure(figsize=(15, 9))
    cfg = LaserConfig()
    colours = {'circle_fit': 'tab:blue', 'centroid': 'tab:orange', 'discontinuity': 'tab:purple'}
    markers = {'circle_fit': 'x', 'centroid': '+', 'discontinuity': '1'}
    for j, (summary, world, grid, poses, example) in enumerate(runs):
        ax = fig.add_subplot(2, 2, j + 1)
        pose = poses[example[0]]
        with Scene(world, robot_radius=ROBOT_RADIUS) as scene:
            clean, _ = scene.cast(pose)
            laser = scene.laser_pose(pose)
            visible = view_from(scene, pose).in_view
        ranges = noisy(clean, NOISE, np.random.default_rng(1), cfg.range_min, cfg.range_max)
        det = ObstacleDetector(grid, DetectionParams(correct_pose=False))   # exact poses
        x0, y0, x1, y1 = grid.bounds
        ax.imshow(grid.data, origin='lower', extent=(x0, x1, y0, y1), cmap='gray_r', vmin=0, vmax=140)
        local, _ = scan_to_points(ranges, cfg.angle_min, cfg.angle_increment, cfg.range_min, cfg.range_max)
        pts = transform_points(laser, local)
        ax.plot(pts[:, 0], pts[:, 1], '.', ms=1.5, color='tab:green', label='scan (0.01 m noise)')
        for i, c in enumerate(world.movable_obstacles):
            ax.add_patch(plt.Circle((c.x, c.y), c.radius, fill=False, lw=1.2,
                                    color='tab:red' if i in visible else 'lightcoral',
                                    ls='-' if i in visible else ':'))
            ax.plot(c.x, c.y, 'o', ms=3, color='tab:red', label='true centres' if i == 0 else None)
        for m in METHODS:
            found = det.detect(ranges, cfg.angle_min, cfg.angle_increment, cfg.range_min,
                               cfg.range_max, laser, m)
            ax.plot([d.center[0] for d in found], [d.center[1] for d in found], markers[m],
                    ms=9, mew=1.5, color=colours[m], label=m)
        x, y, th = pose
        ax.add_patch(plt.Circle((x, y), ROBOT_RADIUS, color='tab:blue', alpha=0.4))
        ax.arrow(x, y, 0.4 * math.cos(th), 0.4 * math.sin(th), width=0.03, color='tab:blue')
        ax.set_title('%s: %d in view (solid circles)' % (world.name, len(visible)), fontsize=10)
        ax.set_xlabel('x [m] (map)')
        ax.set_ylabel('y [m] (map)')
        ax.legend(loc='upper right', fontsize=7)
    ax = fig.add_subplot(2, 2, 3)
    names = [r[0]['world'] for r in runs]
    width = 0.25
    for k, m in enumerate(METHODS):
        view = [(r[0]['methods'][m]['rms_error_m'] or 0) * 100 for r in runs]
        clear = [(r[0]['methods'][m]['rms_error_clear_m'] or 0) * 100 for r in runs]
        x = np.arange(len(names)) + (k - 1) * width
        ax.bar(x, view, width, color=colours[m], alpha=0.35)
        ax.bar(x, clear, width * 0.6, color=colours[m], label=m + ' (clear view; pale: all in view)')
    ax.axhline(TARGETS['rms_error_m'] * 100, color='k', ls='--', lw=1, label='target (circle_fit)')
    ax.set_yscale('log')
    ax.set_xticks(np.arange(len(names)))
    ax.set_xticklabels(names)
    ax.set_ylabel('centre RMS error [cm] (log)')
    ax.set_title('centre RMS error, 0.01 m noise', fontsize=10)
    ax.set_ylim(top=ax.get_ylim()[1] * 8)
    ax.legend(fontsize=7, loc='upper left')
    ax = fig.add_subplot(2, 2, 4)
    for n in sorted({r['points'] for r in scale_rows}):
        rows = [r for r in scale_rows if r['points'] == n]
        m = [r['occupied_cells'] for r in rows]
        ax.loglog(m, [r['brute_force_ms'] for r in rows], 'o-', label='brute force, N=%d' % n)
        ax.loglog(m, [r['transform_ms'] for r in rows], 's--', label='distance transform, N=%d' % n)
    ax.set_xlabel('occupied map cells M')
    ax.set_ylabel('map subtraction of N points [ms]')
    ax.set_title('map subtraction: O(N) look-up vs O(N*M) comparison', fontsize=10)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--quick', action='store_true', help='fewer poses, a short service run')
    ap.add_argument('--no-service', action='store_true', help='skip the ROS service round trip')
    ap.add_argument('--poses', type=int, default=None, help='poses per world (default 60, quick 12)')
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--laser-model', choices=('ideal', 'tiago'), default='ideal',
                    help="the simulated laser: ideal (exact cast + noise, today's figures) or tiago "
                         "(self-hits, mixed pixels, dropouts); tiago writes detection_tiago.*")
    ap.add_argument('--correct-pose', action='store_true',
                    help='run with the pose correction (off by default here: the scans are placed '
                         'with their exact poses, so a correction could only add the map '
                         'raster\'s bias; bench_detection_sensing.py measures it with the '
                         'localisation\'s error)')
    ap.add_argument('--service-child', nargs=4, help=argparse.SUPPRESS)
    ap.add_argument('--od-child', nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.od_child:
        print(json.dumps(live_comparison(args.od_child[0], int(args.od_child[1]))))
        return
    if args.service_child:
        w, start, calls, rtf = args.service_child
        print(json.dumps(measure_service(w, start, int(calls), rtf)))
        return
    os.makedirs(RESULTS, exist_ok=True)
    n = args.poses or (12 if args.quick else 60)
    repeats = 1 if args.quick else 3
    out = {'machine': {'cores': os.cpu_count()}, 'noise_std_m': NOISE, 'seed': args.seed,
           'targets_circle_fit': TARGETS,
           'params': dataclasses.asdict(DetectionParams(correct_pose=args.correct_pose)),
           'worlds': {}}
    runs = []
    for j, name in enumerate(WORLDS):
        summary, world, grid, poses, example = evaluate_world(
            os.path.join(ROOT, 'worlds', name), n, args.seed + j, repeats,
            LaserModel(laser_model=args.laser_model), args.correct_pose)
        out['worlds'][world.name] = summary
        runs.append((summary, world, grid, poses, example))
        print('\n%s: %d poses with obstacles in view (%d drawn), %d occupied cells, transform '
              'built in %.1f ms' % (world.name, summary['poses'], summary['poses_tried'],
                                   summary['occupied_cells'], summary['distance_transform_build_ms']))
        print('  %-14s %12s %12s %4s %10s %10s %10s %10s %10s' % (
            'method', 'recall view', 'recall clear', 'FP', 'RMS clear', 'RMS view', 'max view',
            'call [ms]', 'p95 [ms]'))
        for m in METHODS:
            s = summary['methods'][m]
            print('  %-14s %5d/%-6d %5d/%-6d %4d %7.2f cm %7.2f cm %7.2f cm %10.2f %10.2f' % (
                m, s['found_in_view'], s['in_view'], s['found_clear'], s['clear_view'],
                s['false_positives'], (s['rms_error_clear_m'] or 0) * 100,
                (s['rms_error_m'] or 0) * 100, (s['max_error_m'] or 0) * 100,
                s['latency_ms_median'], s['latency_ms_p95']))
        sb = summary['subtraction']
        print('  map subtraction of %d points: transform %.3f ms, brute force %.2f ms, %.0fx faster; '
              '%d points classified differently' % (sb['points_median'], sb['transform_ms_median'],
                                                     sb['brute_force_ms_median'], sb['speedup_median'],
                                                     sb['points_classified_differently']), flush=True)
    rows = scaling(os.path.join(ROOT, 'worlds', WORLDS[0]), np.random.default_rng(args.seed))
    out['subtraction_scaling'] = rows
    print('\nmap subtraction scaling (%s rasterised at 0.1/0.05/0.025 m):' % runs[0][0]['world'])
    print('  %8s %6s %12s %12s %9s %10s' % ('M cells', 'N', 'transform', 'brute force', 'speedup', 'build'))
    for r in rows:
        print('  %8d %6d %9.3f ms %9.2f ms %8.0fx %7.1f ms' % (
            r['occupied_cells'], r['points'], r['transform_ms'], r['brute_force_ms'], r['speedup'],
            r['transform_build_ms']))
    if not args.no_service:
        summary, world, grid, poses, example = runs[0]
        pose = poses[example[0]]
        try:
            svc = service_round_trip(os.path.join(ROOT, 'worlds', WORLDS[0]), pose,
                                     10 if args.quick else 30, 1.0)
            svc['pose'] = [round(pose[0], 3), round(pose[1], 3), round(math.degrees(pose[2]), 1)]
            out['service'] = svc
            print('\nservice round trip (%s, %d calls, sim at 1x): median %.1f ms, p95 %.1f ms '
                  '(mostly the wait for the next 15 Hz scan; the answer carries no processing '
                  'time)' % (world.name, svc['calls'], svc['round_trip_ms_median'],
                             svc['round_trip_ms_p95']))
        except (RuntimeError, subprocess.TimeoutExpired) as e:
            out['service'] = {'error': str(e)}
            print('\nservice round trip: not measured (%s)' % e)
    out['obstacle_detector'] = obstacle_detector_comparison(args.laser_model, args.quick)
    # targets, circle_fit, over all worlds
    cf = [s['methods']['circle_fit'] for s in out['worlds'].values()]
    errs_sq = sum((c['rms_error_m'] or 0) ** 2 * c['found_in_view'] for c in cf)
    clear_sq = sum((c['rms_error_clear_m'] or 0) ** 2 * c['found_clear'] for c in cf)
    met = {
        'recall_clear': sum(c['found_clear'] for c in cf) / max(sum(c['clear_view'] for c in cf), 1),
        'recall_in_view': sum(c['found_in_view'] for c in cf) / max(sum(c['in_view'] for c in cf), 1),
        'false_positives': sum(c['false_positives'] for c in cf),
        'rms_error_m': math.sqrt(clear_sq / max(sum(c['found_clear'] for c in cf), 1)),
        'rms_error_in_view_m': math.sqrt(errs_sq / max(sum(c['found_in_view'] for c in cf), 1)),
        'max_error_in_view_m': max(c['max_error_m'] or 0 for c in cf),
        'latency_ms': max(c['latency_ms_median'] for c in cf),
        'latency_ms_p95': max(c['latency_ms_p95'] for c in cf),
        'subtraction_speedup': min(s['subtraction']['speedup_median'] for s in out['worlds'].values()),
    }
    out['circle_fit_overall'] = {k: round(v, 4) for k, v in met.items()}
    ok = {'recall_clear': met['recall_clear'] >= TARGETS['recall_clear'],
          'false_positives': met['false_positives'] <= TARGETS['false_positives'],
          'rms_error_m': met['rms_error_m'] <= TARGETS['rms_error_m'],
          'latency_ms': met['latency_ms'] <= TARGETS['latency_ms'],
          'subtraction_speedup': met['subtraction_speedup'] >= TARGETS['subtraction_speedup']}
    out['targets_met'] = ok
    print('\ncircle_fit over all worlds: recall (clear view) %.1f %%, recall (in view) %.1f %%, '
          '%d false positives, RMS %.2f cm in clear view (%.2f cm over all in view, max %.1f cm), '
          'call %.2f ms median (p95 %.2f), subtraction %.0fx faster'
          % (100 * met['recall_clear'], 100 * met['recall_in_view'], met['false_positives'],
             100 * met['rms_error_m'], 100 * met['rms_error_in_view_m'],
             100 * met['max_error_in_view_m'], met['latency_ms'], met['latency_ms_p95'],
             met['subtraction_speedup']))
    print('targets: ' + ', '.join('%s %s' % (k, 'met' if v else 'MISSED') for k, v in ok.items()))
    # latencies are wall time on a shared machine: say how busy it was
    out['load_average_1_5_15'] = [round(v, 2) for v in os.getloadavg()]
    print('load average %s on %d cores' % (out['load_average_1_5_15'], os.cpu_count()))
    stem = 'detection' if args.laser_model == 'ideal' else 'detection_' + args.laser_model
    out['laser_model'] = args.laser_model
    plot(os.path.join(RESULTS, stem + '.png'), runs, rows)
    out['meta'] = meta({k: v for k, v in vars(args).items()
                        if k not in ('service_child', 'od_child')},
                       quick=args.quick, laser_model=args.laser_model,
                       odometry_model='n/a (scans from set poses)',
                       real_time_factor='in process' + ('' if args.no_service else
                                                        '; service run at 1.0'))
    with open(os.path.join(RESULTS, stem + '.json'), 'w') as f:
        json.dump(out, f, indent=2)
    print('wrote bench/results/%s.json and %s.png' % (stem, stem))


if __name__ == '__main__':
    main()
