"""MAVSDK (PyPI mavsdk 4.x, ctypes binding of the C++ library) flies the PX4 personality:
connect, arm, take off, offboard velocity control, land, auto-disarm."""
import math
import time

import pytest

mavsdk = pytest.importorskip("mavsdk")
from mavsdk import ComponentType, Configuration, Mavsdk  # noqa: E402
from mavsdk.plugins.action import Action  # noqa: E402
from mavsdk.plugins.offboard import Offboard, VelocityNedYaw  # noqa: E402
from mavsdk.plugins.telemetry import Telemetry  # noqa: E402


def wait_for(pred, timeout_s, what):
    end = time.time() + timeout_s
    while time.time() < end:
        if pred():
            return
        time.sleep(0.1)
    raise AssertionError(f"timed out waiting for {what}")


def test_mavsdk_arm_takeoff_offboard_land(fake_factory):
    f = fake_factory("px4", speed=2.0)
    cfg = Configuration.create_with_component_type(ComponentType.COMPANION_COMPUTER)
    sdk = Mavsdk(cfg)
    try:
        sdk.add_any_connection(f"udpin://0.0.0.0:{f.remote}")
        system = sdk.first_autopilot(10.0)
        assert system is not None, "MAVSDK did not discover the fake PX4"
        action, telemetry, offboard = Action(system), Telemetry(system), Offboard(system)
        action.arm()
        wait_for(lambda: telemetry.armed(), 3, "armed telemetry")
        action.takeoff()
        wait_for(lambda: f.control(cmd="state")["position_enu_m"][2] > 2.0, 15, "takeoff to MIS_TAKEOFF_ALT")
        wait_for(lambda: telemetry.position().relative_altitude_m > 2.0, 3, "MAVSDK altitude")
        # goto_location sends DO_REPOSITION: 8 m east of the origin at 103 m AMSL
        lon = -3.68982 + math.degrees(8.0 / (6378137.0 * math.cos(math.radians(40.4405))))
        action.goto_location(40.4405, lon, 103.0, 90.0)
        wait_for(lambda: abs(f.control(cmd="state")["position_enu_m"][0] - 8.0) < 0.5, 8, "goto_location")
        offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, 0.0))
        time.sleep(0.8)  # (1.6 s simulated) MAVSDK streams the setpoint at 20 Hz; PX4 wants a stream first
        offboard.start()
        wait_for(lambda: f.control(cmd="state")["mode"] == "OFFBOARD", 3, "OFFBOARD")
        start = f.control(cmd="state")["position_enu_m"]
        offboard.set_velocity_ned(VelocityNedYaw(2.0, 0.0, 0.0, 0.0))  # north 2 m/s
        time.sleep(2.0)
        now = f.control(cmd="state")["position_enu_m"]
        assert now[1] - start[1] > 3.5 and abs(now[0] - start[0]) < 0.6
        ned = telemetry.position_velocity_ned()
        assert ned.velocity.north_m_s > 1.5
        stats = f.control(cmd="setpoint_stats")
        assert stats["count"] > 25 and 35 < stats["p50_ms"] < 65  # MAVSDK's 20 Hz stream
        offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, 0.0))
        offboard.stop()
        action.land()
        wait_for(lambda: not f.control(cmd="state")["armed"], 20, "landing and auto-disarm")
        wait_for(lambda: not telemetry.armed(), 3, "MAVSDK disarmed")
    finally:
        sdk.destroy()
