#!/usr/bin/env bash
# Records the bundled scenarios as MCAP (`video2track sim --mcap`), opens them with the MCAP
# project's Python reader (tests/mcap/check.py) and replays them (`video2track replay`: the metrics
# measured again from the recording must equal the recorded ones).
#
#   bash tests/mcap/check.sh
#
# Needs python3 with venv and PyPI; the reader goes into ${V2T_MCAP_VENV:-target/mcap-venv}.
set -euo pipefail
MCAP_PY_VERSION="1.6.0"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
venv="${V2T_MCAP_VENV:-target/mcap-venv}"
out="target/mcap"
mkdir -p "$out"
if ! "$venv/bin/python" -c "import mcap, importlib.metadata as m; assert m.version('mcap') == '$MCAP_PY_VERSION'" 2>/dev/null; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install -q "mcap==$MCAP_PY_VERSION"
fi
cargo build -q -p video2track
bin="${CARGO_TARGET_DIR:-target}/debug/video2track"
for card in left_turn_basic cut_in_basic; do
    "$bin" sim "config/scenarios/$card.toml" --mcap "$out/$card.mcap" > /dev/null
    "$venv/bin/python" tests/mcap/check.py "$out/$card.mcap"
    "$bin" replay "$out/$card.mcap" | tail -1
done
