"""The harness's CPU accounting, against processes that burn a known amount of CPU."""
import os
import subprocess
import sys

from tiago_nav_tools.testing.harness import tree_cpu_seconds

BURN = 0.4      # [s of CPU] each process burns
# A child that starts a grandchild in a session of its own (as roslaunch starts its nodes); each
# burns BURN seconds of CPU, then both wait until their stdin closes.
TREE = r'''
import subprocess, sys, time
def burn():
    t0 = time.process_time()
    while time.process_time() - t0 < %g:
        pass
if sys.argv[2:] == ['grandchild']:
    burn(); print('done', flush=True); sys.stdin.read()
else:
    g = subprocess.Popen([sys.executable, '-c', sys.argv[1], sys.argv[1], 'grandchild'],
                         start_new_session=True, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                         text=True)
    burn(); g.stdout.readline(); print('done', flush=True); sys.stdin.read()
    g.stdin.close(); g.wait()
''' % BURN


def test_cpu_of_a_process_tree_counts_children_in_their_own_sessions():
    p = subprocess.Popen([sys.executable, '-c', TREE, TREE], stdin=subprocess.PIPE,
                         stdout=subprocess.PIPE, text=True, start_new_session=True)
    try:
        assert p.stdout.readline().strip() == 'done'      # both have burnt their share
        used = tree_cpu_seconds([p.pid])
        # both burns, plus two interpreter start-ups
        assert 2 * BURN <= used <= 2 * BURN + 0.6
        # this process's tree holds that one; an unknown root holds nothing
        assert tree_cpu_seconds([os.getpid()]) >= used
        assert tree_cpu_seconds([2 ** 22 + 1]) == 0.0
    finally:
        p.stdin.close()
        p.wait(10)
