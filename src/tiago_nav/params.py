"""One way to declare, validate and read a node's parameters (no ROS here).

Each node has one dataclass whose fields are its parameters. A field is declared with
:func:`param`: its default is the parameter's only default, and its unit, meaning and valid
range sit next to it::

    @dataclass(frozen=True)
    class DetectionParams:
        scan_minus_map_threshold: float = param(0.12, '[m] a point this close to the map is the map', ge=0)

A field whose default is itself such a dataclass is *nested*: its fields are parameters of the
same node, read under their own names (so ``NavigationParams.nav.robot_radius`` is
``~robot_radius``). A name used on several levels is one parameter.

:func:`read_params` turns ``~name`` values into an instance, validating each and naming the
parameter in its :class:`ParamError`; :func:`validate` is called by ``__post_init__`` so that a
library user who builds the dataclass by hand gets the same checks. :func:`config_yaml` renders a
node's ``config/<node>.yaml`` (every parameter, its default and its comment) from the dataclass,
and a unit test keeps the shipped files equal to it (``python3 -m tiago_nav.nodes`` rewrites
them).

A parameter declared with ``dynamic=(lo, hi)`` can also be changed while the node runs
(dynamic_reconfigure): ``[lo, hi]`` is its range at start-up and at run time alike, and
:func:`dynamic_fields` is the one table the node's ``cfg/*.cfg`` and docs/ros_api.md are made
from. :func:`replace` checks a change as :func:`read_params` checks a start; :class:`ParamChanges`
holds an accepted change until a control cycle's boundary.
"""
import math
import threading
from dataclasses import MISSING, field, fields

_SENTINEL = object()


class ParamError(ValueError):
    """A parameter has a value its node cannot use; the message names the parameter.

    ``name`` is the parameter's name (without ``~``) when known, ``reason`` the sentence
    without it. Raise ``ParamError(reason, name)`` from a cross-field check in ``__post_init__``.
    """

    def __init__(self, reason, name=None, message=None):
        super().__init__(message or ('%s: %s' % (name, reason) if name else reason))
        self.name, self.reason = name, reason


def param(default, doc='', *, gt=None, ge=None, lt=None, le=None, choices=None, nonempty=False,
          name=None, dynamic=None):
    """A dataclass field for a parameter.

    Args:
        default: the only default; its type (bool, int, float, str, list) is the parameter's.
        doc: unit in brackets and meaning, e.g. ``'[m] base footprint radius'``.
        gt, ge, lt, le: bounds for numbers (``gt=0``: must be > 0).
        choices: the allowed values (strings).
        nonempty: a string or list that must not be empty.
        name: the ROS parameter name when it differs from the field's.
        dynamic: ``(lo, hi)``: a number the node lets change at run time (dynamic_reconfigure),
            within ``[lo, hi]`` (also checked at start-up; the default must lie in it).
    """
    if dynamic is not None:
        lo, hi = dynamic
        if not (isinstance(default, (int, float)) and not isinstance(default, bool)
                and lo <= default <= hi):
            raise TypeError('dynamic parameter: default %r must be a number in [%r, %r]'
                            % (default, lo, hi))
        dynamic = (type(default)(lo), type(default)(hi))
    meta = {'doc': doc, 'gt': gt, 'ge': ge, 'lt': lt, 'le': le, 'choices': choices,
            'nonempty': nonempty, 'name': name, 'param': True, 'dynamic': dynamic}
    if isinstance(default, list):
        return field(default_factory=lambda: list(default), metadata=meta)
    return field(default=default, metadata=meta)


def nested(cls, **overrides):
    """A field holding a nested parameter dataclass (its fields are read as the node's own).

    ``overrides`` replace defaults of its parameters (at any depth, by parameter name), e.g.
    ``nested(LaserModel, laser_model='ideal')``: still one default per use, written once.
    """
    factory = (lambda: build(cls, overrides)) if overrides else cls
    return field(default_factory=factory, metadata={'nested': True, 'cls': cls,
                                                     'overrides': overrides})


def _default(f):
    if f.default is not MISSING:
        return f.default
    if f.default_factory is not MISSING:
        return f.default_factory()
    raise TypeError('parameter field %s has no default' % f.name)


def param_name(f):
    """The ROS parameter name of a dataclass field."""
    return f.metadata.get('name') or f.name


def _kind(f):
    d = _default(f)
    for k in (bool, int, float, str, list):
        if isinstance(d, k):
            return k
    raise TypeError('parameter field %s: unsupported default %r' % (f.name, d))


def check_value(f, value):
    """``value`` converted to the field's type and checked against its range; raises
    :class:`ParamError` with a sentence (without the parameter's name)."""
    kind = _kind(f)
    m = f.metadata
    if kind is bool:
        if not isinstance(value, bool):
            raise ParamError('expected true or false, got %r' % (value,))
    elif kind in (int, float):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParamError('expected a number, got %r' % (value,))
        if kind is int:
            if float(value) != int(value):
                raise ParamError('expected a whole number, got %r' % (value,))
            value = int(value)
        else:
            value = float(value)
        if not math.isfinite(value):
            raise ParamError('expected a finite number, got %r' % (value,))
        for key, ok, word in (('gt', lambda v, b: v > b, '>'), ('ge', lambda v, b: v >= b, '>='),
                              ('lt', lambda v, b: v < b, '<'), ('le', lambda v, b: v <= b, '<=')):
            bound = m.get(key)
            if bound is not None and not ok(value, bound):
                raise ParamError('%r is out of range: must be %s %g' % (value, word, bound))
        if m.get('dynamic') is not None and not m['dynamic'][0] <= value <= m['dynamic'][1]:
            raise ParamError('%r is out of range: must be in [%g, %g]' % ((value,) + m['dynamic']))
    elif kind is str:
        if not isinstance(value, str):
            raise ParamError('expected a string, got %r' % (value,))
    elif kind is list:
        if not isinstance(value, (list, tuple)):
            raise ParamError('expected a list, got %r' % (value,))
        value = list(value)
    if m.get('nonempty') and not value:
        raise ParamError('must not be empty')
    if m.get('choices') is not None and value not in m['choices']:
        raise ParamError('%r is not one of %s' % (value, ', '.join(map(str, m['choices']))))
    return value


def _walk(cls, overrides=None):
    """``(name, field, default)`` of every parameter of ``cls``, nested dataclasses flattened
    (first occurrence of each name wins; outer ``nested(..., name=value)`` overrides win)."""
    out, seen = [], set()

    def walk(c, ov):
        for f in fields(c):
            if f.metadata.get('nested'):
                walk(f.metadata['cls'], {**f.metadata['overrides'], **ov})
            elif f.metadata.get('param'):
                n = param_name(f)
                if n not in seen:
                    seen.add(n)
                    out.append((n, f, ov[n] if n in ov else _default(f)))
    walk(cls, dict(overrides or {}))
    return out


def param_fields(cls):
    """The parameter fields of ``cls``, nested dataclasses flattened (first occurrence of each
    name wins), as ``(name, field)`` pairs in declaration order."""
    return [(n, f) for n, f, _ in _walk(cls)]


def validate(obj):
    """Check every parameter field of the dataclass instance ``obj`` (nested ones too); raise
    :class:`ParamError` naming the first bad one. Call it from ``__post_init__``."""
    for f in fields(obj):
        value = getattr(obj, f.name)
        if f.metadata.get('nested') or not f.metadata.get('param'):
            continue
        try:
            checked = check_value(f, value)
        except ParamError as e:
            raise ParamError(e.reason, param_name(f)) from None
        if checked is not value and type(checked) is not type(value):
            object.__setattr__(obj, f.name, checked)


def build(cls, values, overrides=None):
    """An instance of ``cls`` from a flat ``{param name: value}`` mapping (missing names keep
    their defaults; nested dataclasses get the values of their own fields)."""
    given = {**(overrides or {}), **values}
    kw = {}
    for f in fields(cls):
        if f.metadata.get('nested'):
            kw[f.name] = build(f.metadata['cls'], given, f.metadata['overrides'])
        elif f.metadata.get('param') and param_name(f) in given:
            kw[f.name] = given[param_name(f)]
    return cls(**kw)


def read_params(cls, get, resolve=lambda name: name, prefix='~'):
    """Read every parameter of ``cls`` with ``get(name, default)`` (e.g. ``rospy.get_param``)
    under ``prefix``; return the validated instance.

    Raises :class:`ParamError` whose message names the parameter (``resolve`` turns ``~name``
    into its full name, e.g. ``rospy.resolve_name``).
    """
    values = {}
    for n, f in param_fields(cls):
        key = prefix + n
        raw = get(key, _SENTINEL)
        if raw is _SENTINEL:
            continue
        try:
            values[n] = check_value(f, raw)
        except ParamError as e:
            raise ParamError(e.reason, n, 'parameter %s: %s' % (resolve(key), e.reason)) from None
    try:
        return build(cls, values)
    except ParamError as e:
        if e.name:
            raise ParamError(e.reason, e.name, 'parameter %s: %s'
                             % (resolve(prefix + e.name), e.reason)) from None
        raise


def defaults(cls):
    """``{param name: default}`` of every parameter of ``cls`` (nested flattened)."""
    return {n: d for n, _, d in _walk(cls)}


def _yaml_value(v):
    if isinstance(v, bool):
        return 'true' if v else 'false'
    if isinstance(v, float):
        r = repr(v)     # YAML 1.1 (PyYAML, rosparam) reads 1e-06 as a string, 1.0e-06 as a float
        return r.replace('e', '.0e') if 'e' in r and '.' not in r else r
    if isinstance(v, str):
        return v if v and v.strip() == v and not any(c in v for c in ':#{}[],&*?|<>=!%@`\'"') \
            else '"%s"' % v
    if isinstance(v, list):
        return '[%s]' % ', '.join(_yaml_value(x) for x in v)
    return str(v)


def config_yaml(cls, title):
    """The text of ``config/<node>.yaml`` for the parameter dataclass ``cls``: ``title`` as a
    comment, then every parameter with its default and its documentation."""
    lines = ['# %s' % t for t in title.splitlines()]
    lines.append('# Generated from %s.%s (the only place defaults are written): '
                 'python3 -m tiago_nav.nodes' % (cls.__module__, cls.__name__))
    rows = [(n, _yaml_value(d), f.metadata.get('doc', ''), _range(f)) for n, f, d in _walk(cls)]
    width = max(len('%s: %s' % (n, v)) for n, v, _, _ in rows) + 2
    for n, v, doc, rng in rows:
        comment = '; '.join(x for x in (doc, rng) if x)
        lines.append(('%s: %s' % (n, v)).ljust(width) + ('# ' + comment if comment else '')
                     if comment else '%s: %s' % (n, v))
    return '\n'.join(lines) + '\n'


def _range(f):
    m = f.metadata
    parts = ['%s %g' % (w, m[k]) for k, w in (('gt', '>'), ('ge', '>='), ('lt', '<'), ('le', '<='))
             if m.get(k) is not None]
    if m.get('dynamic') is not None:
        parts.append('in [%g, %g], reconfigurable' % m['dynamic'])
    if m.get('choices'):
        parts.append('one of ' + ', '.join(m['choices']))
    if m.get('nonempty'):
        parts.append('not empty')
    return ', '.join(parts)


def markdown_table(cls):
    """A Markdown table (``| parameter | type | default | meaning |``) of every parameter of
    ``cls`` (nested flattened), for the generated reference (docs/ros_api.md)."""
    def cell(text):
        return str(text).replace('|', '\\|')
    lines = ['| parameter | type | default | meaning |', '|---|---|---|---|']
    for n, f, d in _walk(cls):
        doc = f.metadata.get('doc', '')
        lines.append('| `~%s` | %s | `%s` | %s |' % (
            n, _kind(f).__name__, cell(_yaml_value(d) if d != '' else '""'),
            cell('; '.join(x for x in (doc, _range(f)) if x))))
    return '\n'.join(lines)


# --- run-time changes (dynamic_reconfigure) ----------------------------------------------------
def dynamic_fields(cls):
    """The parameters of ``cls`` (nested flattened) declared with ``dynamic=(lo, hi)``, as
    ``(name, type, default, lo, hi, doc)`` in declaration order: the table a node's
    ``cfg/*.cfg`` and docs/ros_api.md are made from."""
    return [(n, _kind(f), d, f.metadata['dynamic'][0], f.metadata['dynamic'][1],
             f.metadata.get('doc', ''))
            for n, f, d in _walk(cls) if f.metadata.get('dynamic') is not None]


def values(obj):
    """``{param name: value}`` of every parameter of the dataclass instance ``obj`` (nested
    flattened; the first occurrence of a name, as :func:`build` reads it)."""
    out = {}

    def walk(o):
        for f in fields(o):
            if f.metadata.get('nested'):
                walk(getattr(o, f.name))
            elif f.metadata.get('param'):
                out.setdefault(param_name(f), getattr(o, f.name))
    walk(obj)
    return out


def replace(obj, changes):
    """A new instance of ``obj``'s class with the parameters in ``changes`` (``{name: value}``)
    replaced, checked as at start-up (ranges, then the classes' cross-field checks). Only
    parameters declared ``dynamic`` may change: :class:`ParamError` names any other, and any
    value the node cannot use."""
    cls = type(obj)
    dynamic = {n: f for n, f in param_fields(cls) if f.metadata.get('dynamic') is not None}
    checked = {}
    for n, v in changes.items():
        if n not in dynamic:
            raise ParamError('cannot be changed while the node runs', n)
        try:
            checked[n] = check_value(dynamic[n], v)
        except ParamError as e:
            raise ParamError(e.reason, n) from None
    return build(cls, {**values(obj), **checked})


class ParamChanges:
    """Run-time changes of a node's parameters, applied only at a control cycle's boundary.

    ``params`` is the parameter dataclass instance in force; ``apply(new)`` puts a new one in
    force (e.g. hands it to the library objects). :meth:`request` (any thread) checks a change
    (:func:`replace`). While the node is idle it is applied at once; while a control loop runs
    (between :meth:`begin` and :meth:`end`) it waits for the loop's next :meth:`boundary`, so
    that no value changes within a cycle: under lockstep every cycle is computed with one set of
    values, the one in force when the simulator released it.
    """

    def __init__(self, params, apply=lambda new: None):
        self.params = params
        self._apply = apply
        self._pending = None
        self._running = False
        self._lock = threading.Lock()

    @property
    def requested(self):
        """The newest accepted parameters (pending or in force)."""
        with self._lock:
            return self._pending or self.params

    def request(self, changes):
        """Accept ``changes`` (``{name: value}``) on top of the newest accepted parameters and
        return the result; :class:`ParamError` (nothing changes) when refused."""
        with self._lock:
            new = replace(self._pending or self.params, changes)
            self._pending = new
            if not self._running:
                self._flush()
            return new

    def _flush(self):
        new, self._pending = self._pending, None
        if new is not None and new != self.params:
            self._apply(new)
            self.params = new

    def begin(self):
        """A control loop's first cycle starts: what was accepted before is in force."""
        with self._lock:
            self._flush()
            self._running = True

    def boundary(self):
        """Between two cycles of the control loop: what was accepted meanwhile comes in force."""
        with self._lock:
            self._flush()

    def end(self):
        """The control loop ended: changes apply at once again."""
        with self._lock:
            self._running = False
            self._flush()
