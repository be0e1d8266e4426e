"""Test support for the localiser: a drifting odometry and a route driven through the in-process
simulator, with the localised and the dead-reckoned pose compared to ground truth.

``python3 -m tiago_nav_tools.testing.localisation`` prints the figures docs/localisation.md quotes.
"""
import math
import statistics
import time
from dataclasses import dataclass

import numpy as np

from tiago_nav.geometry import compose, inverse, wrap_angle
from tiago_nav.gridmap import RASTER_MAP_DEPTH
from tiago_nav.localisation.localiser import Localiser, LocaliserConfig
from tiago_nav.sim.raster import rasterise_world
from tiago_nav.sim.simulator import SimConfig, Simulator

def raster_config(**kw):
    """A :class:`LocaliserConfig` (``kw`` as its fields) for a map rasterised from a world, the
    simulator's: its surfaces lie a quarter cell inside their occupied cells
    (``map_surface_depth``, as sim.launch sets it)."""
    return LocaliserConfig(map_surface_depth=RASTER_MAP_DEPTH, **kw)


SIM_CONFIG = raster_config()
# Through the course world's corridor into the big room, a loop there, and back into the corridor
# (map frame [m]; the movable cylinders stay in the scene, unmapped).
COURSE_ROUTE = ((2.0, 0.0), (5.5, 0.0), (7.2, -0.3), (8.6, -0.9), (8.6, 0.4), (7.0, 0.2),
                (5.0, 0.0))


class DriftingOdometry:
    """Odometry that integrates the true motion with scale errors and noise (in base_footprint):
    each step's distance is scaled by ``1 + distance_error`` and its rotation by
    ``1 + rotation_error``, plus zero-mean noise whose std grows with the step (``noise`` of it).
    The pose is in ``odom`` (origin: the first true pose)."""

    def __init__(self, true_pose, distance_error=0.02, rotation_error=0.03, noise=0.01, seed=0):
        self.last = tuple(true_pose)
        self.pose = (0.0, 0.0, 0.0)
        self.k = (1.0 + distance_error, 1.0 + rotation_error)
        self.noise = noise
        self.rng = np.random.default_rng(seed)

    def step(self, true_pose):
        """Integrate the motion from the last true pose to ``true_pose``; returns the odom pose."""
        dx, dy, dth = compose(inverse(self.last), true_pose)
        self.last = tuple(true_pose)
        n = self.rng.normal(size=3) * self.noise
        d = (dx * self.k[0] + abs(dx) * n[0], dy * self.k[0] + abs(dx) * n[1],
             dth * self.k[1] + (abs(dth) + 0.1 * abs(dx)) * n[2])
        self.pose = compose(self.pose, d)
        return self.pose


def steer(pose, target, v_max=0.5, w_max=1.0):
    """A velocity command ``(v, w)`` [m/s, rad/s] that turns towards ``target`` and drives there."""
    dx, dy = target[0] - pose[0], target[1] - pose[1]
    err = wrap_angle(math.atan2(dy, dx) - pose[2])
    w = max(-w_max, min(w_max, 2.0 * err))
    v = v_max * max(0.0, math.cos(err)) ** 4 * min(1.0, math.hypot(dx, dy) / 0.5)
    return v, w


@dataclass
class RouteResult:
    """Per scan: position error [m] and yaw error [rad] of the localised pose and of dead
    reckoning (drifting odometry from the true start); per registered scan (the localiser's
    ``due`` ones; the others follow odometry) the update time [s] (CPU time of the updating
    thread, so that other processes on the machine do not count).

    Also per scan: ``truth`` ``(N, 3)`` the true pose, ``loc_err`` and ``odo_err`` ``(N, 3)``
    the localised and dead-reckoned pose minus the truth ``(dx, dy, dyaw)`` [m, m, rad] in
    map, ``sigma`` ``(N, 3)`` the standard deviations of the localiser's covariance, and
    ``weak`` ``(N,)`` whether the last registration found a direction unobservable, ``pending``
    ``(N,)`` [m] how far the published estimate still was from the registered pose (a
    re-acquired direction's correction converging, ``max_correction_step`` per estimate),
    ``covariance`` ``(N, 3, 3)`` the published covariance of the estimate (/amcl_pose's)."""
    loc_xy: np.ndarray
    loc_yaw: np.ndarray
    odo_xy: np.ndarray
    odo_yaw: np.ndarray
    seconds: list
    rejected: int
    truth: np.ndarray = None
    loc_err: np.ndarray = None
    odo_err: np.ndarray = None
    sigma: np.ndarray = None
    weak: np.ndarray = None
    pending: np.ndarray = None
    covariance: np.ndarray = None

    def p95(self, what):
        return float(np.percentile(getattr(self, what), 95))


def run_route(world, route=COURSE_ROUTE, initial_error=(0.0, 0.0, 0.0), config=SIM_CONFIG,
              seed=0, drift=(0.02, 0.03, 0.01), scan_hook=None, max_time=120.0, laser=None):
    """Drive the simulator along ``route`` and localise at every scan (registering the ones
    the localiser finds :meth:`~tiago_nav.localisation.localiser.Localiser.due`, as the node does).

    Args:
        world: a :class:`tiago_nav.sim.world.World` (its movable obstacles are unmapped).
        route: waypoints ``(x, y)`` [m] in map.
        initial_error: ``(dx, dy, dyaw)`` [m, m, rad] added to the true start pose given to the
            localiser.
        config: :class:`LocaliserConfig` (default :data:`SIM_CONFIG`).
        seed: seeds the laser noise and the odometry noise.
        drift: ``(distance_error, rotation_error, noise)`` of :class:`DriftingOdometry`.
        scan_hook: optional ``f(ranges) -> ranges`` applied to each scan (to damage it).
        max_time: [s] of simulated time at most.
        laser: the simulator's :class:`tiago_nav.sim.laser.LaserModel` (default ``ideal``).

    Returns:
        a :class:`RouteResult`.
    """
    sim = Simulator(world, SimConfig(seed=seed) if laser is None
                    else SimConfig(seed=seed, laser_model=laser))
    try:
        grid = rasterise_world(world)
        las = sim.config.laser
        odo = DriftingOdometry(sim.pose, *drift, seed=seed)
        start = tuple(a + b for a, b in zip(sim.pose, initial_error))
        loc = Localiser(grid, start, config)
        errs = {k: [] for k in ('lx', 'ly', 'ox', 'oy')}
        rows = {k: [] for k in ('truth', 'loc', 'odo', 'sigma', 'weak', 'pending', 'cov')}
        secs, rejected, i = [], 0, 0
        while i < len(route) and sim.time < max_time:
            pose = sim.pose
            if math.hypot(route[i][0] - pose[0], route[i][1] - pose[1]) < 0.15:
                i += 1
                continue
            sim.command(*steer(pose, route[i]))
            scan_due, _ = sim.step()
            odom = odo.step(sim.pose)
            if not scan_due:
                continue
            ranges = sim.scan()
            if scan_hook is not None:
                ranges = scan_hook(ranges)
            if loc.due(odom):               # as the node does
                t0 = time.thread_time()
                pts = loc.scan_points(ranges, las.angle_min, las.angle_increment, las.range_min,
                                      las.range_max, (las.offset, 0.0, 0.0))
                up = loc.update(odom, pts, (las.offset, 0.0))
                secs.append(time.thread_time() - t0)
                rejected += not up.corrected
                estimate, cov = up.pose, up.covariance
            else:
                estimate, cov = loc.follow(odom)    # as the node does between registrations
            truth = sim.pose
            dead = compose(sim.start_pose, odom)
            for key, est in (('l', estimate), ('o', dead)):
                errs[key + 'x'].append(math.hypot(est[0] - truth[0], est[1] - truth[1]))
                errs[key + 'y'].append(abs(wrap_angle(est[2] - truth[2])))
                rows['loc' if key == 'l' else 'odo'].append(
                    (est[0] - truth[0], est[1] - truth[1], wrap_angle(est[2] - truth[2])))
            rows['truth'].append(tuple(truth))
            rows['sigma'].append(tuple(np.sqrt(np.maximum(np.diag(loc.covariance), 0.0))))
            rows['weak'].append(loc.information is not None and loc.information.degenerate)
            rows['pending'].append(float(np.hypot(*loc.pending)))
            rows['cov'].append(np.asarray(cov, dtype=float))
        return RouteResult(np.array(errs['lx']), np.array(errs['ly']), np.array(errs['ox']),
                           np.array(errs['oy']), secs, rejected,
                           np.array(rows['truth']).reshape(-1, 3),
                           np.array(rows['loc']).reshape(-1, 3),
                           np.array(rows['odo']).reshape(-1, 3),
                           np.array(rows['sigma']).reshape(-1, 3), np.array(rows['weak'], dtype=bool),
                           np.array(rows['pending']), np.array(rows['cov']).reshape(-1, 3, 3))
    finally:
        sim.close()


# Through corridor_long's 20 m corridor (along +x, y = 0) from its start room to the room beyond.
CORRIDOR_LONG_ROUTE = ((0.5, 0.0), (19.5, 0.0), (22.5, 0.5))
# From corridor_start's start, 1 m inside its 8 m corridor, to the room beyond (pose B's place).
CORRIDOR_START_ROUTE = ((7.0, 0.0), (10.5, 0.5))


def corridor_figures(result, axis=0.0):
    """Figures of a run along a corridor whose axis points ``axis`` [rad] in map, from a
    :class:`RouteResult`. *Featureless*: the scans whose last registration found a direction
    unobservable (so the along-axis estimate follows odometry).

    Returns:
        a dict: ``scans``, ``featureless_scans``; over the longest unbroken featureless
        stretch, ``featureless_m`` (its length along the axis [m]), ``loc_along_growth_m`` and
        ``odo_along_growth_m`` (how much the along-axis error of the localised and of the
        dead-reckoned pose changed over it, absolute [m]), ``sigma_along_end_m`` and
        ``error_along_end_m`` (the localiser's standard deviation along the axis, from the x
        and y variances, and its actual along-axis error at the stretch's last scan [m]);
        ``max_step_featureless_m``: the largest change of the localised position error
        between two consecutive featureless estimates [m]; ``max_error_increase_m``: the
        largest increase of the localised position error between two consecutive estimates
        over the whole run [m]; ``max_correction_m``: its largest decrease (a correction
        towards the truth, where the axis is observed again) [m]; ``localised_p95_m`` and
        ``localised_max_m`` over the run; ``lateral_p95_m``: the across-axis error's p95 over
        the featureless scans [m]; ``max_step_m``: the largest change of the localised
        position error between two consecutive estimates over the whole run, re-acquisition
        included [m]; ``max_pending_m``: the largest distance the published estimate was
        behind the registered pose [m] (about what the registration corrected in one step);
        ``converge_estimates``: the most consecutive estimates it took to converge (from the
        first with a pending correction to the first without; 0 when there was none).
    """
    u = np.array([math.cos(axis), math.sin(axis)])
    v = np.array([-u[1], u[0]])
    along = result.loc_err[:, :2] @ u
    odo_along = result.odo_err[:, :2] @ u
    weak = np.asarray(result.weak, dtype=bool)
    out = {'scans': int(len(along)), 'featureless_scans': int(np.count_nonzero(weak)),
           'localised_p95_m': float(np.percentile(result.loc_xy, 95)),
           'localised_max_m': float(result.loc_xy.max())}
    steps = np.diff(result.loc_xy)
    out['max_error_increase_m'] = float(max(steps.max(), 0.0)) if len(steps) else 0.0
    out['max_correction_m'] = float(max(-steps.min(), 0.0)) if len(steps) else 0.0
    moves_all = np.hypot(*np.diff(result.loc_err[:, :2], axis=0).T)
    out['max_step_m'] = float(moves_all.max()) if len(moves_all) else 0.0
    pend = np.zeros(len(along)) if result.pending is None else np.asarray(result.pending)
    busy = pend > 0
    out['max_pending_m'] = float(pend.max()) if len(pend) else 0.0
    if np.any(busy):
        e = np.flatnonzero(np.diff(np.concatenate(([0], busy.astype(int), [0]))))
        out['converge_estimates'] = int(np.max(e[1::2] - e[::2])) + 1
    else:
        out['converge_estimates'] = 0
    both = weak[1:] & weak[:-1]
    if np.any(both):
        out['max_step_featureless_m'] = float(moves_all[both].max())
        out['lateral_p95_m'] = float(np.percentile(np.abs(result.loc_err[weak, :2] @ v), 95))
        # the longest unbroken run of featureless scans
        edges = np.flatnonzero(np.diff(np.concatenate(([0], weak.astype(int), [0]))))
        starts, ends = edges[::2], edges[1::2] - 1
        k = int(np.argmax(ends - starts))
        a, b = starts[k], ends[k]
        out.update({
            'featureless_m': float(abs((result.truth[b, :2] - result.truth[a, :2]) @ u)),
            'loc_along_growth_m': float(abs(along[b] - along[a])),
            'odo_along_growth_m': float(abs(odo_along[b] - odo_along[a])),
            'sigma_along_end_m': float(math.sqrt(u @ np.diag(result.sigma[b, :2] ** 2) @ u)),
            'error_along_end_m': float(abs(along[b]))})
    return out


def main(seeds=range(5)):
    """Print the localised and dead-reckoned errors along :data:`COURSE_ROUTE` per seed and
    pooled, and the median update time."""
    import os
    from tiago_nav.sim.world import load_world
    here = os.path.dirname(os.path.abspath(__file__))
    world = load_world(os.path.join(here, '..', '..', '..', 'worlds', 'ias_lab_room_full.yaml'))
    runs = [run_route(world, seed=seed) for seed in seeds]
    rows = [('seed %d' % s, [r]) for s, r in zip(seeds, runs)] + [('all', runs)]
    print('| run | scans | registered | rejected | localised p95 / max [cm] | [deg] | '
          'dead reckoning p95 [cm] | [deg] | update median [ms] |')
    print('|---|---|---|---|---|---|---|---|---|')
    for name, rs in rows:
        cat = {k: np.concatenate([getattr(r, k) for r in rs])
               for k in ('loc_xy', 'loc_yaw', 'odo_xy', 'odo_yaw')}
        secs = [t for r in rs for t in r.seconds]
        print('| %s | %d | %d | %d | %.1f / %.1f | %.2f / %.2f | %.1f | %.2f | %.1f |' % (
            name, len(cat['loc_xy']), len(secs), sum(r.rejected for r in rs),
            100 * np.percentile(cat['loc_xy'], 95), 100 * cat['loc_xy'].max(),
            math.degrees(np.percentile(cat['loc_yaw'], 95)), math.degrees(cat['loc_yaw'].max()),
            100 * np.percentile(cat['odo_xy'], 95), math.degrees(np.percentile(cat['odo_yaw'], 95)),
            1000 * statistics.median(secs)))


if __name__ == '__main__':
    main()
