"""PX4 personality behaviour over MAVLink (pymavlink as the companion)."""
import math
import time

from conftest import mavlink as M

LOITER, TAKEOFF, LAND, OFFBOARD = 0x03040000, 0x02040000, 0x06040000, 0x00060000


def stream(link, seconds, rate_hz=10, **sp):
    end = time.time() + seconds
    while time.time() < end:
        link.send_local(**sp)
        time.sleep(1.0 / rate_hz)


def test_heartbeat_boot_fields(fake_factory):
    f = fake_factory("px4")
    link = f.connect()
    hb = link.heartbeat_until(lambda h: True)
    assert (hb.type, hb.autopilot, hb.base_mode, hb.custom_mode, hb.system_status) == (2, 12, 29, LOITER, 3)
    assert hb.get_srcSystem() == 1 and hb.get_srcComponent() == 1


def test_offboard_refused_without_stream_then_arm_rejected(fake_factory):
    f = fake_factory("px4")
    link = f.connect()
    # disarmed: selecting OFFBOARD is accepted (as captured) but arming is then refused
    assert link.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0) == M.MAV_RESULT_ACCEPTED
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_TEMPORARILY_REJECTED
    ev = link.recv("EVENT", 2.0)
    assert ev is not None  # arming denial comes as EVENT, never STATUSTEXT
    # armed in LOITER, then OFFBOARD without a stream -> rejected
    assert link.command(M.MAV_CMD_DO_SET_MODE, 1, 4, 3) == M.MAV_RESULT_ACCEPTED
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    assert link.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0) == M.MAV_RESULT_TEMPORARILY_REJECTED
    assert f.control(cmd="state")["mode"] == "AUTO.LOITER"
    assert link.recv("STATUSTEXT", 1.0) is None


def test_offboard_takeoff_goto_and_loss_failsafe_lands(fake_factory):
    f = fake_factory("px4", speed=2.0)  # 10 Hz wall = 5 Hz simulated setpoints
    link = f.connect()
    stream(link, 0.8, x=0, y=0, z=-5)
    assert link.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0) == M.MAV_RESULT_ACCEPTED
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    stream(link, 4.0, x=0, y=0, z=-5)
    hb = link.heartbeat_until(lambda h: True, 2)
    assert hb.base_mode == 145 and hb.custom_mode == OFFBOARD and hb.system_status == 4
    st = f.control(cmd="state")
    assert abs(st["local_ned_m"][2] + 5) < 0.5 and st["landed_state"] == 2
    stream(link, 2.5, x=10, y=5, z=-5)
    st = f.control(cmd="state")
    assert abs(st["local_ned_m"][0] - 10) < 1.0 and abs(st["local_ned_m"][1] - 5) < 1.0
    # ENU truth: north 10, east 5 -> x=5, y=10
    assert abs(st["position_enu_m"][0] - 5) < 1.0 and abs(st["position_enu_m"][1] - 10) < 1.0
    stats = f.control(cmd="setpoint_stats")
    assert stats["count"] > 30 and 80 < stats["p50_ms"] < 130  # wall-clock gaps
    # stop the stream: PX4 leaves OFFBOARD ~1 s later and lands
    t_stop = time.time()
    hb = link.heartbeat_until(lambda h: h.custom_mode == LAND, 4)
    assert hb is not None
    log = f.control(cmd="log")["entries"]
    fs = [e for e in log if e["kind"] == "failsafe"]
    assert fs, log
    mode_change = [e for e in log if e["kind"] == "mode" and "AUTO.LAND" in e["text"]][-1]
    assert 0.04 < mode_change["t"] - fs[0]["t"] < 0.1  # switch ~60 ms after detection, as captured
    assert 0.45 < time.time() - t_stop < 3.0  # 1.06 s simulated
    names = [e["text"] for e in log if e["kind"] == "event"]
    assert "commander_failsafe_enter_generic" in names
    ext = link.recv("EXTENDED_SYS_STATE", 2, lambda m: m.landed_state == 4)
    assert ext is not None


def test_auto_takeoff_land_and_auto_disarm(fake_factory):
    f = fake_factory("px4", speed=3.0)
    link = f.connect()
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    assert link.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, float("nan"), float("nan"), float("nan"),
                        100.0 + 5.0) == M.MAV_RESULT_ACCEPTED
    assert link.heartbeat_until(lambda h: h.custom_mode == TAKEOFF and h.base_mode == 157, 3)
    assert link.recv("EXTENDED_SYS_STATE", 5, lambda m: m.landed_state == 3)
    assert link.heartbeat_until(lambda h: h.custom_mode == LOITER and h.base_mode == 157, 10)
    assert abs(f.control(cmd="state")["position_enu_m"][2] - 5) < 0.4
    assert link.command(M.MAV_CMD_DO_SET_MODE, 1, 4, 6) == M.MAV_RESULT_ACCEPTED
    assert link.recv("EXTENDED_SYS_STATE", 3, lambda m: m.landed_state == 4)
    hb = link.heartbeat_until(lambda h: h.base_mode & 128 == 0, 15)
    assert hb is not None and (hb.base_mode, hb.custom_mode, hb.system_status) == (29, LOITER, 3)
    names = [e["text"] for e in f.control(cmd="log")["entries"] if e["kind"] == "event"]
    assert names.index("commander_landing_detected") < names.index("commander_disarmed_by")


def test_message_interval(fake_factory):
    f = fake_factory("px4")
    link = f.connect()
    assert link.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 32, 2e5) == M.MAV_RESULT_ACCEPTED  # 5 Hz
    assert link.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 331, -1) == M.MAV_RESULT_ACCEPTED  # off
    assert link.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 0, 5e5) == M.MAV_RESULT_FAILED     # HEARTBEAT fixed
    link.recv("LOCAL_POSITION_NED", 1)
    n = {"LOCAL_POSITION_NED": 0, "ODOMETRY": 0}
    end = time.time() + 2.0
    while time.time() < end:
        m = link.recv(["LOCAL_POSITION_NED", "ODOMETRY"], 0.3)
        if m:
            n[m.get_type()] += 1
    assert 8 <= n["LOCAL_POSITION_NED"] <= 12 and n["ODOMETRY"] == 0
    assert link.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 32, 0) == M.MAV_RESULT_ACCEPTED   # default 30 Hz
    link.command(M.MAV_CMD_GET_MESSAGE_INTERVAL, 32)
    mi = link.seen_or_recv("MESSAGE_INTERVAL", 2, lambda m: m.message_id == 32 and m.interval_us > 30000)
    assert mi is not None and 30000 < mi.interval_us < 36000


def test_deny_arm_fault_and_reject_command(fake_factory):
    f = fake_factory("px4")
    link = f.connect()
    f.control(cmd="deny_arm", reason="Preflight Fail: test")
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_TEMPORARILY_REJECTED
    ev = link.recv("EVENT", 2)
    assert ev is not None and ev.id == 16910493  # commander_arm_denied_resolve_failures
    f.control(cmd="deny_arm", enable=False)
    f.control(cmd="reject_command", command=400, result=4, count=1)
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_FAILED
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED


def test_link_drop_and_reboot(fake_factory):
    f = fake_factory("px4")
    link = f.connect()
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    f.control(cmd="link_drop", duration_s=2.0)
    time.sleep(0.2)
    link.drain()
    t0 = time.time()
    # nothing arrives and commands are ignored while the link is down
    link.m.mav.command_long_send(1, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 0, 0, 0, 0, 0, 0)
    assert link.recv(["HEARTBEAT", "ATTITUDE", "COMMAND_ACK"], 1.5) is None
    assert link.recv("HEARTBEAT", 3) is not None and time.time() - t0 >= 1.5
    assert f.control(cmd="state")["armed"] is True
    # reboot: silence, then a fresh boot disarmed with restarted boot time
    before = link.recv("ATTITUDE", 2).time_boot_ms
    f.control(cmd="reboot", gap_s=2.0)
    time.sleep(0.3)
    link.drain()
    assert link.recv("HEARTBEAT", 1.2) is None
    hb = link.recv("HEARTBEAT", 4)
    assert hb is not None and hb.base_mode == 29
    assert link.recv("ATTITUDE", 2).time_boot_ms < before
    st = f.control(cmd="state")
    assert st["boot_count"] == 2 and st["armed"] is False


def test_latency_fault_and_control_errors(fake_factory):
    f = fake_factory("px4")
    link = f.connect()
    t0 = time.time()
    link.command(M.MAV_CMD_REQUEST_MESSAGE, 148)
    fast = time.time() - t0
    f.control(cmd="latency", latency_ms=150)
    t0 = time.time()
    assert link.command(M.MAV_CMD_REQUEST_MESSAGE, 148) == M.MAV_RESULT_ACCEPTED
    slow = time.time() - t0
    assert fast < 0.1 and 0.29 < slow < 0.6  # 150 ms each way
    f.control(cmd="clear_faults")
    # errors are reported, the channel keeps working
    f.ctl.sendall(b'{"cmd": "nope"}\n')
    import json
    reply = json.loads(f.ctl_file.readline())
    assert reply["ok"] is False and "unknown cmd" in reply["error"]
    f.ctl.sendall(b'{"cmd": "state", "vehicle": 5}\n')
    assert json.loads(f.ctl_file.readline())["ok"] is False
    assert f.control(cmd="ping")["ok"] is True


def test_attitude_target_offboard(fake_factory):
    f = fake_factory("px4")
    link = f.connect()
    import math as _m

    def att(thrust, pitch=0.0):
        q = [_m.cos(pitch / 2), 0.0, _m.sin(pitch / 2), 0.0]
        link.m.mav.set_attitude_target_send(0, link.ts, link.tc, 0b00000111, q, 0, 0, 0, thrust)

    for _ in range(15):
        att(0.5)
        time.sleep(0.1)
    assert link.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0) == M.MAV_RESULT_ACCEPTED
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    for _ in range(40):  # climb
        att(0.8)
        time.sleep(0.1)
    z1 = f.control(cmd="state")["position_enu_m"][2]
    assert z1 > 1.0
    for _ in range(20):  # nose down, NED yaw 0 (north): move north
        att(0.5, pitch=-0.2)
        time.sleep(0.1)
    st = f.control(cmd="state")
    assert abs(st["yaw_enu_rad"] - _m.pi / 2) < 0.05
    assert st["velocity_enu_mps"][1] > 1.0 and abs(st["velocity_enu_mps"][0]) < 0.2 and st["mode"] == "OFFBOARD"


def test_offboard_yaw_and_frames(fake_factory):
    f = fake_factory("px4", speed=2.0)
    link = f.connect()
    yaw_mask = 3576 & ~0x400  # position + yaw
    stream(link, 0.8, x=2, y=-3, z=-4, mask=yaw_mask, rate_hz=20)
    link.m.mav.set_position_target_local_ned_send(0, 1, 1, 1, yaw_mask, 2, -3, -4, 0, 0, 0, 0, 0, 0, math.pi / 2, 0)
    assert link.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0) == M.MAV_RESULT_ACCEPTED
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    end = time.time() + 5
    while time.time() < end:
        link.m.mav.set_position_target_local_ned_send(0, 1, 1, 1, yaw_mask, 2, -3, -4, 0, 0, 0, 0, 0, 0, math.pi / 2, 0)
        time.sleep(0.05)
    st = f.control(cmd="state")
    # NED (north 2, east -3, down -4) == ENU (x -3, y 2, z 4); NED yaw +90 deg (east) == ENU yaw 0
    assert abs(st["position_enu_m"][0] + 3) < 0.3 and abs(st["position_enu_m"][1] - 2) < 0.3
    assert abs(st["position_enu_m"][2] - 4) < 0.3 and abs(st["yaw_enu_rad"]) < 0.05
    link.drain()
    att = link.recv("ATTITUDE", 2)
    assert abs(att.yaw - math.pi / 2) < 0.05
    gp = link.recv("GLOBAL_POSITION_INT", 2)
    assert abs(gp.hdg - 9000) < 300 and abs(gp.relative_alt - 4000) < 300
    lp = link.recv("LOCAL_POSITION_NED", 2)
    assert abs(lp.x - 2) < 0.3 and abs(lp.y + 3) < 0.3 and abs(lp.z + 4) < 0.3


def test_timesync_and_params(fake_factory):
    f = fake_factory("px4")
    link = f.connect()
    req = link.recv("TIMESYNC", 2, lambda m: m.tc1 == 0)  # PX4 asks at 10 Hz
    assert req is not None and req.ts1 > 0
    link.m.mav.timesync_send(0, 123456789)
    reply = link.recv("TIMESYNC", 2, lambda m: m.ts1 == 123456789)
    assert reply is not None and reply.tc1 > 0
    link.m.mav.param_request_read_send(1, 1, b"COM_OF_LOSS_T", -1)
    pv = link.recv("PARAM_VALUE", 2, lambda m: m.param_id == "COM_OF_LOSS_T")
    assert pv.param_value == 1.0 and pv.param_type == M.MAV_PARAM_TYPE_REAL32
    link.m.mav.param_set_send(1, 1, b"COM_OF_LOSS_T", 0.5, M.MAV_PARAM_TYPE_REAL32)
    assert link.recv("PARAM_VALUE", 2, lambda m: m.param_id == "COM_OF_LOSS_T").param_value == 0.5
    link.m.mav.param_request_read_send(1, 1, b"COM_OBL_RC_ACT", -1)
    pv = link.recv("PARAM_VALUE", 2, lambda m: m.param_id == "COM_OBL_RC_ACT")
    import struct
    assert struct.unpack("<i", struct.pack("<f", pv.param_value))[0] == 4  # PX4 ints are bytewise


def test_gcs_mode_change_leaves_offboard_and_setpoints_are_ignored_until_offboard_again(fake_factory):
    f = fake_factory("px4", speed=2.0)
    link = f.connect()
    stream(link, 0.8, x=0, y=0, z=-3)
    assert link.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0) == M.MAV_RESULT_ACCEPTED
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    stream(link, 3.0, x=0, y=0, z=-3)
    # QGC on PX4's own GCS link: DO_SET_MODE AUTO.LOITER (main 4, sub 3)
    reply = f.control(cmd="gcs_set_mode", mode="AUTO.LOITER")
    assert (reply["result"], reply["mode"]) == (M.MAV_RESULT_ACCEPTED, "AUTO.LOITER")
    cm = link.recv("CURRENT_MODE", 1.0, lambda m: m.custom_mode == LOITER)
    assert cm is not None, "the mode change is announced at once"
    held = f.control(cmd="state")["position_enu_m"]
    stream(link, 1.5, x=10, y=0, z=-3)  # ignored outside OFFBOARD
    st = f.control(cmd="state")
    assert st["mode"] == "AUTO.LOITER"
    assert math.dist(st["position_enu_m"], held) < 0.3, (st, held)
    got = f.control(cmd="received", since_s=0)
    assert got["setpoints"] > 20
    gcs = [c for c in got["commands"] if c["src"] == [255, 190]]
    assert [c["detail"] for c in gcs] == [M.MAV_CMD_DO_SET_MODE]
    # OFFBOARD again (the companion asks): setpoints fly it
    assert link.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0) == M.MAV_RESULT_ACCEPTED
    stream(link, 3.0, x=10, y=0, z=-3)
    assert abs(f.control(cmd="state")["local_ned_m"][0] - 10) < 1.5


def test_rc_mode_switch_and_gcs_land(fake_factory):
    f = fake_factory("px4", speed=2.0)
    link = f.connect()
    stream(link, 0.8, x=0, y=0, z=-3)
    link.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0)
    link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    stream(link, 3.0, x=0, y=0, z=-3)
    assert f.control(cmd="rc_mode", mode="POSCTL")["mode"] == "POSCTL"
    assert f.control(cmd="gcs_command", command=M.MAV_CMD_NAV_LAND)["mode"] == "AUTO.LAND"
    assert link.heartbeat_until(lambda h: h.custom_mode == LAND, 3) is not None
