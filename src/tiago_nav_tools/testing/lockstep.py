"""Lockstep without ROS: the simulator's step loop and control loops in threads, talking through a
:class:`tiago_nav.lockstep.Gate` as the simulator node and its participants do over topics."""
import queue
import random
import threading
import time

from tiago_nav.lockstep import Ack, ParticipantCore, Tick


class ThreadParticipant(threading.Thread):
    """A control loop in its own thread. At each of its cycles it computes ``law(sim)`` ->
    ``(v, w)`` from the simulator held at the cycle's time, waits a random wall latency in
    ``latency`` [s] (a loaded machine), then answers with the command. ``answers``: how many
    cycles it answers before it goes silent (None: all); ``on_silent(tick)`` is called for each
    tick of a cycle it leaves unanswered (a test can let a fake wall clock run then)."""

    def __init__(self, gate, sim, name, period, law, latency=(0.0, 0.0), seed=0, answers=None,
                 on_silent=None):
        super().__init__(daemon=True)
        self.gate, self.sim, self.name, self.law = gate, sim, name, law
        self.on_silent = on_silent
        self.core = ParticipantCore(period, 0.0)
        self.latency, self.rng, self.answers = latency, random.Random(seed), answers
        self.ticks = queue.Queue()
        self.cycles = []          # stamps [s] of the cycles answered

    def join_schedule(self):
        """The first answer (stamp 0, no command) registers it."""
        self.gate.receive(Ack(self.name, 0.0, self.core.period))

    def run(self):
        while True:
            tick = self.ticks.get()
            if tick is None:
                return
            self.core.on_tick(tick)
            cycle = self.core.next_cycle(tick.stamp)
            if cycle is None:
                continue
            if self.answers is not None and len(self.cycles) >= self.answers:
                if self.on_silent is not None:
                    self.on_silent(tick)
                continue
            stamp = cycle[0]
            cmd = self.law(self.sim)
            time.sleep(self.rng.uniform(*self.latency))
            self.core.answered(stamp)
            self.cycles.append(stamp)
            self.gate.receive(Ack(self.name, stamp, self.core.period, command=cmd))

    def stop(self):
        self.ticks.put(None)


def run_lockstep(sim, gate, participants, seconds):
    """Steps ``sim`` for ``seconds`` of simulated time as the simulator node does in lockstep:
    before each step, :meth:`Gate.hold` (ticks go to every participant), then the commands due
    are applied. Returns the ground-truth poses after each step."""
    def tick(t, waiting):
        for p in participants:
            p.ticks.put(Tick(t))

    for p in participants:
        p.join_schedule()
        p.start()
    poses = []
    try:
        for _ in range(int(round(seconds * sim.config.rate))):
            for v, w in gate.hold(sim.time, tick):
                sim.command(v, w)
            sim.step()
            poses.append(sim.pose)
    finally:
        for p in participants:
            p.stop()
            p.join(timeout=5.0)
    return poses
