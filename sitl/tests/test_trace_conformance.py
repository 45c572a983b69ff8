"""Trace conformance: HEARTBEAT (base_mode, custom_mode, system_status) and landed_state
sequences of the fake, for a session equivalent to a real capture, must follow the capture."""
import os
import time

import pytest

from conftest import mavlink as M, mavutil

TRACES = os.environ.get("KESTREL_TRACES", os.path.join(os.path.dirname(__file__), "..", "..", "..", "..",
                                                      "shared", "traces"))
if not os.path.isdir(TRACES):
    TRACES = "/work/shared/traces"


def capture(name):
    path = os.path.join(TRACES, name)
    if not os.path.exists(path):
        pytest.skip(f"capture {path} not available")
    m = mavutil.mavlink_connection(path, dialect="ardupilotmega")
    hbs, landed = [], []
    while True:
        msg = m.recv_match(type=["HEARTBEAT", "EXTENDED_SYS_STATE"])
        if msg is None:
            break
        if (msg.get_srcSystem(), msg.get_srcComponent()) != (1, 1):
            continue
        if msg.get_type() == "HEARTBEAT":
            _push(hbs, (msg.base_mode, msg.custom_mode, msg.system_status))
        else:
            _push(landed, msg.landed_state)
    return hbs, landed


def _push(seq, item):
    if not seq or seq[-1] != item:
        seq.append(item)


def is_subsequence(sub, seq):
    it = iter(seq)
    return all(any(x == y for y in it) for x in sub)


class Recorder:
    def __init__(self, link):
        self.link = link
        self.hbs, self.landed = [], []
        first = link.m.messages.get("HEARTBEAT")  # the one connect() waited for
        if first is not None:
            _push(self.hbs, (first.base_mode, first.custom_mode, first.system_status))

    def pump(self, seconds, until=None):
        end = time.time() + seconds
        while time.time() < end:
            msg = self.link.recv(["HEARTBEAT", "EXTENDED_SYS_STATE", "COMMAND_ACK"],
                                 max(0.0, min(0.1, end - time.time())))
            if msg is None:
                continue
            if msg.get_type() == "HEARTBEAT":
                _push(self.hbs, (msg.base_mode, msg.custom_mode, msg.system_status))
            elif msg.get_type() == "EXTENDED_SYS_STATE":
                _push(self.landed, msg.landed_state)
            if until and until(msg):
                return msg
        return None

    def command(self, cmd, *params):
        p = list(params) + [0.0] * (7 - len(params))
        self.link.m.mav.command_long_send(self.link.ts, 1, cmd, 0, *p)
        ack = self.pump(3, lambda m: m.get_type() == "COMMAND_ACK" and m.command == cmd)
        assert ack is not None
        return ack.result


def test_px4_auto_takeoff_land_matches_capture(fake_factory):
    cap_hbs, cap_landed = capture("px4_sih_offboard_session.tlog")
    # capture: (29,LOITER,3) -> (157,TAKEOFF,4) -> (157,LOITER,4) -> (157,LAND,4) ...
    f = fake_factory("px4", speed=3.0)
    rec = Recorder(f.connect())
    rec.pump(1.0)
    assert rec.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == 0
    assert rec.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, float("nan"), float("nan"), float("nan"), 105.0) == 0
    rec.pump(12, lambda m: m.get_type() == "HEARTBEAT" and m.custom_mode == 0x03040000 and m.base_mode == 157)
    rec.pump(1.0)
    assert rec.command(M.MAV_CMD_DO_SET_MODE, 1, 4, 6) == 0
    rec.pump(20, lambda m: m.get_type() == "HEARTBEAT" and not m.base_mode & 128)
    hbs = list(rec.hbs)
    if hbs[1] == (157, 0x03040000, 4):
        # armed in LOITER for the few ms before NAV_TAKEOFF; the capture's 1 Hz heartbeat
        # happened not to sample that state (arm and takeoff were 5 ms apart)
        del hbs[1]
    assert hbs[:4] == cap_hbs[:4], (rec.hbs, cap_hbs)
    assert rec.landed == [1, 3, 2, 4, 1] and cap_landed[:5] == [1, 3, 2, 4, 1]


def test_px4_offboard_states_are_captured_states(fake_factory):
    cap_a, _ = capture("px4_sih_offboard_session.tlog")
    cap_b, cap_landed_b = capture("px4_sih_offboard_failsafe_land_variant.tlog")
    f = fake_factory("px4", speed=2.0)
    link = f.connect()
    rec = Recorder(link)
    assert rec.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0) == 0  # no stream: (1, OFFBOARD, 0)
    rec.pump(1.0)
    end = time.time() + 5
    armed = False
    while time.time() < end:
        link.send_local(0, 0, -3, mask=3576)
        rec.pump(0.05)  # 20 Hz wall = 10 Hz simulated
        if not armed and time.time() > end - 3.0:  # >= 3 simulated heartbeats with (17, OFFBOARD, 3)
            assert rec.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == 0
            armed = True
    rec.pump(6, lambda m: m.get_type() == "HEARTBEAT" and m.custom_mode == 0x06040000)
    rec.pump(3, lambda m: m.get_type() == "EXTENDED_SYS_STATE" and m.landed_state == 4)
    allowed = set(cap_a) | set(cap_b)
    assert set(rec.hbs) <= allowed, (rec.hbs, allowed)
    assert (17, 0x60000, 3) in rec.hbs and (145, 0x60000, 4) in rec.hbs and (1, 0x60000, 0) in rec.hbs
    assert is_subsequence([2, 4], cap_landed_b) and is_subsequence([2, 4], rec.landed)


def test_ardupilot_guided_session_matches_capture(fake_factory):
    cap_hbs, cap_landed = capture("ardupilot_copter_guided_session.tlog")
    f = fake_factory("ardupilot", "--ekf-delay", "3", speed=3.0)
    link = f.connect()
    rec = Recorder(link)
    for mid in (245,):
        assert rec.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, mid, 2e5) == 0
    rec.pump(1.2)  # EKF ready after 3 s (sim)
    link.m.mav.set_mode_send(link.ts, 1, 2)  # legacy SET_MODE ALT_HOLD, no ACK
    rec.pump(1.2)
    assert rec.command(M.MAV_CMD_DO_SET_MODE, 1, 4) == 0
    assert rec.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == 0
    rec.pump(0.6)
    assert rec.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, float("nan"), 0, 0, 5) == 0
    rec.pump(8, lambda m: m.get_type() == "EXTENDED_SYS_STATE" and m.landed_state == 2)
    rec.pump(1.5)
    assert rec.command(M.MAV_CMD_DO_SET_MODE, 1, 9) == 0
    rec.pump(20, lambda m: m.get_type() == "HEARTBEAT" and m.base_mode == 89 and m.custom_mode == 9)
    assert is_subsequence(rec.hbs, cap_hbs), (rec.hbs, cap_hbs)
    for key in [(89, 0, 1), (81, 0, 3), (81, 2, 3), (89, 4, 3), (217, 4, 4), (217, 9, 4), (89, 9, 3)]:
        assert key in rec.hbs and key in cap_hbs
    assert rec.landed == cap_landed == [1, 3, 2, 4, 1]
