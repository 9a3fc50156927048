"""A study's pictures of its answer (:mod:`.study_answer`), in ``OUT/plots/``:

- ``study_scatter.png``: each headline metric (rows) against each numeric parameter (columns), the members;
- ``study_sensitivity.png``: per metric, bars of SRC² (the members' linear share of the variance) and S_T (the
  surface's total Sobol index) per parameter;
- ``study_surface_<metric>.png``: the response surface of a metric (the objective's, else the first) over its two
  most influential parameters (the others at the middle of their range), the members on it.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from ..run.units import label
from .sensitivity import QuadraticSurface

log = logging.getLogger(__name__)

__all__ = ["plot_study"]


def plot_study(members: list, answer: dict, folder: Path, focus: str | None = None) -> list[Path]:
    """Draw the pictures above for the members and the ``answer`` of :func:`.study_answer.analyse`; returns them.
    ``focus``: the metric whose response surface is drawn (default: the first with one)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = answer["parameters"]
    good = {k: r for k, r in answer["metrics"].items() if "error" not in r}
    ok = [m for m in members if m.returncode == 0]
    paths: list[Path] = []
    if not keys or not good:
        return paths
    names = list(good)[:6]
    fig, axes = plt.subplots(len(names), len(keys), figsize=(3.2 * len(keys), 2.4 * len(names)), squeeze=False)
    for i, name in enumerate(names):
        for j, key in enumerate(keys):
            pts = [(float(m.values[key]), m.metrics[name]) for m in ok if name in m.metrics]
            axes[i, j].plot([p[0] for p in pts], [p[1] for p in pts], "o", ms=4)
            axes[i, j].grid(alpha=0.3)
            if j == 0:
                axes[i, j].set_ylabel(label(name), fontsize=8)
            if i == len(names) - 1:
                axes[i, j].set_xlabel(key, fontsize=8)
    fig.tight_layout()
    paths.append(_save(fig, folder / "study_scatter.png", plt))

    fig, axes = plt.subplots(len(names), 1, figsize=(1.2 + 1.1 * len(keys), 2.2 * len(names)), squeeze=False)
    x = np.arange(len(keys))
    for ax, name in zip(axes[:, 0], names):
        r = good[name]
        ax.bar(x - 0.2, [r["src"][k] ** 2 for k in keys], 0.4, label=f"SRC² (members, linear R² {r['r2_linear']:.2f})")
        ax.bar(x + 0.2, [r["sobol_total"][k] for k in keys], 0.4,
               label=f"S_T of the {r['surface']['kind']} surface (LOO {100 * r['surface']['loo_rmse_rel_std']:.2g} % std)")
        ax.set_xticks(x, [k.split(".")[-1] for k in keys], fontsize=8)
        ax.set_title(name, fontsize=9)
        ax.set_ylim(0, 1.05)
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    paths.append(_save(fig, folder / "study_sensitivity.png", plt))

    name = focus if focus in good else names[0]
    if len(keys) >= 2:
        paths.append(_surface_map(ok, good[name], name, keys, folder, plt))
    return paths


def _surface_map(ok: list, r: dict, name: str, keys: list[str], folder: Path, plt) -> Path:
    s = r["surface"]
    lo, hi = np.array(s["lo"]), np.array(s["hi"])
    surf = QuadraticSurface(lo, hi, 2 if s["kind"] == "quadratic" else 1, np.array(s["coefficients"]),
                            s["loo_rmse"], s["loo_max"], s["r2"])
    i, j = (keys.index(k) for k in r["ranking"][:2])
    gi, gj = np.meshgrid(np.linspace(lo[i], hi[i], 60), np.linspace(lo[j], hi[j], 60))
    pts = np.tile((lo + hi) / 2, (gi.size, 1))
    pts[:, i], pts[:, j] = gi.ravel(), gj.ravel()
    fig, ax = plt.subplots(figsize=(6.2, 4.8))
    cs = ax.contourf(gi, gj, surf(pts).reshape(gi.shape), levels=20, cmap="viridis")
    fig.colorbar(cs, ax=ax, label=label(name))
    xs = [(float(m.values[keys[i]]), float(m.values[keys[j]]), m.metrics[name]) for m in ok if name in m.metrics]
    ax.scatter([p[0] for p in xs], [p[1] for p in xs], c=[p[2] for p in xs], cmap="viridis", edgecolors="w",
               norm=cs.norm, s=30, label="members (any value of the other parameters)")
    others = [k for n, k in enumerate(keys) if n not in (i, j)]
    ax.set_title(f"{s['kind']} surface, LOO RMS error {s['loo_rmse']:.3g}" +
                 (f"\n{', '.join(k.split('.')[-1] for k in others)} at mid-range" if others else ""), fontsize=9)
    ax.set_xlabel(keys[i])
    ax.set_ylabel(keys[j])
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    return _save(fig, folder / f"study_surface_{name}.png", plt)


def _save(fig, path: Path, plt) -> Path:
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
