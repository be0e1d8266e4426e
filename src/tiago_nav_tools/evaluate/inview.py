"""What "in view" means: the one definition that the evaluator, the benchmarks, the test
harness and the tests judge obstacle detection by (docs/detection.md, docs/evaluation.md).

A movable obstacle is **in view** from a base pose, for a laser profile, when in a noise-free
cast of the laser from that pose (:meth:`tiago_nav.sim.scene.Scene.cast`; the walkers' legs
where :func:`place_walkers` puts them) at least
:data:`MIN_BEAMS` *usable* beams hit it, whatever its edges: that many points are enough for
detection to place a circle (a short arc is fitted with the scan's shared radius, see
:mod:`tiago_nav.detection.pipeline`). A beam is usable when

* the profile's laser measures with it: ``tiago`` loses the beams further than
  :data:`USABLE_ANGLE` from the laser's forward axis (they hit the robot's own shell:
  TIAGo's self-hits, :class:`tiago_nav.sim.laser.LaserModel`'s ``self_hit_angle``); ``ideal``
  has none, its whole fan is usable;
* it hits within the detector's ``max_range`` (:data:`MAX_RANGE`: beyond it detection reads
  nothing).

:data:`MIN_BEAMS` is detection's smallest cluster (``min_points``, 5) plus the two points
(:data:`EDGE_LOSS`) the scan's veil filter may drop at an obstacle's edges (the far point of a
depth step, a cylinder's last point before its tangent). A plainer rule, "at least
:data:`PLAIN_BEAMS` usable beams hit it" (detection's ``min_points`` alone), is available
through ``min_beams`` to rescore results (bench/bench_suites.py).

An obstacle that some beam of the cast reaches but that is not in view is **glimpsed**: a
detector may report it (it is no false positive) but need not (it is no miss); when it does, the
centre's error is measured and reported like any other.

Everything here is in the map (= world) frame; angles in radians, lengths in metres.
"""
import math
from collections import namedtuple

import numpy as np

from tiago_nav.detection.pipeline import DetectionParams
from tiago_nav.sim.laser import LaserModel
from tiago_nav.sim.scene import Scene

EDGE_LOSS = 2                                        # [beams] the veil filter's, one per edge
PLAIN_BEAMS = DetectionParams().min_points           # [beams] detection's smallest cluster: 5
MIN_BEAMS = PLAIN_BEAMS + EDGE_LOSS                  # [beams] usable hits needed: 7
USABLE_ANGLE = math.radians(LaserModel().self_hit_angle)   # [rad] 103.5 deg either side (tiago)
MAX_RANGE = DetectionParams().max_range              # [m] the detector reads no farther
PROFILES = ('tiago', 'ideal')

View = namedtuple('View', 'in_view glimpsed beams usable_beams')
View.__doc__ = """The judgement from one pose: ``in_view`` and ``glimpsed`` (sorted indices into
``world.movable_obstacles``), ``beams`` (index -> beams of the cast that hit it) and
``usable_beams`` (index -> of them, usable ones)."""


def usable_angle(profile='tiago'):
    """[rad] how far from the laser's forward axis the ``profile``'s beams are usable: the
    self-hit angle for ``tiago``, the whole fan (pi) for ``ideal``."""
    if profile not in PROFILES:
        raise ValueError('unknown laser profile %r (expected one of %s)'
                         % (profile, ', '.join(PROFILES)))
    return USABLE_ANGLE if profile == 'tiago' else math.pi


def judge_view(ranges, ids, angles, movable_ids, profile='tiago', min_beams=MIN_BEAMS):
    """The :class:`View` of a noise-free cast: ``ranges`` [m] and ``ids`` (body hit per beam,
    -1 for none) at beam ``angles`` [rad] in the laser frame; ``movable_ids``: the body id of
    each movable obstacle, in world order; ``profile``: the laser profile whose usable beams
    count (:func:`usable_angle`); ``min_beams``: usable hits that make an obstacle in view
    (:data:`MIN_BEAMS`; :data:`PLAIN_BEAMS` for the plain rule)."""
    if int(min_beams) < 1:
        raise ValueError('min_beams must be >= 1, got %r' % (min_beams,))
    r = np.asarray(ranges, dtype=float)
    ids = np.asarray(ids)
    a = np.asarray(angles, dtype=float)
    usable = (np.abs(a) <= usable_angle(profile)) & (r <= MAX_RANGE)
    in_view, glimpsed, beams, usable_beams = [], [], {}, {}
    for i, body in enumerate(movable_ids):
        hit = ids == body
        k = int(np.count_nonzero(hit))
        if not k:
            continue
        beams[i] = k
        usable_beams[i] = int(np.count_nonzero(hit & usable))
        (in_view if usable_beams[i] >= min_beams else glimpsed).append(i)
    return View(in_view, glimpsed, beams, usable_beams)


def place_walkers(scene, walkers=None):
    """Put the walkers' legs of ``scene`` (:class:`tiago_nav.sim.scene.Scene`) where one record
    of the evaluator's walker log has them (``walkers``: per walker ``[x, y, vx, vy,
    leg_radius, legs, state]``, ``legs`` the ``(2, 2)`` leg centres [m]); None: outside the
    world's bounds, where no beam reaches (:meth:`~tiago_nav.sim.scene.Scene.walkers_away`,
    where a new scene has them). A walker hides what stands behind it: an obstacle behind a
    walker's legs is not in view."""
    scene.walkers_away()
    for i, row in enumerate((walkers or [])[:len(scene.walker_leg_ids)]):
        scene.set_walker_legs(i, row[5])


def view_from(scene, base_pose=None, profile='tiago', min_beams=MIN_BEAMS):
    """The :class:`View` of the movable obstacles of ``scene``
    (:class:`tiago_nav.sim.scene.Scene`) from ``base_pose`` ``(x, y, yaw)`` (default: the
    scene's current pose) for the laser ``profile``."""
    ranges, ids = scene.cast(base_pose)
    return judge_view(ranges, ids, scene.laser.angles(), scene.movable_ids, profile, min_beams)


def truth(world, base_pose, profile='tiago', min_beams=MIN_BEAMS):
    """``(in_view, glimpsed)``: rows ``(index, x, y, radius)`` of the ``world``'s movable
    obstacles from ``base_pose`` ``(x, y, yaw)`` (a :class:`tiago_nav.sim.world.World`) for
    the laser ``profile``."""
    v = view(world, base_pose, profile, min_beams)
    rows = [(i, world.movable_obstacles[i].x, world.movable_obstacles[i].y,
             world.movable_obstacles[i].radius) for i in range(len(world.movable_obstacles))]
    return [rows[i] for i in v.in_view], [rows[i] for i in v.glimpsed]


def view(world, base_pose, profile='tiago', min_beams=MIN_BEAMS):
    """The :class:`View` of the ``world``'s movable obstacles from ``base_pose``
    ``(x, y, yaw)`` for the laser ``profile`` (a scene of its own, closed after)."""
    with Scene(world) as scene:
        return view_from(scene, base_pose, profile, min_beams)
