"""Suite files: parsing, validation and expansion into frozen runs (no ROS).

A suite file (YAML, docs/evaluation.md) names worlds (files, or the seeded generator
:func:`tiago_nav.sim.worlds.rooms_world`), poses B per world (listed, or sampled reachable with
:func:`tiago_nav_tools.evaluate.matching.sample_goals`), sensing profiles (mapped to sim.launch's
arguments), the corridor law on/off, seeds and candidates. :func:`expand` turns it into runs:
plain dicts, each with an ``id`` hashed from its row (world content, goal, profile, law, seed,
candidate, limits) and an explicit ``seed``. The same suite gives the same ids anywhere.

Any problem raises :class:`SuiteError` naming the file, the field and the reason (exit 2).
"""
import copy
import hashlib
import json
import math
import os

import yaml

SCHEMA = 1
ROLES = {   # candidate role -> (launch arg that disables the built-in node, interface)
    'navigation': ('navigation', 'action move_base (move_base_msgs/MoveBaseAction)'),
    'corridor': ('corridor', 'action corridor_controller (tiago_nav/CorridorAction)'),
    'detection': ('detection', 'service obstacle_detection (tiago_nav/DetectObstacles)'),
}
PROFILE_KEYS = {   # profile key -> (launch arg, allowed values or a type)
    'laser_model': ('laser_model', ('tiago', 'ideal')),
    'odometry_model': ('odometry_model', ('drift', 'ideal')),
    'localisation': ('localisation', ('scan_matching', 'ground_truth')),
    'laser_noise': ('laser_noise', float),
}
DEFAULT_PROFILES = {'tiago': {'laser_model': 'tiago', 'odometry_model': 'drift',
                              'localisation': 'scan_matching', 'laser_noise': 0.01}}
DEFAULTS = {'real_time_factor': 0.0, 'sim_time_limit': 180.0, 'wall_time_limit': 300.0,
            'startup_timeout': 90.0, 'detection_tolerance': 0.05, 'check_timeout': 30.0}
TOP_KEYS = ('name', 'description', 'defaults', 'worlds', 'profiles', 'corridor_law', 'seeds',
            'candidates')
OWN = 'own'     # the project's own nodes: every suite's baseline candidate


class SuiteError(ValueError):
    """A bad suite file or argument: ``file: field: reason``."""

    def __init__(self, path, field, reason):
        super().__init__('%s: %s: %s' % (path, field, reason))
        self.path, self.field, self.reason = path, field, reason


def _num(path, field, v, lo=None, positive=False, integer=False):
    ok = (isinstance(v, int) if integer else isinstance(v, (int, float))) and not isinstance(v, bool)
    if not ok or (not integer and not math.isfinite(v)):
        raise SuiteError(path, field, 'must be %s, got %r' % ('an integer' if integer else 'a number', v))
    if positive and v <= 0:
        raise SuiteError(path, field, 'must be > 0, got %r' % v)
    if lo is not None and v < lo:
        raise SuiteError(path, field, 'must be >= %g, got %r' % (lo, v))
    return v


def _keys(path, field, d, allowed, required=()):
    if not isinstance(d, dict):
        raise SuiteError(path, field, 'must be a mapping, got %r' % (d,))
    extra = sorted(set(map(str, d)) - set(allowed))
    if extra:
        raise SuiteError(path, field, 'unknown key(s) %s (expected some of %s)'
                         % (', '.join(extra), ', '.join(allowed)))
    for k in required:
        if k not in d:
            raise SuiteError(path, field, 'missing %r' % k)


def canonical_hash(obj, n=12):
    """First ``n`` hex digits of the SHA-256 of ``obj``'s canonical JSON (sorted keys)."""
    text = json.dumps(obj, sort_keys=True, separators=(',', ':'))
    return hashlib.sha256(text.encode()).hexdigest()[:n]


NOT_HASHED = ('id', 'pair', 'world_file')     # derived, or where the file lies on this machine


def run_id(row):
    """A run's id: the hash of its row (everything but :data:`NOT_HASHED`)."""
    return canonical_hash({k: v for k, v in row.items() if k not in NOT_HASHED})


def pair_key(row):
    """What a candidate's run shares with the own nodes' run on the same scenario."""
    return canonical_hash({k: v for k, v in row.items()
                           if k not in NOT_HASHED + ('candidate', 'candidate_spec')})


def load(path):
    """Parse and validate the suite file ``path``; returns ``(suite dict, base directory)``."""
    if not os.path.isfile(path):
        raise SuiteError(path, '(file)', 'no such file')
    try:
        with open(path) as f:
            data = yaml.safe_load(f)
    except yaml.YAMLError as e:
        raise SuiteError(path, '(file)', 'not valid YAML: %s' % e) from None
    validate(data, path)
    return data, os.path.dirname(os.path.abspath(path))


def validate(data, path='<suite>'):
    """Raise :class:`SuiteError` for the first problem of the parsed suite ``data``."""
    _keys(path, '(top level)', data, TOP_KEYS, ('worlds',))
    d = data.get('defaults') or {}
    _keys(path, 'defaults', d, tuple(DEFAULTS))
    for k, v in d.items():
        _num(path, 'defaults.%s' % k, v, lo=0.0, positive=k != 'real_time_factor')
    worlds = data['worlds']
    if not isinstance(worlds, list) or not worlds:
        raise SuiteError(path, 'worlds', 'must be a non-empty list')
    for i, w in enumerate(worlds):
        f = 'worlds[%d]' % i
        _keys(path, f, w, ('file', 'generate', 'poses', 'label'))
        if ('file' in w) == ('generate' in w):
            raise SuiteError(path, f, 'needs exactly one of file or generate')
        if 'file' in w and not isinstance(w['file'], str):
            raise SuiteError(path, f + '.file', 'must be a path, got %r' % (w['file'],))
        if 'generate' in w:
            g = w['generate']
            _keys(path, f + '.generate', g, ('count', 'seed', 'movable', 'static', 'partition_probability'),
                  ('count',))
            _num(path, f + '.generate.count', g['count'], lo=1, integer=True)
            _num(path, f + '.generate.seed', g.get('seed', 0), lo=0, integer=True)
            for k in ('movable', 'static'):
                if k in g and not (isinstance(g[k], list) and len(g[k]) == 2
                                   and all(isinstance(x, int) and x >= 0 for x in g[k])
                                   and g[k][0] <= g[k][1]):
                    raise SuiteError(path, '%s.generate.%s' % (f, k), 'must be [min, max] counts, got %r' % (g[k],))
        poses = w.get('poses')
        if poses is None:
            raise SuiteError(path, f + '.poses', 'missing (a list of [x, y, yaw_deg] or {sample: N, seed: S})')
        if isinstance(poses, dict):
            _keys(path, f + '.poses', poses, ('sample', 'seed', 'clearance'), ('sample',))
            _num(path, f + '.poses.sample', poses['sample'], lo=1, integer=True)
            _num(path, f + '.poses.seed', poses.get('seed', 0), lo=0, integer=True)
            _num(path, f + '.poses.clearance', poses.get('clearance', 0.65), positive=True)
        elif isinstance(poses, list) and poses:
            for j, p in enumerate(poses):
                if not (isinstance(p, list) and len(p) == 3):
                    raise SuiteError(path, '%s.poses[%d]' % (f, j), 'must be [x, y, yaw_deg], got %r' % (p,))
                for k, v in enumerate(p):
                    _num(path, '%s.poses[%d][%d]' % (f, j, k), v)
        else:
            raise SuiteError(path, f + '.poses', 'must be a non-empty list or {sample: N}, got %r' % (poses,))
    profiles = data.get('profiles', DEFAULT_PROFILES)
    if not isinstance(profiles, dict) or not profiles:
        raise SuiteError(path, 'profiles', 'must be a non-empty mapping name -> settings')
    for name, p in profiles.items():
        f = 'profiles.%s' % name
        _keys(path, f, p, tuple(PROFILE_KEYS))
        for k, v in p.items():
            allowed = PROFILE_KEYS[k][1]
            if allowed is float:
                _num(path, '%s.%s' % (f, k), v, lo=0.0)
            elif v not in allowed:
                raise SuiteError(path, '%s.%s' % (f, k), 'must be one of %s, got %r' % (', '.join(allowed), v))
    law = data.get('corridor_law', [True])
    if not isinstance(law, list) or not law or not all(isinstance(x, bool) for x in law):
        raise SuiteError(path, 'corridor_law', 'must be a non-empty list of true/false, got %r' % (law,))
    seeds = data.get('seeds', [0])
    if isinstance(seeds, dict):
        _keys(path, 'seeds', seeds, ('count', 'start'), ('count',))
        _num(path, 'seeds.count', seeds['count'], lo=1, integer=True)
        _num(path, 'seeds.start', seeds.get('start', 0), lo=0, integer=True)
    elif isinstance(seeds, list) and seeds:
        for j, s in enumerate(seeds):
            _num(path, 'seeds[%d]' % j, s, lo=0, integer=True)
    else:
        raise SuiteError(path, 'seeds', 'must be a non-empty list of integers or {count: N, start: S}')
    names = {OWN}
    for i, c in enumerate(data.get('candidates') or []):
        f = 'candidates[%d]' % i
        _keys(path, f, c, ('name', 'replaces', 'command', 'launch', 'check_timeout'), ('name', 'replaces'))
        if not isinstance(c['name'], str) or not c['name'] or c['name'] in names:
            raise SuiteError(path, f + '.name', 'must be a new non-empty name (not %r)' % (c['name'],))
        names.add(c['name'])
        roles = c['replaces'] if isinstance(c['replaces'], list) else [c['replaces']]
        if not roles or any(r not in ROLES for r in roles):
            raise SuiteError(path, f + '.replaces', 'must be some of %s, got %r' % (', '.join(ROLES), c['replaces']))
        if ('command' in c) == ('launch' in c):
            raise SuiteError(path, f, 'needs exactly one of command or launch')
        v = c.get('command', c.get('launch'))
        if not isinstance(v, str) or not v.strip():
            raise SuiteError(path, f + ('.command' if 'command' in c else '.launch'), 'must be a non-empty string')
        if 'check_timeout' in c:
            _num(path, f + '.check_timeout', c['check_timeout'], positive=True)


def _package_root():
    return os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))


def resolve_file(name, base):
    """A world file named in a suite: absolute, relative to the suite file, or to the package."""
    for cand in (name, os.path.join(base, name), os.path.join(_package_root(), name)):
        if os.path.isfile(cand):
            return os.path.abspath(cand)
    return None


def _worlds(data, path, base):
    """``(entry index, world row dict, World, world dict or None)`` for every world."""
    from tiago_nav.sim.world import World, WorldError, load_world
    from tiago_nav.sim.worlds import rooms_world
    out = []
    for i, w in enumerate(data['worlds']):
        if 'file' in w:
            f = resolve_file(w['file'], base)
            if f is None:
                raise SuiteError(path, 'worlds[%d].file' % i, 'no such world file %r' % w['file'])
            try:
                world = load_world(f)
            except WorldError as e:
                raise SuiteError(path, 'worlds[%d].file' % i, str(e)) from None
            with open(f, 'rb') as fh:
                sha = hashlib.sha256(fh.read()).hexdigest()[:12]
            row = {'name': world.name, 'group': w.get('label', world.name), 'file': f, 'sha': sha}
            out.append((i, row, world, None))
        else:
            g = w['generate']
            kw = {k: (tuple(g[k]) if isinstance(g[k], list) else g[k]) for k in g
                  if k in ('movable', 'static', 'partition_probability')}
            for k in range(g['count']):
                s = g.get('seed', 0) + k
                d = rooms_world(s, **kw)
                world = World.from_dict(d, source='rooms_world(%d)' % s)
                row = {'name': d['name'], 'group': w.get('label', 'generated rooms'),
                       'generate': dict(g, seed=s, count=1), 'sha': canonical_hash(d)}
                out.append((i, row, world, d))
    return out


def _poses(spec, world, seed_default):
    if isinstance(spec, list):
        return [[float(v) for v in p] for p in spec]
    import numpy as np
    from tiago_nav_tools.evaluate.matching import sample_goals
    rng = np.random.default_rng(spec.get('seed', seed_default))
    return [list(g) for g in sample_goals(world, spec['sample'], rng,
                                          clearance=spec.get('clearance', 0.65))]


def seeds_of(data):
    s = data.get('seeds', [0])
    if isinstance(s, dict):
        return list(range(s.get('start', 0), s.get('start', 0) + s['count']))
    return list(s)


def candidates_of(data):
    """The candidates, the project's own nodes first (``{'name': 'own'}``)."""
    out = [{'name': OWN}]
    for c in data.get('candidates') or []:
        c = dict(c)
        c['replaces'] = c['replaces'] if isinstance(c['replaces'], list) else [c['replaces']]
        out.append(c)
    return out


def expand(data, path='<suite>', base='.'):
    """The suite's runs, in a fixed order: worlds x poses x profiles x corridor law x seeds x
    candidates. Returns ``(runs, generated)``: run dicts and ``{world name: world dict}`` of
    the generated worlds (written out before running)."""
    validate(data, path)
    defaults = dict(DEFAULTS, **(data.get('defaults') or {}))
    profiles = data.get('profiles', DEFAULT_PROFILES)
    runs, generated, seen = [], {}, {}
    for i, wrow, world, wdict in _worlds(data, path, base):
        if wdict is not None:
            generated[wrow['name']] = wdict
        spec = data['worlds'][i]['poses']
        try:
            poses = _poses(spec, world, 0)
        except Exception as e:      # noqa: BLE001  (a world no pose can be sampled in)
            raise SuiteError(path, 'worlds[%d].poses' % i, 'sampling failed: %s' % e) from None
        if not poses:
            raise SuiteError(path, 'worlds[%d].poses' % i, 'no reachable pose in world %s' % wrow['name'])
        for goal in poses:
            for pname in sorted(profiles):
                largs = {PROFILE_KEYS[k][0]: v for k, v in profiles[pname].items()}
                for law in data.get('corridor_law', [True]):
                    for seed in seeds_of(data):
                        for cand in candidates_of(data):
                            row = {'schema': SCHEMA, 'world': {k: v for k, v in wrow.items() if k != 'file'},
                                   'goal': [round(float(v), 4) for v in goal], 'profile': pname,
                                   'launch_args': largs, 'use_corridor_law': law, 'seed': seed,
                                   'candidate': cand['name'],
                                   'candidate_spec': None if cand['name'] == OWN else
                                   {k: v for k, v in cand.items() if k != 'name'},
                                   'limits': {k: defaults[k] for k in sorted(defaults)}}
                            rid = run_id(row)
                            if rid in seen:
                                raise SuiteError(path, 'worlds[%d]' % i, 'run %s listed twice' % rid)
                            seen[rid] = True
                            row = dict(row, id=rid, pair=pair_key(row))
                            if 'file' in wrow:
                                row['world_file'] = wrow['file']      # where it is here (not hashed)
                            runs.append(row)
    return runs, generated


def suite_hash(data):
    return canonical_hash(data)


def freeze(runs):
    """A deep copy of ``runs`` (what the engine ships to workers)."""
    return copy.deepcopy(runs)
