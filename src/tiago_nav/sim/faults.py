"""Laser faults injected into a running simulator, for tests of what the robot does when its
laser fails (no ROS here; the simulator node takes the commands on ``/sim/laser_fault``).

A command is one line of text:

* ``nan [SECONDS]``: every range NaN (REP 117: invalid);
* ``zero [SECONDS]``: every range 0.0 (finite below ``range_min``: invalid);
* ``freeze [SECONDS]``: the ranges of the last scan again and again, with new stamps (a stuck
  sensor);
* ``dead [SECONDS]``: no scan at all;
* ``none``: clear the fault.

``SECONDS`` is simulated time from the command [s]; without it the fault lasts until cleared.
A new fault replaces the one in force. A command that cannot be understood raises
:class:`FaultError` and changes nothing.
"""
import math
from dataclasses import dataclass

import numpy as np

KINDS = ('nan', 'zero', 'freeze', 'dead')
USAGE = 'expected one of %s followed by an optional SECONDS > 0, or none' % ', '.join(KINDS)


class FaultError(ValueError):
    """A fault command that cannot be understood; the message says why."""


@dataclass(frozen=True)
class Fault:
    """A laser fault of ``kind`` (one of :data:`KINDS`) lasting ``seconds`` [s] of simulated
    time (``inf``: until cleared)."""
    kind: str
    seconds: float = math.inf


def parse_fault(text):
    """The :class:`Fault` a command asks for, None for ``none``; :class:`FaultError` for
    anything else."""
    words = str(text).split()
    if not words:
        raise FaultError('empty command (%s)' % USAGE)
    kind, args = words[0].lower(), words[1:]
    if kind == 'none' and not args:
        return None
    if kind not in KINDS or len(args) > 1:
        raise FaultError('%r is not a fault command (%s)' % (str(text), USAGE))
    if not args:
        return Fault(kind)
    try:
        seconds = float(args[0])
    except ValueError:
        raise FaultError('SECONDS must be a number, got %r' % args[0]) from None
    if not (math.isfinite(seconds) and seconds > 0):
        raise FaultError('SECONDS must be a finite number > 0, got %r' % args[0])
    return Fault(kind, seconds)


class LaserFaults:
    """The fault in force on a laser of ``num_beams`` beams, in simulated time [s]."""

    def __init__(self, num_beams):
        self.num_beams = int(num_beams)
        self.fault = None            # the Fault in force, or None
        self.until = math.inf        # [s] when it ends
        self._last = None            # the ranges of the last scan given out
        self._frozen = None          # the ranges a freeze repeats

    def command(self, text, now):
        """Apply the command ``text`` at simulated time ``now`` [s]. Returns a sentence saying
        what is in force; raises :class:`FaultError` (and changes nothing) for a bad one."""
        fault = parse_fault(text)
        self.fault, self._frozen = fault, None
        if fault is None:
            self.until = math.inf
            return 'laser fault cleared'
        self.until = now + fault.seconds
        if math.isinf(fault.seconds):
            return 'laser fault %s until cleared' % fault.kind
        return 'laser fault %s for %g s of simulated time (until t = %.3f s)' % (
            fault.kind, fault.seconds, self.until)

    def active(self, now):
        """The :class:`Fault` in force at ``now`` [s], or None; one that has run out is cleared."""
        if self.fault is not None and now >= self.until:
            self.fault, self.until, self._frozen = None, math.inf, None
        return self.fault

    def scan(self, now, measure):
        """The ranges [m] the laser gives at ``now`` [s], or None when it gives no scan.

        ``measure()`` returns the healthy sensor's ranges; it is called only when they are used.
        """
        fault = self.active(now)
        kind = fault.kind if fault else None
        if kind == 'dead':
            return None
        if kind == 'nan':
            out = np.full(self.num_beams, np.nan)
        elif kind == 'zero':
            out = np.zeros(self.num_beams)
        elif kind == 'freeze':
            if self._frozen is None:
                self._frozen = self._last if self._last is not None else np.asarray(measure(), float)
            out = self._frozen.copy()
        else:
            out = np.asarray(measure(), dtype=float)
        self._last = out
        return out
