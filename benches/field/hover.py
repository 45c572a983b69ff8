# PX4 SIH alone: arm, AUTO.TAKEOFF, hold in its own AUTO.LOITER; prints how far its estimate wanders from
# its mean after 15 s (p50, p95, max, m) and its speed (p95, m/s). Usage: python hover.py SECONDS, with
# ../shared/anchors/run-px4-sih.sh 0 start running (companion link udp 14540).
import json, math, sys, time
from pymavlink import mavutil
m = mavutil.mavlink_connection('udpin:0.0.0.0:14540', source_system=1, source_component=191)
m.wait_heartbeat(timeout=10)
def cmd(c, *p):
    p = list(p) + [0] * (7 - len(p))
    m.mav.command_long_send(1, 1, c, 0, *p)
time.sleep(2)
cmd(400, 1)  # arm
time.sleep(0.5)
cmd(176, 1, 4, 2)  # AUTO.TAKEOFF
t0 = time.time(); xs = []
while time.time() - t0 < float(sys.argv[1]):
    msg = m.recv_match(type='LOCAL_POSITION_NED', blocking=True, timeout=1)
    if msg and time.time() - t0 > 15:
        xs.append((msg.x, msg.y, msg.z, msg.vx, msg.vy))
if xs:
    mx = sum(x[0] for x in xs) / len(xs); my = sum(x[1] for x in xs) / len(xs); mz = sum(x[2] for x in xs) / len(xs)
    d = sorted(math.hypot(x[0] - mx, x[1] - my) for x in xs)
    sp = sorted(math.hypot(x[3], x[4]) for x in xs)
    print(json.dumps({"n": len(xs), "mean": [mx, my, mz], "p50_m": d[len(d)//2], "p95_m": d[int(len(d)*.95)], "max_m": d[-1], "speed_p95": sp[int(len(sp)*.95)]}))
