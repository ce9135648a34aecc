#!/usr/bin/env bash
# `tessera health`, the containers' health probe, against a real tessera-server on loopback (no
# Docker): SERVING and exit 0 while it runs, exit 1 for a service the server does not know, and
# exit 1 with "cannot reach" once it has stopped.
#
#   health_command_test.sh TESSERA_CLI TESSERA_SERVER
set -euo pipefail
cli=${1:?usage: health_command_test.sh TESSERA_CLI TESSERA_SERVER}
server=${2:?usage: health_command_test.sh TESSERA_CLI TESSERA_SERVER}
tmp=$(mktemp -d /tmp/tessera-health-test.XXXXXX)
pid=""
cleanup() {
  [ -n "$pid" ] && kill -KILL "$pid" 2>/dev/null || true
  rm -rf "$tmp"
}
trap cleanup EXIT
fail() { echo "FAILED: $*" >&2; cat "$tmp"/*.log >&2 2>/dev/null || true; exit 1; }

"$server" --listen 127.0.0.1:0 --data-dir "$tmp/data" >"$tmp/server.log" 2>&1 &
pid=$!
addr=""
for _ in $(seq 1 100); do
  addr=$(grep -oE 'listening on [0-9.]+:[0-9]+' "$tmp/server.log" | head -1 | awk '{print $3}') || true
  [ -n "$addr" ] && break
  kill -0 "$pid" 2>/dev/null || fail "tessera-server exited"
  sleep 0.1
done
[ -n "$addr" ] || fail "tessera-server did not say where it listens"

out=$("$cli" health --coordinator "$addr" --timeout 5) || fail "health of a running coordinator: exit $?: $out"
[ "$out" = "coordinator $addr: SERVING" ] || fail "unexpected output for a running coordinator: '$out'"
out=$("$cli" health --coordinator "$addr" --quiet) || fail "health --quiet: exit $?"
[ -z "$out" ] || fail "health --quiet printed '$out'"

rc=0
out=$("$cli" health --coordinator "$addr" --service no.such.Service 2>&1) || rc=$?
[ "$rc" -eq 1 ] || fail "unknown service: exit $rc, expected 1 ($out)"
[[ "$out" == *"unknown to the coordinator"* ]] || fail "unknown service: '$out'"

kill -TERM "$pid"
wait "$pid" || true
pid=""
rc=0
out=$("$cli" health --coordinator "$addr" --timeout 2 2>&1) || rc=$?
[ "$rc" -eq 1 ] || fail "stopped coordinator: exit $rc, expected 1 ($out)"
[[ "$out" == *"cannot reach the coordinator at $addr"* ]] || fail "stopped coordinator: '$out'"
echo "tessera health: SERVING while running, 1 for an unknown service, 1 once stopped"
