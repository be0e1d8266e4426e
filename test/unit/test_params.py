"""The parameter reader (tiago_nav.params) and the shipped config files."""
import os
from dataclasses import dataclass

import pytest

from conftest import ROOT
from tiago_nav.nodes import CONFIG_FILES, config_text
from tiago_nav.params import ParamError, config_yaml, defaults, nested, param, read_params, validate


@dataclass(frozen=True)
class Inner:
    """Inner."""
    radius: float = param(0.27, '[m] radius', gt=0)
    beams: int = param(666, 'count', ge=1)

    def __post_init__(self):
        validate(self)


@dataclass(frozen=True)
class Outer:
    """Outer node."""
    inner: Inner = nested(Inner)
    radius: float = param(0.27, '[m] radius', gt=0)
    frame: str = param('map', 'a frame', nonempty=True)
    method: str = param('a', 'one method', choices=('a', 'b'))
    gui: bool = param(False, 'window')
    start: list = param([], '[x, y, yaw]')
    offset: float = param(0.2, '[m]', name='laser_offset')

    def __post_init__(self):
        validate(self)


def reader(values):
    return lambda name, default: values.get(name, default)


def test_defaults_and_overrides():
    p = read_params(Outer, reader({'~radius': 0.3, '~beams': 10, '~laser_offset': 1}))
    assert p.radius == 0.3 and p.inner.radius == 0.3       # one name, one parameter
    assert p.inner.beams == 10
    assert p.offset == 1.0 and isinstance(p.offset, float)
    assert p.frame == 'map' and p.gui is False and p.start == []
    assert defaults(Outer)['laser_offset'] == 0.2


@pytest.mark.parametrize('values, name', [
    ({'~radius': -1.0}, 'radius'), ({'~radius': 'x'}, 'radius'), ({'~radius': float('nan')}, 'radius'),
    ({'~beams': 1.5}, 'beams'), ({'~beams': 0}, 'beams'), ({'~frame': ''}, 'frame'),
    ({'~method': 'c'}, 'method'), ({'~gui': 1}, 'gui'), ({'~start': 3}, 'start'),
    ({'~laser_offset': True}, 'laser_offset')])
def test_bad_values_name_the_parameter(values, name):
    with pytest.raises(ParamError) as e:
        read_params(Outer, reader(values), resolve=lambda n: '/node/' + n[1:])
    assert str(e.value).startswith('parameter /node/%s: ' % name), str(e.value)


def test_by_hand_construction_is_validated_too():
    with pytest.raises(ParamError, match='radius'):
        Inner(radius=0.0)


def test_config_yaml_lists_every_parameter_once():
    text = config_yaml(Outer, 'Outer node')
    keys = [line.split(':')[0] for line in text.splitlines() if line and not line.startswith('#')]
    assert keys == ['radius', 'beams', 'frame', 'method', 'gui', 'start', 'laser_offset']


@pytest.mark.ros                 # the node modules (their Params) import rospy
@pytest.mark.parametrize('module', sorted(CONFIG_FILES))
def test_shipped_config_equals_the_dataclass_defaults(module):
    """config/*.yaml are rendered from the dataclasses (python3 -m tiago_nav.nodes): a default
    is written once, in code."""
    with open(os.path.join(ROOT, 'config', CONFIG_FILES[module])) as f:
        assert f.read() == config_text(module), 'run: python3 -m tiago_nav.nodes ' + module


@pytest.mark.ros                 # the node modules (their Params) import rospy
@pytest.mark.parametrize('module', sorted(CONFIG_FILES))
def test_shipped_config_reads_back_as_the_defaults(module):
    """rosparam reads YAML 1.1, where 1e-06 is a string: every value reads back as its default
    (a float default 1e-06 is written 1.0e-06)."""
    import importlib

    import yaml
    cls = importlib.import_module('tiago_nav.nodes.' + module).Params
    with open(os.path.join(ROOT, 'config', CONFIG_FILES[module])) as f:
        values = yaml.safe_load(f)
    expected = {k: list(v) if isinstance(v, tuple) else v for k, v in defaults(cls).items()}
    assert values == expected
