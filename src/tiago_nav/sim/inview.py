"""What "in view" means: the one definition that the evaluator, the benchmarks, the test
harness and the tests judge obstacle detection by (docs/detection.md, docs/evaluation.md).

A movable obstacle is **in view** from a base pose when, in a noise-free cast of the laser from
that pose (:meth:`tiago_nav.sim.scene.Scene.cast`):

1. at least :data:`MIN_BEAMS` *usable* beams hit it. A beam is usable when it is within
   :data:`USABLE_ANGLE` of the laser's forward axis (beyond it, the real laser's beams hit the
   robot's own shell: TIAGo's self-hits, :class:`tiago_nav.sim.laser.LaserModel`'s
   ``self_hit_angle``) and hits within the detector's ``max_range`` (beyond it detection reads
   nothing). :data:`MIN_BEAMS` is detection's smallest cluster (``min_points``, 5) plus the two
   points the scan's veil filter may drop at the obstacle's edges (the far point of a depth
   step: the first point of an obstacle seen past a nearer one, a cylinder's last point before
   its tangent);
2. its outline can be measured: at least one of its two silhouette edges is seen, i.e. the
   usable beam just beyond its hits on that side goes past it (no return, or a return farther
   than the obstacle there). With both edges hidden (behind nearer things, or cut by the end of
   the usable fan) its arc says nothing of where it ends, and no fit can place it.

An obstacle some beam of the cast reaches but that is not in view is **glimpsed**: a detector
may report it (it is no false positive) but need not (it is no miss).

Everything here is in the map (= world) frame; angles in radians, lengths in metres.
"""
import math
from collections import namedtuple

import numpy as np

from tiago_nav.detection.pipeline import DetectionParams
from tiago_nav.sim.laser import LaserModel

EDGE_LOSS = 2                                        # [beams] the veil filter's, one per edge
MIN_BEAMS = DetectionParams().min_points + EDGE_LOSS  # [beams] usable hits needed: 7
USABLE_ANGLE = math.radians(LaserModel().self_hit_angle)   # [rad] 103.5 deg either side
MAX_RANGE = DetectionParams().max_range              # [m] the detector reads no farther

View = namedtuple('View', 'in_view glimpsed beams usable_beams')
View.__doc__ = """The judgement from one pose: ``in_view`` and ``glimpsed`` (sorted indices into
``world.movable_obstacles``), ``beams`` (index -> beams of the cast that hit it) and
``usable_beams`` (index -> of them, usable ones)."""


def judge_view(ranges, ids, angles, movable_ids):
    """The :class:`View` of a noise-free cast: ``ranges`` [m] and ``ids`` (body hit per beam,
    -1 for none) at beam ``angles`` [rad] in the laser frame; ``movable_ids``: the body id of
    each movable obstacle, in world order."""
    r = np.asarray(ranges, dtype=float)
    ids = np.asarray(ids)
    a = np.asarray(angles, dtype=float)
    window = np.abs(a) <= USABLE_ANGLE
    usable = window & (r <= MAX_RANGE)
    in_view, glimpsed, beams, usable_beams = [], [], {}, {}
    for i, body in enumerate(movable_ids):
        hit = ids == body
        k = int(np.count_nonzero(hit))
        if not k:
            continue
        beams[i] = k
        use = hit & usable
        usable_beams[i] = int(np.count_nonzero(use))
        if usable_beams[i] >= MIN_BEAMS and _an_edge_is_seen(r, ids, window, hit, body):
            in_view.append(i)
        else:
            glimpsed.append(i)
    return View(in_view, glimpsed, beams, usable_beams)


def _an_edge_is_seen(r, ids, window, hit, body):
    """Whether the usable beam just beyond the obstacle's outermost hit on either side goes
    past it (see the module's doc)."""
    idx = np.flatnonzero(hit & window)
    if not len(idx):
        return False
    for end, step in ((int(idx.min()), -1), (int(idx.max()), 1)):
        j = end + step
        if 0 <= j < len(r) and window[j] and ids[j] != body and r[j] > r[end]:
            return True
    return False


def view_from(scene, base_pose=None):
    """The :class:`View` of the movable obstacles of ``scene``
    (:class:`tiago_nav.sim.scene.Scene`) from ``base_pose`` ``(x, y, yaw)`` (default: the
    scene's current pose)."""
    ranges, ids = scene.cast(base_pose)
    return judge_view(ranges, ids, scene.laser.angles(), scene.movable_ids)


def truth(world, base_pose):
    """``(in_view, glimpsed)``: rows ``(index, x, y, radius)`` of the ``world``'s movable
    obstacles from ``base_pose`` ``(x, y, yaw)`` (a :class:`tiago_nav.sim.world.World`)."""
    from tiago_nav.sim.scene import Scene
    with Scene(world) as scene:
        v = view_from(scene, base_pose)
    rows = [(i, world.movable_obstacles[i].x, world.movable_obstacles[i].y,
             world.movable_obstacles[i].radius) for i in range(len(world.movable_obstacles))]
    return [rows[i] for i in v.in_view], [rows[i] for i in v.glimpsed]
