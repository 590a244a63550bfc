#!/usr/bin/env bash
# Runs the ASAM Quality Checker's OpenSCENARIO XML bundle (asam-qc-openscenarioxml) on the .xosc
# files given as arguments (`video2track export xosc` writes them) and fails unless it reports
# 0 issues: every error, warning and info counts. Prints every issue found and the counts.
#
#   bash tests/openscenario/qc.sh SCENARIO.xosc [...]
#
# The checker resolves RoadNetwork/LogicFile relative to the .xosc file's folder and reads that
# map (for the signal reference checks): the map must exist there.
#
# Needs python3 with venv (Debian 12: apt-get install python3 python3-venv) and PyPI. The checker
# is installed once into ${V2T_XOSC_QC_VENV:-target/qc-xosc-venv} (about 60 MB, 10-20 s); the
# config and the report of each file go to ${V2T_XOSC_QC_OUT:-target/qc-xosc}/ (config-NAME.xml,
# NAME.xqar, NAME.log). Exit status: 0 no issues, 1 issues (or a check that crashed or was
# skipped), 2 the checker could not be set up or no file was given.
set -euo pipefail

QC_VERSION="1.0.0"         # asam-qc-openscenarioxml
QC_BASELIB_VERSION="1.1.0" # asam-qc-baselib: writes the .xqar report

caller="$(pwd)"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
venv="${V2T_XOSC_QC_VENV:-target/qc-xosc-venv}"
out="${V2T_XOSC_QC_OUT:-target/qc-xosc}"
case "$venv" in /*) ;; *) venv="$root/$venv" ;; esac
case "$out" in /*) ;; *) out="$root/$out" ;; esac
files=()
for file in "$@"; do
    case "$file" in /*) files+=("$file") ;; *) files+=("$caller/$file") ;; esac
done
if [ "${#files[@]}" -eq 0 ]; then
    echo "usage: bash tests/openscenario/qc.sh SCENARIO.xosc [...]" >&2
    exit 2
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

ok = m.version("asam-qc-openscenarioxml") == sys.argv[1] and m.version("asam-qc-baselib") == sys.argv[2]
sys.exit(0 if ok else 1)
PY
}
if ! installed; then
    echo "qc.sh: installing asam-qc-openscenarioxml==$QC_VERSION into $venv"
    rm -rf "$venv"
    mkdir -p "$(dirname "$venv")"
    if ! "$python" -m venv "$venv"; then
        echo "qc.sh: '$python -m venv' failed (Debian: apt-get install python3-venv)" >&2
        exit 2
    fi
    if ! "$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
        "asam-qc-openscenarioxml==$QC_VERSION" "asam-qc-baselib==$QC_BASELIB_VERSION"; then
        echo "qc.sh: pip could not install asam-qc-openscenarioxml==$QC_VERSION" >&2
        exit 2
    fi
    installed || { echo "qc.sh: asam-qc-openscenarioxml did not install into $venv" >&2; exit 2; }
fi

mkdir -p "$out"
status=0
for file in "${files[@]}"; do
    if [ ! -f "$file" ]; then
        echo "qc.sh: $file not found" >&2
        status=1
        continue
    fi
    name="$(basename "$file" .xosc)"
    # An absolute path: the checker changes into the file's folder to read the map.
    file="$(cd "$(dirname "$file")" && pwd)/$(basename "$file")"
    shown="${file#"$root"/}"
    config="$out/config-$name.xml"
    report="$out/$name.xqar"
    log="$out/$name.log"
    rm -f "$report"
    # The checker's configuration: the input file and where the bundle writes its report.
    "$venv/bin/python" - "$file" "$report" "$config" <<'PY'
import sys
from xml.sax.saxutils import quoteattr

input_path, report, config = sys.argv[1:4]
with open(config, "w", encoding="utf-8") as f:
    f.write('<?xml version="1.0" encoding="UTF-8" standalone="no"?>\n<Config>\n')
    f.write(f"    <Param name=\"InputFile\" value={quoteattr(input_path)}/>\n")
    f.write('    <CheckerBundle application="xoscBundle">\n')
    f.write(f"        <Param name=\"resultFile\" value={quoteattr(report)}/>\n")
    f.write("    </CheckerBundle>\n</Config>\n")
PY
    # qc_openscenario logs every check: the log is shown only when it fails.
    if ! (cd "$out" && "$venv/bin/qc_openscenario" -c "$config") >"$log" 2>&1 || [ ! -f "$report" ]; then
        cat "$log" >&2
        echo "qc.sh: qc_openscenario failed on $shown (no $report)" >&2
        status=1
        continue
    fi
    # The report: every issue with its locations, the counts by level, checks that did not complete
    # (a skipped check counts as a failure: its preconditions did not hold).
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
        crashed += status in ("error", "skipped")
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
issues = counts["error"] + counts["warning"] + counts["info"]
sys.exit(1 if issues or crashed or checks == 0 else 0)
PY
        status=1
    fi
done
exit "$status"
