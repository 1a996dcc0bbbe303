#!/usr/bin/env bash
# scripts/demo.sh -- the main job on the bundled data: set everything up (system packages, .venv,
# the FMU), validate the FMU against the bundled reference traces and the Bouc-Wen benchmark, run a
# discovery on a record with hidden effects, and
# leave a report to open (reports/demo/index.html).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
FMU="${KT_BUILD_DIR:-build}/KevlarTether.fmu"
echo
echo "The FMU is at: $PWD/$FMU"
echo
.venv/bin/tether demo --report reports/demo
echo
echo "Open $PWD/reports/demo/index.html"
