#!/usr/bin/env python3
"""check_fmu_sources.py FMU -- does sources/ alone rebuild a working binary?

1. copies the FMU to a temp dir, checks that <SourceFiles> of ModelExchange and CoSimulation list
   exactly the C files in sources/;
2. deletes the shipped binary and runs `fmpy compile` (fmpy's CMake template: sources/ is the only
   include dir, exactly the listed files are compiled, no extra defines);
3. checks that the rebuilt binary leaves no symbol undefined except glibc's (libc/libm);
4. simulates the original and the rebuilt FMU (Co-Simulation and Model Exchange, default
   experiment, at most 1 s) and compares the outputs.
Exit 0 when all pass.  Needs fmpy, numpy and cmake (run it with .venv/bin/python).
"""
import glob
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
import xml.etree.ElementTree as ET

import numpy as np
from fmpy import read_model_description, simulate_fmu


def fail(msg):
    print("check_fmu_sources: FAIL: " + msg)
    sys.exit(1)


def glibc_symbols():
    names = set()
    for lib in ("libc.so.6", "libm.so.6"):
        paths = glob.glob("/lib/*/" + lib) + glob.glob("/usr/lib/*/" + lib) + glob.glob("/lib64/" + lib)
        for p in paths[:1]:
            out = subprocess.run(["nm", "-D", "--defined-only", p], capture_output=True, text=True).stdout
            names |= {line.split()[-1].split("@")[0] for line in out.splitlines() if line.strip()}
    return names


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: check_fmu_sources.py FMU")
    fmu = os.path.abspath(sys.argv[1])
    md = read_model_description(fmu)
    ident = md.coSimulation.modelIdentifier
    with tempfile.TemporaryDirectory(prefix="kt-srccheck-") as tmp:
        copy = os.path.join(tmp, os.path.basename(fmu))
        shutil.copy(fmu, copy)

        with zipfile.ZipFile(copy) as zf:
            names = zf.namelist()
            root = ET.fromstring(zf.read("modelDescription.xml"))
        in_zip = sorted(n[len("sources/"):] for n in names if n.startswith("sources/") and n.endswith(".c"))
        for kind in ("ModelExchange", "CoSimulation"):
            listed = sorted(f.get("name") for f in root.findall("%s/SourceFiles/File" % kind))
            if not listed:
                fail("%s lists no <SourceFiles>" % kind)
            if listed != in_zip:
                fail("%s <SourceFiles> differ from the C files in sources/: listed-only %s, unlisted %s"
                     % (kind, sorted(set(listed) - set(in_zip)), sorted(set(in_zip) - set(listed))))
        print("check_fmu_sources: %d C files listed in both <SourceFiles>, all present" % len(in_zip))

        # drop the shipped binary so the simulation below surely uses the rebuilt one
        stripped = os.path.join(tmp, "stripped.fmu")
        with zipfile.ZipFile(copy) as zin, zipfile.ZipFile(stripped, "w", zipfile.ZIP_DEFLATED) as zout:
            for item in zin.infolist():
                if not item.filename.startswith("binaries/"):
                    zout.writestr(item, zin.read(item.filename))
        os.replace(stripped, copy)

        log = os.path.join(tmp, "compile.log")
        with open(log, "w") as f:
            r = subprocess.run([sys.executable, "-m", "fmpy", "compile", copy], stdout=f, stderr=subprocess.STDOUT)
        if r.returncode != 0:
            print(open(log).read()[-6000:])
            fail("fmpy compile failed (exit %d)" % r.returncode)
        warnings = [line for line in open(log) if "warning:" in line]
        print("check_fmu_sources: fmpy compile OK (%d compiler warnings)" % len(warnings))

        unz = os.path.join(tmp, "unz")
        with zipfile.ZipFile(copy) as zf:
            zf.extractall(unz)
        so = os.path.join(unz, "binaries", "linux64", ident + ".so")
        if not os.path.isfile(so):
            fail("fmpy compile produced no binaries/linux64/%s.so" % ident)
        out = subprocess.run(["nm", "-D", "--undefined-only", so], capture_output=True, text=True).stdout
        undefined = {line.split()[-1].split("@")[0] for line in out.splitlines() if line.strip()}
        undefined -= {"_ITM_deregisterTMCloneTable", "_ITM_registerTMCloneTable", "__gmon_start__", "__cxa_finalize"}
        missing = sorted(undefined - glibc_symbols())
        if missing:
            fail("rebuilt binary has unresolved symbols (a C file missing from sources/?): %s" % " ".join(missing))
        print("check_fmu_sources: rebuilt binary needs only glibc symbols (%d)" % len(undefined))

        outputs = [v.name for v in md.modelVariables if v.causality == "output"]
        stop = 1.0
        if md.defaultExperiment and md.defaultExperiment.stopTime:
            stop = min(stop, float(md.defaultExperiment.stopTime))
        for kind in ("CoSimulation", "ModelExchange"):
            kw = dict(fmi_type=kind, stop_time=stop, output=outputs, output_interval=stop / 100)
            a = simulate_fmu(fmu, **kw)
            b = simulate_fmu(copy, **kw)
            worst = 0.0
            for name in outputs:
                scale = 1.0 + float(np.max(np.abs(a[name])))
                worst = max(worst, float(np.max(np.abs(a[name] - b[name]))) / scale)
            if len(a) != len(b) or not np.isfinite(worst) or worst > 1e-6:
                fail("%s: original and rebuilt FMU disagree (relative difference %.3g)" % (kind, worst))
            print("check_fmu_sources: %s simulation of the rebuilt FMU matches the original "
                  "(%d rows to t=%g, max rel. diff %.2g)" % (kind, len(b), stop, worst))
    print("check_fmu_sources: OK")


if __name__ == "__main__":
    main()
