#!/usr/bin/env bash
# check_binary.sh FILE.so -- the FMU binary may depend on libc, libm (and the loader) only, and may
# export fmi2* functions only. Prints the ldd / nm output it judged; exits 1 on a violation.
set -euo pipefail
so="${1:?usage: check_binary.sh FILE.so}"
[ -f "$so" ] || { echo "check_binary: $so not found" >&2; exit 1; }
rc=0

echo "--- ldd $so"
ldd "$so" | sed 's/^/    /'
bad_deps=$(ldd "$so" | awk '{print $1}' \
  | grep -Ev '^(linux-vdso\.so\.[0-9]+|libc\.so\.[0-9]+|libm\.so\.[0-9]+|/lib64/ld-linux-x86-64\.so\.[0-9]+|ld-linux[-a-z0-9_]*\.so\.[0-9]+|/.*/ld-linux[-a-z0-9_]*\.so\.[0-9]+)$' || true)
if [ -n "$bad_deps" ]; then
  echo "check_binary: FAIL: depends on more than libc/libm: $bad_deps" >&2
  rc=1
fi

echo "--- nm -D --defined-only $so"
defined=$(nm -D --defined-only "$so" | awk '{print $3}')
printf '%s\n' "$defined" | sed 's/^/    /'
bad_syms=$(printf '%s\n' "$defined" | grep -v '^fmi2' | grep -v '^$' || true)
if [ -n "$bad_syms" ]; then
  echo "check_binary: FAIL: exports symbols other than fmi2*: $(echo $bad_syms)" >&2
  rc=1
fi
n_fmi2=$(printf '%s\n' "$defined" | grep -c '^fmi2' || true)
# the 44 functions of FMI 2.0 Model Exchange + Co-Simulation
required="GetTypesPlatform GetVersion SetDebugLogging Instantiate FreeInstance SetupExperiment
  EnterInitializationMode ExitInitializationMode Terminate Reset GetReal GetInteger GetBoolean GetString
  SetReal SetInteger SetBoolean SetString GetFMUstate SetFMUstate FreeFMUstate SerializedFMUstateSize
  SerializeFMUstate DeSerializeFMUstate GetDirectionalDerivative
  EnterEventMode NewDiscreteStates EnterContinuousTimeMode CompletedIntegratorStep SetTime
  SetContinuousStates GetDerivatives GetEventIndicators GetContinuousStates GetNominalsOfContinuousStates
  SetRealInputDerivatives GetRealOutputDerivatives DoStep CancelStep GetStatus GetRealStatus
  GetIntegerStatus GetBooleanStatus GetStringStatus"
missing=""
for f in $required; do
  grep -qx "fmi2$f" <<<"$defined" || missing="$missing fmi2$f"
done
if [ -n "$missing" ]; then
  echo "check_binary: FAIL: FMI 2.0 functions not exported:$missing" >&2
  rc=1
fi

undefined=$(nm -D --undefined-only "$so" | awk '{print $2}' | grep -v '@GLIBC_' | grep -Ev '^(_ITM_|__gmon_start__|__cxa_finalize)' || true)
if [ -n "$undefined" ]; then
  echo "check_binary: FAIL: undefined symbols not from glibc: $(echo $undefined)" >&2
  rc=1
fi

[ $rc -eq 0 ] && echo "check_binary: OK ($n_fmi2 fmi2* exports, deps libc/libm only)"
exit $rc
