# Listens on a MAVLink endpoint for SECONDS and writes the chosen messages as JSON lines (with
# _t, seconds since start). Usage: python listen.py ENDPOINT SECONDS OUT.jsonl MSG1,MSG2
# When HIL_STATE_QUATERNION is among them, asks the autopilot to stream it at 50 Hz (PX4 SIH
# fills it from its simulator's ground truth).
import sys, time, json
from pymavlink import mavutil
m = mavutil.mavlink_connection(sys.argv[1])
dur = float(sys.argv[2]); out = open(sys.argv[3], 'w')
want = set(sys.argv[4].split(','))
t0 = time.time()
asked = {}  # requests sent per system (several autopilots may send to one endpoint)
while time.time() - t0 < dur:
    msg = m.recv_match(blocking=True, timeout=1)
    if msg is None: continue
    t = msg.get_type()
    src = msg.get_srcSystem()
    if 'HIL_STATE_QUATERNION' in want and t == 'HEARTBEAT' and msg.get_srcComponent() == 1 \
            and asked.get(src, 0) < 5:
        # MAV_CMD_SET_MESSAGE_INTERVAL (511): message 115 every 20 000 us, to the sender just heard.
        m.mav.command_long_send(src, 1, 511, 0, 115, 20000, 0, 0, 0, 0, 0)
        asked[src] = asked.get(src, 0) + 1
    if t in want:
        d = msg.to_dict(); d['_t'] = time.time() - t0; d['_src'] = [msg.get_srcSystem(), msg.get_srcComponent()]
        out.write(json.dumps(d) + '\n')
