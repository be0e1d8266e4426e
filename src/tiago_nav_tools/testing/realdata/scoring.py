"""An estimate's error against the reference trajectory of a log (pure numpy).

The estimate at each scan is what a tf consumer gets there: the last published pose
(``/amcl_pose``, stamped with the scan it was computed from) carried forward by the odometry
since that scan (``map → odom`` held, ``odom → base`` moving). A localiser that publishes only
on some scans (AMCL: after ``update_min_d`` / ``update_min_a``) is so scored at every scan,
like one that publishes at each.
"""

import numpy as np

from tiago_nav_tools.testing.realdata.carmen import wrap
from tiago_nav_tools.testing.realdata.odometry import compose, relative

LOST = 0.3              # [m] an estimate further than this from the reference is lost
CONVERGED = 0.2         # [m] back within this of the reference: recovered / converged
HOLD = 3                # scans in a row within CONVERGED to count as converged


def estimates_at_scans(times, odom, stamps, poses, tol=1e-4):
    """``(N, 3)`` estimated map poses at the ``N`` scan ``times`` [s] (``nan`` before the first
    estimate) from the estimates ``poses`` ``(M, 3)`` stamped ``stamps`` ``(M,)`` [s] (each a
    scan's time, within ``tol``; others are ignored) and the odometry ``odom`` ``(N, 3)`` at the
    scans: the last estimate at or before each scan composed with the odometry's motion since."""
    times = np.asarray(times, dtype=float)
    odom = np.asarray(odom, dtype=float)
    out = np.full((len(times), 3), np.nan)
    if not len(stamps):
        return out
    stamps = np.asarray(stamps, dtype=float)
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    idx = np.clip(np.searchsorted(times, stamps), 0, len(times) - 1)
    near = np.abs(times[idx] - stamps) <= tol
    prev = np.clip(idx - 1, 0, len(times) - 1)
    near_prev = np.abs(times[prev] - stamps) <= tol
    idx = np.where(near, idx, prev)
    keep = near | near_prev
    latest = np.full(len(times), -1)
    for k, i in zip(np.nonzero(keep)[0], idx[keep]):   # in publication order: the last one wins
        latest[i] = k
    last = -1
    for i in range(len(times)):
        if latest[i] >= 0:
            last = latest[i]
            base = i
            out[i] = poses[last]
        elif last >= 0:
            out[i] = compose(poses[last], relative(odom[base], odom[i]))[0]
    return out


def errors(reference, estimates):
    """``(position error [m], |yaw error| [rad])`` arrays, ``nan`` where there is no estimate."""
    reference, estimates = np.asarray(reference), np.asarray(estimates)
    return (np.hypot(*(estimates[:, :2] - reference[:, :2]).T),
            np.abs(wrap(estimates[:, 2] - reference[:, 2])))


def recovery(err, start=0, tol=CONVERGED, hold=HOLD):
    """Scans from ``start`` until the first of ``hold`` scans in a row within ``tol`` [m] of the
    reference (0: at ``start`` already), or None if that never happens."""
    within = np.asarray(err[start:]) <= tol
    run = 0
    for i, ok in enumerate(within):
        run = run + 1 if ok else 0
        if run >= hold:
            return i - hold + 1
    return None


def lost_episodes(times, err, lost=LOST):
    """``[(first scan, scans, seconds, recovered)]`` of each stretch of scans lost (error over
    ``lost`` [m]); seconds from its first lost scan to the first scan back within ``lost`` (to
    the last scan when it never comes back: ``recovered`` False)."""
    bad = np.asarray(err) > lost
    out, i, n = [], 0, len(bad)
    while i < n:
        if not bad[i]:
            i += 1
            continue
        j = i
        while j < n and bad[j]:
            j += 1
        end = times[j] if j < n else times[-1]
        out.append((int(i), int(j - i), float(end - times[i]), j < n))
        i = j
    return out


def summary(times, reference, estimates, lost=LOST):
    """The figures of a run: error RMS / median / p95 / max [m], yaw p95 [deg], the share of
    time lost (each scan weighted by the time to the next), the lost stretches and the time to
    recover from them, over the scans from the first estimate on."""
    times = np.asarray(times, dtype=float)
    e, y = errors(reference, estimates)
    have = np.isfinite(e)
    if not have.any():
        return {'scans': int(len(times)), 'estimated_scans': 0}
    first = int(np.argmax(have))
    t, e, y = times[first:], e[first:], y[first:]
    dt = np.diff(t)
    w = np.append(dt, np.median(dt) if len(dt) else 1.0)
    bad = e > lost
    episodes = lost_episodes(t, e, lost)
    recovered = [s for _, _, s, ok in episodes if ok]
    conv = recovery(e)
    after = bad[conv:] if conv is not None else bad
    return {
        'scans': int(len(times)),
        'first_estimate_scan': first,
        'rms_m': float(np.sqrt(np.mean(e ** 2))),
        'median_m': float(np.median(e)),
        'p95_m': float(np.percentile(e, 95)),
        'max_m': float(np.max(e)),
        'yaw_p95_deg': float(np.degrees(np.percentile(y, 95))),
        'lost_time_share': float(np.sum(w[bad]) / np.sum(w)),
        'lost_scans': int(np.sum(bad)),
        'lost_episodes': len(episodes),
        'recovered_episodes': len(recovered),
        'time_to_recover_max_s': float(max(recovered)) if recovered else None,
        'never_recovered_from_scan': (first + episodes[-1][0]) if episodes and not episodes[-1][3]
        else None,
        'converged_after_scans': conv,
        'lost_scans_after_converged': int(np.sum(after)) if conv is not None else None,
        'tracked_until_share': float((first + episodes[-1][0]) / len(times))
        if episodes and not episodes[-1][3] else 1.0,
    }
