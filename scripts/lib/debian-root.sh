# A clean Debian 12 (bookworm, minbase) root for scripts/fresh-check and scripts/install-check.
# Sourced, not run. The caller sets, before calling these functions:
#   root   the folder of the root (made by debian_root_make; may be an existing empty folder)
#   cache  folder keeping debootstrap's and apt's downloaded .debs between roots ("" = none)
#   log    the log file for debootstrap's output
#   mirror the Debian mirror ("" = the host's deb.debian.org-style apt source)
# and a function `say` printing one progress line. Mounts made with debian_root_mount are undone
# and processes left in the root are stopped by debian_root_release (call it from an EXIT trap).
# shellcheck shell=bash

suite=bookworm
debian_root_mounted=()

debian_root_mirror() {  # sets mirror and security from the host's apt sources unless mirror is set
  if [ -z "${mirror:-}" ]; then
    mirror=$(cat /etc/apt/sources.list /etc/apt/sources.list.d/*.list /etc/apt/sources.list.d/*.sources 2>/dev/null \
      | grep -oE 'https?://[^ ]*/debian/?( |$)' | head -n 1 | tr -d ' ' || true)
    mirror=${mirror:-http://deb.debian.org/debian}
  fi
  mirror=${mirror%/}
  security=${mirror%/debian}/debian-security
  [ "$security" != "$mirror/debian-security" ] || security=http://deb.debian.org/debian-security
}

# debootstrap (minbase) into $root, from the cached package set in $cache when there is a recent
# one; then what a Debian 12 install has and debootstrap leaves out (all three suites, the hosts
# file), and a policy-rc.d that keeps packages from starting daemons in the chroot. Returns 1 on
# failure (the log's tail is printed).
debian_root_make() {
  debian_root_mirror
  local boot=(debootstrap --variant=minbase "$suite" "$root" "$mirror")
  if [ -n "$cache" ]; then
    mkdir -p "$cache"
    local tarball=$cache/$suite-minbase.tgz
    # A cached package set older than two weeks misses point-release updates: fetch it anew.
    if [ -f "$tarball" ] && [ -n "$(find "$tarball" -mtime -14)" ]; then
      say "debootstrap $suite (minbase) into $root, packages from $tarball"
    else
      say "downloading the $suite minbase packages from $mirror into $tarball"
      local tmp
      tmp=$(mktemp -d /var/tmp/linerwatch-root-tar.XXXXXX)
      if ! debootstrap --variant=minbase --make-tarball="$tarball.part" "$suite" "$tmp" "$mirror" >>"$log" 2>&1; then
        rm -rf --one-file-system "$tmp"; tail -n 20 "$log" >&2
        say "debootstrap --make-tarball failed (log: $log)"; return 1
      fi
      rm -rf --one-file-system "$tmp"
      mv "$tarball.part" "$tarball"
      say "debootstrap $suite (minbase) into $root"
    fi
    boot=(debootstrap --variant=minbase --unpack-tarball="$tarball" "$suite" "$root" "$mirror")
  else
    say "debootstrap $suite (minbase) into $root from $mirror"
  fi
  if ! "${boot[@]}" >>"$log" 2>&1; then tail -n 20 "$log" >&2; say "debootstrap failed (log: $log)"; return 1; fi

  cat >"$root/etc/apt/sources.list" <<EOF
deb $mirror $suite main
deb $mirror $suite-updates main
deb $security $suite-security main
EOF
  [ -s "$root/etc/hosts" ] || printf '127.0.0.1\tlocalhost\n::1\tlocalhost ip6-localhost ip6-loopback\n' >"$root/etc/hosts"
  # No init runs in a chroot, and the root shares the host's network: packages must not start
  # their daemons here (mosquitto's would take the host's port 1883). The standard chroot answer.
  printf '#!/bin/sh\nexit 101\n' >"$root/usr/sbin/policy-rc.d"
  chmod 755 "$root/usr/sbin/policy-rc.d"
}

debian_root_mount() {  # $1: target under the root, rest: mount arguments
  local target=$root$1; shift
  mkdir -p "$target"
  mount "$@" "$target"
  debian_root_mounted+=("$target")
}

# /proc, /sys, /dev (with pts and shm), the host's resolv.conf, and apt's archive cache in $cache.
debian_root_enter() {
  cp -L /etc/resolv.conf "$root/etc/resolv.conf"
  debian_root_mount /proc -t proc proc
  debian_root_mount /sys -t sysfs sysfs
  debian_root_mount /dev --bind /dev
  debian_root_mount /dev/pts --bind /dev/pts
  debian_root_mount /dev/shm -t tmpfs -o mode=1777 tmpfs
  if [ -n "$cache" ]; then
    mkdir -p "$cache/apt-archives/partial"
    debian_root_mount /var/cache/apt/archives --bind "$cache/apt-archives"
  fi
}

debian_root_mounts_under() { awk -v r="$root/" 'index($2 "/", r) == 1 { print $2 }' /proc/self/mounts; }

# Stops the processes whose root is ours (started in the chroot) and undoes the mounts.
debian_root_release() {
  local p i pids=()
  for p in /proc/[0-9]*; do
    [ "$(readlink "$p/root" 2>/dev/null)" = "$root" ] && pids+=("${p#/proc/}")
  done
  if [ ${#pids[@]} -gt 0 ]; then
    say "stopping ${#pids[@]} process(es) left in the root: ${pids[*]}"
    kill -TERM "${pids[@]}" 2>/dev/null || true
    sleep 2
    kill -KILL "${pids[@]}" 2>/dev/null || true
    sleep 0.5
  fi
  for ((i = ${#debian_root_mounted[@]} - 1; i >= 0; i--)); do
    umount "${debian_root_mounted[$i]}" 2>/dev/null || umount -l "${debian_root_mounted[$i]}" 2>/dev/null \
      || echo "could not unmount ${debian_root_mounted[$i]}" >&2
  done
  debian_root_mounted=()
}

# Removes the root unless something is still mounted in it.
debian_root_remove() {
  if [ -n "$(debian_root_mounts_under)" ]; then
    echo "not removing $root: still mounted there: $(debian_root_mounts_under | tr '\n' ' ')" >&2
    return 1
  fi
  rm -rf --one-file-system "$root"
}
