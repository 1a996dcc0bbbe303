"""Draw docs/rigs.png: the three rigs of the KevlarTether FMU (run: python docs/make_rigs_figure.py)."""
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.patches import FancyArrowPatch, Rectangle


def tether(ax, x, y0, y1, label="tether  L0 + u"):
    n = 14
    ys = [y0 + (y1 - y0) * k / n for k in range(n + 1)]
    xs = [x + (0.08 if k % 2 else -0.08) if 0 < k < n else x for k in range(n + 1)]
    ax.plot(xs, ys, color="#8a5a00", lw=2.2)
    ax.text(x + 0.18, (y0 + y1) / 2, label, va="center", fontsize=9)


def anchor(ax, x, y):
    ax.add_patch(Rectangle((x - 0.45, y), 0.9, 0.12, hatch="////", fill=False, lw=1))
    ax.plot([x - 0.45, x + 0.45], [y, y], color="k", lw=1.5)


def arrow(ax, x0, y0, x1, y1, text, dx=0.1, color="k"):
    ax.add_patch(FancyArrowPatch((x0, y0), (x1, y1), arrowstyle="-|>", mutation_scale=12, color=color, lw=1.4))
    ax.text(x1 + dx, y1, text, va="center", fontsize=9, color=color)


fig, axes = plt.subplots(1, 3, figsize=(11, 4.6))
for ax, title in zip(axes, ["rig = element", "rig = payload", "rig = load"]):
    ax.set_xlim(-1.2, 1.8)
    ax.set_ylim(-0.4, 4.3)
    ax.axis("off")
    ax.set_title(title, fontsize=12, fontweight="bold")

ax = axes[0]  # element: force element between two bodies of a system model
ax.add_patch(Rectangle((-0.35, 3.3), 0.7, 0.5, color="#cfd8e3"))
ax.text(0, 3.55, "body A", ha="center", va="center", fontsize=9)
tether(ax, 0, 3.3, 1.2)
ax.add_patch(Rectangle((-0.35, 0.7), 0.7, 0.5, color="#cfd8e3"))
ax.text(0, 0.95, "body B", ha="center", va="center", fontsize=9)
ax.text(-1.15, 0.1, "in:  elongation u, elongation_rate u'\nout: tension T, strain", fontsize=9, family="monospace")

ax = axes[1]  # payload hanging under gravity
anchor(ax, 0, 3.9)
tether(ax, 0, 3.9, 1.6)
ax.add_patch(Rectangle((-0.35, 0.95), 0.7, 0.65, color="#9fb7d0"))
ax.text(0, 1.27, "m", ha="center", va="center", fontsize=12)
arrow(ax, 0.55, 1.5, 0.55, 0.95, "m g", color="#444")
arrow(ax, -0.6, 1.5, -0.6, 0.95, "force", dx=-0.55, color="#b03030")
ax.plot([0.4, 0.95], [1.6, 1.6], "k--", lw=0.8)
arrow(ax, 1.05, 1.6, 1.05, 1.1, "x (displacement\nfrom balance)", dx=0.06)
ax.text(-1.15, 0.1, "in:  force    params: m, g, x0, v0\nout: displacement, velocity, T", fontsize=9, family="monospace")

ax = axes[2]  # load-controlled test
anchor(ax, 0, 3.9)
tether(ax, 0, 3.9, 1.4)
ax.plot([-0.12, 0.12], [1.4, 1.4], color="k", lw=3)
arrow(ax, 0, 1.4, 0, 0.7, "load T(t)\n(slow: quasi-static)", dx=0.12, color="#b03030")
ax.text(-1.15, 0.1, "in:  load\nout: elongation, strain", fontsize=9, family="monospace")

fig.suptitle("KevlarTether: one tether law (elastic | Kawabata, Bouc-Wen, damping, creep, slack), three rigs", fontsize=11)
fig.tight_layout()
out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "rigs.png")
fig.savefig(out, dpi=110)
print("wrote", out)
