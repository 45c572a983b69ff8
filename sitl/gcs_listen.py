"""A ground station's view, as QGroundControl reads it: listen on a UDP port with pymavlink and
print one JSON line per new (system, component) HEARTBEAT and per STATUSTEXT, the chunks of a
long text (MAVLink 2 `id` and `chunk_seq`) put back together first.

    sitl/.venv/bin/python sitl/gcs_listen.py --port 14550 [--seconds 60]

Lines: {"heartbeat": {"system", "component", "type", "autopilot"}} and
{"statustext": {"system", "component", "severity", "text", "chunks", "complete"}}. Pair it with
the fake autopilot's --gcs-port-base (PX4's MAVLink forwarding) to see what a companion such as
Kestrel shows the operator. Stops on SIGTERM, SIGINT or after --seconds.
"""
import argparse
import json
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from fakeap.mav import mavutil  # noqa: E402

CHUNK = 50


class Reassembler:
    """STATUSTEXT chunks back into texts, as QGroundControl does: `id` 0 is a whole text; else
    chunks of one (system, component, id) are kept until one is shorter than 50 characters (a
    NUL ended it), and joined in `chunk_seq` order. `complete` is False when a chunk is missing."""

    def __init__(self):
        self.pending = {}

    def add(self, system, component, severity, text, msg_id, chunk_seq):
        if msg_id == 0:
            return self._done(system, component, severity, text, 1, True)
        key = (system, component, msg_id)
        parts = self.pending.setdefault(key, {})
        parts[chunk_seq] = text
        if len(text) >= CHUNK:
            return None
        del self.pending[key]
        seqs = sorted(parts)
        complete = seqs == list(range(len(seqs)))
        return self._done(system, component, severity, "".join(parts[s] for s in seqs), len(seqs), complete)

    @staticmethod
    def _done(system, component, severity, text, chunks, complete):
        return {"system": system, "component": component, "severity": severity, "text": text,
                "chunks": chunks, "complete": complete}


def text_of(msg):
    t = msg.text
    if isinstance(t, bytes):
        t = t.decode("ascii", "replace")
    return t.split("\x00", 1)[0]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--seconds", type=float, default=3600.0)
    args = ap.parse_args(argv)
    m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{args.port}", dialect="ardupilotmega",
                                   source_system=255, source_component=190)
    print(json.dumps({"listening": args.port}), flush=True)
    seen = set()
    texts = Reassembler()
    end = time.monotonic() + args.seconds
    while time.monotonic() < end:
        msg = m.recv_match(type=["HEARTBEAT", "STATUSTEXT"], blocking=True, timeout=0.2)
        if msg is None:
            continue
        who = (msg.get_srcSystem(), msg.get_srcComponent())
        if msg.get_type() == "HEARTBEAT":
            if who not in seen:
                seen.add(who)
                print(json.dumps({"heartbeat": {"system": who[0], "component": who[1], "type": msg.type,
                                                "autopilot": msg.autopilot}}), flush=True)
            continue
        done = texts.add(who[0], who[1], msg.severity, text_of(msg), getattr(msg, "id", 0),
                         getattr(msg, "chunk_seq", 0))
        if done is not None:
            print(json.dumps({"statustext": done}), flush=True)


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:
        pass
