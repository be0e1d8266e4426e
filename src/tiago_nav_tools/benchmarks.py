"""The benchmarks: which commands write which bench/results/*.json, the ``meta`` block each JSON
carries, and the rendering of docs/benchmarks.md from those files.

``make bench`` runs ``python3 -m tiago_nav_tools.benchmarks all`` (``make bench BENCH=detection``:
one benchmark); each benchmark's commands are listed once, in :data:`BENCHMARKS`, and the docs
page shows them above the figures they wrote. The page is rendered from the JSON files as they
are (nothing is re-run); a JSON written before meta blocks existed shows "meta: not recorded".
"""
import datetime
import json
import math
import os
import platform as _platform
import shlex
import subprocess
import sys
import xml.etree.ElementTree as ET

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.realpath(__file__)), '..', '..'))

# name -> title, and the runs: (command line relative to the package root, JSON files written)
BENCHMARKS = (
    ('simulator', 'Simulator speed', [
        ('bench/bench_simulator.py', ['simulator.json'])]),
    ('detection', 'Obstacle detection', [
        ('bench/bench_detection.py', ['detection.json']),
        ('bench/bench_detection.py --laser-model tiago --no-service', ['detection_tiago.json']),
        ('bench/bench_detection_sensing.py', ['detection_sensing.json']),
        ('bench/bench_short_arcs.py', ['short_arcs.json'])]),
    ('shapes', 'Shapes: boxes, tables and chairs', [
        ('bench/bench_shapes.py', ['shapes.json'])]),
    ('legs_real', 'People\'s legs on real laser data (leg_tracker)', [
        ('bench/bench_legs_real.py', ['legs_real.json'])]),
    ('covariance', 'Obstacle covariance against the errors of ROS missions', [
        ('bench/bench_covariance.py --warm', ['covariance.json'])]),
    ('navigation', 'Navigation (move_base)', [
        ('bench/bench_navigation.py', ['navigation.json']),
        ('bench/bench_navigation.py --people --set person_clearance=0.3',
         ['navigation_people.json']),
        ('bench/bench_navigation.py --people --set person_clearance=0 '
         '--out bench/results/navigation_people_plain.json',
         ['navigation_people_plain.json'])]),
    ('corridor', 'Corridor law against move_base', [
        ('bench/bench_corridor.py', ['corridor.json'])]),
    ('mission', 'Whole mission', [
        ('bench/bench_mission.py', ['mission.json'])]),
    ('mission_cpu', 'Course mission CPU against an earlier release', [
        ('bench/bench_mission_cpu.py', ['mission_cpu.json'])]),
    ('demo', 'Course mission and localisation (the demo)', [
        ('scripts/run_demo.py', ['demo.json'])]),
    ('lockstep', 'Lockstep', [
        ('bench/bench_lockstep.py --n 20 --nav 0 --modes on --loads idle '
         '--out bench/results/lockstep_idle.json', ['lockstep_idle.json']),
        ('bench/bench_lockstep.py --n 20 --nav 0 --modes on --loads busy '
         '--out bench/results/lockstep_loaded.json', ['lockstep_loaded.json']),
        ('bench/bench_lockstep.py --n 10 --nav 0 --modes on --loads starved '
         '--out bench/results/lockstep_starved.json', ['lockstep_starved.json']),
        ('bench/bench_lockstep.py --n 3 --nav 1 --out bench/results/lockstep.json',
         ['lockstep.json']),
        ('bench/bench_lockstep.py --task nav --n 3 --nav 0 --modes on '
         '--out bench/results/lockstep_nav.json', ['lockstep_nav.json'])]),
    ('localisation', 'Localisation along the course route and through corridors', [
        ('bench/bench_localisation.py', ['localisation.json'])]),
    ('localisation_real', 'Localisation on real building logs', [
        ('bench/bench_localisation_real.py', ['localisation_real.json'])]),
    ('localisation_recovery', 'Lost and found on real building logs, in process', [
        ('bench/bench_localisation_recovery.py', ['localisation_recovery.json'])]),
    ('soak', 'Soak', [
        ('bench/bench_soak.py', ['soak.json'])]),
    ('evaluate', 'Batch evaluation', [
        ('bench/bench_evaluate.py', ['evaluate.json']),
        ('bench/bench_evaluate.py --runs 204 --workers 2 --no-cluster --warm '
         '--out bench/results/evaluate_warm.json', ['evaluate_warm.json'])]),
    ('suites', 'Shipped suites', [
        ('bench/bench_suites.py', ['suites.json']),
        ('bench/bench_suites.py --suites suites/people.yaml --out bench/results/suites_people.json',
         ['suites_people.json']),
        ('bench/bench_suites.py --suites suites/people_move_base.yaml --requires move_base '
         '--out bench/results/suites_people_move_base.json', ['suites_people_move_base.json'])]),
)
NAMES = [b[0] for b in BENCHMARKS]

# name -> what the benchmark measures, how it judges and its targets: shown under its title on
# docs/benchmarks.md (the scripts' docstrings say the same at more length)
ABOUT = {
    'shapes': (
        'Boxes, tables and chairs (and the cylinders among them) in `worlds/room_furniture.yaml` '
        'and `worlds/lab_mixed.yaml` (walkers left out), 30 seeded random poses each, the tiago '
        'laser with 0.01 m noise, one scan and the median of 5 at rest, exact pose, the '
        'detections matched to the objects in view as the evaluator matches them (one to one, '
        'least total distance, within 0.3 m): found once with its shape, centre and orientation '
        'errors, where two faces of a box or three legs of a table or chair are seen (the '
        'targets: <= 3 cm, <= 5 deg) and over all in view; a false positive matches no object '
        'in view ([detection.md](detection.md#shapes)).'),
    'legs_real': (
        'People on leg_tracker\'s real recordings (`../shared/data/real/`), a laser standing '
        'still in rooms nobody mapped: the pipeline with `shapes` on over the static background '
        'built from each recording\'s own scans (`tiago_nav.detection.background`; and over an '
        'empty map, one scan alone): recall and precision of the person `legs` objects against '
        'the marked leg clusters (within 0.15 m; target 85 %; bag 4 held out of the choices but '
        'the rule for whole flat runs); '
        'on the demo, the service on every scan with the 4 before it: people walking past '
        'are reported moving, never static ([detection.md](detection.md#people)).'),
    'covariance': (
        'Every detection of the `tiago` profile\'s successful missions in `suites/course.yaml` '
        'and `suites/robustness.yaml` (`rosrun tiago_nav evaluate --warm`, 2 workers; `--from '
        'DIR ...` reads existing output folders): each reported centre matched one-to-one to a '
        'movable cylinder of the world file (within 0.3 m, glimpsed ones included). Per frame '
        '(map: `center_covariance`; robot: `center_robot_covariance` against the true centre in '
        'the true robot frame at the stop) the mean normalised squared error (NEES, 2 degrees of '
        'freedom: 2 when the covariance is exact), the share of errors inside the reported 95 % '
        'ellipse and those beyond the 99.9 % bound; the mean share of each term of '
        '`center_std`² (fit, laser position, heading, map raster), and the map frame\'s NEES '
        'with the fit\'s term alone. Targets (map frame): mean NEES between 1 and 3, at least '
        '93 % inside the 95 % ellipse, at least 300 detections.'),
    'mission_cpu': (
        'The course mission (pose B (11, 0, -45°), corridor law on) at `real_time_factor:=0` '
        'on this tree and on an earlier commit (`--commit`, default 07ccd86, the release before '
        'the robustness work; checked out in a git worktree and built with its own `make '
        'setup`), interleaved for `--pairs` pairs (6) in ABBA order (this tree then the commit, '
        'the commit then this tree, ...: a load drifting over the runs favours neither), each '
        'a fresh demo.launch. Each process\'s CPU time (user + system, with its '
        'waited-for children\'s, from `/proc`) is read at the goal, at every change of the '
        'mission\'s feedback state and at the result; phases: *corridor* (goal to the first '
        'NAVIGATING), *navigation* (to the first DETECTING), *detection* (to the result; the '
        'scans it uses were taken at rest before it). The stack is every process of the launch. '
        'Reported per tree: the median and range (least–largest) of each figure; the ratio this '
        'tree / commit of the medians and the median and range of the pairs\' own ratios; the '
        'result of each run (pose B reached, obstacles found of those in view, centre RMS). '
        'The load average at each goal is in the JSON and under the table: on a busy machine '
        'every process\'s CPU time grows (shared caches and cores) and the ranges widen; the '
        'interleaved pairs keep the comparison fair, the figures are comparable only between '
        'runs at similar loads. Target: the stack\'s ratio at most 1.0 '
        'with the same result (pose B, 4/4, RMS at most 1 cm).'),
    'suites': (
        'Every run of the shipped suites through `rosrun tiago_nav evaluate` (2 workers, '
        'lockstep): `suites/course.yaml` (204 runs: the course world, its pose B and four sampled '
        'ones, and twelve generated worlds of its class) and `suites/robustness.yaml` (96 runs: a '
        'start inside a 1.1 m corridor, a 20 m featureless corridor, corridors bent by 30, 45, 60 '
        'and 90°, a cluttered room), both sensing profiles, corridor law on and off, three seeds. '
        'Judged as in docs/evaluation.md (`--from SUITE=DIR` judges an existing output folder '
        'again with the current metrics). Per suite the success rate and its Wilson 95 % '
        'interval, per world group, profile and corridor setting the least clearance (exact, '
        'footprint to walls and cylinders along the true path), the worst localisation p95 and '
        'centre RMS; every run that did not succeed, with its reason. Each suite is also '
        'rescored under two rules of *in view*: the evaluator\'s (at least 7 usable beams hit '
        'the obstacle) and a plain one (at least 5): each one\'s success rate, detection totals '
        'and the runs the rules judge differently. Target: at least 99 % success per suite '
        'under both. `suites/people.yaml` (204 runs: the office with four walkers, the lab with '
        'furniture and two walkers, the furnished room; each pose B and sampled ones, both '
        'profiles, three seeds; the own nodes and the detection with `shapes` on as a '
        'candidate) is run apart (its own JSON) and adds, per profile and candidate in worlds '
        'with walkers, the least gap of the base\'s body to a walker\'s legs and the runs under '
        '0.3 m, the time spent standing still away from pose B, the walkers reported as '
        'persons (moving or legs) and as static obstacles, and the oldest ghost in move_base\'s '
        'published costmap and the runs with one over 2 s ([evaluation.md](evaluation.md#people)); '
        'its targets are issue 49\'s: 99 % success, no collision, no run under 0.3 m, no walker '
        'reported static, no ghost older than 2 s. `suites/people_move_base.yaml` (48 runs: the '
        'two worlds with walkers, their poses, both profiles, one seed) runs ROS\'s move_base '
        '(navfn, DWA and costmap_2d with the own navigation\'s footprint, limits and '
        'tolerances: `bench/move_base/`) as a navigation candidate beside the own nodes, both at '
        'real time (move_base does not take part in the lockstep); `make move-base` builds it '
        'from source (Debian does not package the navigation stack) and `make bench` sources it '
        'when built, else skips this suite.'),
    'evaluate': (
        'The batch evaluator as a user runs it (`rosrun tiago_nav evaluate`): `--runs` (20) rows '
        'spread evenly over `suites/course.yaml` (the course world and generated worlds, both '
        'sensing profiles, corridor law on and off, three seeds), run with 1, 2 and 3 local Dask '
        'workers and then on a separately started cluster (`python3 -m dask scheduler` and '
        '`python3 -m dask worker --nworkers 2`). Reported per setting: missions per minute (runs ÷ the command\'s wall '
        'time, start-up and teardown included), outcomes, infrastructure errors, processes left '
        'behind; and the rows whose result differs from the 1-worker one in any field but the '
        'wall-clock ones. Target: the best local setting at least 1.25× the 1-worker rate, '
        'every result equal. Each setting also shows where the time goes: the median run\'s '
        'start-up, mission, teardown and judging, and the missions\' share of the worker time. '
        '`evaluate_warm.json`: every row of the suite with 2 workers, on fresh stacks and then '
        '(`--warm`) on warm ones, reset between the rows that share world, profile and '
        'candidate: the warm rate over the fresh one, every row\'s warm result against its '
        'fresh one, the missions\' share of the worker time in both. Target: warm at least 2.5× '
        'fresh, every row equal, 0 infrastructure errors, missions at least 60 % of the worker '
        'time.'),
    'simulator': (
        'How much faster than real time the mock TIAGo runs at `real_time_factor:=0` with the '
        'full laser (666 beams at 15 Hz) and 60 Hz physics, the base driving in circles, in both '
        'shipped worlds: the library alone (no ROS) and the ROS node on its own master (measured '
        'from /clock). Target: the node at least 20× real time. `--quick`: shorter runs.'),
    'detection': (
        '`bench_detection.py`: seeded random reachable poses in both shipped worlds (60 per '
        'world, 12 with `--quick`) from which a movable obstacle is in view; each scan is the '
        'exact ray cast plus 0.01 m Gaussian noise (`--laser-model tiago`: the tiago model), '
        'placed with its exact pose. A found centre matches a movable obstacle of the world file '
        'within that obstacle\'s radius + 5 cm (nearest first, one each); one that matches none '
        'is a false positive. *In view*: the one definition of `tiago_nav_tools.evaluate.inview` (at least 7 '
        'usable beams of the noise-free cast hit it, the whole fan for the ideal profile; '
        'docs/detection.md); *clear '
        'view*: also within `max_range` and hit by at least 80 % of the beams its silhouette '
        'spans. Latency is one library call; the service round trip is measured with the node '
        'on its own master (`--no-service` skips it). Targets for `circle_fit`: recall 100 % in '
        'clear view, 0 false positives, centre RMS at most 1 cm, a median call of at most 5 ms, '
        'map subtraction at least 100× faster than brute force; the scaling table times both on '
        'the course map rasterised at 0.1, 0.05 and 0.025 m. `bench_detection_sensing.py`: the '
        'same pipeline under the default sensing, in process: the tiago laser and the '
        'localisation\'s error at the detection instant (emulated: odometry drift at a stop, '
        'then five scans registered at rest; or an injected error of a live mission\'s size), '
        'with the pose correction on, off, with neither it nor the shared radius, and as the '
        'service runs at a stop (the pose correction on, the median of 5 scans at rest); at the '
        'course\'s pose B and at random poses B in the shipped, test and soak worlds. An '
        'obstacle in view (`tiago_nav_tools.evaluate.inview`) must be found, its centre within 3 cm; a '
        'found centre that no obstacle a beam reaches takes (one-to-one, within 0.3 m) is a false positive. The comparison with '
        'tysik/obstacle_detector (`make obstacle-detector` builds it; skipped when it is not '
        'installed): `bench_detection.py` runs the course mission (demo.launch at real-time '
        'factor 2, the default sensing), then gives each of the next 20 scans at pose B to this '
        'package\'s service and to obstacle_detector\'s obstacle_extractor (its default '
        'parameters, reading the scan with the robot\'s own body and the veils set invalid, its '
        'circles placed in map through tf at the scan\'s stamp); both are judged against the '
        'world file as above (obstacles in view from the true pose; false '
        'positives on the static map counted apart: this package subtracts the map by design).'),
    'navigation': (
        'The move_base node\'s own goal runner and navigator, in process, drive the simulator '
        'library to seeded random reachable goals, one after the other from the world\'s start '
        '(30 per shipped world, 5 with `--quick`), at 10 Hz control and 15 Hz scans with the ideal '
        'laser (0.01 m noise) and exact odometry. From the world file: a goal is reachable when '
        'it lies in the robot\'s connected free space (walls and every movable obstacle, a '
        'table\'s or chair\'s legs too, grown by its radius), '
        'and L is the shortest collision-free path to it. Per goal: success (SUCCEEDED within '
        '0.15 m and 0.1 rad, on the true pose), collisions, time ratio = time to goal / (L / '
        '1 m/s), length ratio = driven / L. Targets: at least 98 % success, 0 collisions, time '
        'ratio at most 1.3. With `--people` the same among walkers (office_walkers, lab_mixed), '
        'with the ideal and the TIAGo laser, scored also on the people: the smallest gap between '
        'the base\'s footprint and a walker\'s leg over each goal (target: never under 0.3 m), '
        'the time the base stood still away from its goal, and the oldest ghost (a cell the '
        'laser marked that stayed marked after a scan saw it free where the costmap could '
        'clear it, its centre half a cell inside raytrace_range; target: 2 s); targets there: at least 99 % success, 0 collisions. It '
        'runs with `person_clearance` 0.3 m (the default: people kept 0.3 m away, '
        'docs/navigation.md) and with 0 (people are obstacles like any other); neither meets '
        'the targets yet.'),
    'corridor': (
        'Seeded starts ±0.15 m off the centre line and ±15° in heading, 1 m before straight '
        'corridors 0.8, 1.07 and 1.5 m wide and 5 m long, and around the course world\'s start: '
        'the law in process, then through ROS (`navigation.launch` at `real_time_factor:=4`) the '
        '`corridor_controller` action and `move_base` sent to the pose where the law stopped '
        '(same start, same end). Per trial, from ground truth: success (stopped with the base '
        'out of the corridor, no contact), time to exit (until the base centre passes the first '
        'wall end) and to stop, lateral RMS from 1 m into the corridor, minimum clearance. '
        'Targets: lateral RMS at most 3 cm, clearance at least 5 cm, faster than move_base. '
        '`--quick`: fewer trials; `--no-ros`: in process only. Bends (`--bends`, or '
        '`--bends-only` keeping the other figures): the shipped `worlds/corridor_bend_{30,45,60,'
        '90}.yaml` (1.1 m wide), the law in process from 6 seeded starts (stopped with no '
        'contact and at least 5 cm from every wall), and the whole mission to each world\'s pose '
        'B with the law on through the batch evaluator (profiles tiago and ideal, 2 seeds); '
        'minimum clearance of the base\'s disc from the ground-truth path, exact and as the '
        'evaluator\'s 5 cm grid gives it. Targets: every mission succeeds, 0 collisions, '
        'clearance at least 5 cm.'),
    'mission': (
        'Whole missions over `demo.launch`, one launch (a private master) per shipped world, each '
        'mission starting where the last ended: in the course world first the course mission '
        '(pose B (11, 0, −45°), corridor law on), then `--n` (3; 1 with `--quick`) seeded random '
        'poses B per world with the corridor law off, reachable, at least 0.65 m from anything '
        'and facing a movable obstacle. Each is judged against the world file: the obstacles in '
        'view from the true final pose (`tiago_nav_tools.evaluate.inview`) are matched one-to-one to the '
        'reported centres (least total distance, within 0.3 m; an unmatched reported centre that '
        'matches no glimpsed obstacle either is a false positive); recall, false positives and centre RMS '
        'over the missions that succeeded; collisions from `/sim/collisions`. It runs at each '
        'real-time factor of `--rtf` (default 5, the demo\'s, then 0). Target: every mission '
        'succeeds within 20 s of wall time.'),
    'demo': (
        '`make demo`: the course mission once in `demo.launch` with the default sensing, at '
        '`real_time_factor:=5` (`--rtf`), judged like the mission benchmark (the obstacles in '
        'view from the true final pose), with the localisation error along the mission (tf '
        '`map → base_footprint` against the ground truth). It exits 0 only if the mission '
        'succeeded with no collision.'),
    'lockstep': (
        'Each run is a fresh `demo.launch` at `real_time_factor:=0` (same world, same seed); a '
        'plain `SimpleActionClient` sends the course mission (`--task nav`: one move_base goal '
        'to pose B) after a random 0-3 s wall delay, then `--nav` seeded move_base goals. Per '
        'condition (lockstep on or off, the machine idle, with a busy loop per core, or starved: '
        'each node of the stack, the simulator too, stopped in turn for 3 s of wall time while '
        'the goals run): successes, collisions, wall and CPU time per mission, the spread over '
        'the runs of the true final pose, the reported final pose and the obstacle centres, and '
        'how many participants the simulator dropped. Targets: the same result in every run; '
        'idle in lockstep, at most 3 s of wall time per course mission.'),
    'localisation': (
        'In process: the simulator library drives the course route (start room, corridor, a '
        'loop in the big room and back; the nine cylinders present and unmapped) with injected '
        'odometry drift (distance × 1.02, rotation × 1.03, 1 % noise per step), and the '
        'localiser registers each scan it finds due, as the node does; its error against the '
        'truth, and dead reckoning\'s, over `--seeds` (5) seeds, with the ideal and the tiago '
        'laser. Bar: p95 at most 5 cm and 2°. Then, with the tiago laser and the same drift, '
        'worlds/corridor_start.yaml (a start 1 m inside an 8 m corridor, to the room beyond; '
        'bar: max 5 cm, p95 3 cm) and worlds/corridor_long.yaml (through a 20 m featureless '
        'corridor; bar: the error along it grows no faster than dead reckoning\'s, no step '
        'over 2 cm between consecutive estimates over the whole run, re-acquisition of the axis '
        'included, which the published estimate approaches by at most `max_correction_step` '
        'per estimate). Both score the published covariance: the NEES of the position '
        '(`eᵀ Σ⁻¹ e`, mean 2 and 95 % of the scans within the 95 % ellipse when it is right) and '
        'of the heading (mean 1), with `map_sigma` 0 (the map is the world\'s own raster).'),
    'localisation_real': (
        'Real laser data: the Radish building logs in `../shared/data/real/` (Intel Research '
        'Lab, Freiburg building 079, ACES; CARMEN format, SLAM-corrected poses as the reference; '
        'skipped with a message when absent, `--data DIR`), each turned by '
        '`tiago_nav_tools.testing.realdata` into a bag (/scan in `base_laser_link`, /odom and tf '
        '`odom → base_footprint` at each scan, odometry synthesised from the reference\'s steps: '
        'translation × (1 + N(0, 0.02)) per step, rotation + N(0, 1) × (2 % of the turn + 0.5° '
        'per metre), composed so that it drifts, seed 0) and a map built from the scans at '
        'their reference poses (0.05 m, map_server YAML + PGM, published latched on /map). The '
        'node is started with `localisation.launch` at the given pose on simulated time, and '
        'once it has taken the map in the bag is played with `rosbag play --clock`, at the rate '
        'that brings one scan every 0.5 s of wall time, at least real time. Each /amcl_pose is scored at every '
        'scan against the reference (the last estimate carried by the odometry since, as tf '
        'gives it): error RMS, p95, max, yaw p95, the share of time lost (error > 0.3 m, each '
        'scan weighted by the time to the next), the time to recover from a lost stretch, '
        'CPU per scan (the node\'s process, tf and ROS included, over the playback; it '
        'depends on the machine\'s load: a node woken for each of the 100 /clock messages a '
        'second costs less per message when they queue up while it waits for the processor; '
        'so the localisers of a log and scenario play the bag at the same time, each with its '
        'own ROS master, and share the load: their figures compare with each other, and '
        '`loadavg_1min` in the JSON says what the load was; `--one-at-a-time` plays them in '
        'turn) and its '
        'peak resident memory. A synthetic building of 100 m × 100 m at 0.05 m (4 million '
        'cells, `tiago_nav_tools.testing.realdata.synthetic`: 10 m rooms joined by doors, a log '
        'ray-cast through a row of them, `tracking` only) checks what grows with the map. '
        'Scenarios: started on the reference (`tracking`), 2 m to its '
        'left and turned 90° (`offset`), carried 3 m in one step at 40 % of the log with the '
        'odometry reporting no motion (`kidnap`), `/global_localization` called before the '
        'bag plays (`global`, "not offered" when the node has no such service). Targets '
        '(issue 48): never lost after the first converged estimate, p95 ≤ 10 cm, at least as '
        'good as tuned amcl on p95 and time lost; back within 0.2 m of the reference (3 '
        'scans in a row) within 30 scans of an offset start or a kidnap, 60 after '
        '`/global_localization`; peak memory ≤ 300 MB (also on the synthetic building); '
        'CPU per scan no more than tuned '
        'amcl\'s. ROS\'s amcl (ros-planning/navigation, noetic-devel, built from source by '
        'the user against the platform\'s ROS 1; `--amcl-setup PATH/devel/setup.bash` or '
        '`AMCL_SETUP`) runs on the same bags with its defaults and with the tuned set '
        '(`laser_max_beams` 90, `odom_alpha1`-`4` 0.05, `min_particles` 500, '
        '`laser_sigma_hit` 0.1, `update_min_a` 0.2), only the frames, the initial pose and '
        '`use_map_topic` set besides.'),
    'localisation_recovery': (
        'The localisation library (`RecoveringLocaliser`, no ROS) replayed scan by scan on the '
        'same logs, scenarios, odometry and maps as `localisation_real` (every scan taken in, '
        'no timing): the scans until the estimate is back within 0.2 m of the reference for 3 '
        'scans in a row (from the start or the kidnap; for `global` from the first scan at '
        'which the relocalisation was accepted), what `/diagnostics` said before (OK / '
        'degraded / lost scans), the scans said lost after it, the error p95 / max and the '
        'share of scans lost (> 0.3 m) after it, the NEES of `/amcl_pose`\'s covariance after '
        'it (position `eᵀ Σ⁻¹ e`: mean 2 and 95 % of the scans within the 95 % ellipse when the '
        'covariance covers the error as it claims; heading: mean 1), the CPU per scan. Targets (issue 48): back within 30 scans of an offset start or a kidnap '
        'with lost reported meanwhile, 60 after `/global_localization`; never lost after.'),
    'soak': (
        'Many whole missions over `demo.launch`, one launch (a private master) per world, each '
        'mission starting where the last ended: `--n` (10; 2 with `--quick`) seeded random '
        'reachable poses B per world in the two shipped worlds and three generated ones '
        '(`gen_straight_0.9`, `gen_bend_1.2` with a 30° bend, `gen_straight_1.5`: a closed room '
        'whose only way out is the corridor, an unmapped cylinder beyond it), the corridor law '
        'on for every other mission, at `--rtf` (default 5). Counted: successes; hangs (no '
        'terminal state within `--limit`, 150 s of wall time; the task is then cancelled); '
        'collisions; node deaths (a node of the launch that no longer answers the master API\'s '
        '`getPid`, checked after every mission); and the message of every failure. Target: 0 '
        'hangs, 0 collisions, 0 node deaths, every failure explained.'),
}


# --- the meta block ------------------------------------------------------------------------
def commit(root=ROOT):
    """``git rev-parse HEAD`` of ``root``, with ``-dirty`` when a tracked file outside
    bench/results differs from it (results written earlier in the same ``make bench`` do not
    count); None outside a git checkout."""
    try:
        head = subprocess.run(['git', '-C', root, 'rev-parse', 'HEAD'], stdout=subprocess.PIPE,
                              stderr=subprocess.DEVNULL, text=True, check=True).stdout.strip()
        dirty = subprocess.run(['git', '-C', root, 'status', '--porcelain', '--untracked-files=no',
                                '--', '.', ':(exclude)bench/results'], stdout=subprocess.PIPE,
                               stderr=subprocess.DEVNULL, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None
    return head + ('-dirty' if dirty else '')


# what the platform table (docs/getting-started.md) tells apart: the distribution, ROS 1, Python and
# the Python packages whose versions differ between its rows
PLATFORM_PACKAGES = ('rospy', 'numpy', 'scipy', 'matplotlib', 'PyYAML', 'pybullet', 'dask')


def os_release(path='/etc/os-release'):
    """``PRETTY_NAME`` of ``/etc/os-release`` (e.g. ``Debian GNU/Linux 12 (bookworm)``), or
    ``platform.platform()`` where there is none."""
    try:
        with open(path) as f:
            for line in f:
                if line.startswith('PRETTY_NAME='):
                    return shlex.split(line.partition('=')[2])[0]
    except (OSError, ValueError, IndexError):
        pass
    return _platform.platform()


def platform_info():
    """The platform a figure was measured on: ``{'os', 'python', 'packages': {name: version or
    None when not installed}}``, read from package metadata (nothing is imported)."""
    import importlib.metadata as metadata
    versions = {}
    for name in PLATFORM_PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return {'os': os_release(), 'python': _platform.python_version(), 'packages': versions}


def launch_defaults(root=ROOT, launch='sim.launch'):
    """``{arg: default}`` of a launch file's own arguments."""
    tree = ET.parse(os.path.join(root, 'launch', launch)).getroot()
    return {a.get('name'): a.get('default') for a in tree.findall('arg') if 'default' in a.attrib}


def launch_models(launch_args=(), root=ROOT):
    """``(laser_model, odometry_model)`` a launch runs with: sim.launch's defaults unless
    ``launch_args`` (``name:=value`` strings) set them."""
    d = launch_defaults(root)
    given = dict(a.split(':=', 1) for a in launch_args if ':=' in a)
    return (given.get('laser_model', d.get('laser_model')),
            given.get('odometry_model', d.get('odometry_model')))


def meta(options=None, *, real_time_factor=None, laser_model=None, odometry_model=None,
         quick=False, argv=None, root=ROOT):
    """The ``meta`` block of a benchmark's JSON: the code (commit), when (UTC), the command line,
    the machine (cores, load average), the platform (:func:`platform_info`) and the conditions
    (real-time factor, laser and odometry models, quick run); ``options`` (e.g. ``vars(args)``)
    are the benchmark's own options. A value that does not apply is given as a string saying why (e.g. ``'in process'``)."""
    argv = list(sys.argv if argv is None else argv)
    if argv:
        script = os.path.abspath(argv[0])
        argv[0] = os.path.relpath(script, root) if script.startswith(root + os.sep) else argv[0]
    opts = {k: v for k, v in (options or {}).items() if v is not None and not k.startswith('_')}
    return {'commit': commit(root),
            'date': datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0)
            .isoformat().replace('+00:00', 'Z'),
            'command': ' '.join(shlex.quote(a) for a in argv),
            'cores': os.cpu_count(),
            'loadavg': [round(x, 2) for x in os.getloadavg()],
            'platform': platform_info(),
            'real_time_factor': real_time_factor,
            'laser_model': laser_model,
            'odometry_model': odometry_model,
            'quick': bool(quick),
            'options': opts}


# --- running them --------------------------------------------------------------------------
def commands(names, root=ROOT):
    """The command lines (argv lists) of the named benchmarks (``all``: every one), in order."""
    wanted = NAMES if 'all' in names else names
    unknown = [n for n in wanted if n not in NAMES]
    if unknown:
        raise ValueError('unknown benchmark(s) %s (known: %s, all)'
                         % (', '.join(unknown), ', '.join(NAMES)))
    out = []
    for name, _, runs in BENCHMARKS:
        if name in wanted:
            for cmd, _ in runs:
                argv = shlex.split(cmd)
                out.append([sys.executable, os.path.join(root, argv[0])] + argv[1:])
    return out


def main(argv=None):
    names = (sys.argv[1:] if argv is None else argv) or ['all']
    if names[0] in ('-h', '--help'):
        print('usage: python3 -m tiago_nav_tools.benchmarks [all | %s ...]' % ' | '.join(NAMES))
        return 0
    try:
        cmds = commands(names)
    except ValueError as e:
        print('benchmarks: %s' % e, file=sys.stderr)
        return 2
    os.makedirs(os.path.join(ROOT, 'bench', 'results'), exist_ok=True)
    # every benchmark runs: one that misses its target (exit 1) or fails has still written, or
    # left, its JSON, and the others' figures do not depend on it
    failed = []
    for cmd in cmds:
        line = ' '.join(shlex.quote(os.path.relpath(a, ROOT) if i == 1 else a)
                        for i, a in enumerate(cmd[1:], 1))
        print('== %s' % line, flush=True)
        rc = subprocess.call(cmd, cwd=ROOT)
        if rc:
            print('benchmarks: %s exited %d' % (line, rc), file=sys.stderr, flush=True)
            failed.append((line, rc))
    if failed:
        print('benchmarks: %d of %d exited non-zero (1: a target missed):\n%s'
              % (len(failed), len(cmds), '\n'.join('  %s: %d' % f for f in failed)), file=sys.stderr)
    return failed[0][1] if failed else 0


# --- docs/benchmarks.md --------------------------------------------------------------------
def _f(v, fmt='%.3g'):
    if v is None:
        return '–'
    if isinstance(v, bool):
        return 'yes' if v else 'no'
    if isinstance(v, float):
        return fmt % v if math.isfinite(v) else str(v)
    return str(v)


def _pct(v):
    return '–' if v is None else '%.1f %%' % (100 * v)


def _table(head, rows):
    lines = ['| %s |' % ' | '.join(head), '|%s' % ('---|' * len(head))]
    lines += ['| %s |' % ' | '.join(_f(c) for c in row) for row in rows]
    return lines


def meta_lines(data):
    m = data.get('meta') if isinstance(data, dict) else None
    if not m:
        return ['meta: not recorded']
    load = m.get('loadavg')
    return ['meta: commit `%s`, %s, `%s`, %s cores, load average %s, real-time factor %s, laser '
            'model %s, odometry model %s, quick %s, %s'
            % (m.get('commit'), m.get('date'), m.get('command'), m.get('cores'),
               ' / '.join('%.2f' % x for x in load) if load else '–',
               _f(m.get('real_time_factor')), _f(m.get('laser_model')),
               _f(m.get('odometry_model')), _f(m.get('quick')), platform_line(m.get('platform')))]


def platform_line(p):
    """One phrase for a meta block's ``platform``; JSONs written before it was recorded were
    all measured on Debian 12 with Debian's ROS 1 (the machines the project is developed on)."""
    if not p:
        return 'platform not recorded (Debian 12)'
    pkgs = p.get('packages') or {}
    return '%s, Python %s, %s' % (p.get('os'), p.get('python'), ', '.join(
        '%s %s' % (k, v) for k, v in sorted(pkgs.items(), key=lambda kv: kv[0].lower()) if v))


def render_simulator(d):
    rows = [(w, v.get('library_real_time_factor'), v.get('node_real_time_factor'))
            for w, v in d.get('worlds', {}).items()]
    return _table(('world', 'library (× real time)', 'ROS node (× real time)'), rows) + [
        '', 'Target for the node: ≥ %s× real time (lowest: %s×).'
        % (_f(d.get('target_node_real_time_factor')), _f(d.get('node_real_time_factor_min')))]


def render_detection(d):
    rows = []
    for w, v in d.get('worlds', {}).items():
        for method, m in v.get('methods', {}).items():
            rows.append((w, method, m.get('poses', v.get('poses')), _pct(m.get('recall_clear')),
                         _pct(m.get('recall_in_view')), m.get('false_positives'),
                         m.get('rms_error_clear_m'), m.get('rms_error_m'),
                         m.get('latency_ms_median'), m.get('latency_ms_p95')))
    out = _table(('world', 'method', 'poses', 'recall (clear view)', 'recall (in view)',
                  'false positives', 'RMS error clear [m]', 'RMS error in view [m]',
                  'latency median [ms]', 'latency p95 [ms]'), rows)
    o = d.get('circle_fit_overall')
    if o:
        out += ['', 'circle_fit overall: recall %s (clear view), %s (in view), %s false positives, '
                'RMS error %s m, latency %s ms (p95 %s ms), map subtraction %s× faster than '
                'brute force.' % (_pct(o.get('recall_clear')), _pct(o.get('recall_in_view')),
                                  _f(o.get('false_positives')), _f(o.get('rms_error_m')),
                                  _f(o.get('latency_ms')), _f(o.get('latency_ms_p95')),
                                  _f(o.get('subtraction_speedup')))]
    met = d.get('targets_met')
    if met:
        out += ['', 'Targets met: %s.' % ', '.join('%s %s' % (k, _f(v)) for k, v in met.items())]
    scaling = d.get('subtraction_scaling')
    if scaling:
        out += ['', 'Map subtraction of N scan points against M occupied cells: the distance '
                'transform\'s look-up against comparing every point with every cell.', '']
        out += _table(('cell size [m]', 'occupied cells M', 'points N', 'transform build [ms]',
                       'look-up [ms]', 'brute force [ms]', 'speed-up'),
                      [(r.get('resolution_m'), r.get('occupied_cells'), r.get('points'),
                        r.get('transform_build_ms'), r.get('transform_ms'),
                        r.get('brute_force_ms'), _f(r.get('speedup'), '%.0f')) for r in scaling])
    s = d.get('service')
    if s:
        out += ['', 'Service round trip (%s calls): median %s ms, p95 %s ms (mostly the wait for '
                'the next scan; the answer carries no processing time).'
                % (_f(s.get('calls')), _f(s.get('round_trip_ms_median')),
                   _f(s.get('round_trip_ms_p95')))]
    od = d.get('obstacle_detector')
    if od and od.get('skipped'):
        out += ['', 'obstacle_detector comparison: skipped (%s).' % od.get('reason')]
    elif od:
        out += ['', 'obstacle_detector comparison, %s laser: the course mission, then %s live '
                'scans at pose B (the robot at %s), each given to every detector.'
                % (od.get('laser_model'), _f(od.get('scans')), od.get('truth_pose')), '']
        names = (('tiago_nav_one_scan', 'tiago_nav, the one scan'),
                 ('tiago_nav', 'tiago_nav, median of the scans at rest'),
                 ('obstacle_detector', 'obstacle_detector, the one scan'))
        out += _table(('detector', 'found', 'false positives (off the map)', 'RMS error [m]',
                       'max error [m]'),
                      [(label, '%s/%s' % (_f(od[k].get('found')), _f(od[k].get('must_find'))),
                        '%s (%s)' % (_f(od[k].get('false_positives')),
                                     _f(od[k].get('false_positives_off_map'))),
                        od[k].get('rms_error_m'), od[k].get('max_error_m'))
                       for k, label in names if k in od])
        used = sorted(set(od.get('rest_scans_used') or []))
        out += ['', 'obstacle_detector\'s centre RMS is %s× tiago_nav\'s on the same scan, %s× '
                'the service\'s (the median of the scans at rest, %s per call).'
                % (_f(od.get('rms_ratio')), _f(od.get('rms_ratio_rest')),
                   ' or '.join(str(n) for n in used) or '–')]
    return out


# bench_detection_sensing.py's scene sets and detector variants, in the order they are shown
SENSING_SCENES = (('course', 'course pose B'),
                  ('course_injected', 'course pose B, injected pose error'),
                  ('missions', 'random poses B'))
SENSING_VARIANTS = (('rest', 'median of 5 scans at rest, pose correction on'),
                    ('correction_on', 'pose correction on'),
                    ('correction_off', 'pose correction off'),
                    ('before', 'no pose correction, no shared radius'))


def render_detection_sensing(d):
    """detection_sensing.json: per scene set (``course``, ``course_injected``, ``missions``) the
    localisation error the detection met and, per detector variant, the obstacles to find,
    missed, false positives and centre errors (not detection.json's per-world methods)."""
    tol = d.get('tolerance_m')
    rows = []
    for key, label in SENSING_SCENES:
        part = d.get(key)
        if not isinstance(part, dict):
            continue
        loc = part.get('localisation_error_m_rms')
        for vkey, vlabel in SENSING_VARIANTS:
            m = part.get(vkey)
            if isinstance(m, dict):
                rows.append((label, vlabel, m.get('scenes'), loc, m.get('must_find'),
                             m.get('missed'), m.get('false_positives'), m.get('rms_error_m'),
                             m.get('max_error_m'), m.get('beyond_tolerance'),
                             _pct(m.get('corrected_fraction')), m.get('latency_ms_median'),
                             m.get('cpu_ms_median')))
    out = ['%s laser, %s m range noise; an obstacle in view (at least %s usable beams, an outline '
           'edge seen) must be found, its centre within %s m.' % (d.get('laser_model'), _f(d.get('noise_std_m')),
                                    _f(d.get('min_beams')), _f(tol)), '']
    return out + _table(('scene set', 'detector', 'scenes', 'localisation error RMS [m]',
                         'to find', 'missed', 'false positives', 'RMS error [m]',
                         'max error [m]', 'beyond %s m' % _f(tol), 'pose corrected',
                         'call median [ms]', 'CPU median [ms]'), rows)


def render_navigation(d):
    worlds = dict(d.get('worlds', {}))
    if d.get('overall'):
        worlds['all'] = d['overall']
    rows = [(w, v.get('goals'), _pct(v.get('success_rate')), v.get('collisions'),
             v.get('time_ratio_mean'), v.get('time_ratio_median'),
             v.get('time_ratio_long_paths_mean'), v.get('length_ratio_mean'),
             v.get('wall_per_goal_s')) for w, v in worlds.items()]
    return _table(('world', 'goals', 'success', 'collisions', 'time ratio mean',
                   'time ratio median', 'time ratio (long paths)', 'length ratio mean',
                   'wall per goal [s]'), rows)


def render_navigation_people(d):
    worlds = dict(d.get('worlds', {}))
    if d.get('overall'):
        worlds['all'] = d['overall']
    rows = [(w, v.get('goals'), _pct(v.get('success_rate')), v.get('collisions'),
             v.get('closest_walker'), v.get('walker_gap_under_0_3'), v.get('waiting_mean'),
             v.get('waiting_max'), v.get('ghost_age_max'), v.get('time_ratio_median'))
            for w, v in worlds.items()]
    return _table(('world (laser)', 'goals', 'success', 'collisions',
                   'closest to a walker [m]', 'goals under 0.3 m', 'waiting mean [s]',
                   'waiting max [s]', 'oldest ghost [s]', 'time ratio median'), rows)


def render_corridor(d):
    rows = []
    for w, v in d.get('worlds', {}).items():
        for how in ('corridor_law', 'ros_corridor', 'ros_move_base'):
            s = v.get(how)
            if s:
                rows.append((w, how, s.get('trials'), _pct(s.get('success_rate')),
                             s.get('time_to_exit_mean'), s.get('time_to_stop_mean'),
                             s.get('lateral_rms_max'), s.get('min_clearance')))
    out = _table(('corridor', 'run', 'trials', 'success', 'time to exit [s]',
                  'time to stop [s]', 'lateral RMS max [m]', 'min clearance [m]'), rows)
    if d.get('met'):
        out += ['', 'Targets met: %s.' % ', '.join('%s %s' % (k, _f(v)) for k, v in d['met'].items())]
    b = d.get('bends')
    if b:
        rows = []
        for w, v in b.get('worlds', {}).items():
            law, m = v.get('law', {}), v.get('missions', {})
            stop = law.get('stop_before_corner') or [None, None]
            rows.append((w, '%s°' % _f(v.get('bend_deg')), '%s/%s' % (law.get('success'), law.get('trials')),
                         law.get('min_clearance'), '%s–%s' % (_f(stop[0]), _f(stop[1])),
                         '%s/%s' % (m.get('success'), m.get('runs')) if m else None,
                         m.get('collisions'), m.get('min_clearance'),
                         m.get('inner_corner_clearance')))
        out += ['', 'Bends:', '']
        out += _table(('world', 'bend', 'law stops clear', 'law min clearance [m]',
                       'law stops past the inner corner [m]', 'missions ok', 'mission collisions',
                       'mission min clearance [m]',
                       'mission inner-corner clearance [m]'), rows)
        if b.get('met'):
            out += ['', 'Targets met (bends): %s.' % ', '.join('%s %s' % (k, _f(v))
                                                             for k, v in b['met'].items())]
        out += ['', 'Bends ' + meta_lines(b)[0]]
    return out


def render_mission(d):
    rows = [(r.get('real_time_factor'), s.get('missions'), s.get('succeeded'),
             s.get('within_target'), s.get('wall_s_mean'), s.get('wall_s_max'),
             _pct(s.get('recall')), s.get('false_positives'), s.get('rms_error_m'),
             s.get('collisions'))
            for r in d.get('runs', []) for s in [r.get('summary', {})]]
    return _table(('real-time factor', 'missions', 'succeeded', 'within 20 s',
                   'wall mean [s]', 'wall max [s]', 'recall', 'false positives',
                   'RMS error [m]', 'collisions'), rows)


def render_demo(d):
    out = _table(('world', 'pose B', 'corridor law', 'real-time factor', 'succeeded', 'wall [s]',
                  'collisions', 'recall', 'false positives', 'RMS error [m]', 'max error [m]'),
                 [(d.get('world'), ', '.join(_f(v) for v in d.get('goal', [])),
                   d.get('use_corridor_law'), d.get('real_time_factor'), d.get('succeeded'),
                   d.get('wall_time_s'), d.get('collisions'), _pct(d.get('recall')),
                   d.get('false_positives'), d.get('rms_error_m'), d.get('max_error_m'))])
    loc = d.get('localisation_error')
    if loc:
        out += ['', 'Localisation error over the mission (%s samples): p95 %s m / %s deg, max %s m '
                '/ %s deg.' % (_f(loc.get('samples')), _f(loc.get('p95_m')),
                               _f(loc.get('p95_deg')), _f(loc.get('max_m')),
                               _f(loc.get('max_deg')))]
    return out


def render_lockstep(d):
    rows = [(c.get('label'), s.get('runs'), s.get('succeeded'), s.get('collisions'),
             s.get('wall_s_mean'), s.get('wall_s_max'), s.get('cpu_s_mean'),
             s.get('final_pose_spread_m'), s.get('distinct_final_odometry'),
             s.get('loadavg_1min_mean'))
            + (s.get('result_pose_spread_m'), s.get('centre_spread_m'), s.get('drops'))
            for c in d.get('conditions', []) for s in [c.get('summary', {})]]
    return ['%s: %s runs per condition, %s navigation goals after each, seed %s.'
            % (d.get('task'), _f(d.get('n')), _f(d.get('nav_goals_per_run')), _f(d.get('seed'))),
            ''] + _table(('condition', 'runs', 'succeeded', 'collisions', 'wall mean [s]',
                          'wall max [s]', 'CPU mean [s]', 'true final pose spread [m]',
                          'distinct final odometry', 'load (1 min)',
                          'reported final pose spread [m]', 'obstacle centre spread [m]',
                          'participants dropped'), rows)


def render_localisation(d):
    rows = [(laser, s.get('scans'), s.get('registered'), s.get('rejected'),
             s.get('localised_p95_m'), s.get('localised_p95_deg'), s.get('localised_max_m'),
             s.get('dead_reckoning_p95_m'), s.get('update_median_ms'),
             _f(s.get('nees_mean'), '%.2f'), _pct(s.get('nees_within_95_share')),
             _f(s.get('nees_yaw_mean'), '%.2f'))
            for laser, s in d.get('lasers', {}).items()]
    out = ['%s, %s seeds, drifting odometry.' % (d.get('world'), _f(d.get('seeds'))), ''] + \
        _table(('laser', 'scans', 'registered', 'rejected', 'p95 [m]', 'p95 [deg]', 'max [m]',
                'dead reckoning p95 [m]', 'update median [ms]', 'NEES x-y mean (2)',
                'within the 95 % ellipse', 'NEES yaw mean (1)'), rows)
    c = d.get('corridors')
    if c:
        rows = [(name, r.get('seed'), r.get('scans'), r.get('featureless_m'),
                 r.get('loc_along_growth_m'), r.get('odo_along_growth_m'),
                 r.get('sigma_along_end_m'), r.get('max_step_featureless_m'),
                 r.get('max_step_m'), r.get('max_pending_m'), r.get('converge_estimates'),
                 r.get('max_error_increase_m'), r.get('max_correction_m'),
                 r.get('localised_p95_m'), r.get('localised_max_m'),
                 _f(r.get('nees_mean'), '%.2f'), _f(r.get('nees_yaw_mean'), '%.2f'))
                for name, w in c.get('worlds', {}).items() for r in w.get('runs', [])]
        out += ['', 'Corridors, %s laser, %s seeds: featureless = the longest unbroken stretch '
                'where the scan left the axis unobservable; growth = change of the along-axis '
                'error over it; step in it = largest change of the error between two '
                'consecutive estimates in it; step, run = the same over the whole run, '
                're-acquisition included; pending = the largest distance the published '
                'estimate was behind the registered pose; converged in = the most '
                'consecutive estimates a pending correction took to converge; increase / '
                'correction = the largest rise / fall of the error\'s norm between two '
                'consecutive estimates over the whole run.'
                % (c.get('laser'), _f(c.get('seeds'))), '']
        out += _table(('world', 'seed', 'scans', 'featureless [m]', 'localised growth [m]',
                       'dead reckoning growth [m]', 'σ along at its end [m]',
                       'step in it [m]', 'step, run [m]', 'pending [m]',
                       'converged in [estimates]', 'increase [m]', 'correction [m]', 'p95 [m]', 'max [m]',
                       'NEES x-y mean (2)', 'NEES yaw mean (1)'), rows)
    return out


def render_soak(d):
    s = d.get('summary', {})
    out = ['%s missions per world, real-time factor %s, seed %s.'
           % (_f(d.get('missions_per_world')), _f(d.get('real_time_factor')), _f(d.get('seed'))),
           '']
    rows = [(w, v.get('missions'), v.get('succeeded'), v.get('hangs'), v.get('collisions'),
             v.get('node_deaths'), v.get('unexplained'))
            for w, v in d.get('by_world', {}).items()]
    rows.append(('all', s.get('missions'), s.get('succeeded'), s.get('hangs'),
                 s.get('collisions'), s.get('node_deaths'), s.get('unexplained')))
    out += _table(('world / corridor law', 'missions', 'succeeded', 'hangs', 'collisions',
                   'node deaths', 'unexplained'), rows)
    for f in s.get('failures', []):
        out += ['', '- %s, pose B %s: %s' % (f.get('world'), f.get('goal'), f.get('message'))]
    return out


def render_evaluate(d):
    settings = d.get('settings', [])
    ref = settings[0].get('setting') if settings else '1 worker'    # what the others are held to
    key = 'runs_differing_from_' + ref.replace(' ', '_')
    rows = [(s.get('setting'), '%d/%d' % (s.get('results', 0), s.get('runs', 0)), s.get('wall_s'),
             s.get('missions_per_minute'),
             ', '.join('%s %d' % kv for kv in sorted((s.get('outcomes') or {}).items())),
             s.get('infrastructure_errors'), s.get('leftover_processes'),
             '–' if key not in s else '%d of %d' % (len(s[key]), s.get('runs_compared', 0)))
            for s in settings]
    out = ['%s rows of `%s`.' % (_f(len(d.get('run_ids', []))), d.get('suite')), '']
    out += _table(('setting', 'results', 'wall [s]', 'missions per minute', 'outcomes',
                   'infrastructure errors', 'processes left', 'rows differing from %s' % ref), rows)
    fresh_local = [s for s in settings if s.get('setting') != 'Dask cluster, 2 workers'
                   and not s.get('setting', '').endswith(', warm')]
    if len(fresh_local) > 1:
        out += ['', 'Best local setting: %s, %s× the rate of %s; every result equal in every '
                'setting: %s.' % (d.get('best_local'), _f(d.get('best_speedup_over_1_worker')),
                                  ref, _f(d.get('all_equal')))]
    timed = [s for s in d.get('settings', []) if s.get('time')]
    if timed:       # where the time goes: per phase, the median run's wall and CPU seconds
        phases = ('startup', 'mission', 'teardown', 'judging')
        rows = [(s.get('setting'),
                 ', '.join('%s %d' % kv for kv in sorted((s.get('isolation') or {}).items())),
                 _pct(s['time'].get('mission_share')))
                + tuple('%s / %s' % (_f(s['time']['phases'][k].get('median_wall_s')),
                                     _f(s['time']['phases'][k].get('median_cpu_s'))) for k in phases)
                for s in timed]
        out += ['', 'Where the time goes (median run, wall / CPU seconds; the missions\' share of '
                'the worker time, wall time × workers):', '']
        out += _table(('setting', 'isolation', 'in missions') + phases, rows)
    warm = d.get('warm') or []
    if warm:        # warm stacks against fresh ones, same rows, same worker count
        rows = [(w.get('workers'), _f(w.get('fresh_missions_per_minute')),
                 _f(w.get('warm_missions_per_minute')), _f(w.get('speedup')),
                 '%d of %d' % (w.get('runs_compared', 0) - len(w.get('runs_differing') or {}),
                               w.get('runs_compared', 0)),
                 w.get('infrastructure_errors'), _pct(w.get('fresh_mission_share')),
                 _pct(w.get('warm_mission_share')), (w.get('stacks') or {}).get('reset'))
                for w in warm]
        out += ['', 'Warm stacks (`evaluate --warm`) against fresh ones on the same rows:', '']
        out += _table(('workers', 'fresh missions/min', 'warm missions/min', 'speed-up',
                       'rows equal to fresh', 'infrastructure errors', 'in missions, fresh',
                       'in missions, warm', 'rows after a reset'), rows)
    return out


def render_covariance(d):
    rows = []
    for key, label in (('map', 'map (`center_covariance`)'),
                       ('robot', 'robot (`center_robot_covariance`)'),
                       ('map_fit_term_only', 'map, the fit\'s term alone')):
        f = d.get(key) or {}
        rows.append((label, f.get('n'), f.get('mean_nees'), f.get('median_nees'),
                     _pct(f.get('inside_95')), f.get('beyond_999'), f.get('max_nees')))
    out = _table(('frame', 'detections', 'mean NEES', 'median NEES', 'inside 95 %',
                  'beyond 99.9 %', 'max NEES'), rows)
    sh = d.get('variance_share_mean') or {}
    out += ['', 'Mean share of `center_std`²: %s. Centre error RMS %s m, median `center_std` '
            '%s m, over %s runs. Targets met: %s.'
            % (', '.join('%s %s' % (k, _pct(v)) for k, v in sh.items()),
               _f(d.get('error_rms_m')), _f(d.get('center_std_median_m')), _f(d.get('runs')),
               _f(d.get('targets_met')))]
    return out


def render_suites(d):
    out = []
    for name, s in d.get('suites', {}).items():
        lo, hi = s.get('wilson_95') or (None, None)
        out += ['`%s`: %s runs, %s succeeded (%s, Wilson 95 %% %s–%s), %s collisions%s.'
                % (s.get('suite'), s.get('runs'), s.get('succeeded'), _pct(s.get('rate')), _pct(lo),
                   _pct(hi), s.get('collisions'),
                   '' if not s.get('missions_per_minute') else
                   ', %s missions per minute' % _f(s['missions_per_minute'])), '']
        rows = [(g['group'], g['profile'], 'on' if g['corridor_law'] else 'off',
                 g.get('candidate', 'own'),
                 '%d/%d' % (g['succeeded'], g['runs']), g['collisions'], g['min_clearance_m'],
                 g['loc_error_p95_m_max'], g['rms_error_m_max']) for g in s.get('groups', [])]
        out += _table(('world group', 'profile', 'corridor law', 'candidate', 'succeeded',
                       'collisions', 'least clearance [m]', 'worst localisation p95 [m]',
                       'worst centre RMS [m]'), rows)
        if s.get('people'):
            out += ['', 'Among walkers (runs in worlds with walkers):', '']
            out += _table(('profile', 'candidate', 'runs', 'collisions',
                           'closest to a walker [m]', 'runs under 0.3 m', 'waiting mean [s]',
                           'waiting max [s]', 'walkers reported as persons',
                           'walkers reported static', 'runs with one static',
                           'oldest ghost [s]', 'runs with a ghost over 2 s',
                           'runs without a costmap'),
                          [(g['profile'], g['candidate'], g['runs'], g['collisions'],
                            g['closest_walker_m'], g['runs_under_gap'], g['waiting_s_mean'],
                            g['waiting_s_max'], g['walkers_reported'], g['walkers_static'],
                            g['runs_walker_static'], g.get('ghost_age_s_max'),
                            g.get('runs_ghost_over'), g.get('runs_no_costmap'))
                           for g in s['people']])
        fails = s.get('not_succeeded') or []
        out += ['', 'Not succeeded: %s' % ('none.' if not fails else '')]
        out += ['- `%s` %s, %s, law %s, seed %s%s: %s: %s' % (
            f['run_id'], f['world'], f['profile'], 'on' if f['use_corridor_law'] else 'off',
            f['seed'], ', %s' % f['candidate'] if f.get('candidate', 'own') != 'own' else '',
            f['outcome'], f['reason']) for f in fails]
        out += ['']
        out += _suite_rules(s)
    out += ['Target (at least %s success per suite) met: %s.' % (
        _pct(d.get('target_rate')), ', '.join('%s %s' % (k, _f(v)) for k, v in d.get('met', {}).items()))]
    if d.get('met_plain'):
        out += ['', 'Under the plain rule (at least 5 usable beams): %s.' % ', '.join(
            '%s %s' % (k, _f(v)) for k, v in d['met_plain'].items())]
    return out


def _suite_rules(s):
    """A suite's results under each rule of "in view" (bench_suites.py's ``rules``)."""
    rules = s.get('rules')
    if not rules:
        return []
    out = ['Rescored under two rules of *in view* (usable beams of the noise-free cast that hit '
           'the obstacle; glimpsed: fewer; a centre reported for a glimpsed obstacle is scored '
           'too):', '']
    rows = []
    for name, r in rules.items():
        lo, hi = r.get('wilson_95') or (None, None)
        for prof, t in sorted((r.get('detection') or {}).items()):
            rows.append((name, '>= %s' % r.get('min_usable_beams'),
                         '%s/%s (%s, %s–%s)' % (r.get('succeeded'), r.get('runs'), _pct(r.get('rate')),
                                                _pct(lo), _pct(hi)),
                         prof, t['in_view'], t['glimpsed'], t['found'], t['missed'],
                         t['false_positives'], t['matched_glimpsed'], t['rms_error'],
                         t['max_error'], t['max_error_glimpsed']))
    out += _table(('rule', 'usable beams', 'succeeded (suite)', 'profile', 'in view', 'glimpsed',
                   'found', 'missed', 'false positives', 'glimpsed found', 'centre RMS [m]',
                   'centre max [m]', 'glimpsed max [m]'), rows)
    diff = s.get('rules_differ') or []
    out += ['', 'Runs judged differently by the two rules: %s' % ('none.' if not diff else '')]
    out += ['- `%s`: %s' % (d['run_id'], '; '.join(
        '%s %s (%s)' % (k, v[0], v[1] or '') for k, v in d.items() if k != 'run_id'))
        for d in diff]
    return out + ['']


def render_mission_cpu(d):
    a, b = d.get('this', {}), d.get('other', {})
    sa, sb, r = a.get('summary', {}), b.get('summary', {}), d.get('ratios', {})

    def rng(s):
        return '–' if not s else '%s (%s–%s)' % (_f(s.get('median')), _f(s.get('min')),
                                                _f(s.get('max')))

    def ratio(q):
        p = (q or {}).get('pairs') or {}
        return (_f((q or {}).get('median_ratio')),
                '–' if not p else '%s (%s–%s)' % (_f(p.get('median')), _f(p.get('min')),
                                                  _f(p.get('max'))))
    rows = [('**stack**', rng(sa.get('cpu_s')), rng(sb.get('cpu_s'))) + ratio(r.get('cpu_s'))]
    procs = r.get('cpu_by_process_s', {})
    rows += [(n, rng(sa.get('cpu_by_process_s', {}).get(n)),
              rng(sb.get('cpu_by_process_s', {}).get(n))) + ratio(procs[n])
             for n in sorted(procs, key=lambda n: -(((sa.get('cpu_by_process_s') or {}).get(n)
                                                     or {}).get('median') or 0.0))]
    for ph, q in r.get('phases', {}).items():
        rows.append(('phase: %s' % ph, rng(sa.get('phases', {}).get(ph, {}).get('cpu_s')),
                     rng(sb.get('phases', {}).get(ph, {}).get('cpu_s'))) + ratio(q))
    rows += [('wall [s]', rng(sa.get('wall_s')), rng(sb.get('wall_s'))) + ratio(r.get('wall_s')),
             ('simulated [s]', rng(sa.get('sim_s')), rng(sb.get('sim_s'))) + ratio(r.get('sim_s'))]
    out = ['%s interleaved pairs; this tree `%s`, the other `%s` (%s).'
           % (_f(d.get('pairs')), a.get('commit'), b.get('commit'), b.get('label')), '']
    out += _table(('CPU [s]', 'this tree: median (range)', '%s: median (range)' % b.get('label'),
                   'ratio of medians', 'ratio per pair: median (range)'), rows)
    loads = [x.get('loadavg_at_goal', [None])[0] for x in a.get('runs', []) + b.get('runs', [])
             if x.get('loadavg_at_goal')]
    for label, s in (('this tree', sa), (b.get('label'), sb)):
        out += ['', '%s: %s/%s missions succeeded, pose B reached within %s m, %s of %s '
                'obstacles in view found, %s false positives, centre RMS %s m.'
                % (label, _f(s.get('succeeded')), _f(s.get('runs')),
                   _f((s.get('goal_error_m') or {}).get('max')), rng(s.get('matched')),
                   rng(s.get('in_view')), rng(s.get('false_positives')), rng(s.get('rms_error_m')))]
    if loads:
        out += ['', 'Load average (1 min) at the goals: %s–%s.' % (_f(min(loads)), _f(max(loads)))]
    return out


def render_localisation_real(d):
    """localisation_real.json: per log its size and dead reckoning, then per log, scenario
    and localiser the figures of the run."""
    logs = d.get('logs', {})
    out = ['%s; odometry: %s; lost: error > %s m. Scans with an estimate: how many the node '
           'answered (a node that drops scans under load, or publishes only after motion as '
           'amcl does, answers fewer; every scan is scored).'
           % (d.get('data'), d.get('odometry'), _f(d.get('lost_m'))), '']
    out += _table(('log', 'scans', 'beams', 'driven [m]', 'duration [s]',
                   'timestamps repaired', 'played at [× real time]',
                   'dead reckoning p95 [m]', 'dead reckoning max [m]'),
                  [(n, v.get('scans'), v.get('beams'), _f(v.get('path_m'), '%.0f'),
                    _f(v.get('duration_s'), '%.0f'), v.get('repaired_times'),
                    _f(v.get('rate'), '%.1f'), v.get('dead_reckoning_p95_m'),
                    v.get('dead_reckoning_max_m')) for n, v in logs.items()])
    rows = []
    for r in d.get('runs', []):
        if r.get('error'):
            rows.append((r['log'], r['scenario'], r['localiser'], 'error: %s' % r['error'])
                        + ('',) * 12)
            continue
        if r.get('global_localization') == 'not offered':
            rows.append((r['log'], r['scenario'], r['localiser'],
                         '/global_localization not offered') + ('',) * 12)
            continue
        back = r.get('back_within_0_2_m_after_scans', '')
        if 'limit_scans' in r:
            back = '%s (limit %s)' % ('never' if back is None else back, r['limit_scans'])
        recover = r.get('time_to_recover_max_s')
        if r.get('never_recovered_from_scan') is not None:
            recover = 'never (from scan %d)' % r['never_recovered_from_scan']
        rows.append((r['log'], r['scenario'], r['localiser'],
                     '%s/%s' % (r.get('estimates'), r.get('scans')), r.get('rms_m'),
                     r.get('median_m'), r.get('p95_m'), r.get('max_m'), r.get('yaw_p95_deg'),
                     _pct(r.get('lost_time_share')), recover, back,
                     _f(r.get('cpu_ms_per_scan'), '%.1f') + (
                         ' (load %.1f%s)' % (r['loadavg_1min'], ', side by side'
                                             if r.get('side_by_side') else '')
                         if r.get('cpu_ms_per_scan') is not None
                         and r.get('loadavg_1min') is not None else ''),
                     _f(r.get('peak_rss_mb'), '%.0f'),
                     r.get('sigma_xy_median_m'), _diagnostics_said(r)))
    out += [''] + _table(('log', 'scenario', 'localiser', 'scans with an estimate', 'RMS [m]',
                          'median [m]', 'p95 [m]', 'max [m]', 'yaw p95 [deg]', 'time lost',
                          'time to recover [s]', 'back within 0.2 m after [scans]',
                          'CPU per scan [ms] (machine load; side by side: played with the '
                          'other localisers of its log and scenario at once)', 'peak RSS [MB]', 'σ claimed, median [m]',
                          '/diagnostics (lost said before back; scans skipped)'), rows)
    return out


def _diagnostics_said(run):
    """The /diagnostics cell of a localisation_real run: published or not, whether an ERROR
    status came between the start (or the kidnap) and the estimate back within 0.2 m, and the
    scans the node said it skipped."""
    if not run.get('diagnostics_published'):
        return 'no'
    parts = []
    if run.get('lost_reported_before_back') is not None:
        parts.append('lost said: %s' % ('yes' if run['lost_reported_before_back'] else 'no'))
    if run.get('skipped_scans') is not None:
        parts.append('skipped %d' % run['skipped_scans'])
    return 'yes' + ('; ' + ', '.join(parts) if parts else '')


def render_localisation_recovery(d):
    """localisation_recovery.json: per log and scenario the recovery and the error after it."""
    rows = []
    for r in d.get('runs', []):
        st = r.get('status_before_back', {})
        back = r.get('back_within_0_2_m_after_scans')
        rows.append((r['log'], r['scenario'], r.get('scans'),
                     '%s%s' % ('never' if back is None else back,
                               '' if r.get('limit_scans') is None
                               else ' (limit %s)' % r['limit_scans']),
                     '%s / %s / %s' % (st.get('ok'), st.get('degraded'), st.get('lost')),
                     r.get('lost_reported_after_back_scans'), r.get('p95_after_m'),
                     r.get('max_after_m'), _pct(r.get('lost_share_after')),
                     _f(r.get('nees_xy_mean_after'), '%.2f'),
                     _pct(r.get('nees_xy_within_95_share')),
                     _f(r.get('nees_yaw_mean_after'), '%.2f'),
                     _f(r.get('cpu_ms_per_scan'), '%.1f')))
    return _table(('log', 'scenario', 'scans', 'back within 0.2 m after [scans]',
                   'status before: OK / degraded / lost [scans]', 'said lost after [scans]',
                   'p95 after [m]', 'max after [m]', 'lost after', 'NEES x-y mean (2)',
                   'within the 95 % ellipse', 'NEES yaw mean (1)', 'CPU per scan [ms]'), rows)


RENDER = {'mission_cpu': render_mission_cpu, 'covariance': render_covariance, 'suites': render_suites, 'evaluate': render_evaluate, 'simulator': render_simulator, 'detection': render_detection,
          'navigation': render_navigation, 'corridor': render_corridor,
          'mission': render_mission, 'demo': render_demo, 'lockstep': render_lockstep,
          'soak': render_soak, 'localisation': render_localisation,
          'localisation_real': render_localisation_real,
          'localisation_recovery': render_localisation_recovery}
# a JSON whose structure is not its benchmark's usual one: rendered by its own function
def render_short_arcs(d):
    """short_arcs.json: per cut of the arc, profile and count of usable beams, how often the
    cylinder was found and placed within the tolerance."""
    tol = d.get('tolerance_m') or 0
    rows = [(r['cut'], r['profile'], r['usable_beams'],
             'yes' if r['in_view'] else ('plain rule only' if r['in_view_plain'] else 'no'),
             '%d/%d' % (r['found'], r['trials']), '%d/%d' % (r['within_tolerance'], r['trials']),
             r['max_error_m']) for r in d.get('rows', [])]
    out = ['A %s m cylinder %s m from the laser, its arc cut short; the median of %s scans at '
           'rest, exact pose.' % (_f(d.get('radius_m')), _f(d.get('range_m')), d.get('rest_scans')),
           '']
    out += _table(('cut', 'profile', 'usable beams', 'in view', 'found',
                   'within %.0f cm' % (100 * tol), 'worst error [m]'), rows)
    out += ['']
    for name in ('evaluator', 'plain'):
        r = d.get(name) or {}
        out += ['- rule %s (at least %s usable beams): %s of %s placed within %.0f cm.' % (
            name, d.get('min_beams' if name == 'evaluator' else 'plain_beams'),
            r.get('within_tolerance'), r.get('trials'), 100 * tol)]
    return out


def render_shapes(d):
    """shapes.json: per mode and shape, the objects where the targets apply (two faces of a box,
    three legs of a table or chair seen) and all in view."""
    out = ['Worlds %s, tiago laser, %s m noise, exact pose; targets: centre <= %s m, orientation '
           '<= %s deg where two faces or three legs are seen.' % (
               ', '.join(d.get('worlds', [])), _f(d.get('noise_m')),
               _f((d.get('targets') or {}).get('centre_m')),
               _f((d.get('targets') or {}).get('orientation_deg'))), '']
    rows = []
    for mode, m in (d.get('summary') or {}).items():
        for which in ('targets_apply', 'all_in_view'):
            for shape, r in (m.get(which) or {}).items():
                rows.append((mode, which.replace('_', ' '), shape, r.get('objects'),
                             r.get('found_once'), r.get('found_as_other'), r.get('missed'),
                             r.get('centre_rms_m'), r.get('centre_max_m'), r.get('within_3cm'),
                             r.get('orientation_max_deg'), r.get('within_5deg'),
                             r.get('inside_95_ellipse'), r.get('mean_nees')))
    out += _table(('scans', 'objects', 'shape', 'n', 'found once', 'as another shape', 'missed',
                   'centre RMS [m]', 'max [m]', 'within 3 cm', 'orientation max [deg]',
                   'within 5 deg', 'inside 95 % ellipse', 'mean NEES'), rows)
    out += ['']
    for mode, m in (d.get('summary') or {}).items():
        out += ['- %s: %s false positives; %s objects where the targets apply reported with a '
                'centre not fixed' % (mode, m.get('false_positives'),
                                      m.get('center_not_fixed_when_target_applies'))]
    return out


def render_legs_real(d):
    """legs_real.json: recall and precision on the marked bags, motion on the demo."""
    m = d.get('marked') or {}
    out = []
    for mode, what in (('background', 'over the static background built from each bag\'s '
                        'scans'), ('single_scan', 'over an empty map (one scan, everything '
                                   'unmapped)')):
        f = m.get(mode) or {}
        a, b, h = f.get('all') or {}, f.get('built_on') or {}, f.get('held_out') or {}
        out += ['- %s: of %s marked leg clusters %s within %s m of a person\'s `legs` object '
                '(recall), %s of %s such objects near a marked leg (precision; %s of the %s in '
                'the region where every cluster was marked); bags 1-3: recall %s, precision %s '
                '(%s in the region); held out (%s): recall %s, precision %s (%s in the region); '
                'target %s.'
                % (what, a.get('marked_legs'), a.get('recall'), _f(d.get('near_m')),
                   a.get('precision'), a.get('legs_objects'),
                   a.get('precision_in_marked_region'), a.get('legs_objects_in_marked_region'),
                   b.get('recall'), b.get('precision'), b.get('precision_in_marked_region'),
                   ', '.join(d.get('held_out') or []), h.get('recall'), h.get('precision'),
                   h.get('precision_in_marked_region'), _f(d.get('target')))]
    out += ['']
    out += _table(('bag', 'scans', 'marked legs', 'recall', 'precision', 'in the region',
                   'legs objects', 'recall, one scan', 'precision, one scan',
                   'legs objects, one scan'),
                  [(b['bag'] + (' (held out)' if b.get('held_out') else ''), b['scans'],
                    b['background']['marked_legs'], b['background']['recall'],
                    b['background']['precision'],
                    b['background'].get('precision_in_marked_region'),
                    b['background']['legs_objects'],
                    b['single_scan']['recall'], b['single_scan']['precision'],
                    b['single_scan']['legs_objects'])
                   for b in d.get('marked_per_bag', []) if 'background' in b])
    dm = d.get('demo') or {}
    out += ['', '- demo: %s calls; %s people walking past (objects whose place was seen free '
            'within 1 s before and after): %s reported moving, %s static, %s not judged; of '
            'the %s objects in front of the static background %s moving (%s with a velocity), '
            '%s static; speed of what moved: median %s m/s, p95 %s m/s.' % (
                dm.get('calls'), dm.get('passing'), dm.get('passing_moving'),
                dm.get('passing_static'), dm.get('passing_unknown'), dm.get('foreground'),
                dm.get('foreground_moving'), dm.get('moving_with_velocity'),
                dm.get('foreground_static'), dm.get('speed_median_m_s'),
                dm.get('speed_p95_m_s'))]
    return out


RENDER.update(shapes=render_shapes, legs_real=render_legs_real)
RENDER_FILE = {'detection_sensing.json': render_detection_sensing,
               'short_arcs.json': render_short_arcs,
               'navigation_people.json': render_navigation_people,
               'navigation_people_plain.json': render_navigation_people}


def render_page(results, header):
    """docs/benchmarks.md from the JSON files in ``results``."""
    lines = [header, '', '# Benchmarks', '',
             'The current figures, rendered from `bench/results/*.json` by `make docs`. Each table '
             'is headed by the command that regenerates its JSON (`make bench` runs them all; the '
             'benchmarks do not run in the test suite). Each JSON\'s `meta` block says which code, '
             'machine and conditions it comes from. Each benchmark\'s own targets are in its paragraph '
             '(some are stricter than the quality bars in '
             '[design-decisions.md](design-decisions.md#quality-bars)).', '']
    for name, title, runs in BENCHMARKS:
        lines += ['## %s' % title, '']
        if name in ABOUT:
            lines += [ABOUT[name], '']
        for cmd, files in runs:
            for fname in files:
                path = os.path.join(results, fname)
                lines += ['### `make bench BENCH=%s`: %s' % (name, fname), '',
                          'Command: `%s`' % cmd, '']
                if not os.path.exists(path):
                    lines += ['not written yet', '']
                    continue
                with open(path) as f:
                    data = json.load(f)
                render = RENDER_FILE.get(fname, RENDER[name])
                lines += render(data) + [''] + meta_lines(data) + ['']
                png = os.path.splitext(fname)[0] + '.png'
                if os.path.exists(os.path.join(results, png)):
                    lines += ['![%s](../bench/results/%s)' % (fname, png), '']
    return '\n'.join(lines).rstrip('\n') + '\n'


if __name__ == '__main__':
    sys.exit(main())
