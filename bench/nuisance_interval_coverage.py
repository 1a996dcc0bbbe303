#!/usr/bin/env python3
"""How often do the nuisance parameters' 95 % intervals hold their truth (issue 30)? Not a CI test.

Takes a record of python_tests/hidden_effects.py's nuisance family (its JSON, which names the
generator's seed, noise and rate), draws its noise-free measured column again, adds DRAWS fresh
noise draws of the record's own sigma, fits MODEL to each with its default free parameters plus
m, x0, v0 and offset_measured (tether.fit.fit_traces, as discovery's final fit frees them), and
prints per draw and in total how often each truth lies in its interval, with the errors in
standard errors (z): calibrated intervals give about 95 % coverage and z of mean 0, spread 1.

    nice -n 19 .venv/bin/python bench/nuisance_interval_coverage.py RECORD.json MODEL [--draws 40]

MODEL is the model discovery named (its OUT.json's `model`), so the law is the generator's
approximation, as on the record itself. Figures go to docs/nuisance-discovery.md with their date.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

import this_tree  # noqa: E402  (bench/, this file's folder, is on sys.path)

REPO = this_tree.use()

NUISANCE = ("m", "x0", "v0", "offset_measured")


def regenerated(meta: dict):
    """The record drawn again by its generator (the same seed, noise and rate)."""
    import hidden_effects as H

    hid = meta["hidden"]
    return H.generate(meta["experiment"], hid["effects"], hid["seed"], noise=hid["noise_sigma_m"],
                      rate=hid["rate_Hz"], nuisance=True)


def truths(meta: dict, free: list) -> dict:
    nz = meta["hidden"]["nuisance"]
    known = {"m": nz["m_true"], "x0": nz["x0"], "v0": nz["v0"], "offset_measured": nz["offset_measured"]}
    return {n: known[n] for n in free if n in known}


def one_draw(tr, clean, sigma, k: int, model: str, folder: Path):
    from tether.fit.engine import fit_traces
    from tether.fit.parameters import default_free_parameters, model_spec
    from tether.nuisance import refusal
    from tether.traces import read_trace

    tr.columns[tr.measured_name] = clean + sigma * np.random.default_rng(1000 + k).standard_normal(len(clean))
    tr.write(folder, f"draw{k}")
    t = read_trace(folder / f"draw{k}")
    spec = model_spec(model)
    nuisance = [n for n in NUISANCE if refusal(t, n) is None]
    return fit_traces([t], model, free=[*default_free_parameters(spec, t.experiment), *nuisance])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("record", type=Path, help="a nuisance-family record's JSON")
    ap.add_argument("model", help="the model to fit (discovery's named model)")
    ap.add_argument("--draws", type=int, default=40, help="noise draws (default 40)")
    args = ap.parse_args(argv)
    meta = json.loads(args.record.read_text())
    tr = regenerated(meta)
    on_file = np.loadtxt(args.record.with_suffix(".csv"), delimiter=",", skiprows=1)[:, -1]
    gap = float(np.max(np.abs(on_file - tr.measured)))
    print(f"{args.record.name}: {args.model}, {args.draws} noise draws; the record drawn again differs from "
          f"the file by {gap:.2g} at most", flush=True)
    clean, sigma = tr.truth["measured"], meta["hidden"]["noise_sigma_m"]
    hits, zs = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.draws):
            r = one_draw(tr, clean, sigma, k, args.model, Path(tmp))
            line = []
            for n, v in truths(meta, r.free).items():
                lo, hi = r.ci95[n]
                inside = lo <= v <= hi
                hits[n] = hits.get(n, 0) + inside
                z = (r.values[n] - v) / r.std_error[n] if r.std_error[n] else float("nan")
                zs.setdefault(n, []).append(z)
                line.append(f"{n} {'in ' if inside else 'OUT'} z {z:+.2f}")
            print(f"draw {k:2d}: RMS error {r.rms / sigma:.3f} x noise; " + "; ".join(line), flush=True)
    print("inside the 95 % interval: " + ", ".join(f"{n} {h} of {args.draws}" for n, h in hits.items()))
    print("z (error / standard error): " + ", ".join(
        f"{n} mean {np.nanmean(z):+.2f} spread {np.nanstd(z):.2f}" for n, z in zs.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
