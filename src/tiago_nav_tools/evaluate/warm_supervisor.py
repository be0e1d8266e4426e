"""A warm evaluation stack's supervisor: ``python3 -m tiago_nav_tools.evaluate.warm_supervisor STACK_DIR``.

Started by :mod:`tiago_nav_tools.evaluate.warm` with the worker slot's environment (as
:mod:`tiago_nav_tools.evaluate.supervisor`). It keeps one stack (roscore, demo.launch) for rows that
share world, sensing profile and candidate (the corridor law is a goal field), and runs them one after the other.
It reads one run folder per line on stdin (each holds its ``spec.json``) and answers each with
one JSON line on stdout once the run's ``raw.json`` is written:
``{"run_dir": ..., "reset": "fresh" | "reset", "failed": null | "reset" | "infra"}``.

The first run starts the stack as :class:`~tiago_nav_tools.evaluate.supervisor.Supervisor` does; each
later one resets it (:meth:`WarmSupervisor.reset`): every node's ``~reset/stop``, the row's seed
on the simulator's parameter and ``/simulator/reset`` (simulated time goes back to its start),
then ``~reset/start`` on the localisation (its first ``map → odom``, latched, must be out
before the nodes that read it subscribe to tf) and on the other nodes together, and the checks of a fresh start (``/clock`` at
the start, the robot at the world's start, no contact). A reset that fails ends the stack
(answer ``failed: "reset"``, no ``raw.json``): the worker runs that row on a fresh stack. An
infrastructure error in a run ends the stack too (``failed: "infra"``). EOF on stdin, or the
worker's death, stops the stack.
"""
import json
import os
import sys
import time

from tiago_nav_tools.evaluate.supervisor import Infra, Supervisor, watch_parent, write_json

# the nodes of demo.launch that reset, in the order their ~reset/start must come
RESET_ORDER = ('localisation', 'move_base', 'corridor_controller', 'obstacle_detection',
               'tiago_controller')
FIRST = ('localisation',)   # started before the others (they read its map -> odom)
SIMULATOR = 'simulator'
RESET_TIMEOUT = 60.0        # [s wall] the longest a whole reset may take
START_TIME = 1.0            # [s sim] simulated time at a (reset) start in lockstep


class ResetFailed(Exception):
    """A reset did not restore a fresh start's state: the row goes to a fresh stack."""


class WarmSupervisor(Supervisor):
    """:class:`Supervisor` for a sequence of runs on one stack."""

    def __init__(self, stack_dir):
        with open(os.path.join(stack_dir, 'spec.json')) as f:
            first = f.read()
        Supervisor.__init__(self, stack_dir)    # (reads the stack's first row, as its spec)
        self.stack_dir = stack_dir
        self.launched = False
        self.first = json.loads(first)

    def use_run(self, run_dir):
        """The next run: its folder and spec; the per-run records emptied."""
        with open(os.path.join(run_dir, 'spec.json')) as f:
            self.spec = json.load(f)
        self.dir = run_dir
        with self.lock:
            self.path, self.loc_err, self.loc_due = [], [], []
            self.loc_bucket, self.loc_from, self.loc_until, self.loc_missing = None, None, None, 0

    def start(self, name, cmd):
        # the stack's processes log into the stack's folder, not the first run's
        run_dir, self.dir = self.dir, self.stack_dir
        try:
            Supervisor.start(self, name, cmd)
        finally:
            self.dir = run_dir

    def tail(self, name, n=3):
        run_dir, self.dir = self.dir, self.stack_dir
        try:
            return Supervisor.tail(self, name, n)
        finally:
            self.dir = run_dir

    # --- reset -------------------------------------------------------------------------------
    def resettable(self):
        """The nodes of :data:`RESET_ORDER` running on this stack (the master lists their
        ``~reset/stop``)."""
        import rosgraph
        master = rosgraph.Master('/evaluate_probe')
        _, _, services = master.getSystemState()
        names = {name for name, _ in services}
        return [n for n in RESET_ORDER if '/%s/reset/stop' % n in names]

    def _call(self, service, timeout):
        import rospy
        from std_srvs.srv import Trigger
        t0 = time.monotonic()
        try:
            rospy.wait_for_service(service, timeout)
            answer = rospy.ServiceProxy(service, Trigger)()
        except (rospy.ROSException, rospy.ServiceException) as e:
            raise ResetFailed('%s: %s' % (service, e)) from None
        if not answer.success:
            raise ResetFailed('%s: %s' % (service, answer.message))
        self.timings.append((service, time.monotonic() - t0))

    def _call_all(self, services, timeout):
        """:meth:`_call` on each of ``services`` at once; the first failure is raised."""
        import threading
        failed = []

        def call(service):
            try:
                self._call(service, timeout)
            except ResetFailed as e:
                failed.append(e)
        threads = [threading.Thread(target=call, args=(s,), daemon=True) for s in services]
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout + 5.0)
        if failed:
            raise failed[0]
        if any(t.is_alive() for t in threads):
            raise ResetFailed('a ~reset/start did not answer within %g s' % timeout)

    def reset(self):
        """The stack back to a fresh start's state for the current spec (its seed); raises
        :class:`ResetFailed`."""
        import rospy
        t0 = time.monotonic()
        self.timings = []
        self.check_alive_reset()
        nodes = self.resettable()
        for n in nodes:
            self._call('/%s/reset/stop' % n, 5.0)
        with self.lock:
            self.truth = self.truth_msg = None
            self.clock = None
            self.collisions = None
        rospy.set_param('/%s/seed' % SIMULATOR, int(self.spec['seed']))
        self._call('/%s/reset' % SIMULATOR, 20.0)
        # the localisation first (its first map -> odom, latched, before anyone subscribes to
        # tf again), then the others together: a fresh start's order is any order
        first = [n for n in nodes if n in FIRST]
        for group in (first, [n for n in nodes if n not in FIRST]):
            left = RESET_TIMEOUT - (time.monotonic() - t0)
            if left <= 0:
                raise ResetFailed('the reset took more than %g s' % RESET_TIMEOUT)
            self._call_all(['/%s/reset/start' % n for n in group], left)
        # the fresh start's state, as the supervisor sees it
        end = t0 + RESET_TIMEOUT
        while True:
            with self.lock:
                ok = self.clock is not None and self.truth is not None and self.collisions == 0 \
                    and abs(self.truth[0].to_sec() - START_TIME) < 1e-9
                clock = self.clock
            if ok and abs(clock - START_TIME) < 1e-9:
                sys.stderr.write('%s: reset in %.2f s (%s)\n' % (self.spec['id'], time.monotonic() - t0, ', '.join(
                    '%s %.2f' % (name, dt) for name, dt in self.timings)))
                return
            if time.monotonic() > end:
                raise ResetFailed('after the reset: /clock %s, ground truth %s, contacts %s '
                                  '(want %g s, at %g s, 0)' % (
                                      clock, self.truth and self.truth[0].to_sec(),
                                      self.collisions, START_TIME, START_TIME))
            self.check_alive_reset()
            time.sleep(0.01)

    def check_alive_reset(self):
        for name in ('roscore', 'roslaunch'):
            p = self.procs.get(name)
            if p is not None and p.poll() is not None:
                raise ResetFailed('%s exited with %s (see %s.log)' % (name, p.returncode, name))

    def mission_once(self):
        """:meth:`Supervisor.mission`, and then what it subscribed to for the run (its tf
        listener, its action client) unsubscribed: the next run subscribes anew, and its
        action client's new status subscription makes the server send its status at once
        (while simulated time stands still, actionlib's status timer does not run)."""
        from tiago_nav.ros.reset import Generation
        gen = Generation()
        try:
            with gen:
                return self.mission()
        finally:
            self.stage('teardown')      # (the run's end on the stack, for its time breakdown)
            gen.close()

    # --- one run -----------------------------------------------------------------------------
    def run(self, run_dir):
        """One run: start or reset, check the scenario, the mission. Returns the answer line's
        dict; writes ``raw.json`` unless the reset failed."""
        self.use_run(run_dir)
        raw = {'schema': 1, 'id': self.spec['id']}
        answer = {'run_dir': run_dir, 'reset': 'reset' if self.launched else 'fresh', 'failed': None}
        try:
            t0 = time.monotonic()
            if self.launched:
                self.stage('reset')
                self.reset()
            else:
                self.stage('startup')
                self.launched = True
                self.launch()
                self.ready(t0)
            self.scenario()
            raw['startup_wall_s'] = time.monotonic() - t0
            raw['stack'] = answer['reset']
            self.stage('mission')
            raw.update(self.mission_once())
        except ResetFailed as e:
            answer.update(failed='reset', reason=str(e))
            self.stage('reset failed')
            return answer
        except Infra as e:
            raw.update(infra=e.code, reason=str(e))
            answer['failed'] = 'infra'
        except Exception as e:      # noqa: BLE001  (the supervisor's own failure is the run's)
            raw.update(infra='INFRA_LAUNCH', reason='supervisor: %s: %s' % (type(e).__name__, e))
            answer['failed'] = 'infra'
        write_json(os.path.join(run_dir, 'raw.json'), raw)
        self.stage('done')
        return answer


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    sup = WarmSupervisor(argv[0])
    watch_parent(sup)
    out = sys.stdout
    sys.stdout = sys.stderr         # nothing else may write to the answer channel
    try:
        for line in sys.stdin:
            run_dir = line.strip()
            if not run_dir:
                continue
            answer = sup.run(run_dir)
            out.write(json.dumps(answer) + '\n')
            out.flush()
            if answer['failed']:
                break
    finally:
        try:
            import rospy
            rospy.signal_shutdown('stack done')
        except Exception:       # noqa: BLE001
            pass
        sup.stop()
    return 0


if __name__ == '__main__':
    sys.exit(main())
