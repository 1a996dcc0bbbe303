#!/usr/bin/env bash
# scripts/test.sh -- setup (packages, venv, build), then every check; exits non-zero if any fails.
#   1. fmpy validate            build/KevlarTether.fmu
#   2. fmutool -check           build/KevlarTether.fmu
#   3. ldd / nm                 build/KevlarTether.so depends on libc/libm only, exports fmi2* only
#   4. sources/ rebuild         fmpy compile of the FMU's sources/ + simulate, same results as ours
#   5. test_identify            the identification engine's own C++ test
#   6. pytest                   python_tests, a worker per core (no tests collected counts as a failure)
set -uo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR="${KT_BUILD_DIR:-build}"
FMU="$BUILD_DIR/KevlarTether.fmu"
SO="$BUILD_DIR/KevlarTether.so"
PY=.venv/bin/python

bash scripts/setup.sh || { echo "test.sh: setup failed" >&2; exit 1; }

passed=0; failed=0; failed_names=()
check() {
  local name="$1"; shift
  local t0; t0=$(date +%s%3N)
  echo "==> [test] $name"
  if "$@"; then
    passed=$((passed + 1)); echo "    [test] $name: ok ($(( ($(date +%s%3N) - t0) / 1000 )) s)"
  else
    failed=$((failed + 1)); failed_names+=("$name"); echo "    [test] $name: FAILED" >&2
  fi
}
fmutool_check() {
  if [ ! -x .venv/bin/fmutool ]; then
    echo "fmutool not installed in .venv (pyproject's [test] extra needs fmu-manipulation-toolbox)" >&2; return 1
  fi
  local out rc
  out=$(.venv/bin/fmutool -input "$FMU" -check 2>&1); rc=$?
  printf '%s\n' "$out" | sed 's/^/    /'
  # belt and braces: fmutool exits 7 on a failed check; also refuse ERROR lines
  [ $rc -eq 0 ] && ! grep -q '^ERROR' <<<"$out"
}

check "fmpy validate" "$PY" -m fmpy validate "$FMU"
check "fmutool -check" fmutool_check
check "ldd/nm of $SO" bash scripts/check_binary.sh "$SO"
check "fmpy compile + simulate from sources/" "$PY" scripts/check_fmu_sources.py "$FMU"
check "identification engine (C++ test)" "$BUILD_DIR/fmu_src/identify/test_identify"
echo "build checks: $passed passed, $failed failed"

echo "==> [test] pytest python_tests (one worker per core: docs/test-suite-time.md)"
"$PY" -m pytest python_tests -q -n auto --dist worksteal
rc=$?
if [ $rc -eq 5 ]; then
  echo "test.sh: pytest collected no tests -- counted as a failure" >&2
  failed_names+=("pytest (no tests)")
elif [ $rc -ne 0 ]; then
  failed_names+=("pytest (exit $rc)")
fi

if [ ${#failed_names[@]} -gt 0 ]; then
  echo "test.sh: FAILED: ${failed_names[*]}" >&2
  exit 1
fi
echo "test.sh: all checks passed"
