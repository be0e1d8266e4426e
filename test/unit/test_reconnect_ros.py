"""rospy's registration race, made to happen (tiago_nav.ros.topics): an action client whose
status subscriber missed its server's publisher at start-up is connected again while
``wait_server`` waits, so the server counts as there. On a private roscore; each node is a
process of its own. The race is forced by dropping the master's ``publisherUpdate`` for the
status topic once in the client's process, as a late ``registerSubscriber`` reply does; the
test checks that the client was left without the status connection before it waits."""
import os
import shutil
import socket
import subprocess
import sys
import textwrap
import time

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.skipif(
    shutil.which('roscore') is None, reason='needs roscore (source /opt/ros/*/setup.bash)')]
pytest.importorskip('tiago_nav.msg', reason='needs the built workspace (source .ws/devel/setup.bash)')

SERVER = textwrap.dedent('''
    import actionlib, rospy
    from tiago_nav.msg import CorridorAction
    rospy.init_node('server')
    s = actionlib.SimpleActionServer('/srv', CorridorAction, lambda g: s.set_succeeded(), auto_start=False)
    s.start()
    rospy.spin()
''')

CLIENT = textwrap.dedent('''
    import json, sys, time
    import actionlib, rospy
    import rospy.impl.registration as reg
    from tiago_nav.msg import CorridorAction
    from tiago_nav.ros.actions import server_connected, wait_server
    dropped = []
    update = reg.RegManager.publisher_update

    def lose_once(self, topic, uris):
        if topic == '/srv/status' and uris and not dropped:
            dropped.append(uris)            # the race: this update is overtaken, never acted on
            return
        update(self, topic, uris)
    reg.RegManager.publisher_update = lose_once
    rospy.init_node('client')
    c = actionlib.SimpleActionClient('/srv', CorridorAction)
    print('subscribed', flush=True)
    sys.stdin.readline()                     # the server is up
    ac = c.action_client
    end = time.monotonic() + 20.0
    while not (dropped and ac.result_sub.get_num_connections()) and time.monotonic() < end:
        time.sleep(0.05)
    orphan = ac.status_sub.get_num_connections() == 0 and not server_connected(c)
    t0 = time.monotonic()
    up = wait_server(c, 20.0)
    print(json.dumps({'dropped': bool(dropped), 'orphan': orphan, 'up': up,
                      'wait_s': time.monotonic() - t0}), flush=True)
''')


def free_port():
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def test_an_action_client_that_missed_its_servers_status_finds_it_while_it_waits(tmp_path):
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI='http://127.0.0.1:%d' % port, ROS_IP='127.0.0.1',
               ROS_HOSTNAME='127.0.0.1', ROS_HOME=str(tmp_path), ROS_LOG_DIR=str(tmp_path))
    env.pop('ROS_NAMESPACE', None)
    procs = []
    try:
        procs.append(subprocess.Popen(['roscore', '-p', str(port)], env=env,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        import rosgraph
        master = rosgraph.Master('/test', master_uri=env['ROS_MASTER_URI'])
        end = time.monotonic() + 30.0
        while not master.is_online():
            assert time.monotonic() < end, 'roscore did not come up'
            time.sleep(0.1)
        client = subprocess.Popen([sys.executable, '-c', CLIENT], env=env, stdin=subprocess.PIPE,
                                  stdout=subprocess.PIPE, text=True)
        procs.append(client)
        assert client.stdout.readline().strip() == 'subscribed'
        procs.append(subprocess.Popen([sys.executable, '-c', SERVER], env=env))
        client.stdin.write('go\n')
        client.stdin.flush()
        import json
        out = json.loads(client.stdout.readline())
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(10.0)
            except subprocess.TimeoutExpired:
                p.kill()
    assert out['dropped'] and out['orphan'], out     # the race happened: no status connection
    assert out['up'], out                            # ... and the wait connected it
