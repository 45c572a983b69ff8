#!/usr/bin/env python3
"""Tiny client for the fake autopilot's control channel.

    python sitl/ctl.py [--port 15999] state
    python sitl/ctl.py link_drop vehicle=0 duration_s=5
    python sitl/ctl.py '{"cmd": "setpoint_stats", "reset": true}'
key=value arguments are parsed as JSON values when possible (numbers, true/false, null, "all").
"""
import argparse
import json
import socket
import sys


def request(req, host="127.0.0.1", port=15999, timeout_s=5.0):
    with socket.create_connection((host, port), timeout=timeout_s) as s:
        s.sendall((json.dumps(req) + "\n").encode())
        return json.loads(s.makefile("rb").readline())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=15999)
    ap.add_argument("cmd")
    ap.add_argument("fields", nargs="*", metavar="key=value")
    a = ap.parse_args()
    if a.cmd.startswith("{"):
        req = json.loads(a.cmd)
    else:
        req = {"cmd": a.cmd}
        for kv in a.fields:
            k, _, v = kv.partition("=")
            try:
                req[k] = json.loads(v)
            except json.JSONDecodeError:
                req[k] = v
    reply = request(req, a.host, a.port)
    print(json.dumps(reply, indent=1))
    return 0 if reply.get("ok") else 1


if __name__ == "__main__":
    sys.exit(main())
