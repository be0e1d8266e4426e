"""Inbound TCPROS handshakes that cannot hold up one another.

rospy's TCPROS server accepts connections in one thread and reads each one's handshake header
in that same thread (``TCPServer.run`` leaves "threading decisions up to inbound_handler", and
rospy's topic handler takes none), with the 60 s socket timeout rospy sets for every socket.
One client that connects and sends nothing (a subscriber given up half-way on a loaded
machine) therefore keeps every other subscriber of that node waiting for up to 60 s: seen in
``start_order.test`` with two busy loops, where the simulator accepted no /scan, tick or tf
subscriber for 60 s ("Inbound TCP/IP connection failed: timed out"), move_base gave up on
/scan after 30 s and the mission failed. :func:`concurrent_handshakes` gives each inbound
connection its own thread for its handshake; a silent client then blocks only itself.
"""
import threading

from rospy.impl import tcpros_base


def concurrent_handshakes():
    """Make this process's TCPROS server read each inbound handshake in a thread of its own.
    Call before ``rospy.init_node`` (the server takes its handler when it starts); calling it
    again does nothing."""
    server = tcpros_base.TCPROSServer
    if getattr(server, '_handshake_threads', False):
        return
    handle = server._tcp_server_callback

    def callback(self, sock, client_addr):
        threading.Thread(target=handle, args=(self, sock, client_addr),
                         name='tcpros-handshake %s:%s' % tuple(client_addr[:2]),
                         daemon=True).start()

    server._tcp_server_callback = callback
    server._handshake_threads = True
