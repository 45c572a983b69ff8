# Listens on a MAVLink endpoint for SECONDS and writes the chosen messages as JSON lines (with
# _t, seconds since start). Usage: python listen.py ENDPOINT SECONDS OUT.jsonl MSG1,MSG2
import sys, time, json
from pymavlink import mavutil
m = mavutil.mavlink_connection(sys.argv[1])
dur = float(sys.argv[2]); out = open(sys.argv[3], 'w')
want = set(sys.argv[4].split(','))
t0 = time.time()
while time.time() - t0 < dur:
    msg = m.recv_match(blocking=True, timeout=1)
    if msg is None: continue
    t = msg.get_type()
    if t in want:
        d = msg.to_dict(); d['_t'] = time.time() - t0; d['_src'] = [msg.get_srcSystem(), msg.get_srcComponent()]
        out.write(json.dumps(d) + '\n')
