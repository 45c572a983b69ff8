"""World, sensors and multi-vehicle: ports, system ids, start poses, range beams, faults."""
import json
import math
import os
import time

from conftest import SITL, mavlink as M

WORLD = os.path.join(SITL, "worlds", "low.json")


def test_multi_vehicle_ports_sysids_and_start_poses(fake_factory, tmp_path):
    world = json.load(open(WORLD))
    f = fake_factory("px4", "--vehicles", "2", "--world", WORLD)
    info = f.control(cmd="info")
    assert [v["sysid"] for v in info["vehicles"]] == [1, 2]
    states = f.control(cmd="state", vehicle="all")["vehicles"]
    for st, start in zip(states, world["starts_xy_yaw"]["2"]):
        assert abs(st["position_enu_m"][0] - start[0]) < 1e-6 and abs(st["position_enu_m"][1] - start[1]) < 1e-6
        assert st["local_ned_m"] == [0.0, 0.0, 0.0]
    # vehicle 1 talks on listen+1 / remote+1 with system id 2
    from conftest import mavutil
    m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{f.remote + 1}", source_system=2, source_component=191)
    hb = m.wait_heartbeat(timeout=5)
    assert hb.get_srcSystem() == 2
    # GLOBAL_POSITION_INT of the two vehicles differ by their ENU start offset
    gp = m.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=3)
    lat0 = 40.4405 + math.degrees(world["starts_xy_yaw"]["2"][1][1] / 6378137.0)
    assert abs(gp.lat / 1e7 - lat0) < 1e-6
    m.close()


def test_distance_sensors_see_world_obstacles(fake_factory, tmp_path):
    world = {"name": "box", "bounds_m": {"x": [-20, 20], "y": [-20, 20]}, "pole_radius_m": 0.5,
             "poles_xy_m": [[3.0, 0.0]], "starts_xy_yaw": {"1": [[0.0, 0.0, 0.0]]},
             "boxes": [{"center_xy_m": [0.0, 2.5], "size_xy_m": [4.0, 1.0], "yaw_rad": 0.0, "height_m": 10.0}]}
    path = tmp_path / "w.json"
    path.write_text(json.dumps(world))
    f = fake_factory("px4", "--world", str(path))
    link = f.connect()
    seen = {}
    end = time.time() + 3
    while time.time() < end and len(seen) < 5:
        m = link.recv("DISTANCE_SENSOR", 1)
        if m:
            seen[m.id] = m
    # ENU yaw 0 faces east: front beam hits the pole at x=3 (r 0.5) -> 2.5 m;
    # left (north) hits the box face at y=2.0 -> 2.0 m; right and back see nothing (4 m max)
    assert seen[0].orientation == M.MAV_SENSOR_ROTATION_PITCH_270 and seen[0].current_distance == 0
    assert seen[1].orientation == 0 and abs(seen[1].current_distance - 250) <= 1
    assert seen[4].orientation == 6 and abs(seen[4].current_distance - 200) <= 1
    assert seen[2].current_distance == 400 and seen[3].current_distance == 400


def test_ardupilot_proximity_ids_and_packet_loss(fake_factory, tmp_path):
    world = {"poles_xy_m": [[0.0, 5.0]], "pole_radius_m": 0.25, "starts_xy_yaw": {"1": [[0.0, 0.0, 0.0]]}}
    path = tmp_path / "w.json"
    path.write_text(json.dumps(world))
    f = fake_factory("ardupilot", "--world", str(path))
    link = f.connect()
    assert link.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 132, 1e5) == M.MAV_RESULT_ACCEPTED
    seen = {}
    end = time.time() + 3
    while time.time() < end and len(seen) < 10:
        m = link.recv("DISTANCE_SENSOR", 1)
        if m:
            seen[m.id] = m
    assert sorted(seen) == [0] + list(range(10, 18)) + [19]
    # ENU yaw 0 = facing east; the pole is north = 90 deg left = sector orientation 6 (270 deg)
    assert seen[16].orientation == 6 and abs(seen[16].current_distance - 475) <= 1
    assert seen[10].current_distance == 20000
    # 50 % loss: roughly half of the ATTITUDE messages arrive
    assert link.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 30, 2e4) == M.MAV_RESULT_ACCEPTED
    f.control(cmd="packet_loss", probability=0.5)
    time.sleep(0.3)
    link.drain()
    n = 0
    end = time.time() + 2
    while time.time() < end:
        if link.recv("ATTITUDE", 0.2):
            n += 1
    assert 25 < n < 75, n
    f.control(cmd="clear_faults")


def test_ardupilot_two_vehicles_tcp_ports_and_log_file(fake_factory, tmp_path):
    log = tmp_path / "fake.jsonl"
    f = fake_factory("ardupilot", "--vehicles", "2", "--log-jsonl", str(log))
    from conftest import mavutil
    m = mavutil.mavlink_connection(f"tcp:127.0.0.1:{f.tcp + 10}", source_system=255, source_component=190)
    hb = m.wait_heartbeat(timeout=5)
    assert hb.get_srcSystem() == 2 and hb.autopilot == 3
    m.mav.command_long_send(2, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0, 30, 1e5, 0, 0, 0, 0, 0)
    ack = m.recv_match(type="COMMAND_ACK", blocking=True, timeout=3)
    assert ack.result == 0
    m.close()
    # The fake writes its log from its own loop: give it a moment to reach the file.
    deadline = time.monotonic() + 2.0
    while True:
        lines = [line for line in log.read_text().splitlines() if line.endswith("}")]
        acks = [e for e in map(json.loads, lines) if e["kind"] == "ack"]
        if acks or time.monotonic() > deadline:
            break
        time.sleep(0.05)
    assert acks, f"no ack in the fake's log: {lines}"
    assert {"vehicle": 1, "kind": "ack", "command": 511}.items() <= acks[0].items()
