"""Inbound TCPROS handshakes that a silent client cannot hold up.

rospy's TCPROS server accepts connections in one thread and reads each one's handshake header
in that same thread (``TCPServer.run`` leaves "threading decisions up to inbound_handler", and
rospy's handler takes none), with the 60 s socket timeout rospy sets for every socket. One
client that connects and sends nothing therefore keeps every other subscriber of that node
waiting for up to 60 s (ros/ros_comm#1918). Seen in ``start_order.test`` with two busy loops:
the simulator accepted no /scan, tick or tf subscriber for 60 s ("Inbound TCP/IP connection
failed: timed out"), move_base gave up on /scan and the mission failed.

:func:`concurrent_handshakes` waits for each connection's header in a thread of its own, then
hands the connection to rospy's own handler, one connection at a time as rospy does: rospy's
handlers are not written to run concurrently (a publisher drops an older connection of the same
subscriber while that one's handshake may still be writing). A subscriber that opened two
connections to the same topic keeps the later one, as with rospy's accept order.
"""
import itertools
import socket
import struct
import threading
import time

from rosgraph.network import ROSHandshakeException, decode_ros_handshake_header
from rospy.core import logwarn
from rospy.impl import tcpros_base

HEADER_TIMEOUT = 60.0      # [s wall] the longest wait for a header: rospy's socket timeout
PARTIAL_POLL = 0.005       # [s wall] re-read period while only part of a header has come

_handle_lock = threading.Lock()
_accepted = itertools.count()
_newest = {}               # (topic, callerid) -> accept number of its newest handled connection


def peek_header(sock, timeout=HEADER_TIMEOUT):
    """The handshake header waiting on ``sock``, decoded but left unread for rospy's handler:
    a ``{str: str}``, or None once the peer has closed. Raises socket.timeout when no whole
    header has come within ``timeout`` wall seconds and ROSHandshakeException when it is
    malformed."""
    end = time.monotonic() + timeout
    need = 4
    while True:
        left = end - time.monotonic()
        if left <= 0:
            raise socket.timeout('no handshake header within %g s' % timeout)
        sock.settimeout(left)
        data = sock.recv(max(need, 4096), socket.MSG_PEEK)
        if not data:
            return None
        if len(data) >= 4:
            need = 4 + struct.unpack('<I', data[:4])[0]
            if len(data) >= need:
                return decode_ros_handshake_header(data[:need])
        time.sleep(PARTIAL_POLL)        # part of the header has come: the rest is on its way


def concurrent_handshakes():
    """Make this process's TCPROS server wait for each inbound handshake in a thread of its own.
    Call before ``rospy.init_node`` (the server takes its handler when it starts); calling it
    again does nothing."""
    server = tcpros_base.TCPROSServer
    if getattr(server, '_handshake_threads', False):
        return
    handle = server._tcp_server_callback

    def wait_then_handle(self, sock, client_addr, number):
        timeout = sock.gettimeout()
        try:
            header = peek_header(sock, timeout or HEADER_TIMEOUT)
        except (OSError, ROSHandshakeException) as e:
            logwarn('Inbound TCP/IP connection from %s:%s failed: %s'
                    % (client_addr[0], client_addr[1], e))
            sock.close()
            return
        sock.settimeout(timeout)
        with _handle_lock:
            if header and 'topic' in header:
                key = (header['topic'], header.get('callerid'))
                if _newest.get(key, -1) > number:
                    sock.close()         # the subscriber's newer connection is already in use
                    return
                _newest[key] = number
            handle(self, sock, client_addr)

    def callback(self, sock, client_addr):
        threading.Thread(target=wait_then_handle, args=(self, sock, client_addr, next(_accepted)),
                         name='tcpros-handshake %s:%s' % tuple(client_addr[:2]),
                         daemon=True).start()

    server._tcp_server_callback = callback
    server._handshake_threads = True
