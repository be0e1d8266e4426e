"""Fakes of the ROS side of a node, for unit tests that drive its decisions without a master."""


class FakeClock:
    """A :mod:`tiago_nav.clock` clock in simulated time: ``sleep(dt)`` advances wall time by
    ``dt`` and, unless ``stalled``, ROS time too, then calls every ``on_advance(dt)`` hook
    (e.g. to move a fake robot). ``shutdown_at``: ROS time at which ``shutdown()`` turns
    True.

    As the real clock's source fails: ``stalled`` alone is a live simulator that has fallen
    behind (ROS time stands still, ``source_dead()`` says ``''``) until the wall time
    ``resume_at`` (None: never); a dead one is ``stalled`` with ``dead`` set to the reason
    ``source_dead()`` gives (as :func:`tiago_nav.clock.source_verdict` would). ``rate``: ROS
    seconds per wall second (a bag played faster or slower than real time)."""

    def __init__(self, t=0.0, shutdown_at=None):
        self.t = float(t)
        self.w = 0.0
        self.rate = 1.0
        self.stalled = False
        self.resume_at = None
        self.dead = ''
        self.asked = 0          # how often source_dead() was asked
        self.shutdown_at = shutdown_at
        self.hooks = []

    def source_dead(self):
        self.asked += 1
        return self.dead

    def now(self):
        return self.t

    def wall(self):
        return self.w

    def sleep(self, dt):
        self.w += dt
        if self.stalled and self.resume_at is not None and self.w >= self.resume_at:
            self.stalled, self.resume_at = False, None
        if not self.stalled:
            self.t += dt * self.rate
            for hook in self.hooks:
                hook(dt * self.rate)

    def shutdown(self):
        return self.shutdown_at is not None and self.t >= self.shutdown_at

    def on_advance(self, hook):
        self.hooks.append(hook)
        return hook


class FakeActionServer:
    """Stands for actionlib's SimpleActionServer in an execute callback: records feedback and
    the terminal state; ``preempt_at`` (a time on ``clock``) makes ``is_preempt_requested``
    turn True then."""

    def __init__(self, clock=None, preempt_at=None):
        self.clock, self.preempt_at = clock, preempt_at
        self.feedback = []
        self.state = None          # 'succeeded' | 'aborted' | 'preempted'
        self.result = None
        self.text = None

    def is_preempt_requested(self):
        return self.preempt_at is not None and self.clock is not None \
            and self.clock.now() >= self.preempt_at

    def is_active(self):
        return self.state is None

    def publish_feedback(self, fb):
        self.feedback.append(fb)

    def _end(self, state, result, text):
        assert self.state is None, 'goal ended twice (%s, then %s)' % (self.state, state)
        self.state, self.result, self.text = state, result, text

    def set_succeeded(self, result=None, text=''):
        self._end('succeeded', result, text)

    def set_aborted(self, result=None, text=''):
        self._end('aborted', result, text)

    def set_preempted(self, result=None, text=''):
        self._end('preempted', result, text)


class FakePublisher:
    """Records what is published."""

    def __init__(self):
        self.messages = []

    def publish(self, msg):
        self.messages.append(msg)

    @property
    def last(self):
        return self.messages[-1] if self.messages else None
