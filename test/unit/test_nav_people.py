"""People in the navigation: what moved (tiago_nav.nav.people) is kept person_clearance away,
waited for, and given way to. Measured on the simulator's ground truth (walkers' legs, the
base's pose and contacts) through the navigation closed loop without ROS."""
import copy
import math
import os

import numpy as np
import yaml

from conftest import WORLDS
from tiago_nav.gridmap import GridMap
from tiago_nav.nav.costmap import Costmap, MapScan
from tiago_nav.nav.navigator import ABORTED, SUCCEEDED, NavConfig
from tiago_nav.nav.people import MovedMarks
from tiago_nav.sim.world import World, load_world
from tiago_nav_tools.testing.navigation import ClosedLoop

INC = math.radians(0.25)
N = 721                                  # beams over +-90 deg


def scan_of(ranges, pose=(0.0, 0.0, 0.0), stamp=0.0):
    return MapScan(pose, np.asarray(ranges, dtype=float), -math.pi / 2, INC, 0.05, 10.0, stamp)


def bearing_beam(x, y):
    return int(round((math.atan2(y, x) + math.pi / 2) / INC))


def test_free_space_is_seen_beyond_only_where_every_beam_near_the_point_passed():
    free = scan_of(np.full(N, 5.0))
    pts = np.array([[2.0, 0.0], [4.95, 0.0], [2.0, 2.0]])
    assert free.seen_beyond(pts, 0.1).tolist() == [True, False, True]
    # a post 4 cm beside the line of sight at 2 m stops the beams near it: no verdict there
    r = np.full(N, 5.0)
    i = bearing_beam(2.0, 0.04)
    r[i - 1:i + 2] = 2.0
    assert not scan_of(r).seen_beyond(pts[:1], 0.1)[0]
    # a thin object whose one beam came back invalid (a mixed pixel) was not seen through
    r = np.full(N, 5.0)
    r[bearing_beam(2.0, 0.0)] = np.nan
    assert not scan_of(r).seen_beyond(pts[:1], 0.1)[0]
    # beams farther apart than max_gap at the point vouch for nothing
    assert not free.seen_beyond(np.array([[4.0, 0.0]]), 0.1, max_gap=0.01)[0]


def test_the_witnesses_together_say_what_each_says_alone():
    # MovedMarks.seen_free weighs all witnesses at once: it must say exactly what asking each
    # one (MapScan.seen_beyond) says, over scans of several sizes, beam spacings and
    # directions with invalid, too-close and no-return beams, as the witnesses come and go
    rng = np.random.default_rng(4)
    marks = MovedMarks(grid(), memory=3.0, keep_every=1.0)
    said = 0
    for t in range(12):
        n = int(rng.integers(40, 800))
        inc = float(rng.choice([-1.0, 1.0]) * rng.uniform(0.002, 0.012))
        r = np.repeat(rng.uniform(0.3, 6.0, n // 30 + 1), 30)[:n]     # surfaces 30 beams wide
        r[rng.random(n) < 0.01] = np.nan
        r[rng.random(n) < 0.01] = 0.01
        r[rng.random(n) < 0.02] = np.inf
        r[rng.random(n) < 0.005] = -np.inf
        pose = (float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)), float(rng.uniform(-3, 3)))
        scan = MapScan(pose, r, -inc * n / 2, inc, 0.05, 5.5, float(t))
        for margin, gap, beyond in ((0.1, 0.02, 0.2), (0.1, None, 0.1), (0.05, 0.05, 0.05)):
            marks.margin, marks.max_gap, marks.beyond = margin, gap, beyond
            xy = rng.uniform(-4.0, 4.0, (300, 2))
            want = np.zeros(len(xy), dtype=bool)
            for w in marks.witnesses:
                want |= w.seen_beyond(xy, margin, gap, beyond)
            assert marks.seen_free(xy, float(t) + 0.5).tolist() == want.tolist()
            said += int(want.sum())
        marks.update(scan)
    assert said > 100, said


def grid(size=10.0):
    n = int(size / 0.05)
    return GridMap(np.zeros((n, n), dtype=np.int8), 0.05, (-size / 2, -size / 2))


def ranges_with_disc(cx, cy, radius, pose=(0.0, 0.0, 0.0), room=4.5):
    """Ranges of the +-90 deg fan from ``pose`` in a square room (walls at +-``room``, not in
    the map) with a disc at (cx, cy) (none for radius 0)."""
    a = pose[2] - math.pi / 2 + INC * np.arange(N)
    c, s = np.cos(a), np.sin(a)
    with np.errstate(divide='ignore'):
        tx = np.where(c > 0, (room - pose[0]) / c, (-room - pose[0]) / c)
        ty = np.where(s > 0, (room - pose[1]) / s, (-room - pose[1]) / s)
    r = np.minimum(np.abs(tx), np.abs(ty))
    if radius > 0:
        dx, dy = cx - pose[0], cy - pose[1]
        along = dx * c + dy * s
        miss2 = dx * dx + dy * dy - along ** 2
        hit = (along > 0) & (miss2 < radius * radius)
        r[hit] = np.minimum(r[hit], along[hit] - np.sqrt(radius * radius - miss2[hit]))
    return r


def test_a_leg_that_stepped_into_free_space_is_a_person_and_stays_one_while_it_stands():
    marks = MovedMarks(grid(), memory=10.0)
    assert not marks.update(scan_of(ranges_with_disc(0, 0, 0), stamp=0.0)).any()  # the witness
    leg = scan_of(ranges_with_disc(2.0, 0.0, 0.06), stamp=1.0)
    person = marks.update(leg)
    pts = leg.obstacles[0]
    near = np.hypot(pts[:, 0] - 2.0, pts[:, 1]) < 0.1
    assert person[near].all() and not person[~near].any()
    # standing still for longer than the memory: still a person (its cells stay held)
    for t in np.arange(1.5, 25.0, 0.5):
        person = marks.update(scan_of(ranges_with_disc(2.0, 0.0, 0.06), stamp=float(t)))
    assert person[near].all()


def test_a_person_who_moved_out_of_view_is_one_where_seen_next_within_a_walk_of_it():
    # seen stepping into free space ahead-left; the base turns right while they take a step
    # onto floor no kept scan saw free (right of the first fan): still a person there, within
    # what a walker covers in the time; a post as far from them as they could not have walked
    # is none
    marks = MovedMarks(grid(), memory=10.0)
    left = (0.0, 0.0, math.pi / 2)
    marks.update(scan_of(ranges_with_disc(0, 0, 0, left), left, stamp=0.0))        # the witness
    assert marks.update(scan_of(ranges_with_disc(2.0, 0.5, 0.06, left), left, stamp=1.0)).any()
    ahead = (0.0, 0.0, 0.0)
    for (x, y), person in (((2.0, -0.4), True), ((2.0, -1.5), False)):
        scan = scan_of(ranges_with_disc(x, y, 0.06, ahead), ahead, stamp=2.0)
        got = MovedMarks.update(copy.deepcopy(marks), scan)
        pts = scan.obstacles[0]
        near = np.hypot(pts[:, 0] - x, pts[:, 1] - y) < 0.1
        assert near.sum() >= 3 and got[near].all() == person and not got[~near].any(), (x, y)


def test_what_stood_there_all_along_is_no_person_seen_from_anywhere():
    marks = MovedMarks(grid(), memory=10.0)
    for k, pose in enumerate([(0.0, 0.0, 0.0), (0.5, 0.8, -0.3), (1.0, -0.8, 0.4), (1.3, 0.0, 0.0)]):
        person = marks.update(scan_of(ranges_with_disc(2.5, 0.0, 0.2, pose), pose, stamp=0.6 * k))
        assert not person.any(), pose


def test_what_stands_still_is_no_person_when_the_scans_are_placed_with_a_pose_error():
    # the base drives past a cylinder in a room whose walls are not in the map, each scan
    # placed with a pose error that drifts (about 2.8 cm and 0.9 deg std, up to 7 cm and 2.6
    # deg: a localisation's error through ROS in the course world reached 1.4 deg): it moves
    # every hit of what stands still off where earlier scans saw it, and none is a person's,
    # with the laser's marks kept as the costmap keeps them (with 0.1 m beyond and no look at
    # the marks, 2,589-2,948 hits within 4 m were a person's in each of these seeds)
    for seed in (0, 2, 3):
        rng = np.random.default_rng(seed)
        marks = MovedMarks(grid(), memory=10.0)
        cm = Costmap(grid())
        err = np.zeros(3)
        for k in range(60):
            true = (-1.0 + 0.05 * k, 0.8 * math.sin(0.1 * k), 0.3 * math.sin(0.07 * k))
            err = 0.9 * err + 0.4 * rng.normal(0.0, (0.03, 0.03, math.radians(1.0)))
            scan = scan_of(ranges_with_disc(2.5, 0.0, 0.2, true), tuple(true + err), 0.2 * k)
            person = marks.update(scan, cm.obstacles)
            cm.add_scan(scan)
            assert not person.any(), (seed, k, scan.obstacles[0][person][:3])


def test_what_stands_still_is_no_person_after_clear_costmaps():
    # as above, through the navigation, whose clear_costmaps forgets the laser's marks: the
    # marks that told the cylinder's hits from a person's went with them, and so must the
    # free space the earlier scans saw (the rostest's costmap once kept the course's cylinder
    # a person's distance away after its clear_costmaps)
    from tiago_nav.nav.navigator import Navigator
    for seed in (0, 2, 3):
        rng = np.random.default_rng(seed)
        nav = Navigator(grid())
        err = np.zeros(3)
        for k in range(60):
            if k in (15, 30, 45):
                nav.clear_costmaps()
            true = (-1.0 + 0.05 * k, 0.8 * math.sin(0.1 * k), 0.3 * math.sin(0.07 * k))
            err = 0.9 * err + 0.4 * rng.normal(0.0, (0.03, 0.03, math.radians(1.0)))
            nav.add_scan(scan_of(ranges_with_disc(2.5, 0.0, 0.2, true), tuple(true + err),
                                 0.2 * k))
            person = nav.margins == nav.cfg.person_clearance      # a person's points
            assert not nav.costmap.people.any() and not person.any(), (seed, k)


def test_a_lone_return_in_free_space_is_a_mixed_pixel_not_a_person():
    marks = MovedMarks(grid(), memory=10.0)
    marks.update(scan_of(ranges_with_disc(0, 0, 0), stamp=0.0))
    r = ranges_with_disc(0, 0, 0)
    r[bearing_beam(2.0, 0.0)] = 2.0
    assert not marks.update(scan_of(r, stamp=1.0)).any()


PEOPLE = NavConfig()                            # people kept 0.3 m away (the default)
PLAIN = NavConfig(person_clearance=0.0)         # people are obstacles like any other


def walker_gap_run(world, goal, config=PEOPLE, limit=120.0):
    loop = ClosedLoop(world, config, seed=1)
    try:
        return loop.run_goal(goal, limit)
    finally:
        loop.close()


def test_the_base_keeps_its_clearance_from_a_person_who_stopped_for_it():
    # lab_mixed: on the way to (9, 0) the robot meets a walker crossing at x = 7 who stops to
    # let it pass; without the person rule it drives by at 0.10 m from the legs
    w = load_world(os.path.join(WORLDS, 'lab_mixed.yaml'))
    r = walker_gap_run(w, (9.0, 0.0, 0.0))
    assert r['state'] == SUCCEEDED, r['reason']
    assert r['collisions'] == 0
    assert r['closest_walker'] >= 0.3
    assert walker_gap_run(w, (9.0, 0.0, 0.0), PLAIN)['closest_walker'] < 0.2


def corridor(walkers):
    return World.from_dict(dict(
        name='corridor_person', resolution=0.05, bounds=[-0.5, -0.7, 11.0, 0.7],
        robot_start=[0.5, 0.0, 0.0], static_cylinders=[], movable_obstacles=[],
        walls=[dict(x=5.0, y=0.6, length=10.0, width=0.15, yaw_deg=0),
               dict(x=5.0, y=-0.6, length=10.0, width=0.15, yaw_deg=0)],
        walkers=walkers))


def test_a_person_who_stands_in_the_only_way_is_waited_for_then_the_goal_aborts_naming_them():
    # the walker comes towards the robot and stops for good in the corridor
    w = corridor([dict(path=[[7.0, 0.0], [4.0, 0.0]], speed=0.6, loop=False, start_delay=0.0)])
    r = walker_gap_run(w, (8.0, 0.0, 0.0), NavConfig(person_clearance=0.3, person_patience=8.0))
    assert r['state'] == ABORTED
    assert 'person' in r['reason'], r['reason']
    assert r["time"] >= 8.0 + 3.0                  # waited the person's patience, not 3 s
    assert r['collisions'] == 0
    assert r['closest_walker'] >= 0.3


def test_the_goal_clocks_stand_still_while_the_base_waits_for_a_person():
    # as above, with a deadline (goal_timeout_factor 1.5: 12.25 s for the 7.5 m plan) and a
    # no-progress window (5 s) shorter than the wait: neither ends the goal while the base
    # waits for the person; person_patience does, naming them
    w = corridor([dict(path=[[7.0, 0.0], [4.0, 0.0]], speed=0.6, loop=False, start_delay=0.0)])
    cfg = NavConfig(person_clearance=0.3, person_patience=8.0, goal_timeout_factor=1.5,
                    goal_timeout_allowance=1.0, no_progress_timeout=5.0)
    r = walker_gap_run(w, (8.0, 0.0, 0.0), cfg)
    assert r['state'] == ABORTED
    assert 'person' in r['reason'] and 'timeout' not in r['reason'], r['reason']
    assert r['time'] >= 8.0 + 3.0


def test_a_person_met_in_a_doorway_is_given_way_to_beside_a_wall_and_the_goal_is_reached():
    # office_walkers: the base drives west along the hallway into the first office while a
    # walker comes out through the 1 m doorway towards it; both stop. Giving way to the
    # nearest place 1.5 m from the person put the base on the walker's line, where the walker
    # waited for it until the goal timed out; beside the hallway's wall the walker passes
    with open(os.path.join(WORLDS, 'office_walkers.yaml')) as f:
        data = yaml.safe_load(f)
    data['walkers'] = [dict(data['walkers'][2], start_delay=0.0)]
    data['robot_start'] = [7.5, 0.0, 180.0]
    r = walker_gap_run(World.from_dict(data), (1.5, 0.0, math.pi), PEOPLE)
    assert r['state'] == SUCCEEDED, r['reason']
    assert r['collisions'] == 0
