#!/usr/bin/env bash
# The ASAM Quality Checker runner shared by tests/opendrive/qc.sh and tests/openscenario/qc.sh:
# installs the pinned checker bundle into a venv once, runs it on each file given, prints every
# issue with its locations and the counts, and fails on errors (strict: on any issue, and on a
# skipped check). The wrappers set:
#
#   QC_PACKAGE QC_VERSION QC_BASELIB_VERSION  the PyPI packages (the baselib writes the .xqar report)
#   QC_BUNDLE QC_EXE QC_EXT                   the bundle's application name, its command, the file suffix
#   QC_VENV QC_OUT                            where the venv and the configs/reports/logs go
#   QC_STRICT                                 1: warnings, infos and skipped checks fail too
#
#   bash tests/asam-qc.sh FILE [...]   (relative paths from the caller's folder)
#
# Exit status: 0 passed, 1 issues (or a check that crashed), 2 the checker could not be set up or
# no file was given.
set -euo pipefail

: "${QC_PACKAGE:?}" "${QC_VERSION:?}" "${QC_BASELIB_VERSION:?}" "${QC_BUNDLE:?}" "${QC_EXE:?}" "${QC_EXT:?}"
: "${QC_VENV:?}" "${QC_OUT:?}" "${QC_STRICT:=0}"

caller="$(pwd)"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="$QC_VENV"
out="$QC_OUT"
case "$venv" in /*) ;; *) venv="$root/$venv" ;; esac
case "$out" in /*) ;; *) out="$root/$out" ;; esac
files=()
for file in "$@"; do
    case "$file" in /*) files+=("$file") ;; *) files+=("$caller/$file") ;; esac
done
if [ "${#files[@]}" -eq 0 ]; then
    echo "qc.sh: no file to check" >&2
    exit 2
fi

python="${PYTHON:-python3}"
if ! command -v "$python" >/dev/null; then
    echo "qc.sh: $python not found (Debian: apt-get install python3 python3-venv)" >&2
    exit 2
fi

# Install (or repair) the checker; a venv that already holds the pinned versions is reused.
installed() {
    "$venv/bin/python" - "$QC_VERSION" "$QC_BASELIB_VERSION" "$QC_PACKAGE" 2>/dev/null <<'PY'
import importlib.metadata as m
import sys

ok = m.version(sys.argv[3]) == sys.argv[1] and m.version("asam-qc-baselib") == sys.argv[2]
sys.exit(0 if ok else 1)
PY
}
if ! installed; then
    echo "qc.sh: installing $QC_PACKAGE==$QC_VERSION into $venv"
    rm -rf "$venv"
    mkdir -p "$(dirname "$venv")"
    if ! "$python" -m venv "$venv"; then
        echo "qc.sh: '$python -m venv' failed (Debian: apt-get install python3-venv)" >&2
        exit 2
    fi
    if ! "$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
        "$QC_PACKAGE==$QC_VERSION" "asam-qc-baselib==$QC_BASELIB_VERSION"; then
        echo "qc.sh: pip could not install $QC_PACKAGE==$QC_VERSION" >&2
        exit 2
    fi
    installed || { echo "qc.sh: $QC_PACKAGE did not install into $venv" >&2; exit 2; }
fi

mkdir -p "$out"
status=0
for file in "${files[@]}"; do
    if [ ! -f "$file" ]; then
        echo "qc.sh: $file not found" >&2
        status=1
        continue
    fi
    name="$(basename "$file" "$QC_EXT")"
    # An absolute path: the checker changes into the file's folder to read the map.
    file="$(cd "$(dirname "$file")" && pwd)/$(basename "$file")"
    shown="${file#"$root"/}"
    config="$out/config-$name.xml"
    report="$out/$name.xqar"
    log="$out/$name.log"
    rm -f "$report"
    # The checker's configuration: the input file and where the bundle writes its report.
    "$venv/bin/python" - "$file" "$report" "$config" "$QC_BUNDLE" <<'PY'
import sys
from xml.sax.saxutils import quoteattr

input_path, report, config, bundle = sys.argv[1:5]
with open(config, "w", encoding="utf-8") as f:
    f.write('<?xml version="1.0" encoding="UTF-8" standalone="no"?>\n<Config>\n')
    f.write(f"    <Param name=\"InputFile\" value={quoteattr(input_path)}/>\n")
    f.write(f"    <CheckerBundle application={quoteattr(bundle)}>\n")
    f.write(f"        <Param name=\"resultFile\" value={quoteattr(report)}/>\n")
    f.write("    </CheckerBundle>\n</Config>\n")
PY
    # The checker logs every check: the log is shown only when it fails.
    if ! (cd "$out" && "$venv/bin/$QC_EXE" -c "$config") >"$log" 2>&1 || [ ! -f "$report" ]; then
        cat "$log" >&2
        echo "qc.sh: $QC_EXE failed on $shown (no $report)" >&2
        status=1
        continue
    fi
    # The report: every issue with its locations, the counts by level, checks that did not complete
    # (strict: a skipped check counts as a failure, its preconditions did not hold).
    if ! "$venv/bin/python" - "$report" "$shown" "$QC_STRICT" <<'PY'; then
import sys
import xml.etree.ElementTree as ET

report, shown, strict = sys.argv[1], sys.argv[2], sys.argv[3] == "1"
root = ET.parse(report).getroot()
levels = {"1": "error", "2": "warning", "3": "info"}
counts = {"error": 0, "warning": 0, "info": 0}
checks, crashed = 0, 0
for checker in root.iter("Checker"):
    checks += 1
    status = checker.get("status", "")
    if status != "completed":
        print(f"  {status or 'no status'}: {checker.get('checkerId')}: {checker.get('summary', '')}")
        crashed += status == "error" or (strict and status == "skipped")
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
failing = counts["error"] + (counts["warning"] + counts["info"] if strict else 0)
sys.exit(1 if failing or crashed or checks == 0 else 0)
PY
        status=1
    fi
done
exit "$status"
