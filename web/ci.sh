#!/usr/bin/env bash
# Ground station CI: npm deps from the lock file, type check and build of web/dist, unit tests,
# then browser tests in Debian's chromium against the real kestrel named by $KESTREL_BIN.
#   KESTREL_BIN=target/release/kestrel bash web/ci.sh
#   WEB_E2E=0 bash web/ci.sh     # build and unit tests only (no kestrel yet)
set -euo pipefail
# A relative KESTREL_BIN is relative to where the script was called from.
if [ -n "${KESTREL_BIN:-}" ]; then KESTREL_BIN="$(realpath -m "$KESTREL_BIN")"; fi
cd "$(dirname "$0")"

echo "== web: npm ci"
npm ci --no-audit --no-fund --loglevel=error

echo "== web: type check and build (web/dist)"
npm run --silent build

echo "== web: unit tests"
npx vitest run

if [ "${WEB_E2E:-1}" = "0" ]; then
  echo "== web: browser tests skipped (WEB_E2E=0)"
  exit 0
fi

: "${KESTREL_BIN:?KESTREL_BIN must name the kestrel binary for the browser tests}"
if [ ! -x /usr/bin/chromium ]; then
  echo "== web: installing Debian chromium"
  export DEBIAN_FRONTEND=noninteractive
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq chromium >/dev/null
fi

echo "== web: browser tests (playwright-core + /usr/bin/chromium, kestrel at $KESTREL_BIN)"
rm -rf ../artifacts/web
[ -x "$KESTREL_BIN" ] || { echo "KESTREL_BIN=$KESTREL_BIN is not an executable" >&2; exit 1; }
KESTREL_BIN="$KESTREL_BIN" node --test --test-concurrency=1 e2e/
