"""ArduPilot personality behaviour over MAVLink (TCP, pymavlink as the companion)."""
import math
import time

from conftest import mavlink as M

GUIDED, LAND, ALT_HOLD = 4, 9, 2


def request_streams(link):
    for mid, hz in ((32, 10), (33, 5), (245, 2), (193, 2), (85, 5), (30, 10)):
        assert link.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, mid, 1e6 / hz) == M.MAV_RESULT_ACCEPTED


def test_nothing_streamed_by_default_and_boot_heartbeat(fake_factory):
    f = fake_factory("ardupilot")
    link = f.connect()
    hb = link.recv("HEARTBEAT", 3)
    assert (hb.type, hb.autopilot) == (2, 3)
    assert link.recv(["ATTITUDE", "LOCAL_POSITION_NED", "GLOBAL_POSITION_INT", "SYS_STATUS"], 1.5) is None
    hb = link.heartbeat_until(lambda h: h.system_status == 3, 4)
    assert (hb.base_mode, hb.custom_mode) == (81, 0)
    # unknown message id -> DENIED with a STATUSTEXT, as captured
    assert link.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 11037, 2e5) == M.MAV_RESULT_DENIED
    # REQUEST_DATA_STREAM (legacy) works too
    link.m.mav.request_data_stream_send(link.ts, 1, M.MAV_DATA_STREAM_EXTRA1, 10, 1)
    assert link.recv("ATTITUDE", 2) is not None


def test_arm_needs_position_estimate(fake_factory):
    f = fake_factory("ardupilot", "--ekf-delay", "6")
    link = f.connect()
    link.m.mav.set_mode_send(link.ts, 1, GUIDED)  # legacy SET_MODE: no COMMAND_ACK
    assert link.recv("COMMAND_ACK", 1.0) is None
    assert link.heartbeat_until(lambda h: h.custom_mode == GUIDED and h.base_mode == 89, 4)
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_FAILED
    st = link.seen_or_recv("STATUSTEXT", 2, lambda m: "Arm:" in m.text)
    assert st is not None and st.text == "Arm: Need Position Estimate"
    assert link.recv("LOCAL_POSITION_NED", 0.5) is None
    assert link.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 193, 2e5) == M.MAV_RESULT_ACCEPTED
    ekf = link.recv("EKF_STATUS_REPORT", 8, lambda m: m.flags & 0x10 and not m.flags & 0x80)
    assert ekf is not None and ekf.flags == 0x33F
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED


def test_guided_takeoff_goto_velocity_timeout_land(fake_factory):
    f = fake_factory("ardupilot", "--ekf-delay", "1", speed=3.0)
    link = f.connect()
    request_streams(link)
    link.recv("EKF_STATUS_REPORT", 5, lambda m: m.flags & 0x10)
    # takeoff refused outside GUIDED / disarmed
    assert link.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 5) == M.MAV_RESULT_FAILED
    assert link.command(M.MAV_CMD_DO_SET_MODE, 1, GUIDED) == M.MAV_RESULT_ACCEPTED
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    assert link.heartbeat_until(lambda h: h.base_mode == 217, 3)
    assert link.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, float("nan"), 0, 0, 5) == M.MAV_RESULT_ACCEPTED
    assert link.recv("EXTENDED_SYS_STATE", 4, lambda m: m.landed_state == 3)
    lp = link.recv("LOCAL_POSITION_NED", 8, lambda m: m.z < -4.8)
    assert lp is not None
    assert link.recv("EXTENDED_SYS_STATE", 4, lambda m: m.landed_state == 2)
    # position target: no ACK, echoed in POSITION_TARGET_LOCAL_NED
    link.send_local(10, 5, -5, mask=3576)
    assert link.recv("COMMAND_ACK", 0.3) is None
    echo = link.recv("POSITION_TARGET_LOCAL_NED", 2, lambda m: m.type_mask == 3576 and abs(m.x - 10) < 0.01)
    assert echo is not None and (echo.y, echo.z, echo.coordinate_frame) == (5, -5, 1)
    lp = link.recv("LOCAL_POSITION_NED", 8, lambda m: abs(m.x - 10) < 0.5 and abs(m.y - 5) < 0.5)
    assert lp is not None
    # one velocity target then silence: stops after GUID_TIMEOUT (3 s sim)
    link.send_local(vx=0, vy=-2, mask=3527)
    moving = link.recv("LOCAL_POSITION_NED", 3, lambda m: m.vy < -1.5)
    assert moving is not None
    t0 = f.control(cmd="state")["time_s"]
    stopped = link.recv("LOCAL_POSITION_NED", 10, lambda m: abs(m.vy) < 0.1)
    assert stopped is not None
    dt = f.control(cmd="state")["time_s"] - t0
    assert dt > 2.0
    log = f.control(cmd="log")["entries"]
    assert any("GUID_TIMEOUT" in e["text"] for e in log)
    # LAND -> touchdown -> auto disarm with "Disarming motors"
    assert link.command(M.MAV_CMD_DO_SET_MODE, 1, LAND) == M.MAV_RESULT_ACCEPTED
    assert link.recv("EXTENDED_SYS_STATE", 3, lambda m: m.landed_state == 4)
    st = link.recv("STATUSTEXT", 20, lambda m: m.text == "Disarming motors")
    assert st is not None
    hb = link.heartbeat_until(lambda h: True, 2)
    assert (hb.base_mode, hb.custom_mode) == (89, LAND)


def test_set_gps_global_origin_indoors(fake_factory):
    f = fake_factory("ardupilot", "--no-gps")
    link = f.connect()
    assert link.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 32, 1e5) == M.MAV_RESULT_ACCEPTED
    assert link.recv("LOCAL_POSITION_NED", 1.5) is None
    link.m.mav.set_gps_global_origin_send(link.ts, int(40.4405e7), int(-3.68982e7), 100000)
    origin = link.recv("GPS_GLOBAL_ORIGIN", 2)
    assert origin is not None and origin.latitude == int(40.4405e7)
    assert link.recv("LOCAL_POSITION_NED", 2) is not None


def test_deny_arm_reason_statustext(fake_factory):
    f = fake_factory("ardupilot", "--ekf-delay", "0.5", "--deny-arm", "Battery below minimum")
    link = f.connect()
    time.sleep(0.8)
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_FAILED
    st = link.seen_or_recv("STATUSTEXT", 2, lambda m: m.text.startswith("Arm:"))
    assert st.text == "Arm: Battery below minimum" and st.severity == M.MAV_SEVERITY_CRITICAL


def test_guided_setpoint_stats_link_drop_and_reconnect(fake_factory):
    f = fake_factory("ardupilot", "--ekf-delay", "0.5")
    link = f.connect()
    link.recv("HEARTBEAT", 3, lambda h: h.system_status == 3)
    assert link.command(M.MAV_CMD_DO_SET_MODE, 1, GUIDED) == M.MAV_RESULT_ACCEPTED
    for _ in range(25):  # 25 Hz for 1 s while in GUIDED
        link.send_local(vx=0.0, mask=3527)
        time.sleep(0.04)
    stats = f.control(cmd="setpoint_stats", reset=True)
    assert stats["count"] == 25 and stats["gaps"] == 24
    assert 35 < stats["p50_ms"] < 50 and stats["max_ms"] < 150 and stats["p99_ms"] <= stats["max_ms"]
    assert stats["over_500ms"] == 0
    assert f.control(cmd="setpoint_stats")["count"] == 0
    # link drop: silence both ways, then the same TCP connection carries traffic again
    f.control(cmd="link_drop", duration_s=1.5)
    time.sleep(0.1)
    link.drain()
    assert link.recv("HEARTBEAT", 1.2) is None
    assert link.recv("HEARTBEAT", 2.5) is not None
    # a second client replaces the first (one TCP client per SERIAL0)
    link.close()
    link2 = f.connect()
    assert link2.command(M.MAV_CMD_REQUEST_MESSAGE, 148) == M.MAV_RESULT_ACCEPTED
    assert link2.seen_or_recv("AUTOPILOT_VERSION", 2).flight_sw_version == 67567616


def test_setpoint_stats_leave_out_the_autopilots_own_takeoff_climb(fake_factory):
    """NAV_TAKEOFF climbs on ArduPilot's own target: the silence of the setpoint stream then is
    by design and is not a gap; the stream before and after it is measured as usual."""
    f = fake_factory("ardupilot", "--ekf-delay", "0.5")
    link = f.connect()
    request_streams(link)
    link.recv("EKF_STATUS_REPORT", 5, lambda m: m.flags & 0x10)
    assert link.command(M.MAV_CMD_DO_SET_MODE, 1, GUIDED) == M.MAV_RESULT_ACCEPTED
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    for _ in range(10):
        link.send_local(vx=0.0, mask=3527)
        time.sleep(0.04)
    assert link.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 2) == M.MAV_RESULT_ACCEPTED
    assert link.recv("LOCAL_POSITION_NED", 15, lambda m: m.z < -1.95) is not None
    assert link.recv("EXTENDED_SYS_STATE", 4, lambda m: m.landed_state == 2)
    for _ in range(10):
        link.send_local(0, 0, -2, mask=3576)
        time.sleep(0.04)
    stats = f.control(cmd="setpoint_stats")
    assert stats["count"] == 20 and stats["gaps"] == 18, stats
    assert stats["max_ms"] < 150, stats


def test_reposition_condition_yaw_and_reboot_drops_tcp(fake_factory):
    f = fake_factory("ardupilot", "--ekf-delay", "0.5", speed=2.0)
    link = f.connect()
    link.recv("HEARTBEAT", 3, lambda h: h.system_status == 3)
    time.sleep(0.3)
    assert link.command(M.MAV_CMD_DO_SET_MODE, 1, GUIDED) == M.MAV_RESULT_ACCEPTED
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    assert link.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 3) == M.MAV_RESULT_ACCEPTED
    deadline = time.time() + 8
    while f.control(cmd="state")["landed_state"] != 2 and time.time() < deadline:
        time.sleep(0.2)
    # CONDITION_YAW 90 deg absolute (east) -> ENU yaw 0
    assert link.command(M.MAV_CMD_CONDITION_YAW, 90, 30, 1, 0) == M.MAV_RESULT_ACCEPTED
    time.sleep(2.0)
    assert abs(f.control(cmd="state")["yaw_enu_rad"]) < 0.05
    # DO_REPOSITION via COMMAND_INT to a point 10 m north of the origin, 104 m AMSL
    lat = int((40.4405 + math.degrees(10.0 / 6378137.0)) * 1e7)
    link.m.mav.command_int_send(link.ts, 1, 0, M.MAV_CMD_DO_REPOSITION, 0, 0, -1, 1, 0, float("nan"),
                                lat, int(-3.68982e7), 104.0)
    assert link.recv("COMMAND_ACK", 2, lambda a: a.command == M.MAV_CMD_DO_REPOSITION).result == 0
    time.sleep(4.0)
    pos = f.control(cmd="state")["position_enu_m"]
    assert abs(pos[1] - 10) < 1.0 and abs(pos[0]) < 0.5 and abs(pos[2] - 4) < 0.3
    # a reboot closes the TCP connection like a restarting SITL; reconnecting works afterwards
    f.control(cmd="reboot", gap_s=2.0)
    time.sleep(0.5)
    link.drain()
    assert link.recv("HEARTBEAT", 0.5) is None
    link.close()  # the old connection was closed by the "autopilot"
    time.sleep(1.0)
    link2 = f.connect()
    hb = link2.recv("HEARTBEAT", 3)
    assert hb.base_mode in (81, 89) and f.control(cmd="state")["boot_count"] == 2


def test_rc_mode_switch_leaves_guided_and_setpoints_are_ignored(fake_factory):
    f = fake_factory("ardupilot", "--ekf-delay", "1", speed=2.0)
    link = f.connect()
    deadline = time.time() + 10
    while not f.control(cmd="state")["ekf_position_ok"] and time.time() < deadline:
        time.sleep(0.1)
    assert link.command(M.MAV_CMD_DO_SET_MODE, 1, 4) == M.MAV_RESULT_ACCEPTED
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    assert link.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 3) == M.MAV_RESULT_ACCEPTED
    # Switched once the takeoff is done: a switch mid-climb holds where the climb brakes to,
    # up to 0.3 m above the point read at the switch.
    deadline = time.time() + 10
    while f.control(cmd="state")["position_enu_m"][2] < 2.95 and time.time() < deadline:
        time.sleep(0.1)
    reply = f.control(cmd="rc_mode", mode="LOITER")
    assert (reply["taken"], reply["mode"]) == (True, "LOITER")
    hb = link.recv("HEARTBEAT", 1.0, lambda h: h.custom_mode == 5)
    assert hb is not None, "ArduPilot announces a mode change at once"
    held = f.control(cmd="state")["position_enu_m"]
    for _ in range(20):
        link.send_local(x=10, y=0, z=-3)
        time.sleep(0.05)
    assert math.dist(f.control(cmd="state")["position_enu_m"], held) < 0.3
    # a ground station's mode change: DO_SET_MODE from 255/190
    assert f.control(cmd="gcs_set_mode", mode="RTL")["mode"] == "RTL"
    assert f.control(cmd="received")["commands"][-1]["src"] == [255, 190]
