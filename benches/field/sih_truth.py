# How far PX4's own estimate (LOCAL_POSITION_NED) was from PX4 SIH's ground truth
# (HIL_STATE_QUATERNION) in one listener capture, while flying above 1.5 m.
# Usage: python3 sih_truth.py CAPTURE.jsonl
# The two are paired by arrival time (SIH leaves time_usec at 0); the truth's geodetic position is
# put in a local north-east frame at its first sample, and the constant offset between the two
# frames (the mean over the flight) is taken out of the position error.
import bisect, json, math, sys

rows = [json.loads(line) for line in open(sys.argv[1])]
truth = [r for r in rows if r['mavpackettype'] == 'HIL_STATE_QUATERNION']
est = [r for r in rows if r['mavpackettype'] == 'LOCAL_POSITION_NED']
if not truth or not est:
    print('truth: n/a (no HIL_STATE_QUATERNION or LOCAL_POSITION_NED)')
    sys.exit(0)
lat0, lon0 = truth[0]['lat'] / 1e7, truth[0]['lon'] / 1e7
m_per_deg = math.pi / 180 * 6378137


def north_east(h):
    return ((h['lat'] / 1e7 - lat0) * m_per_deg,
            (h['lon'] / 1e7 - lon0) * m_per_deg * math.cos(math.radians(lat0)))


times = [h['_t'] for h in truth]
pairs = []
for e in est:
    i = bisect.bisect_left(times, e['_t'])
    if 0 < i < len(truth) and -e['z'] > 1.5:
        h = truth[i]
        n, ea = north_east(h)
        pairs.append((e['x'] - n, e['y'] - ea, e['vx'] - h['vx'] / 100, e['vy'] - h['vy'] / 100))
if not pairs:
    print('truth: n/a (never above 1.5 m)')
    sys.exit(0)
ox = sum(p[0] for p in pairs) / len(pairs)
oy = sum(p[1] for p in pairs) / len(pairs)
pos = sorted(math.hypot(p[0] - ox, p[1] - oy) for p in pairs)
vel = sorted(math.hypot(p[2], p[3]) for p in pairs)


def q(v, f):
    return v[min(int(f * len(v)), len(v) - 1)]


print('estimate vs truth: position p50 %.2f p95 %.2f max %.2f m; velocity p50 %.2f p95 %.2f max %.2f m/s'
      % (q(pos, .5), q(pos, .95), pos[-1], q(vel, .5), q(vel, .95), vel[-1]))
