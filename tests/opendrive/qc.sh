#!/usr/bin/env bash
# Runs the ASAM Quality Checker's OpenDRIVE bundle (asam-qc-opendrive) on the project's proving
# ground, config/maps/proving_ground.xodr (or on the .xodr files given as arguments), and fails
# unless it reports 0 errors. Prints every issue found and the error, warning and info counts.
#
#   bash tests/opendrive/qc.sh [MAP.xodr ...]
#
# Needs python3 with venv (Debian 12: apt-get install python3 python3-venv) and PyPI. The checker
# is installed once into ${V2T_QC_VENV:-target/qc-venv} (about 300 MB, 20-30 s); the config and
# the report of each map go to ${V2T_QC_OUT:-target/qc}/ (config-NAME.xml, NAME.xqar, NAME.log).
# Exit status: 0 no errors, 1 errors (or a check that crashed), 2 the checker could not be set up.
set -euo pipefail

QC_VERSION="1.0.0"         # asam-qc-opendrive
QC_BASELIB_VERSION="1.1.0" # asam-qc-baselib: writes the .xqar report

caller="$(pwd)"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
venv="${V2T_QC_VENV:-target/qc-venv}"
out="${V2T_QC_OUT:-target/qc}"
case "$venv" in /*) ;; *) venv="$root/$venv" ;; esac
case "$out" in /*) ;; *) out="$root/$out" ;; esac
maps=()
for map in "$@"; do
    case "$map" in /*) maps+=("$map") ;; *) maps+=("$caller/$map") ;; esac
done
if [ "${#maps[@]}" -eq 0 ]; then
    maps=("$root/config/maps/proving_ground.xodr")
fi

python="${PYTHON:-python3}"
if ! command -v "$python" >/dev/null; then
    echo "qc.sh: $python not found (Debian: apt-get install python3 python3-venv)" >&2
    exit 2
fi

# Install (or repair) the checker; a venv that already holds the pinned versions is reused.
installed() {
    "$venv/bin/python" - "$QC_VERSION" "$QC_BASELIB_VERSION" 2>/dev/null <<'PY'
import importlib.metadata as m
import sys

ok = m.version("asam-qc-opendrive") == sys.argv[1] and m.version("asam-qc-baselib") == sys.argv[2]
sys.exit(0 if ok else 1)
PY
}
if ! installed; then
    echo "qc.sh: installing asam-qc-opendrive==$QC_VERSION into $venv"
    rm -rf "$venv"
    mkdir -p "$(dirname "$venv")"
    if ! "$python" -m venv "$venv"; then
        echo "qc.sh: '$python -m venv' failed (Debian: apt-get install python3-venv)" >&2
        exit 2
    fi
    if ! "$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
        "asam-qc-opendrive==$QC_VERSION" "asam-qc-baselib==$QC_BASELIB_VERSION"; then
        echo "qc.sh: pip could not install asam-qc-opendrive==$QC_VERSION" >&2
        exit 2
    fi
    installed || { echo "qc.sh: asam-qc-opendrive did not install into $venv" >&2; exit 2; }
fi

mkdir -p "$out"
status=0
for map in "${maps[@]}"; do
    if [ ! -f "$map" ]; then
        echo "qc.sh: $map not found" >&2
        status=1
        continue
    fi
    name="$(basename "$map" .xodr)"
    map="$(cd "$(dirname "$map")" && pwd)/$(basename "$map")"
    shown="${map#"$root"/}"
    config="$out/config-$name.xml"
    report="$out/$name.xqar"
    log="$out/$name.log"
    rm -f "$report"
    # The checker's configuration: the input file and where the bundle writes its report.
    "$venv/bin/python" - "$map" "$report" "$config" <<'PY'
import sys
from xml.sax.saxutils import quoteattr

map_path, report, config = sys.argv[1:4]
with open(config, "w", encoding="utf-8") as f:
    f.write('<?xml version="1.0" encoding="UTF-8" standalone="no"?>\n<Config>\n')
    f.write(f"    <Param name=\"InputFile\" value={quoteattr(map_path)}/>\n")
    f.write('    <CheckerBundle application="xodrBundle">\n')
    f.write(f"        <Param name=\"resultFile\" value={quoteattr(report)}/>\n")
    f.write("    </CheckerBundle>\n</Config>\n")
PY
    # qc_opendrive logs every check: the log is shown only when it fails.
    if ! (cd "$out" && "$venv/bin/qc_opendrive" -c "$config") >"$log" 2>&1 || [ ! -f "$report" ]; then
        cat "$log" >&2
        echo "qc.sh: qc_opendrive failed on $shown (no $report)" >&2
        status=1
        continue
    fi
    # The report: every issue with its locations, the counts by level, checks that did not complete.
    if ! "$venv/bin/python" - "$report" "$shown" <<'PY'; then
import sys
import xml.etree.ElementTree as ET

report, shown = sys.argv[1], sys.argv[2]
root = ET.parse(report).getroot()
levels = {"1": "error", "2": "warning", "3": "info"}
counts = {"error": 0, "warning": 0, "info": 0}
checks, crashed = 0, 0
for checker in root.iter("Checker"):
    checks += 1
    status = checker.get("status", "")
    if status != "completed":
        print(f"  {status or 'no status'}: {checker.get('checkerId')}: {checker.get('summary', '')}")
        crashed += status == "error"
    for issue in checker.iter("Issue"):
        level = levels.get(issue.get("level", "1"), "error")
        counts[level] += 1
        print(f"  {level.upper()} {checker.get('checkerId')}: {issue.get('description', '').strip()}")
        for loc in issue.iter("Locations"):
            xml_loc = loc.find("XMLLocation")
            xyz = loc.find("InertialLocation")
            where = xml_loc.get("xpath") if xml_loc is not None else ""
            if xyz is not None:
                where += f" (x {float(xyz.get('x')):.2f}, y {float(xyz.get('y')):.2f})"
            print(f"      {loc.get('description', '')}: {where.strip()}")
print(f"{shown}: {checks} checks, {counts['error']} errors, {counts['warning']} warnings, {counts['info']} info")
sys.exit(1 if counts["error"] or crashed or checks == 0 else 0)
PY
        status=1
    fi
done
exit "$status"
