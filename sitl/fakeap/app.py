"""Process: CLI, vehicles, main loop (select + fixed-rate simulation ticks), control API."""
import argparse
import json
import select
import sys
import time

from .ardupilot import ArduPilotVehicle
from .control import ControlServer
from .links import TcpServerLink, UdpLink
from .mav import mavlink as M
from .px4 import Px4Vehicle
from .world import World

PHYSICS_DT_S = 0.01  # integrate at 100 Hz simulated time


class Clock:
    """Simulated seconds since start; runs speed_factor times faster than the wall clock."""

    def __init__(self, speed_factor):
        self.speed = speed_factor
        self.wall0 = time.monotonic()

    def now(self):
        return (time.monotonic() - self.wall0) * self.speed


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description="Fake PX4/ArduPilot autopilot(s) speaking MAVLink 2.")
    ap.add_argument("--personality", choices=["px4", "ardupilot"], default="px4")
    ap.add_argument("--vehicles", type=int, default=1)
    ap.add_argument("--world", default=None, help="world JSON (sitl/worlds/*.json); default empty world")
    ap.add_argument("--speed-factor", type=float, default=1.0, help="simulated seconds per wall second")
    ap.add_argument("--control-port", type=int, default=15999, help="JSON-lines TCP control port (0 = off)")
    ap.add_argument("--px4-listen-base", type=int, default=14580, help="PX4: UDP listen port of vehicle 0")
    ap.add_argument("--px4-remote-base", type=int, default=14540, help="PX4: UDP port vehicle 0 sends to")
    ap.add_argument("--ardupilot-tcp-base", type=int, default=5760, help="ArduPilot: TCP port of vehicle 0 (+10 per vehicle)")
    ap.add_argument("--sysid-base", type=int, default=1)
    ap.add_argument("--ekf-delay", type=float, default=3.0, help="ArduPilot: seconds until the EKF uses GPS (real SITL ~40)")
    ap.add_argument("--no-gps", action="store_true", help="ArduPilot: no GPS; position valid only after SET_GPS_GLOBAL_ORIGIN")
    ap.add_argument("--offboard-loss-action", choices=["land", "position"], default="land",
                    help="PX4 failsafe on offboard loss: AUTO.LAND, or POSCTL descending without RC")
    ap.add_argument("--offboard-prestream-s", type=float, default=1.0,
                    help="PX4: setpoint stream age needed before OFFBOARD is allowed")
    ap.add_argument("--rangers", choices=["none", "cf4", "prox8"], default=None,
                    help="horizontal range beams (default: cf4 for px4, prox8 for ardupilot)")
    ap.add_argument("--attitude-hz", type=float, default=50.0, help="PX4 ATTITUDE/GLOBAL_POSITION_INT default rate")
    ap.add_argument("--px4-z-offset-m", type=float, default=0.0,
                    help="PX4: constant offset added to local z (real PX4 sits at -0.2..-1 m on the ground)")
    ap.add_argument("--reboot-gap-s", type=float, default=3.0, help="silence during a simulated reboot")
    ap.add_argument("--no-collisions", dest="collisions", action="store_false")
    ap.add_argument("--seed", type=int, default=1)
    # faults at start
    ap.add_argument("--deny-arm", metavar="REASON", default=None, help="deny every arming with this reason")
    ap.add_argument("--packet-loss", type=float, default=0.0, help="loss probability per message, both ways")
    ap.add_argument("--latency-ms", type=float, default=0.0, help="added one-way latency, both ways")
    ap.add_argument("--velocity-wander-mps", type=float, default=0.0,
                    help="the autopilot's own velocity-tracking error in the air (OU process, std m/s, 3 s)")
    ap.add_argument("--velocity-wander-in-estimate", action="store_true",
                    help="the wander is the velocity estimate's error (as real PX4 SIH's): the reported "
                         "velocity shows the command while the vehicle flies command + wander")
    ap.add_argument("--telemetry-jitter-ms", type=float, default=0.0,
                    help="telemetry (autopilot to companion) delayed a further 0..J ms at random, order kept")
    ap.add_argument("--reject", action="append", default=[], metavar="CMD:RESULT[:COUNT]",
                    help="reject command id CMD with MAV_RESULT RESULT (COUNT times, default always)")
    ap.add_argument("--gcs-port-base", type=int, default=0, metavar="PORT",
                    help="forward what the companion sends that is not for the autopilot (its HEARTBEAT, "
                         "STATUSTEXT) to UDP 127.0.0.1:PORT+N, as PX4 with MAVLink forwarding on does to "
                         "its ground-station link (0 = off)")
    ap.add_argument("--log-jsonl", metavar="PATH", default=None,
                    help="append every log entry (modes, acks, events, faults) as JSON lines")
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    if args.rangers is None:
        args.rangers = "cf4" if args.personality == "px4" else "prox8"
    if args.vehicles < 1:
        ap.error("--vehicles must be >= 1")
    if args.speed_factor <= 0:
        ap.error("--speed-factor must be > 0")
    return args


class App:
    def __init__(self, args):
        self.args = args
        self.clock = Clock(args.speed_factor)
        self.world = World.load(args.world)
        poses = self.world.start_poses(args.vehicles)
        self.vehicles = []
        for i in range(args.vehicles):
            if args.personality == "px4":
                link = UdpLink(args.px4_listen_base + i, args.px4_remote_base + i)
                v = Px4Vehicle(i, link, self.world, poses[i], self.clock, args)
            else:
                link = TcpServerLink(args.ardupilot_tcp_base + 10 * i)
                v = ArduPilotVehicle(i, link, self.world, poses[i], self.clock, args)
            self.vehicles.append(v)
            self.apply_start_faults(v)
        self.control = ControlServer(args.control_port, self) if args.control_port else None
        self.running = True

    def apply_start_faults(self, v):
        a = self.args
        if a.deny_arm:
            v.faults.deny_arm_reason = a.deny_arm
        v.faults.loss_probability = a.packet_loss
        v.faults.latency_s = a.latency_ms / 1000.0
        v.faults.jitter_s = a.telemetry_jitter_ms / 1000.0
        for spec in a.reject:
            parts = spec.split(":")
            count = int(parts[2]) if len(parts) > 2 else None
            v.faults.reject[int(parts[0])] = [int(parts[1]), count]

    def banner(self):
        return {"personality": self.args.personality, "world": self.world.name,
                "control_port": self.args.control_port, "speed_factor": self.args.speed_factor,
                "vehicles": [{"index": v.index, "sysid": v.sysid, "link": v.link.describe,
                              "start_xy_yaw_enu": list(v.start_pose)} for v in self.vehicles]}

    # ------------------------------------------------------------------ loop
    def run(self):
        next_tick = time.monotonic()
        last_sim = self.clock.now()
        while self.running:
            socks = []
            owners = {}
            for v in self.vehicles:
                for s in v.link.sockets():
                    socks.append(s)
                    owners[s] = v
            if self.control:
                socks += self.control.sockets()
            timeout = max(0.0, next_tick - time.monotonic())
            try:
                readable, _, _ = select.select(socks, [], [], timeout)
            except (ValueError, OSError):
                readable = []
            for s in readable:
                if s in owners:
                    v = owners[s]
                    v.receive(v.link.on_readable(s))
                elif self.control and self.control.owns(s):
                    self.control.on_readable(s)
            for v in self.vehicles:
                v.flush_delayed()
            if time.monotonic() >= next_tick:
                now = self.clock.now()
                elapsed = now - last_sim
                last_sim = now
                steps = max(1, int(round(elapsed / PHYSICS_DT_S)))
                steps = min(steps, 200)
                dt = elapsed / steps if elapsed > 0 else PHYSICS_DT_S
                for v in self.vehicles:
                    for _ in range(steps):
                        v.tick(now, dt)
                    v.send_streams(now)
                next_tick += PHYSICS_DT_S  # wall-clock tick; each covers speed_factor x dt simulated
                if next_tick < time.monotonic() - 0.1:
                    next_tick = time.monotonic()

    # ------------------------------------------------------------------ control API
    def _targets(self, req, allow_all=True):
        which = req.get("vehicle", 0)
        if which == "all" and allow_all:
            return self.vehicles
        i = int(which)
        if not 0 <= i < len(self.vehicles):
            raise ValueError(f"no vehicle {i} (have {len(self.vehicles)})")
        return [self.vehicles[i]]

    def handle_control(self, req):
        cmd = req["cmd"]
        now = self.clock.now()
        if cmd == "ping":
            return {"ok": True, "time_s": round(now, 3), "speed_factor": self.args.speed_factor}
        if cmd == "info":
            return {"ok": True, **self.banner()}
        if cmd == "state":
            if req.get("vehicle") == "all":
                return {"ok": True, "vehicles": [v.state() for v in self.vehicles]}
            return {"ok": True, **self._targets(req, False)[0].state()}
        if cmd == "setpoint_stats":
            out = []
            for v in self._targets(req):
                s = v.stats.summary()
                s["vehicle"] = v.index
                if req.get("reset"):
                    v.stats.reset()
                out.append(s)
            return {"ok": True, **out[0]} if len(out) == 1 else {"ok": True, "vehicles": out}
        if cmd == "log":
            v = self._targets(req, False)[0]
            since = float(req.get("since_s", 0.0))
            return {"ok": True, "entries": [e for e in v.log if e["t"] >= since]}
        if cmd == "received":
            v = self._targets(req, False)[0]
            return {"ok": True, **v.received_since(float(req.get("since_s", 0.0)))}
        if cmd in ("gcs_command", "gcs_set_mode", "rc_mode"):
            v = self._targets(req, False)[0]
            if cmd == "rc_mode":
                taken = v.rc_mode(req["mode"])
                return {"ok": True, "taken": taken, "mode": v.mode_name(), "time_s": round(now, 3)}
            if cmd == "gcs_set_mode":
                command, params = M.MAV_CMD_DO_SET_MODE, v.set_mode_params(req["mode"])
            else:
                command, params = int(req["command"]), req.get("params", [])
            result = v.from_gcs(command, params)
            return {"ok": True, "result": result, "mode": v.mode_name(), "time_s": round(now, 3)}
        targets = self._targets(req)
        for v in targets:
            f = v.faults
            if cmd == "link_drop":
                f.link_down_until = now + float(req.get("duration_s", 5.0))
                v.note("fault", f"link down for {req.get('duration_s', 5.0)} s")
            elif cmd == "reboot":
                v.reboot(float(req.get("gap_s", self.args.reboot_gap_s)))
            elif cmd == "reject_command":
                count = req.get("count", 1)
                f.reject[int(req["command"])] = [int(req.get("result", 4)), None if count is None else int(count)]
            elif cmd == "packet_loss":
                p = float(req["probability"])
                if not 0.0 <= p <= 1.0:
                    raise ValueError("probability must be within [0, 1]")
                f.loss_probability = p
            elif cmd == "latency":
                f.latency_s = float(req.get("latency_ms", 0.0)) / 1000.0
                f.jitter_s = float(req.get("jitter_ms", 0.0)) / 1000.0
            elif cmd == "deny_arm":
                f.deny_arm_reason = req.get("reason", "Denied by fault injection") if req.get("enable", True) else None
                if req.get("px4_event"):
                    f.deny_arm_px4_event = req["px4_event"]
            elif cmd == "clear_faults":
                f.clear()
            elif cmd == "teleport":
                b = v.model.body
                b.pos = [float(x) for x in req["position_enu_m"]]
            else:
                raise ValueError(f"unknown cmd {cmd!r}")
        return {"ok": True, "vehicles": [v.index for v in targets]}


def main(argv=None):
    args = parse_args(argv)
    args.log_sink = open(args.log_jsonl, "a") if args.log_jsonl else None
    app = App(args)
    if not args.quiet:
        print(json.dumps({"ready": True, **app.banner()}), flush=True)
    try:
        app.run()
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
