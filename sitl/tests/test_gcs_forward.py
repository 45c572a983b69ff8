"""The fake PX4's ground-station forwarding (--gcs-port-base) and gcs_listen.py's reassembly:
what a companion sends reaches a ground station as QGroundControl would read it."""
import json
import os
import socket
import subprocess
import sys

from conftest import SITL, mavlink as M

sys.path.insert(0, SITL)
from gcs_listen import Reassembler  # noqa: E402


def test_reassembler_joins_chunks_in_order_and_flags_gaps():
    r = Reassembler()
    assert r.add(1, 191, 6, "short", 0, 0)["text"] == "short"
    a, b = "x" * 50, "y" * 50
    assert r.add(1, 191, 6, b, 7, 1) is None  # out of order
    assert r.add(1, 191, 6, a, 7, 0) is None
    done = r.add(1, 191, 6, "end", 7, 2)
    assert (done["text"], done["chunks"], done["complete"]) == (a + b + "end", 3, True)
    # an empty chunk ends a text that filled its chunks; a lost chunk shows as incomplete
    assert r.add(1, 191, 6, a, 8, 0) is None
    assert r.add(1, 191, 6, "", 8, 1)["text"] == a
    assert r.add(1, 191, 6, "tail", 9, 1)["complete"] is False


def free_udp_port():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def test_companion_heartbeat_and_chunked_statustext_reach_the_ground_station(fake_factory):
    gcs = free_udp_port()
    listener = subprocess.Popen([sys.executable, os.path.join(SITL, "gcs_listen.py"), "--port", str(gcs),
                                 "--seconds", "20"], stdout=subprocess.PIPE, text=True)
    try:
        assert "listening" in listener.stdout.readline()
        f = fake_factory("px4", "--gcs-port-base", str(gcs))
        link = f.connect()
        link.companion_heartbeat()
        text = "Kestrel: go_to #2 started (position=[10.0, 0.0, 5.0])"
        assert len(text) > 50
        for seq, start in enumerate(range(0, len(text), 50)):
            link.m.mav.statustext_send(M.MAV_SEVERITY_INFO, text[start:start + 50].encode(), 3, seq)
        # a setpoint for the autopilot is not forwarded (it is addressed to it)
        link.send_local(z=-1.0)
        lines = [json.loads(listener.stdout.readline()) for _ in range(2)]
    finally:
        listener.terminate()
        listener.wait(5)
    assert lines[0] == {"heartbeat": {"system": 1, "component": 191, "type": 18, "autopilot": 8}}
    st = lines[1]["statustext"]
    assert (st["text"], st["chunks"], st["complete"], st["severity"]) == (text, 2, True, 6)
