#!/usr/bin/env bash
# A server started on a full disk (docs/reliability.md, "Disk-full run"): it must start, serve what
# it has read-only, answer /healthz 503 "degraded" with the reason, refuse REST writes with 503 (and
# take nothing from the broker, so nothing is acked), and store again once space returns.
#
#   bench/chaos/disk_full_start.sh DIR [BUILD]
# DIR must be a small file system of its own that may be filled, e.g. as root:
#   mkdir -p /mnt/lwfull && mount -t tmpfs -o size=16m tmpfs /mnt/lwfull
# BUILD is the build tree (default build). Exit status 0 when every check held.
set -u
cd "$(dirname "$0")/../.."
dir=${1:?usage: bench/chaos/disk_full_start.sh DIR [BUILD]}
build=${2:-build}
port=$((20000 + RANDOM % 20000))
db=$dir/lw-diskfull.sqlite
server=("$build/bin/linerwatch-server" --broker tcp://127.0.0.1:1 --db "$db" --crusher-dir fuzz/data --http "127.0.0.1:$port")
reading() { echo "{\"readings\":[{\"sensor\":\"1001\",\"seq\":$1,\"time\":\"2026-02-0$1T00:00:00Z\",\"thickness_mm\":11$1.0,\"loops_intact\":3,\"flags\":0,\"battery_mv\":3600}]}"; }
post() { curl -s -o /dev/null -w '%{http_code}' -X POST -H 'Content-Type: application/json' "127.0.0.1:$port/api/v1/crushers/fz1/readings" -d "$(reading "$1")"; }
wait_up() { for _ in $(seq 100); do curl -s -o /dev/null "127.0.0.1:$port/healthz" && return 0; sleep 0.2; done; return 1; }
failed=0
check() { if eval "$2"; then echo "ok    $1"; else echo "FAIL  $1"; failed=1; fi; }

rm -f "$db" "$db-wal" "$db-shm" "$dir/filler"
"${server[@]}" >/dev/null 2>&1 & pid=$!
wait_up
check "stores readings 1 and 2 with space" '[ "$(post 1)" = 200 ] && [ "$(post 2)" = 200 ]'
kill "$pid"; wait "$pid"
dd if=/dev/zero of="$dir/filler" bs=64k 2>/dev/null
echo "filled: $(df -B1 --output=avail "$dir" | tail -1) bytes free"
log=$(mktemp)
"${server[@]}" >"$log" 2>&1 & pid=$!
wait_up
sleep 1
check "starts on the full disk" 'kill -0 $pid'
check "/healthz 503 degraded, reason disk full" '[ "$(curl -s -o /tmp/lw-h.json -w "%{http_code}" 127.0.0.1:$port/healthz)" = 503 ] && grep -q "\"reason\":\"disk full" /tmp/lw-h.json'
check "serves the 2 stored readings" '[ "$(curl -s 127.0.0.1:$port/api/v1/crushers/fz1/sensors/1001/readings | grep -o "\"seq\"" | wc -l)" = 2 ]'
check "refuses a REST write with 503" '[ "$(post 3)" = 503 ]'
rm -f "$dir/filler"
sleep 7
check "healthy again once space returned" '[ "$(curl -s -o /dev/null -w "%{http_code}" 127.0.0.1:$port/healthz)" = 200 ]'
check "stores reading 3 again" '[ "$(post 3)" = 200 ]'
check "3 readings stored" '[ "$(curl -s 127.0.0.1:$port/api/v1/crushers/fz1/sensors/1001/readings | grep -o "\"seq\"" | wc -l)" = 3 ]'
kill "$pid"; wait "$pid"
grep -E "disk full|writable again" "$log" | cut -c1-220
rm -f "$log" "$db" "$db-wal" "$db-shm" /tmp/lw-h.json
[ "$failed" = 0 ] && echo "disk_full_start: every check held" || echo "disk_full_start: FAILED"
exit "$failed"
