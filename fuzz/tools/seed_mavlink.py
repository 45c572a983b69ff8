#!/usr/bin/env python3
"""Cuts small seed tlogs for the `mavlink` fuzz target out of the captures in shared/traces.

Usage: fuzz/tools/seed_mavlink.py TRACES_DIR OUT_DIR

For each capture: per message id, the first HEARTBEAT then the first three records of that id
(so the session has heard the autopilot when they arrive); and a window of records around every
COMMAND_ACK (the command tracker's and actions' inputs).
"""
import pathlib
import sys


def records(data):
    i = 0
    while i + 10 <= len(data):
        stx, plen = data[i + 8], data[i + 9]
        if stx == 0xFD:
            signed = data[i + 10] & 1 if i + 10 < len(data) else 0
            n = 12 + plen + (13 if signed else 0)
            msgid = int.from_bytes(data[i + 15:i + 18], "little")
        elif stx == 0xFE:
            n = 8 + plen
            msgid = data[i + 13]
        else:
            return
        end = i + 8 + n
        if end > len(data):
            return
        yield msgid, data[i:end]
        i = end


def main():
    traces, out = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
    out.mkdir(parents=True, exist_ok=True)
    for tlog in sorted(traces.glob("*.tlog")):
        recs = list(records(tlog.read_bytes()))
        heartbeat = next((r for m, r in recs if m == 0), b"")
        by_id = {}
        for m, r in recs:
            by_id.setdefault(m, [])
            if len(by_id[m]) < 3:
                by_id[m].append(r)
        stem = tlog.stem
        for m, rs in by_id.items():
            (out / f"{stem}_msg{m}").write_bytes(heartbeat + b"".join(rs))
        acks = [k for k, (m, _) in enumerate(recs) if m == 77]
        for n, k in enumerate(acks[:12]):
            window = [r for m, r in recs[max(0, k - 30):k + 10] if m in (0, 77, 245, 253, 410, 32, 331, 242)]
            (out / f"{stem}_ack{n}").write_bytes(heartbeat + b"".join(window))


main()
