#!/usr/bin/env bash
# scripts/demo.sh -- build everything, then show the FMU. (The lead extends this with the real demo.)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
FMU="${KT_BUILD_DIR:-build}/KevlarTether.fmu"
echo
echo "The FMU is at: $PWD/$FMU"
echo
.venv/bin/python -m fmpy info "$FMU"
