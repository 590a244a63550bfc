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
# The runner is tests/asam-qc.sh.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
if [ "$#" -eq 0 ]; then
    echo "usage: bash tests/openscenario/qc.sh SCENARIO.xosc [...]" >&2
    exit 2
fi
QC_PACKAGE=asam-qc-openscenarioxml QC_VERSION=1.0.0 QC_BASELIB_VERSION=1.1.0 \
    QC_BUNDLE=xoscBundle QC_EXE=qc_openscenario QC_EXT=.xosc QC_STRICT=1 \
    QC_VENV="${V2T_XOSC_QC_VENV:-target/qc-xosc-venv}" QC_OUT="${V2T_XOSC_QC_OUT:-target/qc-xosc}" \
    exec bash "$here/../asam-qc.sh" "$@"
