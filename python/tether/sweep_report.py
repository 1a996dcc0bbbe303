"""A sweep's report: the prediction band (5/50/95 %) against the measurement, and the
distributions of the summary outputs.

The band at each sample is the quantiles of the runs' predictions, each with the measurement noise
``sigma`` around it (a prediction band: where a new measurement would fall, for a model whose
parameters scatter as the runs' do): the quantiles of the mixture of normals N(y_k(t), sigma^2)
over the runs k. With ``sigma`` = 0 they are the plain quantiles of the runs' predictions.
"""

from __future__ import annotations

import html
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

QUANTILES = (0.05, 0.5, 0.95)


def mixture_quantiles(Y: np.ndarray, sigma: float, q: Sequence[float] = QUANTILES) -> np.ndarray:
    """Quantiles (len(q) x samples) of the equal mixture of N(Y[k, j], sigma^2) over the runs k,
    by bisection on the mixture's distribution function."""
    from scipy.special import ndtr

    Y = np.asarray(Y, float)
    if sigma <= 0:
        return np.quantile(Y, q, axis=0)
    out = np.empty((len(q), Y.shape[1]))
    for m, p in enumerate(q):
        lo = Y.min(axis=0) - 9.0 * sigma
        hi = Y.max(axis=0) + 9.0 * sigma
        for _ in range(42):                           # 2^-42: 1e-12 of the bracket
            mid = 0.5 * (lo + hi)
            below = ndtr((mid[None, :] - Y) / sigma).mean(axis=0) < p
            lo = np.where(below, mid, lo)
            hi = np.where(below, hi, mid)
        out[m] = 0.5 * (lo + hi)
    return out


def coverage(measured: np.ndarray, band: np.ndarray) -> float:
    """The share of measured samples inside [5 %, 95 %]."""
    return float(np.mean((measured >= band[0]) & (measured <= band[-1])))


def fit_noise(extra: Mapping | None, trace_name: str) -> float:
    """The measurement noise a fit left: its RMS error on this trace (else over all its traces)."""
    if not extra:
        return 0.0
    per = extra.get("rms_per_trace")
    if isinstance(per, dict) and isinstance(per.get(trace_name), (int, float)):
        return float(per[trace_name])
    rms = extra.get("rms")
    return float(rms) if isinstance(rms, (int, float)) else 0.0


def write_sweep_report(folder: Path, trace, Y: np.ndarray, sigma: float, columns: Sequence[str],
                       rows: np.ndarray, first_output: int, title: str) -> dict:
    """DIR/index.html, band.png, distributions.png, band.csv and band.json; returns band.json's figures."""
    from .atomic import write_with
    from .report import UNITS, pyplot, save_figure_atomic, write_json_atomic, write_text_atomic

    folder = Path(folder)
    band = mixture_quantiles(Y, sigma)
    measured = getattr(trace, "measured", None)
    cov = coverage(measured, band) if measured is not None else None
    col = trace.measured_column
    unit = UNITS.get(col, "")

    plt = pyplot()
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(10, 7), sharex=True, height_ratios=[3, 2])
    t = trace.time
    ax.fill_between(t, band[0], band[-1], color="tab:blue", alpha=0.3, lw=0, label="5-95 % band")
    ax.plot(t, band[1], color="tab:blue", lw=1, label="median")
    # the band about its median: on the scale of the noise, where the record's own scale hides it
    ax2.fill_between(t, band[0] - band[1], band[-1] - band[1], color="tab:blue", alpha=0.3, lw=0)
    ax2.axhline(0.0, color="tab:blue", lw=1)
    if measured is not None:
        ax.plot(t, measured, ".", ms=1.5, color="k", label="measured")
        ax2.plot(t, measured - band[1], ".", ms=1.5, color="k")
    ax2.set_xlabel("time [s]")
    ax.set_ylabel(f"{col} [{unit}]")
    ax2.set_ylabel(f"minus the median [{unit}]")
    ax.legend(loc="upper right")
    ax.set_title(f"{trace.name}: prediction band of {Y.shape[0]} runs" +
                 (f" (noise {sigma:.3g} {unit})" if sigma > 0 else "") +
                 (f"; {100 * cov:.1f} % of the samples inside" if cov is not None else ""), fontsize=10)
    fig.tight_layout()
    save_figure_atomic(fig, folder / "band.png")
    plt.close(fig)

    outs = list(columns[first_output:])
    ncol = 4
    nrow = -(-len(outs) // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(12, 2.8 * nrow), squeeze=False)
    for k, ax in enumerate(axes.flat):
        if k >= len(outs):
            ax.axis("off")
            continue
        v = rows[:, first_output + k]
        v = v[np.isfinite(v)]
        ax.hist(v, bins=min(30, max(5, len(v) // 4)), color="tab:gray")
        ax.set_title(outs[k], fontsize=9)
    fig.tight_layout()
    save_figure_atomic(fig, folder / "distributions.png")
    plt.close(fig)

    data = np.column_stack([t, band.T] + ([measured] if measured is not None else []))
    names = ["time", "q05", "q50", "q95"] + ([col] if measured is not None else [])
    write_with(folder / "band.csv", lambda f: (f.write(",".join(names) + "\n"),
                                                np.savetxt(f, data, delimiter=",", fmt="%.17g")))
    figures = {"format": "tether-sweep-band/1", "trace": str(trace.stem), "runs": int(Y.shape[0]),
               "noise_sigma": sigma, "quantiles": list(QUANTILES), "coverage": cov,
               "band_width_median": float(np.median(band[-1] - band[0]))}
    write_json_atomic(folder / "band.json", figures)
    cover = "" if cov is None else f"<p>{100 * cov:.1f} % of the measured samples lie inside the 5-95 % band.</p>"
    noise = (f"<p>Each run's prediction carries the fit's noise, sigma = {sigma:.4g} {unit} (a prediction "
             "band).</p>" if sigma > 0 else "<p>The band is the spread of the runs' predictions alone.</p>")
    page = (f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title></head><body>"
            f"<h1>{html.escape(title)}</h1>{noise}{cover}<img src='band.png' alt='prediction band'>"
            "<h2>Distributions of the summary outputs</h2><img src='distributions.png' alt='distributions'>"
            "<p>Numbers: band.json, band.csv.</p></body></html>\n")
    write_text_atomic(folder / "index.html", page)
    return figures
