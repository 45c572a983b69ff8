#!/usr/bin/env bash
# Installs Kestrel as a systemd service: the binary, a `kestrel` system user (in `dialout`,
# for the serial link), /etc/kestrel/kestrel.toml, an API token, the unit, and the autopilot
# profiles and example missions under /usr/share/kestrel. (The .deb installs the same files:
# `cargo deb`, see README.)
#
#   cargo build --release && sudo systemd/install.sh
#
# DESTDIR=/some/root installs the files under that root only (no user, no systemctl): for
# packaging and for testing this script.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${1:-target/release/kestrel}
ROOT=${DESTDIR:-}
[ -x "$BIN" ] || { echo "no binary at $BIN: run cargo build --release first" >&2; exit 1; }

install -D -m 0755 "$BIN" "$ROOT/usr/bin/kestrel"
if [ -z "$ROOT" ] && ! id kestrel >/dev/null 2>&1; then
    useradd --system --home-dir /var/lib/kestrel --no-create-home \
        --shell /usr/sbin/nologin --groups dialout kestrel
fi
install -d -m 0750 "$ROOT/etc/kestrel"
if [ ! -f "$ROOT/etc/kestrel/kestrel.toml" ]; then
    install -m 0640 systemd/kestrel.toml "$ROOT/etc/kestrel/kestrel.toml"
fi
if [ ! -s "$ROOT/etc/kestrel/api-token" ]; then
    (umask 027 && head -c 32 /dev/urandom | base64 | tr -d '/+=\n' > "$ROOT/etc/kestrel/api-token")
    echo "API token written to $ROOT/etc/kestrel/api-token"
fi
if [ -z "$ROOT" ]; then
    /usr/bin/kestrel check-config --config /etc/kestrel/kestrel.toml
else
    # The config names /etc/kestrel/api-token: check a copy naming the one under $ROOT.
    copy=$(mktemp)
    sed "s#\"/etc/kestrel/#\"$ROOT/etc/kestrel/#" "$ROOT/etc/kestrel/kestrel.toml" > "$copy"
    "$ROOT/usr/bin/kestrel" check-config --config "$copy" || { rm -f "$copy"; exit 1; }
    rm -f "$copy"
fi
install -D -m 0644 systemd/kestrel.service "$ROOT/etc/systemd/system/kestrel.service"
install -D -m 0644 README.md "$ROOT/usr/share/doc/kestrel/README.md"
install -d -m 0755 "$ROOT/usr/share/kestrel/platforms" "$ROOT/usr/share/kestrel/missions"
install -m 0644 platforms/*.toml "$ROOT/usr/share/kestrel/platforms/"
install -m 0644 missions/*.json "$ROOT/usr/share/kestrel/missions/"
if [ -z "$ROOT" ]; then
    chgrp -R kestrel /etc/kestrel
    systemctl daemon-reload
    systemctl enable --now kestrel
    echo "kestrel.service enabled; logs: journalctl -u kestrel -f"
fi
