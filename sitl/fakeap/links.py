"""Transports: PX4-style UDP endpoint and ArduPilot-style TCP server (SERIAL0).

Links are non-blocking; the main loop registers their sockets with a selector and calls
``on_readable`` which returns raw byte chunks with their arrival time.
"""
import socket
import time


class UdpLink:
    """Listens on listen_port; sends to 127.0.0.1:remote_port until a peer talks, then
    answers the address the last datagram came from (as PX4 does)."""

    def __init__(self, listen_port, remote_port, host="0.0.0.0"):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind((host, listen_port))
        self.sock.setblocking(False)
        self.default_peer = ("127.0.0.1", remote_port)
        self.peer = self.default_peer
        self.describe = f"udp listen {listen_port} -> 127.0.0.1:{remote_port}"

    def sockets(self):
        return [self.sock]

    def on_readable(self, sock):
        chunks = []
        while True:
            try:
                data, addr = self.sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # e.g. ICMP port unreachable from a previous send
                break
            self.peer = addr
            chunks.append((time.monotonic(), data))
        return chunks

    def send(self, data):
        try:
            self.sock.sendto(data, self.peer)
        except OSError:
            pass  # nobody listening yet: like a real UDP link, drop

    def reset_peer(self):
        self.peer = self.default_peer

    def set_down(self, down):
        pass  # UDP: silence is enough

    def close(self):
        self.sock.close()


class TcpServerLink:
    """TCP server on port; one client at a time (a new client replaces the old one)."""

    def __init__(self, port, host="0.0.0.0"):
        self.server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.server.bind((host, port))
        self.server.listen(4)
        self.server.setblocking(False)
        self.client = None
        self.down = False   # simulated reboot: the autopilot process is gone
        self.describe = f"tcp server {port}"
        self.on_change = None  # callback(selector-relevant sockets changed)

    def sockets(self):
        return [self.server] + ([self.client] if self.client else [])

    def on_readable(self, sock):
        if sock is self.server:
            try:
                conn, _ = self.server.accept()
            except (BlockingIOError, InterruptedError):
                return []
            if self.down:
                conn.close()  # nobody home while rebooting
                return []
            conn.setblocking(False)
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._drop_client()
            self.client = conn
            if self.on_change:
                self.on_change()
            return []
        chunks = []
        while self.client is not None:
            try:
                data = self.client.recv(65535)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                data = b""
            if not data:
                self._drop_client()
                if self.on_change:
                    self.on_change()
                break
            chunks.append((time.monotonic(), data))
        return chunks

    def _drop_client(self):
        if self.client is not None:
            try:
                self.client.close()
            except OSError:
                pass
            self.client = None

    def send(self, data):
        if self.client is None:
            return
        try:
            self.client.sendall(data)
        except (BlockingIOError, InterruptedError):
            pass  # slow reader: drop, as a saturated serial link would
        except OSError:
            self._drop_client()
            if self.on_change:
                self.on_change()

    def reset_peer(self):
        pass

    def set_down(self, down):
        """Reboot of a real ArduPilot (SITL) closes its TCP connection; clients must reconnect."""
        self.down = down
        if down:
            self._drop_client()
            if self.on_change:
                self.on_change()

    def close(self):
        self._drop_client()
        self.server.close()
