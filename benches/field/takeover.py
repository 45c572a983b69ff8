# Mid-go_to on a real SITL autopilot, a ground station (QGC's ids 255/190) switches the vehicle to
# a hold mode on its own GCS link; reports how long until Kestrel's mission shows
# PAUSED/pilot_takeover, checks 3 s later that Kestrel switched nothing back, then RESUMEs and
# waits for the mission's end.
#
#   python takeover.py API_URL px4        # PX4 SIH: GCS link udpin:127.0.0.1:14550, AUTO.LOITER
#   python takeover.py API_URL ardupilot  # ArduCopter SITL: SERIAL1 tcp:127.0.0.1:5762, LOITER
import json, sys, threading, time, urllib.request
from pymavlink import mavutil

api, autopilot = sys.argv[1], (sys.argv[2] if len(sys.argv) > 2 else 'px4')
# MAV_CMD_DO_SET_MODE (176): base mode 1 (custom mode enabled), then the custom mode. PX4: main
# mode 4 (AUTO), sub mode 3 (LOITER). ArduCopter: mode 5 (LOITER).
link, mode = {'px4': ('udpin:127.0.0.1:14550', (4, 3)),
              'ardupilot': ('tcp:127.0.0.1:5762', (5, 0))}[autopilot]


def get(p):
    return json.load(urllib.request.urlopen(api + p))


def post(p, body):
    r = urllib.request.Request(api + p, data=json.dumps(body).encode(),
                               headers={'Content-Type': 'application/json'})
    return json.load(urllib.request.urlopen(r))


gcs = mavutil.mavlink_connection(link, source_system=255, source_component=190)
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
# ArduCopter's hold (LOITER) takes the pilot's throttle stick as a climb rate, and SITL's sticks
# rest at zero throttle: without a pilot's hand on them the vehicle descends to the ground. The
# pilot holds the sticks centred (RC_CHANNELS_OVERRIDE, channels 1-4 at 1500 us, the rest
# untouched) from just before the switch until 2 s after the RESUME.
sticks = threading.Event()


def hold_sticks():
    while not sticks.is_set():
        gcs.mav.rc_channels_override_send(1, 1, 1500, 1500, 1500, 1500, *([65535] * 4))
        time.sleep(0.2)


if autopilot == 'ardupilot':
    threading.Thread(target=hold_sticks, daemon=True).start()
    time.sleep(0.5)
t0 = time.time()
for _ in range(3):
    gcs.mav.command_long_send(1, 1, 176, 0, 1, mode[0], mode[1], 0, 0, 0, 0)
    time.sleep(0.05)
while time.time() - t0 < 5:
    m = get('/api/status')['drones'][0]['mission']
    if m.get('state') == 2 or m.get('last_error_code') == 'pilot_takeover':
        print('paused after %.2f s:' % (time.time() - t0), m.get('state'), m.get('last_error_code'),
              m.get('last_error'))
        break
    time.sleep(0.02)
else:
    print('NOT paused within 5 s', get('/api/status')['drones'][0]['mission'])
time.sleep(3)
d = get('/api/status')['drones'][0]
print('after 3 s: mode', d.get('mode'), 'position', d.get('position_enu_m'))
print('resume', post('/api/mission_update', {"drone_id": "drone_0", "mission_id": mid, "action": "RESUME"}))
t1 = time.time()
time.sleep(2)
sticks.set()
while time.time() - t1 < 120:
    m = get('/api/status')['drones'][0]['mission']
    if m.get('state') == 0:
        print('mission ended after resume in %.1f s:' % (time.time() - t1), json.dumps(m)[:400])
        break
    time.sleep(0.5)
else:
    print('mission NOT ended 120 s after resume', get('/api/status')['drones'][0]['mission'])
