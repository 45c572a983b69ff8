"""Fixtures: start the fake autopilot as a subprocess on free ports and talk to it."""
import collections
import json
import os
import threading
import socket
import subprocess
import sys
import time

import pytest

SITL = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, SITL)

from fakeap.mav import mavutil, mavlink  # noqa: E402

_port_counter = [20000 + (os.getpid() % 400) * 100]
# layout of one block: control base, PX4 listen base+1.., PX4 remote base+11.., ArduPilot TCP base+21, +31..
PORT_OFFSETS = (0, 1, 2, 3, 11, 12, 13, 21, 31, 41)


def free_port():
    """A TCP port on 127.0.0.1 free a moment ago (another process may still take it)."""
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def wait_until(what, max_s, f, poll_s=0.2):
    """f()'s first truthy value within max_s seconds; fails naming `what` after that."""
    deadline = time.time() + max_s
    while True:
        v = f()
        if v:
            return v
        assert time.time() < deadline, f"timed out waiting for {what}"
        time.sleep(poll_s)


def free_port_block():
    """A base port whose block (see PORT_OFFSETS) is free."""
    while True:
        _port_counter[0] += 50
        base = _port_counter[0]
        ok = True
        for off in PORT_OFFSETS:
            for kind in (socket.SOCK_DGRAM, socket.SOCK_STREAM):
                s = socket.socket(socket.AF_INET, kind)
                try:
                    s.bind(("127.0.0.1", base + off))
                except OSError:
                    ok = False
                finally:
                    s.close()
        if ok:
            return base


class Fake:
    def __init__(self, personality, extra, speed=1.0):
        base = free_port_block()
        self.control_port = base
        self.personality = personality
        if personality == "px4":
            self.listen, self.remote = base + 1, base + 11
            ports = ["--px4-listen-base", str(self.listen), "--px4-remote-base", str(self.remote)]
        else:
            self.tcp = base + 21
            ports = ["--ardupilot-tcp-base", str(self.tcp)]
        cmd = [sys.executable, os.path.join(SITL, "fake_autopilot.py"), "--personality", personality,
               "--control-port", str(self.control_port), "--speed-factor", str(speed), "--quiet"] + ports + extra
        self.links = []
        self.proc = subprocess.Popen(cmd)
        self.speed = speed
        deadline = time.time() + 10
        while True:
            try:
                self.ctl = socket.create_connection(("127.0.0.1", self.control_port), timeout=5)
                break
            except OSError:
                if time.time() > deadline or self.proc.poll() is not None:
                    raise RuntimeError("fake autopilot did not start")
                time.sleep(0.05)
        self.ctl_file = self.ctl.makefile("rb")

    def control(self, **req):
        self.ctl.sendall((json.dumps(req) + "\n").encode())
        reply = json.loads(self.ctl_file.readline())
        assert reply.get("ok"), reply
        return reply

    def connect(self):
        """pymavlink connection as the companion computer (sysid 1, component 191)."""
        if self.personality == "px4":
            url = f"udpin:127.0.0.1:{self.remote}"
        else:
            url = f"tcp:127.0.0.1:{self.tcp}"
        m = mavutil.mavlink_connection(url, source_system=1 if self.personality == "px4" else 255,
                                       source_component=191 if self.personality == "px4" else 190,
                                       dialect="ardupilotmega")
        m.wait_heartbeat(timeout=10)
        link = Link(m, self)
        self.links.append(link)
        return link

    def stop(self):
        for link in self.links:
            try:
                link.close()
            except Exception:
                pass
        try:
            self.ctl.close()
        except OSError:
            pass
        self.proc.terminate()
        try:
            self.proc.wait(5)
        except subprocess.TimeoutExpired:
            self.proc.kill()


class Link:
    """A pymavlink connection read continuously by a background thread, so that the
    socket's receive buffer never overflows while a test sleeps or streams setpoints
    (a full UDP buffer silently drops datagrams, e.g. a COMMAND_ACK)."""

    def __init__(self, m, fake):
        self.m = m
        self.fake = fake
        self.ts = m.target_system
        self.tc = 1
        self.history = []  # every message received through recv(), in order
        self._queue = collections.deque()
        self._cond = threading.Condition()
        self._stop = False
        self._thread = threading.Thread(target=self._reader, daemon=True)
        self._thread.start()

    def _reader(self):
        while not self._stop:
            try:
                msg = self.m.recv_match(blocking=True, timeout=0.05)
            except Exception:  # socket closed under us
                return
            if msg is not None:
                with self._cond:
                    self._queue.append(msg)
                    self._cond.notify_all()

    def drain(self):
        """Drop everything received so far."""
        with self._cond:
            self._queue.clear()

    def seen_or_recv(self, types, timeout=2.0, cond=None):
        """First matching message already received (e.g. before a COMMAND_ACK), else wait."""
        types = [types] if isinstance(types, str) else types
        for msg in self.history:
            if msg.get_type() in types and (cond is None or cond(msg)):
                return msg
        return self.recv(types, timeout, cond)

    def recv(self, types, timeout=5.0, cond=None):
        types = [types] if isinstance(types, str) else types
        deadline = time.time() + timeout
        while True:
            with self._cond:
                while not self._queue:
                    left = deadline - time.time()
                    if left <= 0:
                        return None
                    self._cond.wait(left)
                msg = self._queue.popleft()
            self.history.append(msg)
            if len(self.history) > 20000:
                del self.history[:10000]
            if msg.get_type() in types and (cond is None or cond(msg)):
                return msg

    def command(self, cmd, *params, timeout=1.5, attempts=2):
        """COMMAND_LONG with one retransmission (confirmation 1), as ground stations do."""
        p = list(params) + [0.0] * (7 - len(params))
        for confirmation in range(attempts):
            self.m.mav.command_long_send(self.ts, self.tc, cmd, confirmation, *p)
            ack = self.recv("COMMAND_ACK", timeout, lambda a: a.command == cmd)
            if ack is not None:
                return ack.result
        raise AssertionError(f"no COMMAND_ACK for {cmd}")

    def heartbeat_until(self, cond, timeout=10.0):
        return self.recv("HEARTBEAT", timeout, lambda h: h.get_srcSystem() == self.ts and cond(h))

    def send_local(self, x=0.0, y=0.0, z=0.0, vx=0.0, vy=0.0, vz=0.0, mask=3576, frame=1):
        self.m.mav.set_position_target_local_ned_send(0, self.ts, self.tc, frame, mask, x, y, z, vx, vy, vz,
                                                      0, 0, 0, 0, 0)

    def companion_heartbeat(self):
        self.m.mav.heartbeat_send(mavlink.MAV_TYPE_ONBOARD_CONTROLLER, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 4)

    def close(self):
        self._stop = True
        self._thread.join(1.0)
        self.m.close()


@pytest.fixture
def fake_factory():
    made = []

    def make(personality, *extra, speed=1.0):
        f = Fake(personality, list(extra), speed)
        made.append(f)
        return f

    yield make
    for f in made:
        f.stop()
