#!/usr/bin/env bash
# scripts/setup.sh -- make this checkout ready: system packages, .venv, build/ (Release).
# Idempotent: every stage checks first and does nothing when nothing is missing or changed.
#
# Environment:
#   KT_PYTHON       interpreter for the venv (default: python3 on PATH)
#   KT_CMAKE_ARGS   extra arguments for the first cmake configure, e.g. "-DKT_SUNDIALS_ROOT=/opt/sundials"
#   KT_FORCE_PIP=1  re-run pip even if pyproject.toml did not change
#   KT_BUILD_DIR    build directory (default: build)
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT="$PWD"
BUILD_DIR="${KT_BUILD_DIR:-build}"
VENV="$ROOT/.venv"

now() { date +%s%3N; }   # milliseconds
secs() { local ms=$(( $(now) - $1 )); printf '%d.%d s' $((ms / 1000)) $((ms % 1000 / 100)); }
T_ALL=$(now)
stage_begin() { STAGE="$1"; T0=$(now); echo "==> [setup] $STAGE"; }
stage_end() { echo "    [setup] $STAGE: $(secs "$T0")"; }
die() { echo "setup.sh: ERROR: $*" >&2; exit 1; }

# ---------------------------------------------------------------------------------------------
stage_begin "system packages"
# Debian package -> what it gives us
PKGS=(cmake ninja-build gcc g++ make binutils python3 python3-venv libeigen3-dev libtbb12 debian-archive-keyring)
missing=()
if command -v dpkg-query >/dev/null 2>&1; then
  for p in "${PKGS[@]}"; do
    st=$(dpkg-query -W -f='${db:Status-Status}' "$p" 2>/dev/null || true)
    [ "$st" = "installed" ] || missing+=("$p")
  done
else
  echo "    no dpkg-query (not Debian?): checking commands only"
  for c in cmake gcc g++ nm python3; do command -v "$c" >/dev/null 2>&1 || missing+=("$c"); done
  [ ${#missing[@]} -eq 0 ] || die "missing tools: ${missing[*]} (install them with your package manager)"
fi
if [ ${#missing[@]} -gt 0 ]; then
  echo "    missing: ${missing[*]}"
  if [ "$(id -u)" -eq 0 ]; then
    SUDO=()
  elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
    SUDO=(sudo)
  else
    die "packages missing (${missing[*]}) and not root, no password-less sudo. Run as root:
    apt-get update && apt-get install -y --no-install-recommends ${missing[*]}"
  fi
  echo "    apt-get update"
  "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -q
  echo "    apt-get install ${missing[*]}"
  "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${missing[@]}"
else
  echo "    all present: ${PKGS[*]}"
fi
stage_end

# ---------------------------------------------------------------------------------------------
stage_begin "python venv (.venv)"
PY="${KT_PYTHON:-python3}"
if [ -x "$VENV/bin/python" ] && "$VENV/bin/python" -c 'import sys; sys.exit(0)' 2>/dev/null; then
  echo "    exists: $("$VENV/bin/python" --version 2>&1)"
else
  rm -rf "$VENV"
  echo "    $PY -m venv .venv"
  "$PY" -m venv "$VENV" || die "'$PY -m venv' failed (Debian: apt-get install python3-venv)"
fi
stage_end

stage_begin "python packages"
STAMP="$VENV/.kt-pip-stamp"
if [ -f pyproject.toml ]; then
  # the package's module files too: the editable install maps each module to its file, so a module
  # added, moved or made a package (tether/discover/) needs the install again
  want="pyproject $(sha256sum pyproject.toml | cut -d' ' -f1) $("$VENV/bin/python" --version 2>&1) modules $(cd python && find . -name '*.py' | sort | sha256sum | cut -c1-16)"
  # editable: the Python package only (pyproject.toml); CMake builds $BUILD_DIR below, where it finds the FMU
  PIP_ARGS=(-e '.[test]')
else
  # no pyproject.toml yet: the tools the checks need
  want="direct fmpy fmu-manipulation-toolbox libcosimpy numpy scipy matplotlib pytest"
  PIP_ARGS=(fmpy fmu-manipulation-toolbox libcosimpy numpy scipy matplotlib pytest)
fi
if [ "${KT_FORCE_PIP:-0}" != "1" ] && [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$want" ]; then
  echo "    up to date ($want)"
else
  echo "    pip install ${PIP_ARGS[*]}"
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check "${PIP_ARGS[@]}"
  echo "$want" > "$STAMP"
fi
stage_end

# ---------------------------------------------------------------------------------------------
stage_begin "cmake configure ($BUILD_DIR, Release)"
CFG=(-S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release "-DPython3_EXECUTABLE=$VENV/bin/python")
if [ ! -f "$BUILD_DIR/CMakeCache.txt" ]; then
  if command -v ninja >/dev/null 2>&1; then CFG+=(-G Ninja); else CFG+=(-G "Unix Makefiles"); fi
fi
# shellcheck disable=SC2206
[ -n "${KT_CMAKE_ARGS:-}" ] && CFG+=(${KT_CMAKE_ARGS})
echo "    cmake ${CFG[*]}"
mkdir -p "$BUILD_DIR"
LOG="$BUILD_DIR/configure.log"
cmake "${CFG[@]}" > "$LOG" 2>&1 || { cat "$LOG"; die "cmake configure failed (log: $LOG)"; }
grep -E '^-- SUNDIALS' "$LOG" | sed 's/^/    /' || true
stage_end

stage_begin "cmake build"
echo "    cmake --build $BUILD_DIR --parallel"
cmake --build "$BUILD_DIR" --parallel "$(nproc 2>/dev/null || echo 2)"
stage_end

echo "==> [setup] done in $(secs "$T_ALL"): $BUILD_DIR/KevlarTether.fmu"
