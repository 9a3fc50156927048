"""The paper's contact-viscosity study (section 4): bar impact with nu = 0, 1e4, 1e6 kg/m^3, the
viscous contact stress -nu |v_n| v_n acting on the pair's relative normal velocity.

Run: ``.venv/bin/python studies/bar_impact/viscosity_study.py OUT_DIR [--nx 40 --ny 20]``; writes
``viscosity_study.png`` and ``viscosity_study.json`` (per nu: plateau, std, duration, the
short-wave amplitude = rms of the stress minus its 0.1 ms running mean over the plateau window,
first peak, minimum, contact dissipation).
"""
from __future__ import annotations

import argparse
import json
import sys
import logging
from pathlib import Path
from typing import Dict, Sequence

import numpy as np

from pulseform.solvers.dolfinx.verification import bar_impact

__all__ = ["run_study", "short_wave_rms"]

log = logging.getLogger(__name__)


def short_wave_rms(t: np.ndarray, s: np.ndarray, t0: float, t1: float,
                   window: float = 1e-4) -> float:
    """RMS (Pa) over [t0, t1] of the stress minus its running mean over ``window`` seconds."""
    dt = np.median(np.diff(t))
    k = max(int(round(window / dt)), 1)
    smooth = np.convolve(s, np.ones(k) / k, mode="same")
    sel = (t >= t0) & (t <= t1)
    return float(np.sqrt(np.mean((s[sel] - smooth[sel]) ** 2)))


def run_study(out_dir, nus: Sequence[float] = (0.0, 1e4, 1e6), nx: int = 40,
              ny: int = 20) -> Dict[str, dict]:
    """Run the bar impact for each nu; write the plot and JSON into ``out_dir``; return results."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    res, curves = {}, {}
    for nu in nus:
        try:
            r = bar_impact(nx=nx, ny=ny, viscosity=nu)
        except Exception as err:      # a run that breaks is a result of the study, not a crash
            log.warning("nu = %g failed: %s", nu, err)
            res[f"{nu:g}"] = {"failed": str(err)}
            continue
        m = dict(r["metrics"])
        if "contact_start_ms" in m:
            t0 = 1e-3 * (m["contact_start_ms"] + 0.25 * m["contact_duration_ms"])
            t1 = 1e-3 * (m["contact_start_ms"] + 0.75 * m["contact_duration_ms"])
            m["short_wave_rms_MPa"] = short_wave_rms(r["t"], r["stress"], t0, t1) / 1e6
        m["peak_MPa"] = float(r["stress"].max() / 1e6)
        m["min_MPa"] = float(r["stress"].min() / 1e6)   # < 0: viscous pull while separating
        m["contact_dissipated_J"] = r["energies"][-1]["contact_dissipated_J"]
        res[f"{nu:g}"] = m
        curves[nu] = (r["t"], r["stress"])
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for nu, (t, s) in curves.items():
        ax.plot(t * 1e3, s / 1e6, lw=1, label=f"nu = {nu:g}")
    ax.axhline(70.0, color="k", ls="--", lw=0.8, label="rho c v / 2 = 70 MPa")
    ax.set_xlabel("t (ms)")
    ax.set_ylabel("contact stress at mid contact surface (MPa)")
    ax.set_title(f"bar impact, plane stress, {nx}x{ny} cells per bar, k = 1e8 Pa m, h0 = 0.01 m")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "viscosity_study.png", dpi=120)
    plt.close(fig)
    (out / "viscosity_study.json").write_text(json.dumps(res, indent=2))
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description="paper's contact-viscosity study")
    ap.add_argument("out_dir")
    ap.add_argument("--nx", type=int, default=40)
    ap.add_argument("--ny", type=int, default=20)
    a = ap.parse_args()
    logging.basicConfig(level=logging.INFO)
    sys.stdout.write(json.dumps(run_study(a.out_dir, nx=a.nx, ny=a.ny), indent=2) + "\n")


if __name__ == "__main__":
    main()
