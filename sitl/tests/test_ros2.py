"""Kestrel's ROS 2 topics checked with implementations that are not Kestrel's.

A real `kestrel sim` (the binary named by $KESTREL_BIN, else target/debug/kestrel, built with
the default features) with `[ros2] enabled` connects to a Zenoh router this test opens with
eclipse-zenoh, standing in for `rmw_zenohd`. A second eclipse-zenoh session, configured as
rmw_zenoh's nodes are (a peer that listens on the loopback and gossips), stands in for a ROS 2
node: it reads the liveliness tokens and checks them against rmw_zenoh's design document
(docs/design.md: token and topic key formats, QoS string, attachment layout); decodes `pose`,
`odom` and `/tf` with the rosbags Jazzy type store and compares them with GET /api/status;
joins `/map` late with Zenoh's advanced subscriber (as rmw_zenoh's transient-local
subscriptions do) and compares it with GET /api/map; sends `goal_pose`s serialized by rosbags:
malformed and refused ones change nothing, a good one is flown. Type hashes are rosbags' own
REP-2011 computation. No ROS 2 installation is used.

Margins: the drone sits on the ground while poses are compared (the simulator's position noise
is centimetres); a goal is reached within 0.3 m on every axis; the simulator runs at 20 times
real time.
"""

import json
import math
import os
import struct
import subprocess
import tempfile
import threading
import time
import urllib.request

import pytest
import zenoh
from conftest import free_port, wait_until
import zenoh.ext as zext
from rosbags.typesys import Stores, get_typestore

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
TYPES = get_typestore(Stores.ROS2_JAZZY)

# rmw's QoS enums (rmw/types.h) and rmw_zenoh's defaults, which its QoS string leaves empty.
RELIABLE = 1
TRANSIENT_LOCAL, VOLATILE = 1, 2
KEEP_LAST = 1
AUTOMATIC = 1
DEFAULT_QOS = {"reliability": RELIABLE, "durability": VOLATILE, "history": KEEP_LAST,
               "depth": 42, "deadline": (0, 0), "lifespan": (0, 0), "liveliness": AUTOMATIC,
               "lease": (0, 0)}

# The drone's topics and the fleet's, as a ROS 2 node would see them: (type, durability, depth).
PUBLISHED = {
    "/drone_0/pose": ("geometry_msgs/msg/PoseStamped", VOLATILE, 10),
    "/drone_0/odom": ("nav_msgs/msg/Odometry", VOLATILE, 10),
    "/drone_0/path": ("nav_msgs/msg/Path", VOLATILE, 10),
    "/tf": ("tf2_msgs/msg/TFMessage", VOLATILE, 10),
    "/map": ("nav_msgs/msg/OccupancyGrid", TRANSIENT_LOCAL, 1),
}
SUBSCRIBED = {"/drone_0/goal_pose": ("geometry_msgs/msg/PoseStamped", VOLATILE, 10)}


def open_session(config):
    return zenoh.open(zenoh.Config.from_json5(json.dumps(config)))


# --- rmw_zenoh's names, written from its design document ------------------------------------

def dds_name(ros_type):
    """`pkg/msg/Type` as rmw_zenoh names it in keys: `pkg::msg::dds_::Type_`."""
    pkg, kind, name = ros_type.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def demangle(part):
    return part.replace("%", "/")


def parse_pair(text, default):
    a, b = text.split(",")
    return (int(a) if a else default[0], int(b) if b else default[1])


def parse_qos(text):
    """rmw_zenoh's compact QoS: `rel:dur:hist,depth:dl_s,dl_ns:ls_s,ls_ns:liv,lease_s,lease_ns`,
    each field left empty where it equals the default."""
    parts = text.split(":")
    assert len(parts) == 6, f"QoS {text!r}: {len(parts)} fields"
    history, depth = parts[2].split(",")
    liveliness, lease_s, lease_ns = parts[5].split(",")
    d = DEFAULT_QOS
    return {
        "reliability": int(parts[0]) if parts[0] else d["reliability"],
        "durability": int(parts[1]) if parts[1] else d["durability"],
        "history": int(history) if history else d["history"],
        "depth": int(depth) if depth else d["depth"],
        "deadline": parse_pair(parts[3], d["deadline"]),
        "lifespan": parse_pair(parts[4], d["lifespan"]),
        "liveliness": int(liveliness) if liveliness else d["liveliness"],
        "lease": (int(lease_s) if lease_s else d["lease"][0], int(lease_ns) if lease_ns else d["lease"][1]),
    }


def parse_token(key):
    """`@ros2_lv/<domain>/<zid>/<nid>/<id>/<kind>/<enclave>/<namespace>/<node>` and, for an
    endpoint, `/<topic>/<type>/<hash>/<qos>`; names mangled (`/` as `%`)."""
    parts = key.split("/")
    assert parts[0] == "@ros2_lv", key
    assert all(parts), f"empty component in {key}"
    kind = parts[5]
    assert kind in ("NN", "MP", "MS", "SS", "SC"), key
    assert len(parts) == (9 if kind == "NN" else 13), f"{len(parts)} components: {key}"
    token = {"domain": int(parts[1]), "zid": parts[2], "nid": int(parts[3]), "id": int(parts[4]),
             "kind": kind, "enclave": demangle(parts[6]), "namespace": demangle(parts[7]),
             "node": demangle(parts[8])}
    if kind != "NN":
        token.update(topic=demangle(parts[9]), type=parts[10], hash=parts[11], qos=parse_qos(parts[12]))
    return token


def topic_key(domain, topic, dds_type, type_hash):
    """`<domain>/<fully qualified name without the leading />/<type>/<hash>`."""
    return f"{domain}/{topic.lstrip('/')}/{dds_type}/{type_hash}"


def parse_attachment(raw):
    """Sequence number (int64 LE), source timestamp (int64 LE, ns since the epoch), the GID's
    length (one byte, 16), the GID."""
    assert len(raw) == 33, f"attachment of {len(raw)} bytes"
    seq, ts_ns, gid_len = struct.unpack_from("<qqB", raw)
    assert gid_len == 16, gid_len
    return seq, ts_ns, bytes(raw[17:33])


def attachment(seq, gid):
    return struct.pack("<qqB", seq, time.time_ns(), 16) + gid


def test_the_parsers_read_rmw_zenohs_own_examples():
    # Tokens and a key as docs/design.md of rmw_zenoh shows them for demo_nodes_cpp.
    t = parse_token("@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MS/%/%/listener/%chatter/"
                    "std_msgs::msg::dds_::String_/RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
                    "/::,10:,:,:,,")
    assert (t["domain"], t["nid"], t["id"], t["kind"], t["namespace"], t["node"], t["topic"]) == (
        2, 0, 10, "MS", "/", "listener", "/chatter")
    assert t["qos"] == dict(DEFAULT_QOS, depth=10)
    assert t["hash"] == TYPES.hash_rihs01("std_msgs/msg/String")
    assert parse_token("@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener")["kind"] == "NN"
    assert topic_key(0, "/robot1/chatter", dds_name("std_msgs/msg/String"), t["hash"]) == (
        "0/robot1/chatter/std_msgs::msg::dds_::String_/" + t["hash"])


# --- the running Kestrel ---------------------------------------------------------------------

class Ros:
    """The router, the ROS-node stand-in, what it heard, and Kestrel's API."""

    def __init__(self):
        self.zenoh_port, self.api_port = free_port(), free_port()
        self.endpoint = f"tcp/127.0.0.1:{self.zenoh_port}"
        self.lock = threading.Lock()
        self.tokens = {}  # key -> alive
        self.router = self.node = self.token_sub = self.proc = self.log = None

    def open_router(self):
        endpoint = self.endpoint
        self.router = open_session({
            "mode": "router", "listen": {"endpoints": [endpoint]},
            "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": True, "multihop": False}},
        })
        self.node = open_session({
            "mode": "peer", "connect": {"endpoints": [endpoint]},
            "listen": {"endpoints": ["tcp/127.0.0.1:0"]},
            "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": True, "multihop": False}},
        })

        def on_token(sample):
            with self.lock:
                self.tokens[str(sample.key_expr)] = sample.kind == zenoh.SampleKind.PUT

        self.token_sub = self.node.liveliness().declare_subscriber("@ros2_lv/0/**", on_token, history=True)

    def start_kestrel(self, tmp):
        config = os.path.join(tmp, "kestrel.toml")
        with open(config, "w") as f:
            # State at 1 Hz: at --speedup 20 one period is 20 s of flight, longer than the goal
            # test's whole hop, whose planned path must still be sent.
            f.write(f'[ros2]\nenabled = true\nrate_hz = 1.0\nconnect = ["{self.endpoint}"]\n')
        binary = os.environ.get("KESTREL_BIN") or os.path.join(REPO, "target", "debug", "kestrel")
        assert os.access(binary, os.X_OK), f"no kestrel binary at {binary} (cargo build, or set KESTREL_BIN)"
        env = dict(os.environ)
        env.pop("KESTREL_API_TOKEN", None)
        self.log = open(os.path.join(tmp, "kestrel.err"), "w")
        self.proc = subprocess.Popen(
            [binary, "sim", "--no-demo", "--speedup", "20", "--listen", f"127.0.0.1:{self.api_port}",
             "--state-dir", os.path.join(tmp, "state"), "--log", os.path.join(tmp, "flight.jsonl"),
             "--config", config, "--sensor", "lidar"],
            env=env, stdout=subprocess.DEVNULL, stderr=self.log)
        self.wait("kestrel's API", 30, lambda: self.get("/api/health") is not None)

    def get(self, path):
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{self.api_port}{path}", timeout=10) as r:
                return json.loads(r.read())
        except OSError:
            assert self.proc.poll() is None, "kestrel exited"
            return None

    def wait(self, what, max_s, f):
        return wait_until(what, max_s, f, poll_s=0.1)

    def graph(self):
        """Kestrel's live tokens, parsed, once the node and all its endpoints are there."""
        def complete():
            with self.lock:
                live = [parse_token(k) for k, alive in self.tokens.items() if alive]
            pubs = {t["topic"] for t in live if t["kind"] == "MP"}
            subs = {t["topic"] for t in live if t["kind"] == "MS"}
            nodes = [t for t in live if t["kind"] == "NN"]
            return live if nodes and pubs >= set(PUBLISHED) and subs >= set(SUBSCRIBED) else None
        return self.wait("the ROS graph's tokens", 30, complete)

    def key(self, topic):
        t = next(t for t in self.graph() if t.get("topic") == topic)
        return topic_key(t["domain"], topic, t["type"], t["hash"])

    def collect(self, topic):
        """Every sample on the topic from now on: (payload, attachment or None)."""
        got = []

        def on_sample(s):
            a = s.attachment.to_bytes() if s.attachment is not None else None
            with self.lock:
                got.append((s.payload.to_bytes(), a))
        sub = self.node.declare_subscriber(self.key(topic), on_sample)
        return got, sub

    def close(self):
        if self.proc is not None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
            self.log.close()
        if self.token_sub is not None:
            self.token_sub.undeclare()
        for session in (self.node, self.router):
            if session is not None:
                session.close()


def run_kestrel(router_first):
    with tempfile.TemporaryDirectory() as tmp:
        r = Ros()
        try:
            if router_first:
                r.open_router()
            r.start_kestrel(tmp)
            yield r
        finally:
            r.close()
            err = os.path.join(tmp, "kestrel.err")
            if os.path.exists(err):
                with open(err) as f:
                    print("kestrel stderr (last lines):\n" + "".join(f.readlines()[-20:]))


@pytest.fixture(scope="module")
def ros():
    yield from run_kestrel(router_first=True)


@pytest.fixture
def ros_before_the_router():
    yield from run_kestrel(router_first=False)


def drone_0(status):
    return status["drones"][0]


def yaw_of(q):
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


def angle_diff(a, b):
    return abs((a - b + math.pi) % (2 * math.pi) - math.pi)


def test_the_liveliness_tokens_follow_rmw_zenohs_format(ros):
    graph = ros.graph()
    zids = {str(ros.router.info.zid()), str(ros.node.info.zid())}
    nodes = [t for t in graph if t["kind"] == "NN"]
    assert len(nodes) == 1, nodes
    node = nodes[0]
    assert (node["domain"], node["enclave"], node["namespace"], node["node"]) == (0, "/", "/", "kestrel")
    assert node["id"] == node["nid"], "a node's entity id is its node id"
    zid = node["zid"]
    assert all(c in "0123456789abcdef" for c in zid) and 1 <= len(zid) <= 32, zid
    assert zid not in zids, "the tokens name Kestrel's own session"
    endpoints = [t for t in graph if t["kind"] != "NN"]
    assert len({t["id"] for t in graph}) == len(graph), "entity ids are unique"
    for t in endpoints:
        assert (t["zid"], t["nid"], t["node"], t["namespace"], t["enclave"]) == (zid, node["nid"], "kestrel", "/", "/"), t
    found = {(t["kind"], t["topic"]): t for t in endpoints}
    assert set(found) == {("MP", k) for k in PUBLISHED} | {("MS", k) for k in SUBSCRIBED}, sorted(found)
    for kind, table in (("MP", PUBLISHED), ("MS", SUBSCRIBED)):
        for topic, (ros_type, durability, depth) in table.items():
            t = found[(kind, topic)]
            assert t["type"] == dds_name(ros_type), t
            assert t["hash"] == TYPES.hash_rihs01(ros_type), f"{topic}: {t['hash']}"
            assert t["qos"] == dict(DEFAULT_QOS, durability=durability, depth=depth), f"{topic}: {t['qos']}"


def test_pose_odom_and_tf_match_the_status(ros):
    streams = {topic: ros.collect(topic) for topic in ("/drone_0/pose", "/drone_0/odom", "/tf")}
    ros.wait("3 samples on each topic", 20, lambda: all(len(got) >= 3 for got, _ in streams.values()))
    status = drone_0(ros.get("/api/status"))
    with ros.lock:
        samples = {topic: list(got) for topic, (got, _) in streams.items()}
    for _, sub in streams.values():
        sub.undeclare()
    truth, yaw = status["position_enu_m"], status["yaw_rad"]
    now_ns = time.time_ns()
    gids = {}
    for topic, got in samples.items():
        last_seq = None
        for _, raw in got:
            assert raw is not None, f"{topic}: a sample without an attachment"
            seq, ts_ns, gid = parse_attachment(raw)
            assert last_seq is None or seq == last_seq + 1, f"{topic}: sequence {last_seq} then {seq}"
            last_seq = seq
            assert abs(ts_ns - now_ns) < 30e9, f"{topic}: source timestamp {ts_ns} vs now {now_ns}"
            gids.setdefault(topic, set()).add(gid)
    assert all(len(g) == 1 for g in gids.values()), "one GID per publisher"
    assert len({next(iter(g)) for g in gids.values()}) == 3, "publishers' GIDs differ"

    def close_to(p):
        return all(abs(a - b) < 0.05 for a, b in zip(p, truth))

    for payload, _ in samples["/drone_0/pose"]:
        msg = TYPES.deserialize_cdr(payload, "geometry_msgs/msg/PoseStamped")
        assert msg.header.frame_id == "world"
        p, q = msg.pose.position, msg.pose.orientation
        assert close_to((p.x, p.y, p.z)), f"pose {p} vs status {truth}"
        assert abs(math.hypot(math.hypot(q.x, q.y), math.hypot(q.z, q.w)) - 1) < 1e-9
        assert angle_diff(yaw_of(q), yaw) < 0.05, f"yaw {yaw_of(q)} vs status {yaw}"
        stamp_ns = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        assert abs(stamp_ns - now_ns) < 30e9, "stamped with the wall clock"
    for payload, _ in samples["/drone_0/odom"]:
        msg = TYPES.deserialize_cdr(payload, "nav_msgs/msg/Odometry")
        assert (msg.header.frame_id, msg.child_frame_id) == ("world", "drone_0/base_link")
        p = msg.pose.pose.position
        assert close_to((p.x, p.y, p.z)), f"odom {p} vs status {truth}"
        assert angle_diff(yaw_of(msg.pose.pose.orientation), yaw) < 0.05
        v = msg.twist.twist.linear
        assert math.sqrt(v.x ** 2 + v.y ** 2 + v.z ** 2) < 0.1, f"the drone on the ground moves at {v}"
    for payload, _ in samples["/tf"]:
        msg = TYPES.deserialize_cdr(payload, "tf2_msgs/msg/TFMessage")
        frames = {(t.header.frame_id, t.child_frame_id): t.transform for t in msg.transforms}
        assert set(frames) == {("world", "drone_0/base_link")}, set(frames)
        tr = frames[("world", "drone_0/base_link")]
        assert close_to((tr.translation.x, tr.translation.y, tr.translation.z))
        assert angle_diff(yaw_of(tr.rotation), yaw) < 0.05


def map_matches(grid, api):
    """The OccupancyGrid is /api/map's grid cut to a rectangle; every cell outside is unknown."""
    spec, data = api["spec"], api["data"]
    info = grid.info
    r = spec["resolution_m"]
    if abs(info.resolution - r) > 1e-6 or grid.header.frame_id != "world":
        return f"resolution {info.resolution} vs {r}, frame {grid.header.frame_id}"
    x0 = (info.origin.position.x - spec["origin_enu_m"][0]) / r
    y0 = (info.origin.position.y - spec["origin_enu_m"][1]) / r
    if abs(x0 - round(x0)) > 1e-6 or abs(y0 - round(y0)) > 1e-6:
        return f"origin {info.origin.position} off the grid's cells"
    x0, y0, w, h = round(x0), round(y0), info.width, info.height
    if len(grid.data) != w * h or x0 < 0 or y0 < 0 or x0 + w > spec["width_cells"] or y0 + h > spec["height_cells"]:
        return f"{w}x{h} at ({x0}, {y0}) does not fit {spec}"
    q = info.origin.orientation
    if (q.x, q.y, q.z, q.w) != (0, 0, 0, 1):
        return f"origin rotated: {q}"
    width = spec["width_cells"]
    inside = 0
    for row in range(h):
        api_row = data[(y0 + row) * width + x0:(y0 + row) * width + x0 + w]
        if list(grid.data[row * w:(row + 1) * w]) != api_row:
            return f"row {row} differs"
        inside += sum(1 for v in api_row if v != -1)
    if sum(1 for v in data if v != -1) != inside:
        return "known cells outside the rectangle"
    return None


def test_map_to_a_late_joiner_matches_the_api(ros):
    key = ros.key("/map")
    # Kestrel has published its map (the lidar sees the world from the ground) before this joins.
    ros.wait("a known map", 20, lambda: any(v != -1 for v in (ros.get("/api/map") or {"data": [-1]})["data"]))
    time.sleep(2)
    got = []

    def on_sample(s):
        with ros.lock:
            got.append(s.payload.to_bytes())
    joined_ns = time.time_ns()
    # As rmw_zenoh's transient-local subscription: history with late publisher detection.
    sub = zext.declare_advanced_subscriber(
        ros.node, key, on_sample,
        history=zext.HistoryConfig(detect_late_publishers=True, max_samples=1),
        recovery=zext.RecoveryConfig(heartbeat=True), subscriber_detection=True)
    try:
        grids = ros.wait("/map", 10, lambda: [TYPES.deserialize_cdr(b, "nav_msgs/msg/OccupancyGrid")
                                             for b in list(got)])
        first = grids[0].header.stamp
        assert first.sec * 10**9 + first.nanosec < joined_ns, "the first /map was made before joining"

        def latest_matches():
            with ros.lock:
                latest = TYPES.deserialize_cdr(got[-1], "nav_msgs/msg/OccupancyGrid")
            return map_matches(latest, ros.get("/api/map")) is None
        if not latest_matches():
            # The map may change between the sample and the GET: it is sent again when it does.
            ros.wait("a /map equal to /api/map", 15, latest_matches)
        with ros.lock:
            latest = TYPES.deserialize_cdr(got[-1], "nav_msgs/msg/OccupancyGrid")
        assert any(v != -1 for v in latest.data), "the map has known cells"
    finally:
        sub.undeclare()


def pose_stamped(frame, x, y, z, yaw=0.0):
    t = TYPES.types
    msg = t["geometry_msgs/msg/PoseStamped"](
        header=t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=int(time.time()), nanosec=0),
                                        frame_id=frame),
        pose=t["geometry_msgs/msg/Pose"](
            position=t["geometry_msgs/msg/Point"](x=x, y=y, z=z),
            orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))))
    return bytes(TYPES.serialize_cdr(msg, "geometry_msgs/msg/PoseStamped"))


def test_goal_pose_bad_ones_change_nothing_a_good_one_is_flown(ros):
    key = ros.key("/drone_0/goal_pose")
    paths, path_sub = ros.collect("/drone_0/path")
    before = drone_0(ros.get("/api/status"))
    gid = bytes(range(16))
    good = pose_stamped("world", 3.0, 2.0, 2.0)
    bad = [b"\xde\xad\xbe\xef", good[:len(good) // 2], bytes(4096),
           pose_stamped("base_link", 3.0, 2.0, 2.0), pose_stamped("world", 5000.0, 0.0, 2.0)]
    for seq, payload in enumerate(bad, 1):
        ros.node.put(key, payload, attachment=attachment(seq, gid))
    time.sleep(2)
    assert ros.get("/api/missions?drone=drone_0") == [], "a refused goal left a mission"
    after = drone_0(ros.get("/api/status"))
    assert after["flight"] in ("disarmed", "landed"), after["flight"]
    assert all(abs(a - b) < 0.05 for a, b in zip(after["position_enu_m"], before["position_enu_m"]))

    ros.node.put(key, good, attachment=attachment(len(bad) + 1, gid))
    target = (3.0, 2.0, 2.0)
    ros.wait("the drone at the goal", 90, lambda: all(
        abs(a - b) < 0.3 for a, b in zip(drone_0(ros.get("/api/status"))["position_enu_m"], target)))
    # The planned path was published on the way: in world, ending at the goal.
    with ros.lock:
        planned = [TYPES.deserialize_cdr(p, "nav_msgs/msg/Path") for p, _ in paths]
    path_sub.undeclare()
    flown = [m for m in planned if m.poses]
    assert flown, f"{len(planned)} paths, none with poses"
    end = flown[0].poses[-1].pose.position
    assert flown[0].header.frame_id == "world"
    assert math.hypot(end.x - target[0], end.y - target[1]) < 0.3, f"the path ends at {end}"


def test_a_router_that_comes_later_is_reached(ros_before_the_router):
    ros = ros_before_the_router
    time.sleep(3)
    assert ros.get("/api/status")["drones"], "kestrel runs without a router"
    ros.open_router()
    graph = ros.graph()
    assert {t["topic"] for t in graph if t["kind"] == "MP"} == set(PUBLISHED)
    got, sub = ros.collect("/drone_0/pose")
    ros.wait("poses", 10, lambda: len(got) >= 3)
    sub.undeclare()
