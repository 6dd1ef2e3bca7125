#!/bin/sh
# Prints an STM32 image's flash and RAM use against the budgets its linker script enforces
# (symbols __lw_*; the link fails when either is exceeded). Usage: budget.sh NM ELF
nm="$1"
elf="$2"
sym() {
  v=$("$nm" "$elf" | awk -v s="$1" '$3 == s { print $1 }')
  [ -n "$v" ] && echo $((0x$v))
}
fu=$(sym __lw_flash_used) fb=$(sym __lw_flash_budget) ru=$(sym __lw_ram_used) rb=$(sym __lw_ram_budget)
[ -n "$fu" ] && [ -n "$fb" ] && [ -n "$ru" ] && [ -n "$rb" ] || { echo "budget.sh: no __lw_* budget symbols in $elf" >&2; exit 1; }
echo "$(basename "$elf"): flash $fu of $fb B ($((fu * 100 / fb))%), RAM $ru of $rb B ($((ru * 100 / rb))%, stack included)"
