#!/usr/bin/env bash
# Run one command inside a User-Mode-Linux guest kernel that has SocketCAN and a vcan0 interface.
#
#   tests/vcan/run-guest.sh [--mem SIZE] [--] COMMAND [ARGS...]
#
# The host kernel of our machines and CI has no CAN support (CONFIG_CAN unset), so the SocketCAN
# tests run in a guest: Debian's `user-mode-linux` kernel (6.1, it ships the can, can-raw, can-dev
# and vcan modules), booted with the host's file system as its root (hostfs), so the command sees
# the same paths, binaries and working directory as here. In the guest: proc, sys, /dev/shm and a
# fresh /tmp/iceoryx2 are mounted, the four modules are loaded with `insmod` (can, can-raw, can-dev, vcan,
# in that order), vcan0 is created and set up, and the command runs with V2T_CAN_IFACE=vcan0. Its
# exit status comes back through a marker line on the console and becomes this script's.
#
# Needs: linux.uml (Debian package user-mode-linux, or V2T_UML=path/to/linux.uml with its
# modules under V2T_UML_MODULES), insmod (kmod) and ip (iproute2) on the host.
#
# Exit status: the command's; 124 when the guest reported none; 77 when the guest kernel cannot
# boot on this host's CPU at all (the command did not run: callers report it as not run).
set -euo pipefail

mem=1024M
while [ $# -gt 0 ]; do
  case "$1" in
    --mem) mem="$2"; shift 2 ;;
    --) shift; break ;;
    -*) echo "run-guest.sh: unknown option $1" >&2; exit 2 ;;
    *) break ;;
  esac
done
if [ $# -eq 0 ]; then
  echo "usage: run-guest.sh [--mem SIZE] [--] COMMAND [ARGS...]" >&2
  exit 2
fi

uml="${V2T_UML:-$(command -v linux.uml || true)}"
if [ -z "$uml" ] || [ ! -x "$uml" ]; then
  echo "run-guest.sh: linux.uml not found (apt-get install user-mode-linux, or set V2T_UML)" >&2
  exit 2
fi
modules="${V2T_UML_MODULES:-}"
if [ -z "$modules" ]; then
  # Debian installs the modules of its one UML kernel under /usr/lib/uml/modules/<version>.
  uml_root="$(dirname "$(dirname "$(readlink -f "$uml")")")"
  modules="$(find "$uml_root/lib/uml/modules" -mindepth 1 -maxdepth 1 -type d 2>/dev/null | sort | tail -n 1)"
fi
for ko in net/can/can.ko net/can/can-raw.ko drivers/net/can/dev/can-dev.ko drivers/net/can/vcan.ko; do
  if [ ! -f "$modules/kernel/$ko" ]; then
    echo "run-guest.sh: module $ko not found under '${modules}' (set V2T_UML_MODULES)" >&2
    exit 2
  fi
done
for tool in insmod ip; do
  if ! PATH="$PATH:/usr/sbin:/sbin" command -v "$tool" >/dev/null; then
    echo "run-guest.sh: $tool not found on the host (apt-get install kmod iproute2)" >&2
    exit 2
  fi
done

work="$(mktemp -d "${TMPDIR:-/tmp}/v2t-guest.XXXXXX")"
trap 'rm -rf "$work"' EXIT
marker="V2T_GUEST_EXIT_$$_$RANDOM"

# The guest's init: everything it needs is written into it (the kernel passes no environment
# worth having). The command and the environment are quoted with printf %q.
{
  echo '#!/bin/sh'
  echo 'export PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin'
  echo 'fail() { echo "guest: $*"; echo "'"$marker"'=125"; echo o > /proc/sysrq-trigger; sleep 5; exit 1; }'
  echo 'mount -t proc proc /proc || fail "mount /proc"'
  echo 'mount -t sysfs sys /sys || fail "mount /sys"'
  # The host's /tmp stays visible (the checkout or the build may live there); iceoryx2's own
  # directory gets a fresh tmpfs so the guest's nodes never meet (or clean up) the host's.
  echo 'mkdir -p /tmp/iceoryx2 && mount -t tmpfs -o size=64m iceoryx2 /tmp/iceoryx2 || fail "mount /tmp/iceoryx2"'
  # /dev is the guest's own devtmpfs (mounted by the kernel) with a fresh tmpfs on /dev/shm.
  echo 'grep -q " /dev " /proc/mounts || mount -t devtmpfs dev /dev || fail "mount /dev"'
  echo 'mkdir -p /dev/shm /dev/pts && mount -t tmpfs -o size=256m shm /dev/shm || fail "mount /dev/shm"'
  echo 'hostname v2t-guest'
  for ko in net/can/can.ko net/can/can-raw.ko drivers/net/can/dev/can-dev.ko drivers/net/can/vcan.ko; do
    printf 'insmod %q || fail "insmod %s"\n' "$modules/kernel/$ko" "$ko"
  done
  echo 'ip link add dev vcan0 type vcan || fail "ip link add vcan0"'
  echo 'ip link set up vcan0 || fail "ip link set up vcan0"'
  echo 'ip link set lo up'
  printf 'cd %q || fail "cd"\n' "$PWD"
  for var in HOME USER CARGO_HOME RUST_BACKTRACE RUST_LOG V2T_TRACE_PLANS V2T_EDGE_CONFIG V2T_EDGE_BIN; do
    if [ -n "${!var:-}" ]; then printf 'export %s=%q\n' "$var" "${!var}"; fi
  done
  echo 'export V2T_CAN_IFACE=vcan0'
  printf '%q ' "$@"; echo
  echo 'rc=$?'
  echo 'echo "'"$marker"'=$rc"'
  echo 'sync'
  echo 'echo o > /proc/sysrq-trigger'
  echo 'sleep 10'
} > "$work/init"
chmod +x "$work/init"

# UML keeps its memory in a file under TMPDIR; the console is our stdout. Everything the guest
# prints is passed through, and the marker line gives the status.
console="$work/console.log"
set +e
TMPDIR="$work" "$uml" "mem=$mem" root=/dev/root rootfstype=hostfs "rootflags=/" rw \
  "init=$work/init" con0=fd:0,fd:1 con=null quiet 2>&1 </dev/null \
  | grep -v -e '^SELinux:' -e '^mmapper_init' -e '^Failed to initialize ubd' -e 'is not on tmpfs' | tee "$console"
set -e
rc="$(sed -n "s/^.*$marker=\([0-9][0-9]*\).*$/\1/p" "$console" | tail -n 1)"
if [ -z "$rc" ]; then
  # Debian 12's UML kernel (6.1) cannot restore a process's FPU state on a host whose extended
  # state is larger than it handles (seen on a Xeon with AMX): it panics at boot, whatever the
  # command. That is this host's limit, not the command's failure: exit 77, "not run".
  if grep -q 'ptrace set fp regs failed' "$console"; then
    echo "NOT RUN $*: this User-Mode-Linux kernel ($uml) cannot boot on this host's CPU" \
      "('ptrace set fp regs failed': the host's extended FPU state, e.g. AMX, is larger than it handles);" \
      "run the SocketCAN tests on another host, or set V2T_UML to a newer UML kernel" >&2
    exit 77
  fi
  echo "run-guest.sh: the guest ended without reporting the command's status" >&2
  exit 124
fi
exit "$rc"
