"""Checks a Kestrel MCAP flight log with an independent reader (the `mcap` package).

Usage: mcap_check.py FILE [--cut]

Reads every message and checks each channel against the flight's own records (the
/kestrel/records channel, the JSON-lines records unchanged): its schema and encodings, its
message count, and its content (each drone's poses and transforms against its pose records,
the events against the behavior, mission and alert records, the stamps against the header's
start time plus `t`). Without --cut the file must be complete: a summary whose statistics
agree with what was read. With --cut (a process killed mid-flight) the file is read linearly
up to the first record that cannot be read, and only what came before is checked.

Prints a JSON summary on stdout (channels with schema and count, records, poses, events,
complete); exits non-zero with the failed check on stderr.
"""

import base64
import json
import math
import os
import sys
from datetime import datetime, timezone

from mcap.reader import NonSeekingReader, make_reader

EVENT_KINDS = {"behavior", "mission", "safety", "collision", "error"}
# Foxglove's fields of each kind, as its schemas define them.
FIELDS = {
    "foxglove.PoseInFrame": {"timestamp", "frame_id", "pose"},
    "foxglove.FrameTransform": {
        "timestamp",
        "parent_frame_id",
        "child_frame_id",
        "translation",
        "rotation",
    },
    "foxglove.Log": {"timestamp", "level", "message", "name", "file", "line"},
    "foxglove.SceneUpdate": {"deletions", "entities"},
    "foxglove.Grid": {
        "timestamp",
        "frame_id",
        "pose",
        "column_count",
        "cell_size",
        "row_stride",
        "cell_stride",
        "fields",
        "data",
    },
}


def fail(text):
    print(f"mcap_check: {text}", file=sys.stderr)
    sys.exit(1)


def check(cond, text):
    if not cond:
        fail(text)


def read(path, cut):
    """(schema name, schema, channel, log_time, decoded JSON) per message, complete?, summary."""
    out = []
    with open(path, "rb") as f:
        reader = NonSeekingReader(f) if cut else make_reader(f)
        try:
            for schema, channel, message in reader.iter_messages(log_time_order=False):
                out.append((schema, channel, message.log_time, json.loads(message.data)))
        except Exception as e:  # a cut file ends in a record that cannot be read
            if not cut:
                fail(f"reading {path}: {e!r}")
            return out, False, None
        summary = None if cut else reader.get_summary()
    return out, True, summary


def near(a, b, tol=1e-9):
    return abs(a - b) <= tol * max(1.0, abs(a), abs(b))


def check_pose(pose_msg, tf_msg, record, drone, stamp_ns):
    for name, msg in (("pose", pose_msg), ("tf", tf_msg)):
        ts = msg["timestamp"]
        check(
            abs(ts["sec"] * 10**9 + ts["nsec"] - stamp_ns) <= 1000,
            f"{name} stamp {ts} of {drone} at t={record['t']}",
        )
    p = pose_msg["pose"]["position"]
    q = pose_msg["pose"]["orientation"]
    check(pose_msg["frame_id"] == "world", f"frame {pose_msg['frame_id']}")
    for k in "xyz":
        check(near(p[k], record[k]), f"{drone} {k} {p[k]} != {record[k]} at t={record['t']}")
        check(near(tf_msg["translation"][k], record[k]), f"{drone} tf {k} at t={record['t']}")
    yaw = 2.0 * math.atan2(q["z"], q["w"])
    d = (yaw - record["yaw"] + math.pi) % (2 * math.pi) - math.pi
    check(abs(d) < 1e-9, f"{drone} yaw {yaw} != {record['yaw']}")
    check(tf_msg["parent_frame_id"] == "world", "tf parent")
    check(tf_msg["child_frame_id"] == drone, f"tf child {tf_msg['child_frame_id']} != {drone}")


def goal_points(goal):
    """The points a goal shows: its path, or its x, y, z target; None for neither."""
    if not isinstance(goal, dict) or goal.get("frame_id") not in (None, "earth"):
        return None
    if isinstance(goal.get("path"), list) and goal["path"]:
        return [list(map(float, p[:3])) for p in goal["path"]]
    if all(isinstance(goal.get(k), (int, float)) for k in "xyz"):
        return [[float(goal[k]) for k in "xyz"]]
    return None


def check_plans(by_topic, header, records, slack):
    """Each behavior's goal and path are drawn when it starts and deleted when it ends."""
    for drone in header["drones"]:
        want = []
        for r in records:
            if r["type"] != "behavior" or r["drone"] != drone:
                continue
            if r["event"] in ("started", "modified"):
                points = goal_points(r.get("goal"))
                if points is not None:
                    want.append(("show", r["id"], points))
            elif r["event"] == "finished":
                want.append(("delete", r["id"], None))
        got = [b for _, b in by_topic.get(f"/{drone}/plan", [])]
        check(0 <= len(want) - len(got) <= slack, f"{drone}: {len(got)} plans of {len(want)}")
        for (kind, bid, points), update in zip(want, got):
            if kind == "delete":
                ids = {d["id"] for d in update["deletions"]}
                check(ids == {f"{bid}/path", f"{bid}/goal"}, f"deleted {ids}")
                continue
            by_id = {e["id"]: e for e in update["entities"]}
            goal = by_id[f"{bid}/goal"]["spheres"][0]["pose"]["position"]
            check([goal["x"], goal["y"], goal["z"]] == points[-1], f"goal {goal} of {bid}")
            if len(points) > 1:
                line = by_id[f"{bid}/path"]["lines"][0]["points"]
                check([[p["x"], p["y"], p["z"]] for p in line] == points, f"path of {bid}")


def check_world(by_topic, header, log_dir):
    """The header's world's obstacles, once."""
    world = header.get("world")
    got = [b for _, b in by_topic.get("/world", [])]
    if not world:
        check(not got, "a world without one in the header")
        return
    path = world if os.path.isabs(world) else os.path.join(log_dir, world)
    if not os.path.exists(path):
        return
    with open(path) as f:
        w = json.load(f)
    check(len(got) == 1, f"{len(got)} world messages")
    entity = got[0]["entities"][0]
    cylinders = len(w.get("poles_xy_m", [])) + len(w.get("cylinders", []))
    check(len(entity["cylinders"]) == cylinders, f"{len(entity['cylinders'])} cylinders")
    check(len(entity["cubes"]) == len(w.get("boxes", [])), f"{len(entity['cubes'])} boxes")
    for c, xy in zip(entity["cylinders"], w.get("poles_xy_m", [])):
        p = c["pose"]["position"]
        check(near(p["x"], xy[0]) and near(p["y"], xy[1]), f"pole at {p}, not {xy}")


def check_grid(by_topic, header, cut):
    """A log with a world ends with its known map (one UINT8 grid); the known cells."""
    grids = [b for _, b in by_topic.get("/map/known", [])]
    if cut or not header.get("world"):
        check(not grids, "a known map in a log without a world or an end")
        return None
    check(len(grids) == 1, f"{len(grids)} known maps")
    g = grids[0]
    cells = base64.b64decode(g["data"])
    check(g["fields"] == [{"name": "known", "offset": 0, "type": 1}], f"fields {g['fields']}")
    check(g["cell_stride"] == 1 and g["row_stride"] == g["column_count"], "strides")
    check(len(cells) % g["column_count"] == 0 and cells, f"{len(cells)} cells")
    check(set(cells) <= {0, 100}, "cells other than 0 and 100")
    return sum(1 for c in cells if c == 100)


def main():
    path = sys.argv[1]
    cut = "--cut" in sys.argv[2:]
    messages, complete, summary = read(path, cut)
    channels = {}
    by_topic = {}
    for schema, channel, log_time, body in messages:
        name = schema.name if schema else ""
        known = channels.setdefault(channel.topic, {"schema": name, "count": 0})
        check(known["schema"] == name, f"{channel.topic} changed schema")
        check(channel.message_encoding == "json", f"{channel.topic} {channel.message_encoding}")
        check(schema.encoding == "jsonschema", f"{channel.topic} schema {schema.encoding}")
        json.loads(schema.data)
        if name in FIELDS:
            check(set(body) == FIELDS[name], f"{channel.topic}: fields {sorted(body)}")
        known["count"] += 1
        by_topic.setdefault(channel.topic, []).append((log_time, body))

    records = [b for _, b in by_topic.get("/kestrel/records", [])]
    check(records, "no record")
    check(channels["/kestrel/records"]["schema"] == "kestrel.FlightLogRecord", "records schema")
    header = records[0]
    check(header["type"] == "header", f"first record {header['type']}")
    start = datetime.strptime(header["start_time"], "%Y-%m-%dT%H:%M:%SZ")
    start_ns = int(start.replace(tzinfo=timezone.utc).timestamp()) * 10**9

    poses = [r for r in records if r["type"] == "pose"]
    events = [r for r in records if r["type"] in EVENT_KINDS]
    tfs = [b for _, b in by_topic.get("/tf", [])]
    # A cut can fall between a record and the messages made of it: at most one behind.
    slack = 1 if cut else 0
    check(0 <= len(poses) - len(tfs) <= slack, f"{len(tfs)} transforms, {len(poses)} poses")
    tf_at = 0
    for drone in header["drones"]:
        mine = [r for r in poses if r["drone"] == drone]
        msgs = by_topic.get(f"/{drone}/pose", [])
        check(mine, f"no pose of {drone}")
        check(channels[f"/{drone}/pose"]["schema"] == "foxglove.PoseInFrame", "pose schema")
        check(0 <= len(mine) - len(msgs) <= slack, f"{drone}: {len(msgs)} of {len(mine)} poses")
        drone_tfs = [t for t in tfs if t["child_frame_id"] == drone]
        for record, (log_time, msg), tf in zip(mine, msgs, drone_tfs):
            stamp = start_ns + round(record["t"] * 1e9)
            check(abs(log_time - stamp) <= 1000, f"log_time {log_time} vs {stamp}")
            check_pose(msg, tf, record, drone, stamp)
        tf_at += len(drone_tfs)
    check(tf_at == len(tfs), "transforms to frames that are no drone's")
    if tfs:
        check(channels["/tf"]["schema"] == "foxglove.FrameTransform", "tf schema")

    logs = [b for _, b in by_topic.get("/events", [])]
    check(0 <= len(events) - len(logs) <= slack, f"{len(logs)} logs, {len(events)} events")
    for record, log in zip(events, logs):
        check(log["name"] == record["drone"], f"log of {log['name']} for {record['drone']}")
        if record["type"] == "behavior":
            want = f"{record['behavior']} {record['event']}"
        else:
            want = f"{record['type']}: {record['reason']}"
        check(log["message"].startswith(want), f"log {log['message']!r}, wanted {want!r}")
        check(log["level"] in (2, 3, 4), f"level {log['level']}")
    if logs:
        check(channels["/events"]["schema"] == "foxglove.Log", "events schema")

    check_plans(by_topic, header, records, slack)
    check_world(by_topic, header, os.path.dirname(os.path.abspath(path)))
    known_cells = check_grid(by_topic, header, cut)

    if not cut:
        check(summary is not None, "no summary")
        stats = summary.statistics
        check(stats.message_count == len(messages), "statistics' message count")
        for cid, count in stats.channel_message_counts.items():
            topic = summary.channels[cid].topic
            check(channels[topic]["count"] == count, f"{topic}: summary says {count}")

    json.dump(
        {
            "channels": channels,
            "records": len(records),
            "poses": len(poses),
            "events": len(events),
            "plans": sum(len(v) for k, v in by_topic.items() if k.endswith("/plan")),
            "world": len(by_topic.get("/world", [])),
            "known_cells": known_cells,
            "complete": complete,
            "last_t": records[-1].get("t"),
        },
        sys.stdout,
    )


if __name__ == "__main__":
    main()
