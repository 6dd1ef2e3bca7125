#!/usr/bin/env bash
# scripts/flash (docs/firmware.md, "Flashing and provisioning") without a board attached:
# --dry-run on each board and tool prints the tool commands with the board's openocd target, the
# image at the flash base and the record at the address of the board's PROVISION region in its
# linker script, and leaves the record it would write (decoded back by linerwatch-provision);
# a wrong image, bad arguments, a missing tool and an absent probe or port are refused in one line;
# a real stm32flash run against a model of the serial bootloader writes the image and the record.
#   test_flash.sh SOURCE_DIR PROVISION_BIN ARM_BIN_DIR
set -u
src=$1 bin=$3
export LW_PROVISION=$2
flash=$src/scripts/flash
work=$(mktemp -d "${TMPDIR:-/tmp}/lw-flash-test.XXXXXX")
trap 'rm -rf "$work"' EXIT
# The script's own temporary folders too (a dry run without --work keeps its record there).
mkdir -p "$work/tmp"
export TMPDIR=$work/tmp
failed=0
fail() { echo "FAIL: $*"; failed=1; }
has() { grep -qF -- "$2" <<<"$1" || fail "${3:-output} lacks '$2':"$'\n'"$1"; }
lacks() { ! grep -qF -- "$2" <<<"$1" || fail "${3:-output} has '$2':"$'\n'"$1"; }
run() { out=$("$flash" "$@" 2>&1); rc=$?; }
one_error_line() { [ "$(grep -c '^flash: ' <<<"$out")" = "${2:-1}" ] || fail "$1: not one line from flash:"$'\n'"$out"; }

# The record's address as the board's linker script places its PROVISION region.
provision_origin() {
  local o
  o=$(grep -E '^\s*PROVISION\s*\(' "$src/firmware/board/$1/linker.ld" | grep -oE 'ORIGIN = 0x[0-9A-Fa-f]+' | awk '{print $3}')
  [ -n "$o" ] || fail "no PROVISION region in firmware/board/$1/linker.ld"
  printf '0x%08X' "$o"
}

for board in netduinoplus2 l431; do
  image=$bin/linerwatch-firmware-$board.bin
  [ -f "$image" ] || { echo "FAIL: $image missing (the cross build makes it)"; exit 1; }
  at=$(provision_origin "$board")
  case $board in netduinoplus2) cfg=target/stm32f4x.cfg chip=0x413 ;; l431) cfg=target/stm32l4x.cfg chip=0x435 ;; esac
  rec=$work/$board/record-$board-31337.bin rb=$work/$board/readback-$board-31337.bin

  run --board "$board" --image "$image" --sensor-id 31337 --api-mode 1 --ladder-loops 90 --dry-run --work "$work/$board"
  [ "$rc" = 0 ] || fail "$board openocd dry run: exit $rc: $out"
  has "$out" "openocd -f interface/stlink.cfg -f $cfg -c init -c 'mdw 0xE0042000' -c shutdown    # the attached chip must be $chip"
  has "$out" "openocd -f interface/stlink.cfg -f $cfg -c init -c 'reset init' -c 'flash write_image erase $image 0x08000000' -c 'verify_image $image 0x08000000' -c 'flash write_image erase $rec $at' -c 'verify_image $rec $at' -c 'dump_image $rb $at 16' -c 'reset run' -c shutdown"
  has "$out" "linerwatch-provision show --board $board --record $rb"
  has "$out" "nothing written"
  [ -f "$rec" ] || fail "$board: the dry run left no record at $rec"
  shown=$("$LW_PROVISION" show --board "$board" --record "$rec" 2>&1) || fail "$board: the record does not decode: $shown"
  has "$shown" "board $board, sensor 31337, api mode 1, 90 loops" "the record"

  run --board "$board" --image "$image" --sensor-id 31337 --tool st-flash --dry-run --work "$work/$board"
  [ "$rc" = 0 ] || fail "$board st-flash dry run: exit $rc: $out"
  has "$out" "st-info --chipid    # the attached chip must be $chip"
  has "$out" "  st-flash write $image 0x08000000"$'\n'"  st-flash write $rec $at"$'\n'"  st-flash read $rb $at 16"$'\n'"  st-flash reset"

  run --board "$board" --image "$image" --sensor-id 31337 --tool stm32flash --port /dev/ttyUSB7 --baud 57600 --dry-run --work "$work/$board"
  [ "$rc" = 0 ] || fail "$board stm32flash dry run: exit $rc: $out"
  has "$out" "stm32flash -b 57600 /dev/ttyUSB7    # the attached chip must be $chip"
  has "$out" "  stm32flash -b 57600 -c -w $image -v -S 0x08000000 /dev/ttyUSB7"$'\n'"  stm32flash -b 57600 -c -w $rec -v -S $at /dev/ttyUSB7"$'\n'"  stm32flash -b 57600 -c -r $rb -S $at:16 /dev/ttyUSB7"$'\n'"  stm32flash -b 57600 -c -g 0x08000000 /dev/ttyUSB7"
done

# The other board's image: refused before any tool command, one line naming both boards.
run --board l431 --image "$bin/linerwatch-firmware-netduinoplus2.bin" --sensor-id 5 --dry-run --work "$work/wrong"
[ "$rc" = 1 ] || fail "wrong image: exit $rc, expected 1"
has "$out" "flash: refused: $bin/linerwatch-firmware-netduinoplus2.bin is an image for netduinoplus2 (STM32F405), not for l431 (STM32L431)"
lacks "$out" "openocd"
one_error_line "wrong image"
[ ! -e "$work/wrong" ] || fail "wrong image: a record was made"
run --board netduinoplus2 --image "$bin/linerwatch-firmware-netduinoplus2.elf" --sensor-id 5 --dry-run
[ "$rc" = 1 ] || fail "an ELF: exit $rc, expected 1"
has "$out" "is an ELF file; give the .bin"

# Bad command lines: exit 2 and the option named.
l431=$bin/linerwatch-firmware-l431.bin
bad() {
  local text=$1
  shift
  run "$@" --dry-run
  [ "$rc" = 2 ] || fail "scripts/flash $*: exit $rc, expected 2: $out"
  has "$out" "$text" "scripts/flash $*"
}
bad "--sensor-id 0 is out of range" --board l431 --image "$l431" --sensor-id 0
bad "--sensor-id is required" --board l431 --image "$l431"
bad "--image is required" --board l431 --sensor-id 5
bad "--board is required" --image "$l431" --sensor-id 5
bad "unknown board 'f405'" --board f405 --image "$l431" --sensor-id 5
bad "--api-mode" --board l431 --image "$l431" --sensor-id 5 --api-mode 0
bad "--tool: unknown tool 'jlink'" --board l431 --image "$l431" --sensor-id 5 --tool jlink
bad "--tool stm32flash needs --port" --board l431 --image "$l431" --sensor-id 5 --tool stm32flash
bad "--port is for --tool stm32flash" --board l431 --image "$l431" --sensor-id 5 --port /dev/ttyUSB0
bad "unknown argument '--sensor'" --board l431 --image "$l431" --sensor 5
"$flash" --help | grep -qF -- "--dry-run" || fail "--help does not describe --dry-run"

# A real run with no board: the missing tool, the absent port, no probe. The tools themselves are
# hidden by a PATH holding only what the script needs besides them.
mkdir -p "$work/path"
for t in bash env sed grep tr mktemp mkdir rm dirname awk head tail cmp cat wc; do ln -s "$(command -v "$t")" "$work/path/$t"; done
for tool in openocd st-flash; do
  out=$(PATH=$work/path "$flash" --board l431 --image "$l431" --sensor-id 5 --tool $tool 2>&1)
  rc=$?
  [ "$rc" = 1 ] || fail "$tool missing: exit $rc, expected 1"
  has "$out" "not found (apt-get install"
done
run --board l431 --image "$l431" --sensor-id 5 --tool stm32flash --port "$work/ttyNONE"
[ "$rc" = 1 ] || fail "absent port: exit $rc"
has "$out" "flash: $work/ttyNONE does not exist"
# Only where no ST USB device (vendor 0483, the ST-LINKs') is plugged in.
if ! grep -qx 0483 /sys/bus/usb/devices/*/idVendor 2>/dev/null; then
  if command -v openocd >/dev/null; then
    run --board l431 --image "$l431" --sensor-id 5
    [ "$rc" = 1 ] || fail "no probe (openocd): exit $rc"
    has "$out" "flash: no ST-LINK probe or chip answered"
  fi
  if command -v st-info >/dev/null; then
    run --board l431 --image "$l431" --sensor-id 5 --tool st-flash
    [ "$rc" = 1 ] || fail "no probe (st-flash): exit $rc"
    has "$out" "flash: no ST-LINK probe or chip answered"
  fi
fi

# A real run with stm32flash, against a model of the ROM bootloader on a pty
# (tests/fakes/fake_stm32_bootloader.py): the flash it is left with must hold the image at the
# flash base and the record scripts/flash made at the board's address, and another chip on the
# port must be refused with nothing written. A pty cannot carry the bootloader's even parity
# (Linux's pty drops PARENB, and stm32flash checks its settings took), so a shim on PATH runs the
# real stm32flash with -m 8n1.
fake_pid=""
trap '[ -z "$fake_pid" ] || kill "$fake_pid" 2>/dev/null; rm -rf "$work"' EXIT
start_bootloader() {  # PID_OF_CHIP FLASH_SIZE PAGES NAME [--silent]
  rm -f "$work/$4.tty"
  /usr/bin/python3 "$src/tests/fakes/fake_stm32_bootloader.py" --link "$work/$4.tty" --pid "$1" \
    --flash-size "$2" --pages "$3" --dump "$work/$4.flash" ${5:-} &
  fake_pid=$!
  for _ in $(seq 1 100); do [ -L "$work/$4.tty" ] && [ -f "$work/$4.flash" ] && return 0; sleep 0.1; done
  fail "the bootloader model did not start"
}
stop_bootloader() { kill "$fake_pid" 2>/dev/null; wait "$fake_pid" 2>/dev/null; fake_pid=""; }
if stm32flash_bin=$(command -v stm32flash) && [ -x /usr/bin/python3 ]; then
  mkdir -p "$work/shim"
  printf '#!/bin/sh\nexec %s -m 8n1 "$@"\n' "$stm32flash_bin" >"$work/shim/stm32flash"
  chmod +x "$work/shim/stm32flash"
  f405_sectors=16384,16384,16384,16384,65536,131072
  for spec in "netduinoplus2 0x413 1048576 $f405_sectors" "l431 0x435 262144 2048"; do
    read -r board chip size pages <<<"$spec"
    image=$bin/linerwatch-firmware-$board.bin
    at=$(provision_origin "$board")
    start_bootloader "$chip" "$size" "$pages" "$board"
    out=$(PATH=$work/shim:$PATH "$flash" --board "$board" --image "$image" --sensor-id 555 --api-mode 1 \
      --tool stm32flash --port "$work/$board.tty" --work "$work/run-$board" 2>&1)
    rc=$?
    stop_bootloader
    [ "$rc" = 0 ] || fail "$board through stm32flash: exit $rc: $out"
    has "$out" "flash: chip $chip ("
    has "$out" "and the record at $at with stm32flash, both verified; read back: board $board, sensor 555, api mode 1, 100 loops"
    cmp -s -n "$(stat -c %s "$image")" "$image" "$work/$board.flash" || fail "$board: the flash does not start with the image"
    "$LW_PROVISION" record --board "$board" --sensor-id 555 --api-mode 1 --out "$work/expected-$board.bin" >/dev/null
    cmp -s -i "0:$(( at - 0x08000000 ))" -n 16 "$work/expected-$board.bin" "$work/$board.flash" ||
      fail "$board: the flash does not hold the record at $at"
  done
  # An F405 on the port of an l431 job: refused after the chip id, the flash left erased.
  start_bootloader 0x413 1048576 "$f405_sectors" wrong-chip
  out=$(PATH=$work/shim:$PATH "$flash" --board l431 --image "$l431" --sensor-id 555 --tool stm32flash \
    --port "$work/wrong-chip.tty" 2>&1)
  rc=$?
  stop_bootloader
  [ "$rc" = 1 ] || fail "another chip: exit $rc, expected 1"
  has "$out" "flash: the attached chip is 0x413, not 0x435 (STM32L431)"
  [ "$(tr -d '\377' <"$work/wrong-chip.flash" | wc -c)" = 0 ] || fail "another chip: something was written"
  # A port where nothing answers (no board, BOOT0 low): stm32flash's init times out.
  start_bootloader 0x435 262144 2048 silent --silent
  out=$(PATH=$work/shim:$PATH "$flash" --board l431 --image "$l431" --sensor-id 555 --tool stm32flash \
    --port "$work/silent.tty" 2>&1)
  rc=$?
  stop_bootloader
  [ "$rc" = 1 ] || fail "no answer: exit $rc, expected 1"
  has "$out" "flash: no bootloader answered on $work/silent.tty (BOOT0 high and reset?"
else
  fail "stm32flash or /usr/bin/python3 missing (scripts/install-deps installs them)"
fi

[ "$failed" = 0 ] && echo "test_flash: all checks passed"
exit "$failed"
