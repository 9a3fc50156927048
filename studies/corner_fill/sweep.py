"""Corner-filling study (paper sec. 5, Figures 3 and 4): P0 sweep, multi-pulse, restrike, summary.

    .venv/bin/python studies/corner_fill/sweep.py OUT [--amplitudes 5,10,15,20,25,30,35] [--skip-sweep]
                                                  [--skip-multi] [--skip-restrike] [--set k=v ...]

1. ``pulseform sweep cases/corner_fill --param loads[0].amplitude=...`` into OUT/sweep (one member at a
   time: the machine is shared);
2. ``pulseform run cases/corner_fill_multipulse`` into OUT/multipulse and
   ``pulseform run cases/corner_fill_restrike`` into OUT/restrike;
3. OUT/corner_fill_vs_P0.png (fill fraction, max die von Mises, max blank speeds vs P0, with the
   multi-pulse and restrike results as horizontal lines) and OUT/corner_fill_summary.csv; prints the
   fill threshold (largest unfilled and smallest filled P0; "filled": every profile segment touched, fill_fraction >= 0.999).
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PF = str(ROOT / ".venv" / "bin" / "pulseform")
FILLED = 0.999  # filled: every cavity-profile segment touched (fill_fraction = 1, docs/cases.md)


def _run(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        print(f"{' '.join(cmd[:4])}: exit {proc.returncode}: {proc.stderr.strip()[-400:]}")
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--amplitudes", default="5,10,15,20,25,30,35", help="P0 values, MPa")
    ap.add_argument("--skip-sweep", action="store_true")
    ap.add_argument("--skip-multi", action="store_true")
    ap.add_argument("--skip-restrike", action="store_true")
    ap.add_argument("--set", action="append", default=[], dest="sets")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    extra = [x for s in args.sets for x in ("--set", s)]
    amps = [float(a) for a in args.amplitudes.split(",")]
    if not args.skip_sweep:
        w = _run([PF, "sweep", str(ROOT / "cases" / "corner_fill"), "--param",
                  "loads[0].amplitude=" + ",".join(f"{a:g}e6" for a in amps), "--jobs", "1",
                  "--out", str(args.out / "sweep"), "--force", *extra])
        print(f"sweep: {w:.0f} s wall")
    for name, skip in (("multipulse", args.skip_multi), ("restrike", args.skip_restrike)):
        if not skip:
            w = _run([PF, "run", str(ROOT / "cases" / f"corner_fill_{name}"), "--out", str(args.out / name),
                      "--force", "--quiet", *extra])
            print(f"{name}: {w:.0f} s wall")
    summarize(args.out)


def summarize(out: Path) -> None:
    rows = list(csv.DictReader(open(out / "sweep" / "sweep.csv")))
    key = next(k for k in rows[0] if k.endswith("amplitude"))
    pts = sorted((float(r[key]) / 1e6, r) for r in rows if r.get("fill_fraction"))
    extra = {}
    for name in ("multipulse", "restrike"):
        f = out / name / "metrics.json"
        if f.is_file():
            extra[name] = json.loads(f.read_text())
    cols = ["fill_fraction", "unfilled_length_mm", "die_mises_max_MPa", "die_sqrt_J2_max_MPa",
            "die_contact_pressure_max_MPa", "blank_speed_max_m_s", "blank_rms_speed_max_m_s", "die_plastic_strain_max"]
    with open(out / "corner_fill_summary.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["run", "P0_MPa", *cols])
        for p, r in pts:
            w.writerow(["single", p, *[r.get(c, "") for c in cols]])
        for name, m in extra.items():
            w.writerow([name, "", *[m.get(c, "") for c in cols]])
    unfilled = [p for p, r in pts if float(r["fill_fraction"]) < FILLED]
    filled = [p for p, r in pts if float(r["fill_fraction"]) >= FILLED]
    print(f"largest unfilled P0: {max(unfilled) if unfilled else None} MPa; smallest filled P0: "
          f"{min(filled) if filled else None} MPa (paper: 25 < P0* <= 30)")
    for name, m in extra.items():
        print(f"{name}: fill {m.get('fill_fraction'):.3f}, die von Mises max {m.get('die_mises_max_MPa'):.0f} MPa, "
              f"blank speed max {m.get('blank_speed_max_m_s'):.0f} m/s (rms {m.get('blank_rms_speed_max_m_s'):.0f})")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p0 = [p for p, _ in pts]
    fig, ax = plt.subplots(3, 1, figsize=(6.5, 8), sharex=True)
    ax[0].plot(p0, [float(r["fill_fraction"]) for _, r in pts], "o-")
    ax[0].axhline(FILLED, color="0.6", ls=":", lw=0.8)
    ax[0].set_ylabel("fill fraction")
    ax[1].plot(p0, [float(r["die_mises_max_MPa"]) for _, r in pts], "o-", label="single pulse")
    ax[1].set_ylabel("die von Mises max (MPa)")
    ax[2].plot(p0, [float(r["blank_speed_max_m_s"]) for _, r in pts], "o-", label="max nodal, single")
    ax[2].plot(p0, [float(r["blank_rms_speed_max_m_s"]) for _, r in pts], "s-", label="rms, single")
    ax[2].set_ylabel("blank speed (m/s)")
    ax[2].set_xlabel("P0 (MPa)")
    styles = {"multipulse": ("C1", "--"), "restrike": ("C2", "-.")}
    for name, m in extra.items():
        c, ls = styles[name]
        ax[0].axhline(m["fill_fraction"], color=c, ls=ls, label=name)
        ax[1].axhline(m["die_mises_max_MPa"], color=c, ls=ls, label=name)
        ax[2].axhline(m["blank_speed_max_m_s"], color=c, ls=ls, label=f"{name}, max nodal")
        ax[2].axhline(m["blank_rms_speed_max_m_s"], color=c, ls=":", label=f"{name}, rms")
    for a in ax:
        a.legend(fontsize=7)
    fig.suptitle("Corner filling vs P0 (single pulse) and the multi-pulse / restrike alternatives")
    fig.tight_layout()
    fig.savefig(out / "corner_fill_vs_P0.png", dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
