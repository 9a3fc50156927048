"""Clearance sweep of cases/tube_press_fit (paper Figure 7): residual contact pressure vs clearance.

    .venv/bin/python studies/tube_press_fit/clearance_sweep.py OUT [--clearances 0,0.5,1,2,3,4,5,6] [--set k=v ...]
        [--springback-at T]

Runs ``pulseform run`` once per clearance c (in % of R0 = 10.5 mm), one at a time, into OUT/c_<c>/:
the outer tube's inner radius is 12.5 mm + c R0 + h0 (its outer radius stays 25 mm). Writes
OUT/press_fit_sweep.csv and OUT/press_fit_residual_pressure.png (Figure 7) and
OUT/press_fit_displacements.png (Figure 6 for every clearance), and prints the critical clearance:
the bracket between the last sweep point with residual pressure and the first from which on it
stays below 2 % of the zero-clearance value.

The residual pressure is the case's: the mean contact stress after its damped dynamic relaxation to 300 us. With
``--springback-at T`` each run ends undamped at T (s; the damping starts at 150 us) and the residual pressure is
that of the static springback with contact kept (``[springback] contact = "kept"``, metric
``springback_residual_contact_pressure_MPa``; the history's pressure at T is kept as ``contact_pressure_at_end_MPa``).
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CASE = ROOT / "cases" / "tube_press_fit"

from pulseform.orchestrator.run.analyses.tube_press_fit import H0, R0, VANISH, outer_sets  # noqa: E402
from pulseform.orchestrator.run.analyses.tube_press_fit import critical_clearance_of_rows as critical_clearance  # noqa: E402,E501


def run_one(out: Path, c: float, extra: list[str]) -> dict:
    folder = out / f"c_{c:g}"
    cmd = [str(ROOT / ".venv" / "bin" / "pulseform"), "run", str(CASE), "--out", str(folder), "--force", "--quiet",
           *outer_sets(c), *extra]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        print(f"clearance {c} %: failed ({proc.returncode}): {proc.stderr.strip()[-300:]}", file=sys.stderr)
        return {"clearance_percent": c, "ok": 0.0, "wall_s": wall}
    m = json.loads((folder / "metrics.json").read_text())
    if "springback_residual_contact_pressure_MPa" in m:
        m["contact_pressure_at_end_MPa"] = m["residual_contact_pressure_MPa"]
        m["residual_contact_pressure_MPa"] = m["springback_residual_contact_pressure_MPa"]
    return {"clearance_percent": c, "ok": 1.0, "wall_s": wall, **m}


def plots(out: Path, rows: list[dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    ok = [r for r in rows if r.get("ok")]
    c = np.array([r["clearance_percent"] for r in ok])
    p = np.array([r["residual_contact_pressure_MPa"] for r in ok])
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(c, p, "o-")
    lo, hi = critical_clearance(rows)
    if np.isfinite(hi):
        ax.axvspan(lo, hi, color="r", alpha=0.12, label=f"ours: critical clearance between {lo:g} and {hi:g} %")
    ax.axvline(3.0, color="0.5", ls=":", label="paper: clearance <= 3 % of R0")
    ax.set_xlabel("initial radial clearance / R0 (%)")
    ax.set_ylabel("residual contact pressure (MPa)")
    ax.set_title("Pulsed press fit: residual pressure vs clearance (cf. paper Fig. 7)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "press_fit_residual_pressure.png", dpi=110)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for r in ok:
        h = list(csv.DictReader(open(out / f"c_{r['clearance_percent']:g}" / "history.csv")))
        ts = r["t_star_s"]
        t = np.array([float(x["time_s"]) for x in h]) / ts
        gap0 = r["clearance_percent"] / 100.0 * R0 + H0
        ax.plot(t, (np.array([float(x["inner_outer_ur_m"]) for x in h]) - gap0) / R0, ":", lw=1)
        ax.plot(t, np.array([float(x["outer_inner_ur_m"]) for x in h]) / R0, "-", lw=0.8,
                label=f"c = {r['clearance_percent']:g} %")
    ax.set_xlabel("t / (R0 / sqrt(σs0 / ρ))")
    ax.set_ylabel("ΔR / R0")
    ax.set_title("dotted: inner tube outer surface minus the initial gap; solid: outer tube inner surface", fontsize=8)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(out / "press_fit_displacements.png", dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--clearances", default="0,0.5,1,2,3,4,5,6")
    ap.add_argument("--set", action="append", default=[], dest="sets")
    ap.add_argument("--springback-at", type=float, default=None,
                    help="end each run at this time (s) and take the residual pressure from springback with contact kept")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    extra = [x for s in args.sets for x in ("--set", s)]
    if args.springback_at is not None:
        extra += ["--set", f"time.end={args.springback_at:g}", "--set", "springback.contact=kept"]
    rows = []
    for c in [float(x) for x in args.clearances.split(",")]:
        r = run_one(args.out, c, extra)
        rows.append(r)
        print(f"c = {c:g} % R0: residual {r.get('residual_contact_pressure_MPa', float('nan')):.2f} MPa, "
              f"max bore displacement {r.get('max_radial_displacement_inner_mm', float('nan')):.4f} mm, "
              f"wall {r['wall_s']:.0f} s", flush=True)
    keys = ["clearance_percent", "ok", "wall_s", "residual_contact_pressure_MPa", "max_radial_displacement_inner_mm",
            "residual_bore_ur_mm", "residual_inner_outer_ur_mm", "residual_outer_inner_ur_mm",
            "contact_pressure_peak_MPa", "first_contact_t_over_tstar", "final_kinetic_to_elastic", "plastic_work_J",
            "contact_pressure_at_end_MPa", "springback_contact0_closed_nodes"]
    with open(args.out / "press_fit_sweep.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(keys)
        for r in rows:
            w.writerow([r.get(k, "") for k in keys])
    plots(args.out, rows)
    lo, hi = critical_clearance(rows)
    print(f"critical clearance (residual < {VANISH:.0%} of its zero-clearance value from there on): "
          f"between {lo:g} and {hi:g} % of R0 (paper: about 3 %)")


if __name__ == "__main__":
    main()
