"""The maps and frontiers of Kestrel's MCAP flight logs, read with an independent reader.

A real `kestrel explore` (two drones in a generated pole world) and a real `kestrel sim` (the
binary named by $KESTREL_BIN, else target/debug/kestrel) write `--log-format mcap`; the Python
`mcap` package reads the files. Checked: each drone's map (`/<drone>/map`) and the merged map
(`/map`) are `foxglove.Grid` channels with one INT8 `occupancy` field; their message counts fit
the `[map]` update rate and the flight's length (and the log's byte budget per grid topic);
every grid equals the map rebuilt here, with Python's zlib, from the `map` records of
`/kestrel/records` up to that message; the merged map's occupied cells lie on the world's
poles; the frontiers of the `frontiers` records are drawn on `/frontiers` and the goal each
drone holds on `/<drone>/frontier`; a `kestrel sim` killed with SIGKILL leaves grids equal to
what GET /api/map answered before the kill (a drone on the ground: its map stops changing once
the lidar has seen what it can see from there).

Margins: positions of frontiers and goals within 1e-9 m (the MCAP writer parses the JSON records
back, which may move a float by an ulp); an occupied cell within a cell and a half of a pole's
surface or of the world's edge (a hit marks the cell the beam ends in); grid counts within half
of the rate the map rate and the byte budget allow (the records come only when a map changed).
"""

import base64
import json
import math
import os
import signal
import subprocess
import tempfile
import time
import urllib.request
import zlib

import pytest
from conftest import free_port, wait_until
from mcap.reader import NonSeekingReader, make_reader

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
# One INT8 field (Foxglove's NumericType 2), as a ROS OccupancyGrid: -1 unknown, else 0..100.
GRID_FIELDS = [{"name": "occupancy", "offset": 0, "type": 2}]
# flightlog::grids::GRID_BYTES_PER_S: the most base64 bytes a second of grids on one topic.
GRID_BYTES_PER_S = 32_000
EXPLORE_S = 20


def kestrel_binary():
    binary = os.environ.get("KESTREL_BIN") or os.path.join(REPO, "target", "debug", "kestrel")
    assert os.access(binary, os.X_OK), f"no kestrel binary at {binary} (cargo build, or set KESTREL_BIN)"
    return binary


def env():
    e = dict(os.environ)
    e.pop("KESTREL_API_TOKEN", None)
    return e


def read_mcap(path, cut=False):
    """Every message in file order: (topic, schema name, log_time ns, JSON body); a cut file is
    read up to its first unreadable record."""
    out = []
    with open(path, "rb") as f:
        reader = NonSeekingReader(f) if cut else make_reader(f)
        try:
            for schema, channel, message in reader.iter_messages(log_time_order=False):
                assert channel.message_encoding == "json", channel.topic
                assert schema.encoding == "jsonschema", channel.topic
                out.append((channel.topic, schema.name, message.log_time, json.loads(message.data)))
        except Exception:
            if not cut:
                raise
    return out


class Maps:
    """Each map rebuilt from the `map` records: key ("own", drone) or ("merged", None)."""

    def __init__(self):
        self.maps = {}

    def apply(self, record):
        spec = record["grid"]
        key = (record["map"], record["drone"])
        width, height = spec["width_cells"], spec["height_cells"]
        if key not in self.maps or self.maps[key][0] != spec:
            self.maps[key] = (spec, [-1] * (width * height))
        cells = self.maps[key][1]
        x0, y0, w, h = record["region"]
        raw = zlib.decompress(base64.b64decode(record["cells"]))
        assert len(raw) == w * h, f"{len(raw)} cells for a {w}x{h} region"
        values = [b - 256 if b > 127 else b for b in raw]
        for row in range(h):
            start = (y0 + row) * width + x0
            cells[start:start + w] = values[row * w:(row + 1) * w]

    def topic_key(self, topic):
        return ("merged", None) if topic == "/map" else ("own", topic.split("/")[1])


def grid_mismatch(msg, spec, cells):
    """Why the foxglove.Grid `msg` is not the map (`spec`, `cells`) cut to a rectangle with
    every known cell inside; None when it is."""
    if msg["fields"] != GRID_FIELDS or msg["cell_stride"] != 1 or msg["frame_id"] != "world":
        return f"fields {msg['fields']}, cell stride {msg['cell_stride']}, frame {msg['frame_id']}"
    r = spec["resolution_m"]
    if msg["cell_size"] != {"x": r, "y": r} or msg["pose"]["orientation"] != {"x": 0, "y": 0, "z": 0, "w": 1}:
        return f"cell size {msg['cell_size']}, orientation {msg['pose']['orientation']}"
    x0 = (msg["pose"]["position"]["x"] - spec["origin_enu_m"][0]) / r
    y0 = (msg["pose"]["position"]["y"] - spec["origin_enu_m"][1]) / r
    if abs(x0 - round(x0)) > 1e-6 or abs(y0 - round(y0)) > 1e-6:
        return f"corner {msg['pose']['position']} off the grid's cells"
    data = [b - 256 if b > 127 else b for b in base64.b64decode(msg["data"])]
    x0, y0, w = round(x0), round(y0), msg["column_count"]
    if msg["row_stride"] != w or len(data) % w:
        return f"{len(data)} cells in rows of {w} (stride {msg['row_stride']})"
    h = len(data) // w
    width = spec["width_cells"]
    if x0 < 0 or y0 < 0 or x0 + w > width or y0 + h > spec["height_cells"]:
        return f"{w}x{h} at ({x0}, {y0}) leaves the grid"
    inside = 0
    for row in range(h):
        want = cells[(y0 + row) * width + x0:(y0 + row) * width + x0 + w]
        if data[row * w:(row + 1) * w] != want:
            return f"row {row} differs"
        inside += sum(1 for v in want if v != -1)
    if inside != sum(1 for v in cells if v != -1):
        return "known cells outside the grid"
    return None


@pytest.fixture(scope="module")
def explored():
    """An exploration of two drones logged as MCAP: (messages, world, directory)."""
    with tempfile.TemporaryDirectory() as d:
        world = os.path.join(d, "world.json")
        subprocess.run([kestrel_binary(), "world", "generate", "--size-m", "12", "--poles", "4",
                        "--seed", "1", "--out", world], check=True, env=env(), capture_output=True)
        # Unfinished after EXPLORE_S s of simulated time, it exits non-zero: enough for the log.
        subprocess.run([kestrel_binary(), "explore", "--world", world, "--drones", "2",
                        "--max-sim-time-s", str(EXPLORE_S), "--log", "ex.mcap", "--log-format", "mcap"],
                       cwd=d, env=env(), capture_output=True, timeout=300)
        with open(world) as f:
            w = json.load(f)
        yield read_mcap(os.path.join(d, "ex.mcap")), w


def records_of(messages):
    return [body for topic, _, _, body in messages if topic == "/kestrel/records"]


def test_each_drones_map_and_the_merged_map_at_the_map_rate(explored):
    messages, _ = explored
    records = records_of(messages)
    header = records[0]
    rate_hz = header["config"]["map"]["update_rate_hz"]
    flight_s = max(r["t"] for r in records)
    assert flight_s >= EXPLORE_S - 1, flight_s
    for topic in ("/drone_0/map", "/drone_1/map", "/map"):
        grids = [(t, body) for top, schema, t, body in messages if top == topic]
        assert grids, f"no {topic}"
        assert {schema for top, schema, _, _ in messages if top == topic} == {"foxglove.Grid"}
        # At most one a map period from t = 0 on, and the last state when the log closed.
        assert len(grids) <= math.floor(flight_s * rate_hz) + 2, f"{topic}: {len(grids)} grids"
        period_ns = 1e9 / rate_hz
        times = [t for t, _ in grids]
        gaps = [b - a for a, b in zip(times, times[1:-1])]
        # An update's last band may come a few ticks after it was due (the host writes at most
        # 32 Ki cells a tick, for all maps): a tenth of a period (5 ticks at 100 Hz) of slack.
        assert all(g >= 0.9 * period_ns for g in gaps), f"{topic}: gaps {min(gaps)} ns"
        # At least half the map rate, or of what the byte budget allows the largest grid.
        largest = max(len(body["data"]) for _, body in grids)
        rate = min(rate_hz, GRID_BYTES_PER_S / largest)
        assert len(grids) >= 0.5 * flight_s * rate, f"{topic}: {len(grids)} grids in {flight_s} s"


def test_every_grid_is_the_map_of_the_records_so_far(explored):
    messages, _ = explored
    maps = Maps()
    checked = {}
    for topic, schema, _, body in messages:
        if topic == "/kestrel/records" and body["type"] == "map":
            maps.apply(body)
        elif schema == "foxglove.Grid" and topic != "/map/known":
            spec, cells = maps.maps[maps.topic_key(topic)]
            why = grid_mismatch(body, spec, cells)
            assert why is None, f"{topic} grid {checked.get(topic, 0)}: {why}"
            checked[topic] = checked.get(topic, 0) + 1
    assert set(checked) == {"/drone_0/map", "/drone_1/map", "/map"}, checked
    # The merged map knows every cell either drone knows.
    _, merged = maps.maps[("merged", None)]
    for drone in ("drone_0", "drone_1"):
        _, own = maps.maps[("own", drone)]
        assert all(m != -1 for o, m in zip(own, merged) if o != -1), f"{drone}'s cells unknown in /map"


def test_the_merged_maps_obstacles_are_the_worlds_poles(explored):
    messages, world = explored
    records = records_of(messages)
    threshold = records[0]["config"]["map"]["occupied_threshold"]
    last = [body for topic, _, _, body in messages if topic == "/map"][-1]
    r = last["cell_size"]["x"]
    w = last["column_count"]
    data = [b - 256 if b > 127 else b for b in base64.b64decode(last["data"])]
    x0, y0 = last["pose"]["position"]["x"], last["pose"]["position"]["y"]
    occupied = [(x0 + (i % w + 0.5) * r, y0 + (i // w + 0.5) * r) for i, v in enumerate(data) if v >= threshold]
    assert len(occupied) > 10, f"{len(occupied)} occupied cells"
    radius = world["pole_radius_m"]
    (bx0, bx1), (by0, by1) = world["bounds_m"]["x"], world["bounds_m"]["y"]
    seen_poles = set()
    for x, y in occupied:
        # A hit lands in the cell of the pole's surface: within a cell's diagonal of it.
        near = [i for i, (px, py) in enumerate(world["poles_xy_m"])
                if math.hypot(x - px, y - py) <= radius + 1.5 * r]
        at_edge = min(x - bx0, bx1 - x, y - by0, by1 - y) <= 1.5 * r
        assert near or at_edge, f"occupied cell at ({x:.2f}, {y:.2f}) on no pole"
        seen_poles.update(near)
    assert seen_poles, "no pole mapped"


def test_frontiers_are_drawn_as_the_allocator_saw_them(explored):
    messages, _ = explored
    updates = {}
    for topic, schema, _, body in messages:
        if topic == "/frontiers" or topic.endswith("/frontier"):
            assert schema == "foxglove.SceneUpdate", topic
            updates.setdefault(topic, []).append(body)
    records = [r for r in records_of(messages) if r["type"] == "frontiers"]
    assert records, "no frontiers record in an exploration"
    assert len(updates.get("/frontiers", [])) == len(records)
    for record, update in zip(records, updates["/frontiers"]):
        entity = update["entities"][0]
        assert entity["id"] == "frontiers" and entity["frame_id"] == "world"
        assert len(entity["lines"][0]["points"]) == 2 * len(record["frontiers"])
        goals = [[s["pose"]["position"]["x"], s["pose"]["position"]["y"]] for s in entity["spheres"]]
        assert len(goals) == len(record["frontiers"])
        for g, f in zip(goals, record["frontiers"]):
            assert math.dist(g, f["goal_enu_m"]) < 1e-9, f"goal {g} of {f}"

        for f, a, b in zip(record["frontiers"], entity["lines"][0]["points"][::2], entity["lines"][0]["points"][1::2]):
            mid = [(a["x"] + b["x"]) / 2, (a["y"] + b["y"]) / 2]
            assert math.dist(mid, f["centroid_enu_m"]) < 1e-9
            assert abs(math.dist([a["x"], a["y"]], [b["x"], b["y"]]) - f["size_m"]) < 1e-9
    # Each drone's held goal: shown at the claim while it holds one, deleted once when not.
    for drone in ("drone_0", "drone_1"):
        want = []
        held = False
        for record in records:
            claim = [c["goal_enu_m"] for c in record["claims"] if c["drone"] == drone]
            if claim:
                want.append(("goal", claim[0]))
            elif held:
                want.append(("deleted", None))
            held = bool(claim)
        got = updates.get(f"/{drone}/frontier", [])
        assert any(kind == "goal" for kind, _ in want), f"{drone} never held a frontier"
        assert len(got) == len(want), f"{drone}: {len(got)} updates for {len(want)}"
        for (kind, goal), update in zip(want, got):
            if kind == "deleted":
                assert update["deletions"][0]["id"] == f"{drone}/frontier"
                continue
            p = update["entities"][0]["spheres"][0]["pose"]["position"]
            assert math.dist([p["x"], p["y"]], goal) < 1e-9, f"{drone} held {goal}, drawn at {p}"



def get(port, path):
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=10) as r:
            return json.loads(r.read())
    except OSError:
        return None


def wait(what, max_s, f):
    return wait_until(what, max_s, f)


def test_a_killed_sim_leaves_its_grids_up_to_the_last_flush():
    port = free_port()
    with tempfile.TemporaryDirectory() as d:
        log = os.path.join(d, "killed.mcap")
        with open(os.path.join(d, "kestrel.err"), "w") as err:
            proc = subprocess.Popen(
                [kestrel_binary(), "sim", "--no-demo", "--speedup", "5", "--listen", f"127.0.0.1:{port}",
                 "--state-dir", os.path.join(d, "state"), "--log-format", "mcap", "--log", log,
                 "--sensor", "lidar"],
                env=env(), stdout=subprocess.DEVNULL, stderr=err)
            try:
                def known(path):
                    m = get(port, path)
                    return m if m and any(v != -1 for v in m["data"]) else None
                wait("a known map", 30, lambda: known("/api/map"))

                def settled():
                    # On the ground the map stops changing: the same twice, a map period apart.
                    a = (known("/api/map"), known("/api/map?drone=drone_0"))
                    time.sleep(1.0)
                    b = (known("/api/map"), known("/api/map?drone=drone_0"))
                    return a if all(a) and a == b else None
                merged, own = wait("a map that no longer changes", 30, settled)
                # The writer closes a chunk at least every second.
                time.sleep(2.5)
                assert proc.poll() is None, "kestrel exited"
                proc.send_signal(signal.SIGKILL)
                proc.wait(10)
            finally:
                if proc.poll() is None:
                    proc.kill()
                    proc.wait()
        messages = read_mcap(log, cut=True)
    for topic, api in (("/map", merged), ("/drone_0/map", own)):
        grids = [body for top, _, _, body in messages if top == topic]
        assert grids, f"no {topic} before the kill"
        spec = dict(api["spec"])
        why = grid_mismatch(grids[-1], spec, api["data"])
        assert why is None, f"the last {topic}: {why}"
    records = [body for top, _, _, body in messages if top == "/kestrel/records"]
    assert any(r["type"] == "map" for r in records)
    assert not any(top == "/map/known" for top, _, _, _ in messages), "no end, no known map"
