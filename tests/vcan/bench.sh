#!/usr/bin/env bash
# The SocketCAN bench: builds the tests that need a CAN-capable kernel and runs them in a
# User-Mode-Linux guest with vcan0 (tests/vcan/run-guest.sh).
#
#   tests/vcan/bench.sh
#
# 1. v2t-can's vcan tests (every DBC frame bit-exact over the bus, raw frames with bad checksums,
#    counters, extended/remote/FD frames, error frames, the gate's timeout stop on the bus), once
#    with parallel test threads and once with one.
# 2. The onboard runtime's closed loop through its processes with the CAN gateway and the
#    simulated drive-by-wire ECU on vcan0 instead of the iceoryx2 virtual bus.
set -euo pipefail
cd "$(dirname "$0")/../.."
here="tests/vcan"

# The path of a test executable, from cargo's "Executable tests/<name>.rs (<path>)" line.
test_exe() {
  local package="$1" name="$2" out
  out="$(cargo test -p "$package" --test "$name" --no-run 2>&1)" || { echo "$out" >&2; return 1; }
  sed -n "s|^ *Executable tests/$name\.rs (\(.*\))\$|\1|p" <<<"$out" | tail -n 1
}

vcan="$(test_exe v2t-can vcan)"
runtime="$(test_exe v2t-lab runtime)"
# The runtime test starts the onboard runtime's own binary beside it.
cargo build -p v2t-edge --bin v2t-edge
for exe in "$vcan" "$runtime"; do
  if [ -z "$exe" ] || [ ! -x "$exe" ]; then
    echo "bench.sh: could not find a test executable (got '$exe')" >&2
    exit 1
  fi
done

# A guest run that cannot start on this host (run-guest.sh's 77) is counted as not run, never as
# passed, and named in the last line.
not_run=0
guest() {
  local rc=0
  "$here/run-guest.sh" "$@" || rc=$?
  if [ "$rc" = 77 ]; then
    not_run=$((not_run + 1))
    return 0
  fi
  return "$rc"
}

echo "== vcan: v2t-can over SocketCAN (parallel)"
guest -- "$vcan"
echo "== vcan: v2t-can over SocketCAN (one thread)"
guest -- "$vcan" --test-threads=1
echo "== vcan: the onboard runtime's closed loop with the gateway and the ECU on vcan0"
# The guest's system calls are slow and now and then a heartbeat comes late: its runtime uses
# tests/vcan/edge_guest.toml (watchdog 250 ms instead of 60 ms; the 60 ms one is tested natively).
V2T_EDGE_CONFIG="$here/edge_guest.toml" guest -- "$runtime" a_yielding_left_turn --nocapture
if [ "$not_run" -gt 0 ]; then
  echo "== vcan: NOT RUN: $not_run of 3 guest runs (the UML kernel cannot boot on this host's CPU; see above)"
else
  echo "== vcan: all passed"
fi
