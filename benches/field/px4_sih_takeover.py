# Mid-go_to on real PX4 SIH: a ground station (QGC ids 255/190) switches PX4 to AUTO.LOITER on its GCS
# link; reports how long until Kestrel's mission shows PAUSED/pilot_takeover, then RESUMEs and waits.
import json, sys, time, urllib.request
from pymavlink import mavutil
api = sys.argv[1]
def get(p):
    return json.load(urllib.request.urlopen(api + p))
def post(p, body):
    r = urllib.request.Request(api + p, data=json.dumps(body).encode(), headers={'Content-Type': 'application/json'})
    return json.load(urllib.request.urlopen(r))
gcs = mavutil.mavlink_connection('udpin:127.0.0.1:14550', source_system=255, source_component=190)
gcs.wait_heartbeat(timeout=10)
mission = {"target": "drone_0", "plan": [
    {"behavior": "takeoff", "args": {"height": 3.0, "speed": 1.0}},
    {"behavior": "go_to", "method": "go_to_path_facing", "args": {"x": 8.0, "y": 0.0, "z": 3.0, "speed": 1.0}},
    {"behavior": "land", "args": {"speed": 0.5}}]}
mid = post('/api/missions', mission)['mission_id']
post('/api/mission_update', {"drone_id": "drone_0", "mission_id": mid, "action": "START"})
while True:
    d = get('/api/status')['drones'][0]
    if d.get('behavior') == 'go_to' or (d.get('position_enu_m') or [0])[0] > 2.0:
        break
    time.sleep(0.1)
time.sleep(1.0)
t0 = time.time()
for _ in range(3):
    gcs.mav.command_long_send(1, 1, 176, 0, 1, 4, 3, 0, 0, 0, 0)
    time.sleep(0.05)
while time.time() - t0 < 5:
    m = get('/api/status')['drones'][0]['mission']
    if m.get('state') == 2 or m.get('last_error_code') == 'pilot_takeover':
        print('paused after %.2f s:' % (time.time() - t0), m.get('state'), m.get('last_error_code'), m.get('last_error'))
        break
    time.sleep(0.02)
else:
    print('NOT paused within 5 s', get('/api/status')['drones'][0]['mission'])
time.sleep(3)
d = get('/api/status')['drones'][0]
print('after 3 s: mode', d.get('mode'), 'position', d.get('position_enu_m'))
print('resume', post('/api/mission_update', {"drone_id": "drone_0", "mission_id": mid, "action": "RESUME"}))
t1 = time.time()
while time.time() - t1 < 90:
    m = get('/api/status')['drones'][0]['mission']
    if m.get('state') == 0:
        print('mission ended after resume in %.1f s:' % (time.time() - t1), json.dumps(m)[:400])
        break
    time.sleep(0.5)
