"""PX4 personality behaviour over MAVLink (pymavlink as the companion)."""
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
    f = fake_factory("px4")
    link = f.connect()
    stream(link, 1.2, x=0, y=0, z=-5)
    assert link.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0) == M.MAV_RESULT_ACCEPTED
    assert link.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    stream(link, 6.0, x=0, y=0, z=-5)
    hb = link.heartbeat_until(lambda h: True, 2)
    assert hb.base_mode == 145 and hb.custom_mode == OFFBOARD and hb.system_status == 4
    st = f.control(cmd="state")
    assert abs(st["local_ned_m"][2] + 5) < 0.5 and st["landed_state"] == 2
    stream(link, 4.0, x=10, y=5, z=-5)
    st = f.control(cmd="state")
    assert abs(st["local_ned_m"][0] - 10) < 1.0 and abs(st["local_ned_m"][1] - 5) < 1.0
    # ENU truth: north 10, east 5 -> x=5, y=10
    assert abs(st["position_enu_m"][0] - 5) < 1.0 and abs(st["position_enu_m"][1] - 10) < 1.0
    stats = f.control(cmd="setpoint_stats")
    assert stats["count"] > 50 and 80 < stats["p50_ms"] < 130
    # stop the stream: PX4 leaves OFFBOARD ~1 s later and lands
    t_stop = time.time()
    hb = link.heartbeat_until(lambda h: h.custom_mode == LAND, 4)
    assert hb is not None
    log = f.control(cmd="log")["entries"]
    fs = [e for e in log if e["kind"] == "failsafe"]
    assert fs, log
    mode_change = [e for e in log if e["kind"] == "mode" and "AUTO.LAND" in e["text"]][-1]
    last_sp_lag = mode_change["t"] - fs[0]["t"]
    assert last_sp_lag < 0.05
    assert 0.9 < time.time() - t_stop < 4.0
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
    link.m.recv_match(blocking=False)
    while link.m.recv_match(blocking=False):
        pass
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
    while link.m.recv_match(blocking=False):
        pass
    assert link.recv("HEARTBEAT", 1.2) is None
    hb = link.recv("HEARTBEAT", 4)
    assert hb is not None and hb.base_mode == 29
    assert link.recv("ATTITUDE", 2).time_boot_ms < before
    st = f.control(cmd="state")
    assert st["boot_count"] == 2 and st["armed"] is False
