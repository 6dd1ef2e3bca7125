#!/usr/bin/env bash
# linerwatch-provision through its executable (docs/firmware.md, "Flashing and provisioning"):
# record -> show round trip, the record's bytes, check on both boards' real images, and the
# refusals: another board's image, an ELF, an image without a marker, one too big, a corrupted or
# foreign record, sensor id 0 and other bad arguments (exit 1 refused, 2 bad command line, one
# line naming what was wrong).
#   test_provision_cli.sh PROVISION_BIN ARM_BIN_DIR
set -u
tool=$1 bin=$2
work=$(mktemp -d "${TMPDIR:-/tmp}/lw-provision-cli.XXXXXX")
trap 'rm -rf "$work"' EXIT
failed=0
fail() { echo "FAIL: $*"; failed=1; }

# expect RC TEXT ARGS...: the tool exits RC and prints TEXT (a fixed string); a non-zero exit prints
# exactly one line.
expect() {
  local rc=$1 text=$2 got out
  shift 2
  out=$("$tool" "$@" 2>&1)
  got=$?
  [ "$got" = "$rc" ] || fail "linerwatch-provision $*: exit $got, expected $rc; output: $out"
  grep -qF -- "$text" <<<"$out" || fail "linerwatch-provision $*: output lacks '$text': $out"
  if [ "$rc" != 0 ] && [ "$(wc -l <<<"$out")" != 1 ]; then fail "linerwatch-provision $*: not one line: $out"; fi
}

l431=$bin/linerwatch-firmware-l431.bin nd=$bin/linerwatch-firmware-netduinoplus2.bin
for f in "$l431" "$nd" "$bin/linerwatch-firmware-l431.elf"; do
  [ -f "$f" ] || { echo "FAIL: $f missing (the cross build makes it)"; exit 1; }
done

# Round trip: the record's fields come back from its bytes; the bytes are the documented layout.
expect 0 "board l431, sensor 123456, api mode 1, 64 loops, 16 B at 0x0803E800" \
  record --board l431 --sensor-id 123456 --api-mode 1 --ladder-loops 64 --out "$work/r.bin"
[ "$(stat -c %s "$work/r.bin")" = 16 ] || fail "the record is not 16 bytes"
# 'LWPR', version 1, api mode 1, board 0x0431, sensor 123456 = 0x0001E240, 64 loops, 0xFF.
[ "$(head -c 14 "$work/r.bin" | od -An -tx1 | tr -d ' \n')" = 4c5750520101310440e2010040ff ] ||
  fail "record bytes: $(od -An -tx1 "$work/r.bin")"
expect 0 "board l431, sensor 123456, api mode 1, 64 loops" show --board l431 --record "$work/r.bin"
expect 0 "board netduinoplus2, sensor 7, api mode 2, 100 loops, 16 B at 0x08010000" \
  record --board netduinoplus2 --sensor-id 7 --out "$work/n.bin"
expect 0 "board netduinoplus2, sensor 7, api mode 2, 100 loops" show --board netduinoplus2 --record "$work/n.bin"
expect 0 "board l431, sensor 4294967295" record --board l431 --sensor-id 4294967295 --out "$work/max.bin"

# Records refused when read back.
expect 1 "a record for netduinoplus2, not for l431" show --board l431 --record "$work/n.bin"
cp "$work/r.bin" "$work/bad.bin"
printf '\x41' | dd of="$work/bad.bin" bs=1 seek=8 conv=notrunc status=none
expect 1 "fails its CRC" show --board l431 --record "$work/bad.bin"
head -c 16 /dev/zero | tr '\0' '\377' >"$work/erased.bin"
expect 1 "no provisioning record" show --board l431 --record "$work/erased.bin"
head -c 10 "$work/r.bin" >"$work/short.bin"
expect 1 "no provisioning record" show --board l431 --record "$work/short.bin"
expect 1 "cannot read" show --board l431 --record "$work/none.bin"

# Images: each board's own passes, the other's is refused naming both boards.
expect 0 "l431 (STM32L431), $(stat -c %s "$l431") B of 256000 B" check --board l431 --image "$l431"
expect 0 "netduinoplus2 (STM32F405), $(stat -c %s "$nd") B of 32768 B" check --board netduinoplus2 --image "$nd"
expect 1 "is an image for netduinoplus2 (STM32F405), not for l431 (STM32L431)" check --board l431 --image "$nd"
expect 1 "is an image for l431 (STM32L431), not for netduinoplus2 (STM32F405)" check --board netduinoplus2 --image "$l431"
expect 1 "is an ELF file; give the .bin" check --board l431 --image "$bin/linerwatch-firmware-l431.elf"
head -c 4096 /dev/urandom | tr -d 'L' >"$work/noise.bin"
expect 1 "is not a linerwatch firmware image (no board marker" check --board l431 --image "$work/noise.bin"
cp "$nd" "$work/big.bin"
truncate -s 32769 "$work/big.bin"
expect 1 "is 32769 B, over the 32768 B netduinoplus2 has below its provisioning page" check --board netduinoplus2 --image "$work/big.bin"

# Bad command lines: exit 2, nothing written.
expect 2 "--sensor-id 0 is out of range" record --board l431 --sensor-id 0 --out "$work/zero.bin"
[ ! -e "$work/zero.bin" ] || fail "a record was written for sensor id 0"
expect 2 "--sensor-id" record --board l431 --sensor-id 4294967296 --out "$work/zero.bin"
expect 2 "--api-mode" record --board l431 --sensor-id 5 --api-mode 3 --out "$work/zero.bin"
expect 2 "--ladder-loops" record --board l431 --sensor-id 5 --ladder-loops 129 --out "$work/zero.bin"
expect 2 "record needs --sensor-id" record --board l431 --out "$work/zero.bin"
expect 2 "record needs --out" record --board l431 --sensor-id 5
expect 2 "check needs --image" check --board l431
expect 2 "unknown board 'stm32'" check --board stm32 --image "$l431"
expect 2 "unknown command 'flash'" flash --board l431
[ ! -e "$work/zero.bin" ] || fail "a record was written from a bad command line"
expect 0 "usage: linerwatch-provision" --help

[ "$failed" = 0 ] && echo "test_provision_cli: all checks passed"
exit "$failed"
