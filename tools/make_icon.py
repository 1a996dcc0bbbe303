#!/usr/bin/env python3
"""Draw fmu_src/model.png, the FMU's icon: a braided tether hanging from a ceiling with a payload.

usage: python tools/make_icon.py [OUT.png]   (default fmu_src/model.png; packaged by scripts/package_fmu.py)
"""
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import FancyBboxPatch, Rectangle  # noqa: E402

SIZE_PX = 128
KEVLAR = "#d9a400"


def draw(out: Path) -> None:
    fig = plt.figure(figsize=(1, 1), dpi=SIZE_PX)
    ax = fig.add_axes([0, 0, 1, 1])
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.axis("off")
    ax.add_patch(Rectangle((0.18, 0.9), 0.64, 0.07, facecolor="#7a7a7a", edgecolor="none"))
    y = np.linspace(0.36, 0.9, 200)
    for phase in (0.0, np.pi):   # two strands twisted round each other: the braid
        ax.plot(0.5 + 0.05 * np.sin(2 * np.pi * 7 * y + phase), y, color=KEVLAR, lw=2.6, solid_capstyle="butt")
    ax.add_patch(FancyBboxPatch((0.3, 0.08), 0.4, 0.26, boxstyle="round,pad=0.0,rounding_size=0.05",
                                facecolor="#2f4f7f", edgecolor="none"))
    ax.text(0.5, 0.21, "m", color="white", ha="center", va="center", fontsize=13, fontweight="bold")
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=SIZE_PX, transparent=True)
    plt.close(fig)


if __name__ == "__main__":
    draw(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[1] / "fmu_src" / "model.png")
