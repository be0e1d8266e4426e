"""Inbound TCPROS handshakes (tiago_nav.ros.tcpros): a client that connects and sends nothing
must not hold up the next one (rospy reads handshakes one at a time, each with a 60 s socket
timeout), rospy's handler still runs one connection at a time, and of one subscriber's two
connections to a topic the newer stays. No ROS master needed: rospy's TCPROS server alone."""
import socket
import threading
import time

import pytest

pytestmark = pytest.mark.ros         # rospy, rosgraph
pytest.importorskip('rospy')
from rosgraph.network import write_ros_handshake_header, encode_ros_handshake_header  # noqa: E402
from rospy.impl.tcpros_base import TCPROSServer                                       # noqa: E402

from tiago_nav.ros.tcpros import concurrent_handshakes, peek_header                    # noqa: E402

HEADER = {'topic': '/x', 'callerid': '/test', 'md5sum': '*', 'type': '*'}


@pytest.fixture
def server():
    concurrent_handshakes()
    concurrent_handshakes()                  # twice: still one thread per handshake
    s = TCPROSServer(port=0)
    s.handled, s.running, s.overlaps = [], 0, 0
    s.lock = threading.Lock()
    s.cond = threading.Condition()

    def handler(sock, addr, header):
        with s.lock:
            s.running += 1
            s.overlaps += s.running > 1
        time.sleep(0.05)                     # a handler at work: another must not start now
        with s.lock:
            s.running -= 1
        with s.cond:
            s.handled.append(dict(header, port=addr[1]))
            s.cond.notify_all()
        return 'test only'
    s.topic_connection_handler = handler
    s.start_server()
    yield s
    s.shutdown()


def wait_handled(server, n, timeout=5.0):
    with server.cond:
        return server.cond.wait_for(lambda: len(server.handled) >= n, timeout)


def connect(server):
    return socket.create_connection(('127.0.0.1', server.get_address()[1]))


def test_a_silent_client_does_not_hold_up_the_next_handshake(server):
    silent = connect(server)                 # connects, never sends a header
    talker = connect(server)
    try:
        write_ros_handshake_header(talker, HEADER)
        assert wait_handled(server, 1), 'the second handshake waited for the silent client'
    finally:
        talker.close()
        silent.close()


def test_handlers_run_one_at_a_time_and_a_split_header_is_read_whole(server):
    socks = [connect(server) for _ in range(4)]
    try:
        data = encode_ros_handshake_header(dict(HEADER, callerid='/split'))
        socks[0].sendall(data[:7])           # the first arrives in two parts
        for i, s in enumerate(socks[1:]):
            write_ros_handshake_header(s, dict(HEADER, callerid='/c%d' % i))
        time.sleep(0.02)
        socks[0].sendall(data[7:])
        assert wait_handled(server, 4)
        assert server.overlaps == 0
        assert sorted(h['callerid'] for h in server.handled) == ['/c0', '/c1', '/c2', '/split']
    finally:
        for s in socks:
            s.close()


def test_of_one_subscribers_two_connections_the_newer_stays(server):
    older, newer = connect(server), connect(server)
    try:
        header = dict(HEADER, topic='/dup', callerid='/twice')
        write_ros_handshake_header(newer, header)       # the newer's header comes first
        assert wait_handled(server, 1)
        write_ros_handshake_header(older, header)
        older.settimeout(5.0)
        try:
            assert older.recv(1) == b'', 'the older connection was answered'
        except ConnectionResetError:         # closed with its header unread
            pass
        assert [h['port'] for h in server.handled] == [newer.getsockname()[1]]
    finally:
        older.close()
        newer.close()


def test_peek_leaves_the_header_for_rospy():
    a, b = socket.socketpair()
    try:
        write_ros_handshake_header(a, HEADER)
        assert peek_header(b, 1.0) == HEADER
        assert peek_header(b, 1.0) == HEADER             # still there
        a.close()
        c, d = socket.socketpair()
        with pytest.raises(socket.timeout):
            peek_header(d, 0.1)
        c.close()
        assert peek_header(d, 1.0) is None               # the peer closed
        d.close()
    finally:
        b.close()
