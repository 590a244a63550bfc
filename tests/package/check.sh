#!/usr/bin/env bash
# The onboard runtime's Debian package, checked as a vehicle team would install it:
#
#   tests/package/check.sh [--no-build]
#
# 1. scripts/package-deb builds it (release), and packs the same binary again into an absolute and
#    a relative --out (relative to where it is run from);
# 2. it is unpacked into a throw-away root (dpkg-deb -x: nothing is installed on this machine);
# 3. its control data, every file it must carry, that every /etc file is a conffile, and that no
#    key (the demo pair or any *.key) is in it;
# 4. the systemd unit verifies (`systemd-analyze verify --root`, for the instance v2t-edge@bv1,
#    every warning an error);
# 5. the installed `v2t-edge check` passes on the installed bench configuration, and fails (exit
#    2) on a configuration naming a CAN interface that does not exist;
# 6. the installed binary's launcher drives the closed loop on vcan0 in the User-Mode-Linux guest
#    (tests/vcan/run-guest.sh, the runtime test with V2T_EDGE_BIN).
#
# Needs dpkg-dev, systemd (systemd-analyze) and what tests/vcan/ needs (user-mode-linux, kmod,
# iproute2).
set -euo pipefail
cd "$(dirname "$0")/../.."

build=()
[ "${1:-}" = --no-build ] && build=(--no-build)
deb="$(scripts/package-deb "${build[@]}" | tail -n 1)"
echo "== package: $deb"
root="$(mktemp -d "${TMPDIR:-/tmp}/v2t-deb.XXXXXX")"
trap 'rm -rf "$root"' EXIT
dpkg-deb -x "$deb" "$root"
dpkg-deb -e "$deb" "$root/DEBIAN"
fail() { echo "package check: $*" >&2; exit 1; }

echo "== package: --out absolute, and relative to where it runs"
outs="$(mktemp -d "${TMPDIR:-/tmp}/v2t-deb-out.XXXXXX")"
trap 'rm -rf "$root" "$outs"' EXIT
repo="$(pwd)"
mkdir "$outs/here"
made="$(scripts/package-deb --no-build --out "$outs/abs" | tail -n 1)"
[ "$made" = "$outs/abs/$(basename "$deb")" ] && [ -s "$made" ] || fail "package-deb --out $outs/abs made '$made'"
made="$(cd "$outs/here" && "$repo/scripts/package-deb" --no-build --out rel | tail -n 1)"
[ "$made" = "$outs/here/rel/$(basename "$deb")" ] && [ -s "$made" ] \
  || fail "package-deb --out rel, run in $outs/here, made '$made'"
rm -rf "$outs"

echo "== control data"
control="$root/DEBIAN/control"
for field in "Package: v2t-edge" "Architecture: $(dpkg --print-architecture)" "Depends: libc6"; do
  grep -q "^$field" "$control" || fail "control lacks '$field'"
done
for script in postinst prerm postrm; do
  [ -x "$root/DEBIAN/$script" ] || fail "no executable $script"
  sh -n "$root/DEBIAN/$script" || fail "$script is not valid sh"
done

echo "== files"
for f in usr/bin/v2t-edge lib/systemd/system/v2t-edge@.service etc/video2track/edge/bv1.toml \
  etc/video2track/edge/bv1_realtime.toml etc/video2track/iceoryx2.toml usr/share/video2track/bv.dbc \
  usr/share/doc/v2t-edge/copyright usr/share/doc/v2t-edge/DEPLOY.md usr/share/video2track/examples/bv1_link.toml; do
  [ -e "$root/$f" ] || fail "missing /$f"
done
[ -x "$root/usr/bin/v2t-edge" ] || fail "/usr/bin/v2t-edge is not executable"
if objdump -h "$root/usr/bin/v2t-edge" | grep -q '\.debug_info'; then fail "/usr/bin/v2t-edge still has debug sections"; fi
while read -r f; do
  grep -qx "/$f" "$root/DEBIAN/conffiles" || fail "/$f is not a conffile (an upgrade would overwrite local edits)"
done < <(cd "$root" && find etc -type f)
if find "$root" -name '*.key' | grep -q .; then fail "a key file ships: $(find "$root" -name '*.key')"; fi
for key in config/keys/demo_cloud.key config/keys/demo_cloud.pub; do
  if grep -rqF "$(tr -d '\n' < "$key")" "$root/etc" "$root/usr/share"; then fail "the demo key ($key) ships"; fi
done

echo "== systemd unit"
units="$root/lib/systemd/system"
# The host's units give the unit's dependencies (sysinit.target, network-online.target, …) in the
# throw-away root; ours must not be replaced.
for u in /lib/systemd/system/*; do
  [ -e "$units/$(basename "$u")" ] || cp -r "$u" "$units/"
done
ln -s v2t-edge@.service "$units/v2t-edge@bv1.service"
verify="$(systemd-analyze verify --root="$root" v2t-edge@bv1.service 2>&1)" || fail "systemd-analyze verify failed: $verify"
[ -z "$verify" ] || fail "systemd-analyze verify warns: $verify"

echo "== v2t-edge check on the installed configuration"
edge="$root/usr/bin/v2t-edge"
"$edge" check --config "$root/etc/video2track/edge/bv1.toml"
set +e
out="$("$edge" check --config "$root/etc/video2track/edge/bv1.toml" --can-iface nonexistent0 2>&1)"
rc=$?
set -e
[ "$rc" = 2 ] || fail "check with a missing CAN interface exited $rc, not 2: $out"
grep -q nonexistent0 <<<"$out" || fail "check does not name the missing interface: $out"

# 7. (CI only: V2T_PACKAGE_INSTALL=1, as root, on a throw-away machine) the package installs with
#    dpkg for real (its maintainer scripts create the v2t user and /var/lib/video2track), the
#    installed check passes, and a purge removes it again.
if [ "${V2T_PACKAGE_INSTALL:-0}" = 1 ]; then
  echo "== dpkg -i, check, purge (V2T_PACKAGE_INSTALL=1)"
  [ "$(id -u)" = 0 ] || fail "V2T_PACKAGE_INSTALL=1 needs root"
  # A run that died between install and purge left it: this is a throw-away machine.
  if dpkg -s v2t-edge >/dev/null 2>&1; then dpkg --purge v2t-edge; fi
  dpkg -i "$deb"
  getent passwd v2t >/dev/null || fail "postinst made no v2t user"
  [ "$(stat -c %U /var/lib/video2track)" = v2t ] || fail "/var/lib/video2track is not the v2t user's"
  /usr/bin/v2t-edge check --config /etc/video2track/edge/bv1.toml
  dpkg --purge v2t-edge
  [ ! -e /usr/bin/v2t-edge ] && [ ! -e /etc/video2track/edge/bv1.toml ] && [ ! -e /var/lib/video2track ] \
    || fail "purge left files behind"
fi

echo "== the installed launcher on vcan0 in the User-Mode-Linux guest"
runtime="$(cargo test -p v2t-lab --test runtime --no-run 2>&1 | sed -n 's|^ *Executable tests/runtime\.rs (\(.*\))$|\1|p' | tail -n 1)"
[ -x "$runtime" ] || fail "could not build the runtime test"
rc=0
V2T_EDGE_BIN="$edge" V2T_EDGE_CONFIG=tests/vcan/edge_guest.toml tests/vcan/run-guest.sh -- "$runtime" a_yielding_left_turn --nocapture || rc=$?
if [ "$rc" = 77 ]; then
  echo "== package: NOT RUN: the installed launcher on vcan0 (the UML kernel cannot boot on this host's CPU; see above); every other step passed"
elif [ "$rc" != 0 ]; then
  fail "the installed launcher on vcan0 failed (exit $rc)"
else
  echo "== package: all passed"
fi
