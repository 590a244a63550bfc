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
# The runner is tests/asam-qc.sh.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
if [ "$#" -eq 0 ]; then
    set -- "$here/../../config/maps/proving_ground.xodr"
fi
QC_PACKAGE=asam-qc-opendrive QC_VERSION=1.0.0 QC_BASELIB_VERSION=1.1.0 \
    QC_BUNDLE=xodrBundle QC_EXE=qc_opendrive QC_EXT=.xodr QC_STRICT=0 \
    QC_VENV="${V2T_QC_VENV:-target/qc-venv}" QC_OUT="${V2T_QC_OUT:-target/qc}" \
    exec bash "$here/../asam-qc.sh" "$@"
