#!/usr/bin/env python3
"""build_fuzz.py -- build the fuzz and thread drivers from the FMU's own sources/.

usage: build_fuzz.py FMU OUTDIR [--sanitize address,undefined,float-cast-overflow | thread] [--driver fmu_fuzz.c]

Extracts sources/ of FMU, compiles exactly the C files its <SourceFiles> list (sources/ the only
include directory, as `fmpy compile` does) together with the driver into OUTDIR/<driver name>,
with the sanitizers asked for (default: AddressSanitizer with LeakSanitizer, and UBSan with the
float-to-integer overflow check, aborting on the first report). Rebuilds only when the FMU or the driver changed. Prints the path.
"""
import argparse
import hashlib
import os
import shutil
import subprocess
import sys
import zipfile
import xml.etree.ElementTree as ET
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("fmu", type=Path)
    ap.add_argument("outdir", type=Path)
    ap.add_argument("--sanitize", default="address,undefined,float-cast-overflow")
    ap.add_argument("--driver", default="fmu_fuzz.c")
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args()
    driver = HERE / a.driver
    if not a.fmu.is_file():
        print(f"build_fuzz: FMU {a.fmu} not found (build it first)", file=sys.stderr)
        return 2
    key = hashlib.sha256(a.fmu.read_bytes() + driver.read_bytes() + a.sanitize.encode()).hexdigest()[:16]
    tag = a.sanitize.replace(",", "_")
    exe = a.outdir / f"{driver.stem}_{tag}"
    stamp = a.outdir / f"{driver.stem}_{tag}.key"
    if exe.is_file() and stamp.is_file() and stamp.read_text() == key:
        print(exe)
        return 0
    src = a.outdir / f"src_{tag}_{driver.stem}"
    shutil.rmtree(src, ignore_errors=True)
    with zipfile.ZipFile(a.fmu) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
        for name in zf.namelist():
            if name.startswith("sources/") and not name.endswith("/"):
                zf.extract(name, src)
    sources = src / "sources"
    files = [f.get("name") for f in root.findall("CoSimulation/SourceFiles/File")]
    if not files:
        print(f"build_fuzz: {a.fmu} lists no <SourceFiles>", file=sys.stderr)
        return 2
    flags = ["-O1", "-g", "-fno-omit-frame-pointer", f"-fsanitize={a.sanitize}", "-I", str(sources)]
    if "undefined" in a.sanitize:
        flags.append("-fno-sanitize-recover=all")
    objs = []

    def compile_one(item):
        i, path = item
        obj = src / f"o{i}.o"
        r = subprocess.run(["gcc", *flags, "-c", str(path), "-o", str(obj)], capture_output=True, text=True)
        if r.returncode != 0:
            raise SystemExit(f"build_fuzz: compiling {path} failed:\n{r.stderr}")
        return obj

    items = [(i, sources / f) for i, f in enumerate(files)] + [(len(files), driver)]
    with ThreadPoolExecutor(max_workers=max(1, a.jobs)) as pool:
        objs = list(pool.map(compile_one, items))
    extra = ["-lpthread"] if a.sanitize == "thread" else []
    r = subprocess.run(["gcc", *flags, *map(str, objs), "-o", str(exe), "-lm", *extra], capture_output=True, text=True)
    if r.returncode != 0:
        print(f"build_fuzz: linking {exe} failed:\n{r.stderr}", file=sys.stderr)
        return 1
    stamp.write_text(key)
    shutil.rmtree(src, ignore_errors=True)
    print(exe)
    return 0


if __name__ == "__main__":
    sys.exit(main())
