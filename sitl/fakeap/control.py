"""Control channel: TCP, one JSON object per line in each direction.

Request: {"cmd": "<name>", "vehicle": 0, ...}; reply: {"ok": true, ...} or
{"ok": false, "error": "..."}. "vehicle" defaults to 0; fault commands also accept "all".
"""
import json
import socket


class ControlServer:
    def __init__(self, port, app, host="127.0.0.1"):
        self.app = app
        self.server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.server.bind((host, port))
        self.server.listen(8)
        self.server.setblocking(False)
        self.clients = {}  # socket -> buffer

    def sockets(self):
        return [self.server] + list(self.clients)

    def owns(self, sock):
        return sock is self.server or sock in self.clients

    def on_readable(self, sock):
        if sock is self.server:
            try:
                conn, _ = self.server.accept()
                conn.setblocking(True)
                conn.settimeout(2.0)
                self.clients[conn] = b""
            except (BlockingIOError, InterruptedError):
                pass
            return
        try:
            data = sock.recv(65536)
        except OSError:
            data = b""
        if not data:
            self.clients.pop(sock, None)
            sock.close()
            return
        buf = self.clients[sock] + data
        while b"\n" in buf:
            line, buf = buf.split(b"\n", 1)
            if not line.strip():
                continue
            reply = self.handle_line(line)
            try:
                sock.sendall((json.dumps(reply) + "\n").encode())
            except OSError:
                self.clients.pop(sock, None)
                sock.close()
                return
        self.clients[sock] = buf

    def handle_line(self, line):
        try:
            req = json.loads(line)
            if not isinstance(req, dict) or "cmd" not in req:
                raise ValueError('expected a JSON object with "cmd"')
            return self.app.handle_control(req)
        except Exception as exc:  # report every error to the client, keep serving
            return {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
