#!/usr/bin/env bash
# Installs the .deb into a throwaway root and flies the INSTALLED kestrel against the fake PX4.
#
#   tests/deb_install.sh target/debian/kestrel_*.deb     (as root; .ci/run calls it)
#
# The install is real dpkg with the package's maintainer scripts, in a root of its own:
# `dpkg --root=R --force-script-chrootless` runs them on the host with DPKG_ROOT=R, and they
# write under $DPKG_ROOT only (useradd --prefix, numeric ids from R's /etc/group). The root
# holds a dpkg database, a minimal passwd/group, and a policy-rc.d that forbids starting
# services, so nothing on the host is enabled or started. Checked: the files, the conffile, the
# user and token, the unit enabled; `systemd-analyze verify` of the installed unit; the
# installed `kestrel check-config` and `kestrel run` (the unit's command, with the config's
# paths moved under R and the installed profile found through KESTREL_DATA_DIR) until the fake
# PX4 is flying a mission uploaded over the API; a reinstall keeping the token and the config;
# a purge removing token, state and logs; and an install after the purge.
set -euo pipefail
cd "$(dirname "$0")/.."
DEB=${1:?usage: tests/deb_install.sh PACKAGE.deb}
PYTHON=sitl/.venv/bin/python
[ -f "$DEB" ] || { echo "no package at $DEB" >&2; exit 1; }
[ -x "$PYTHON" ] || { echo "$PYTHON missing: run bash sitl/setup.sh" >&2; exit 1; }

R=$(mktemp -d)
W=$(mktemp -d)
pids=()
cleanup() {
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    wait 2>/dev/null || true
    rm -rf "$R" "$W"
}
trap cleanup EXIT
fail() {
    echo "deb_install: FAIL: $*" >&2
    for f in "$W"/*.out; do [ -f "$f" ] && { echo "--- $f" >&2; tail -30 "$f" >&2; }; done
    exit 1
}
check() { local what=$1; shift; "$@" >/dev/null || fail "$what"; }

mkdir -p "$R/var/lib/dpkg/info" "$R/var/lib/dpkg/updates" "$R/etc" "$R/usr/sbin"
touch "$R/var/lib/dpkg/status" "$R/var/lib/dpkg/available"
printf 'root:x:0:0:root:/root:/bin/sh\n' > "$R/etc/passwd"
printf 'root:x:0:\ndialout:x:20:\n' > "$R/etc/group"
printf 'root:*:19000:0:99999:7:::\n' > "$R/etc/shadow"
printf 'root:*::\ndialout:*::\n' > "$R/etc/gshadow"
printf '#!/bin/sh\nexit 101\n' > "$R/usr/sbin/policy-rc.d"
chmod 0755 "$R/usr/sbin/policy-rc.d"
dpkg_r() {
    dpkg --root="$R" --force-script-chrootless --force-depends --log=/dev/null "$@" \
        > "$W/dpkg.out" 2>&1 || fail "dpkg $*"
}

echo "== install $DEB into $R"
dpkg_r -i "$DEB"
for f in usr/bin/kestrel usr/lib/systemd/system/kestrel.service etc/kestrel/kestrel.toml \
    usr/share/kestrel/platforms/px4.toml usr/share/kestrel/platforms/ardupilot-copter.toml \
    usr/share/kestrel/missions/takeoff_go_land.json usr/share/doc/kestrel/README.md; do
    check "$f installed" test -f "$R/$f"
done
check "binary stripped" sh -c "! file -L '$R/usr/bin/kestrel' | grep -q 'not stripped'"
check "kestrel.toml is a conffile" \
    grep -qx /etc/kestrel/kestrel.toml "$R/var/lib/dpkg/info/kestrel.conffiles"
check "user kestrel" grep -q '^kestrel:.*:/var/lib/kestrel:/usr/sbin/nologin$' "$R/etc/passwd"
check "kestrel in dialout" grep -q '^dialout:x:20:kestrel$' "$R/etc/group"
gid=$(awk -F: '$1 == "kestrel" { print $3 }' "$R/etc/group")
check "token 0640 root:kestrel" \
    test "$(stat -c '%a %u %g' "$R/etc/kestrel/api-token")" = "640 0 $gid"
check "token not empty" test -s "$R/etc/kestrel/api-token"
check "config readable by the service" \
    test "$(stat -c '%a %g' "$R/etc/kestrel/kestrel.toml")" = "640 $gid"
check "unit enabled" test -L "$R/etc/systemd/system/multi-user.target.wants/kestrel.service"
token=$(cat "$R/etc/kestrel/api-token")

echo "== systemd-analyze verify of the installed unit"
# verify checks that ExecStart exists on this host and needs the host's targets (the root has
# none): the installed unit, pointed at the installed binary.
sed "s#/usr/bin/kestrel#$R/usr/bin/kestrel#g" "$R/usr/lib/systemd/system/kestrel.service" \
    > "$W/kestrel.service"
systemd-analyze verify "$W/kestrel.service" > "$W/verify.out" 2>&1 || fail "systemd-analyze verify"

echo "== the installed kestrel: check-config, then run against the fake PX4"
free_port() { "$PYTHON" -c "import socket,sys; s=socket.socket(socket.AF_INET,getattr(socket,sys.argv[1])); s.bind(('127.0.0.1',0)); print(s.getsockname()[1])" "$1"; }
control=$(free_port SOCK_STREAM)
px4_listen=$(free_port SOCK_DGRAM)
px4_remote=$(free_port SOCK_DGRAM)
api=$(free_port SOCK_STREAM)
# The shipped config with its paths under the root, the installed profile by path (found under
# KESTREL_DATA_DIR, not in the working directory) and the fake's link.
{
    printf '[mavlink]\nplatform = "platforms/px4.toml"\nconnection = "udpin:127.0.0.1:%s"\n\n' "$px4_remote"
    sed -e "s#\"/etc/kestrel#\"$R/etc/kestrel#; s#\"/var/#\"$R/var/#" \
        -e "s#^listen = .*#listen = \"127.0.0.1:$api\"#" "$R/etc/kestrel/kestrel.toml"
} > "$W/kestrel.toml"
export KESTREL_DATA_DIR="$R/usr/share/kestrel"
unset KESTREL_API_TOKEN STATE_DIRECTORY
(cd "$W" && "$R/usr/bin/kestrel" check-config --config "$W/kestrel.toml") > "$W/check.out" 2>&1 \
    || fail "check-config"
check "check-config summary" grep -q "platform   PX4 ($R/usr/share/kestrel/platforms/px4.toml)" "$W/check.out"
check "check-config token" grep -q "token      yes" "$W/check.out"

"$PYTHON" sitl/fake_autopilot.py --personality px4 --control-port "$control" \
    --px4-listen-base "$px4_listen" --px4-remote-base "$px4_remote" > "$W/fake.out" 2>&1 &
pids+=($!)
(cd "$W" && RUST_LOG=warn exec "$R/usr/bin/kestrel" run --config "$W/kestrel.toml") \
    > "$W/kestrel.out" 2>&1 &
pids+=($!)
fake_state() {
    "$PYTHON" -c "import json,socket,sys; s=socket.create_connection(('127.0.0.1',int(sys.argv[1])),5); s.sendall(b'{\"cmd\":\"state\"}\n'); print(s.makefile().readline())" "$control"
}
base="http://127.0.0.1:$api"
auth=(-H "Authorization: Bearer $token")
wait_for() { # seconds, description, command...
    local until=$((SECONDS + $1)) what=$2; shift 2
    until "$@" >/dev/null 2>&1; do
        [ $SECONDS -lt $until ] || fail "$what"
        sleep 0.5
    done
}
wait_for 30 "API up" curl -sf "$base/api/health"
check "API refuses a missing token" \
    test "$(curl -s -o /dev/null -w '%{http_code}' "$base/api/status")" = 401
mission_id=$(curl -sf "${auth[@]}" -H 'Content-Type: application/json' \
    --data-binary @"$R/usr/share/kestrel/missions/takeoff_go_land.json" "$base/api/missions" \
    | jq -e .mission_id) || fail "mission upload"
start() {
    curl -s "${auth[@]}" -H 'Content-Type: application/json' \
        -d "{\"drone_id\":\"drone_0\",\"mission_id\":$mission_id,\"action\":2}" \
        "$base/api/mission_update" | jq -e '.accepted == true'
}
# START is refused until the autopilot is ready (heartbeat, position, armable).
wait_for 60 "mission START accepted" start
airborne() {
    fake_state | jq -e '.armed == true and .position_enu_m[2] - .local_origin_enu_m[2] > 2.0'
}
wait_for 60 "the fake PX4 flying the mission (armed, above 2 m)" airborne
mission_running() { curl -sf "${auth[@]}" "$base/api/missions" | jq -e '.[0].state == 1'; }
check "mission running" mission_running
check "flight log in the installed log dir" sh -c "ls '$R'/var/log/kestrel/kestrel-run-*.jsonl"
check "mission saved in the installed state dir" test -n "$(ls -A "$R/var/lib/kestrel")"
kill "${pids[@]}" 2>/dev/null || true
wait 2>/dev/null || true
pids=()

echo "== reinstall keeps the token and an edited config"
echo '# edited by the operator' >> "$R/etc/kestrel/kestrel.toml"
dpkg_r -i --force-confold "$DEB"
check "token kept" test "$(cat "$R/etc/kestrel/api-token")" = "$token"
check "edited config kept" grep -q 'edited by the operator' "$R/etc/kestrel/kestrel.toml"
check "one kestrel user" test "$(grep -c '^kestrel:' "$R/etc/passwd")" = 1

echo "== purge"
dpkg_r --purge kestrel
for f in usr/bin/kestrel etc/kestrel var/lib/kestrel var/log/kestrel \
    etc/systemd/system/multi-user.target.wants/kestrel.service; do
    check "$f removed by purge" test ! -e "$R/$f"
done
check "user kept after purge (Debian policy)" grep -q '^kestrel:' "$R/etc/passwd"

echo "== install after purge"
dpkg_r -i "$DEB"
check "new token" test -s "$R/etc/kestrel/api-token"
check "new token differs" test "$(cat "$R/etc/kestrel/api-token")" != "$token"
check "user reused" test "$(grep -c '^kestrel:' "$R/etc/passwd")" = 1
sed -e "s#\"/etc/kestrel#\"$R/etc/kestrel#; s#\"/var/#\"$R/var/#" \
    "$R/etc/kestrel/kestrel.toml" > "$W/again.toml"
"$R/usr/bin/kestrel" check-config --config "$W/again.toml" > "$W/check-again.out" 2>&1 \
    || fail "check-config after reinstall"
echo "deb_install: OK"
