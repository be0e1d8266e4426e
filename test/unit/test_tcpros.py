"""Inbound TCPROS handshakes (tiago_nav.ros.tcpros): a client that connects and sends nothing
must not hold up the next one (rospy reads handshakes one at a time, each with a 60 s socket
timeout). No ROS master needed: rospy's TCPROS server alone."""
import socket
import threading

from rosgraph.network import write_ros_handshake_header
from rospy.impl.tcpros_base import TCPROSServer

from tiago_nav.ros.tcpros import concurrent_handshakes


def test_a_silent_client_does_not_hold_up_the_next_handshake():
    concurrent_handshakes()
    concurrent_handshakes()                  # twice: still one thread per handshake
    server = TCPROSServer(port=0)
    got = threading.Event()
    server.topic_connection_handler = lambda sock, addr, header: got.set() or 'test only'
    server.start_server()
    host, port = server.get_address()
    silent = socket.create_connection(('127.0.0.1', port))   # connects, never sends a header
    try:
        talker = socket.create_connection(('127.0.0.1', port))
        try:
            write_ros_handshake_header(talker, {'topic': '/x', 'callerid': '/test',
                                                'md5sum': '*', 'type': '*'})
            assert got.wait(5.0), 'the second handshake waited for the silent client'
        finally:
            talker.close()
    finally:
        silent.close()
        server.shutdown()
