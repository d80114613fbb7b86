"""rattle from Python: Fig. 2 from the returned arrays, a 128 x 128 map with its classes and
exponents, and the class probabilities of a sensitivity study over a loop of R values.

    pip install ./python matplotlib
    python examples/python_demo.py [OUTDIR]

Writes OUTDIR/python_fig2.png, python_map.png and python_sensitivity.png (default: out/),
and prints what it found.
"""

import sys
from pathlib import Path

import numpy as np

import rattle

ROOT = Path(__file__).resolve().parents[1]
OUT = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "out"
OUT.mkdir(parents=True, exist_ok=True)

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:  # the numbers are printed all the same
    plt = None

# 1. Fig. 2: y1 at the stroboscopic section against eta.
fig2 = rattle.bifurcation(ROOT / "configs" / "fig2.toml")
print(fig2.caption.split(". ")[0])
print("bifurcation points:", [(b["kind"], round(b["value"], 5)) for b in fig2.bifurcations[0]])
if plt:
    fig, ax = plt.subplots(figsize=(9, 5))
    ax.plot(fig2.values, fig2.y[:, 0], ",", color="k", alpha=0.5)
    ax.set_xlabel(fig2.param)
    ax.set_ylabel("y1 at the section")
    ax.set_title("Fig. 2 from rattle.bifurcation: Coulomb friction, lambda = 0.02, R = 0.6")
    fig.savefig(OUT / "python_fig2.png", dpi=120)

# 2. A 128 x 128 map over R and lambda: classes and the largest Lyapunov exponent.
m = rattle.map(ROOT / "configs" / "r_lambda.toml", **{"map.x_points": 128, "map.y_points": 128})
counts = sorted(m.class_counts.items(), key=lambda kv: -kv[1])[:5]
print("map:", m, "most frequent classes:", counts)
if plt:
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 5))
    ext = [m.x[0], m.x[-1], m.y[0], m.y[-1]]
    period = np.where(m.period > 0, m.period, np.nan)
    im = a.imshow(np.log2(period), origin="lower", extent=ext, aspect="auto", cmap="viridis")
    a.set_title("log2 period (white: not periodic)")
    fig.colorbar(im, ax=a)
    lyap = m.lyapunov
    lim = np.nanmax(np.abs(lyap))
    im = b.imshow(lyap, origin="lower", extent=ext, aspect="auto", cmap="RdBu_r", vmin=-lim, vmax=lim)
    b.set_title("largest Lyapunov exponent")
    fig.colorbar(im, ax=b)
    for ax in (a, b):
        ax.set_xlabel(m.x_param)
        ax.set_ylabel(m.y_param)
    fig.tight_layout()
    fig.savefig(OUT / "python_map.png", dpi=110)

# 3. The class probabilities under measurement error, R swept by a Python loop.
rows = []
for r in [0.56, 0.58, 0.60, 0.62, 0.64]:
    s = rattle.sensitivity(
        ROOT / "configs" / "r_lambda.toml",
        uncertain=[f"R={r}+-0.01", "lambda=0.020+-0.005"],
        samples=32,
        seed=1,
    )
    rows.append((r, s.nominal, s.probabilities))
    top = max(s.probabilities.items(), key=lambda kv: kv[1][0])
    print(f"R = {r}: nominal {s.nominal}, most likely {top[0]} p = {top[1][0]:.2f}")
if plt:
    # Every period in one group: the palette cannot tell 15 classes apart.
    def group(name):
        return "periodic (any period)" if name.startswith("period-") else name

    names = ["periodic (any period)", "quasi_periodic", "chaotic", "unresolved"]
    colours = ["tab:blue", "tab:green", "tab:red", "tab:gray"]
    fig, ax = plt.subplots(figsize=(9, 4.5))
    bottom = np.zeros(len(rows))
    for n, colour in zip(names, colours):
        p = np.array([sum(v[0] for k, v in pr.items() if group(k) == n) for _, _, pr in rows])
        ax.bar([r for r, _, _ in rows], p, width=0.015, bottom=bottom, label=n, color=colour)
        bottom += p
    ax.set_xlabel("nominal R (sd 0.01; lambda = 0.020 +- 0.005), 64 independent draws each")
    ax.set_ylabel("probability of the class")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    fig.savefig(OUT / "python_sensitivity.png", dpi=110)
print("figures in", OUT if plt else "(matplotlib not installed: none)")
