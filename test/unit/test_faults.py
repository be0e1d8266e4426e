"""Laser fault injection (tiago_nav.sim.faults): the commands, their durations in simulated
time, and what each fault does to the ranges."""
import math

import numpy as np
import pytest

from tiago_nav.sim.faults import Fault, FaultError, LaserFaults, parse_fault


@pytest.mark.parametrize('text, fault', [
    ('nan', Fault('nan')), ('zero 0.5', Fault('zero', 0.5)), ('  FREEZE   2 ', Fault('freeze', 2.0)),
    ('dead 1e-3', Fault('dead', 0.001)), ('none', None)])
def test_commands(text, fault):
    assert parse_fault(text) == fault


@pytest.mark.parametrize('text', ['', ' ', 'blind', 'nan 0', 'nan -2', 'nan inf', 'nan nan',
                                  'nan x', 'zero 1 2', 'none 1'])
def test_bad_commands_are_refused(text):
    with pytest.raises(FaultError):
        parse_fault(text)


class Laser:
    """A healthy laser whose every reading differs from the last."""

    def __init__(self, n=5):
        self.n, self.calls = n, 0

    def __call__(self):
        self.calls += 1
        return np.full(self.n, float(self.calls))


def test_no_fault_passes_the_sensor_through():
    f, laser = LaserFaults(5), Laser()
    assert f.scan(0.0, laser).tolist() == [1.0] * 5
    assert f.scan(0.1, laser).tolist() == [2.0] * 5


def test_nan_and_zero_for_a_while_then_healthy():
    f, laser = LaserFaults(5), Laser()
    assert 'for 0.5 s' in f.command('nan 0.5', 1.0)
    assert np.isnan(f.scan(1.0, laser)).all() and np.isnan(f.scan(1.49, laser)).all()
    assert f.scan(1.5, laser).tolist() == [1.0] * 5        # ran out; the sensor measured once
    f.command('zero', 2.0)
    assert f.scan(100.0, laser).tolist() == [0.0] * 5      # until cleared
    assert f.command('none', 100.0) == 'laser fault cleared'
    assert f.active(100.0) is None
    assert f.scan(100.0, laser).tolist() == [2.0] * 5


def test_dead_gives_no_scan():
    f, laser = LaserFaults(5), Laser()
    f.command('dead 1', 0.0)
    assert f.scan(0.0, laser) is None and f.scan(0.99, laser) is None
    assert laser.calls == 0
    assert f.scan(1.0, laser) is not None


def test_freeze_repeats_the_last_scan():
    f, laser = LaserFaults(5), Laser()
    f.scan(0.0, laser)
    f.scan(0.1, laser)                                     # the last scan reads 2.0
    f.command('freeze 1', 0.15)
    assert [f.scan(t, laser)[0] for t in (0.2, 0.5, 1.1)] == [2.0, 2.0, 2.0]
    assert f.scan(1.15, laser)[0] == 3.0                    # then measures again
    f.command('freeze', 2.0)
    assert f.scan(2.0, laser)[0] == 3.0


def test_freeze_before_any_scan_freezes_the_first():
    f, laser = LaserFaults(5), Laser()
    f.command('freeze', 0.0)
    assert [f.scan(t, laser)[0] for t in (0.0, 0.1, 0.2)] == [1.0, 1.0, 1.0]


def test_a_bad_command_keeps_the_fault_in_force():
    f = LaserFaults(5)
    f.command('dead', 0.0)
    with pytest.raises(FaultError):
        f.command('nan -1', 1.0)
    assert f.active(5.0) == Fault('dead', math.inf)
