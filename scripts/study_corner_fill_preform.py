"""Is the restrike case's preform quasi-static? Ramp-rate independence of the preformed shape.

    .venv/bin/python scripts/study_corner_fill_preform.py OUT [--durations 4e-3,8e-3] [--set k=v ...]
                                                          [--baseline RESULTS@TIME] [--reuse]

Runs only the preforming stage of ``cases/corner_fill_restrike`` (pressure P_pre sin^2(pi t / T),
its damping (kinetic, or mass-proportional alpha) until T, ``time.end = T``: the restrike never
fires) once per preform duration T, into OUT/T_<T>/, and compares the preformed blanks at rest
(the final field output) node by node with the first duration's (the meshes are identical: same
case, same mesh sizes). ``--baseline RESULTS@TIME`` takes the first shape instead from an existing
``corner_fill_restrike`` results folder at the end of its preform (TIME = its preform duration; the
restrike fires only after it).

Criterion, fixed before the runs: the preform is quasi-static when doubling its duration moves no
blank node by more than 2 h0 = 0.2 mm (the resolution of the fill measure: a profile point counts as
touched within 2 h0) and changes the preform's fill fraction by less than 0.01. The kinetic /
(elastic + plastic) ratios of each run are printed beside it (metrics ``preform_kinetic_ratio_*``).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import time
from pathlib import Path

import numpy as np

from pulseform.orchestrator.run.mech_fields import read_fields

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "cases" / "corner_fill_restrike"
SHAPE_TOL = 2.0e-4  # m: 2 h0
FILL_TOL = 0.01


def run_preform(out: Path, duration: float, extra: list[str], reuse: bool = False) -> Path:
    """The preform of length ``duration`` (s) alone; returns its results folder (``reuse``: keep a
    finished one)."""
    folder = out / f"T_{duration:g}"
    if reuse and (folder / "metrics.json").is_file():
        return folder
    sets = [f"loads[0].omega={np.pi / duration:.9g}", f"loads[0].t_end={duration:.9g}",
            f"mechanics.mass_damping_until={duration:.9g}", f"mechanics.kinetic_damping_until={duration:.9g}",
            f"time.end={duration:.9g}",
            f"output.field_interval={duration / 20:.9g}"]
    cmd = [str(ROOT / ".venv" / "bin" / "pulseform"), "run", str(CASE), "--out", str(folder), "--force", "--quiet",
           *[x for s in sets for x in ("--set", s)], *extra]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    print(f"T = {duration * 1e3:g} ms: exit {proc.returncode}, {time.perf_counter() - t0:.0f} s wall", flush=True)
    if proc.returncode != 0:
        raise SystemExit(proc.stderr[-800:])
    return folder


def blank_at(folder: Path, t: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(reference coordinates, displacement) of the blank, m, at the field output nearest to t
    (s; None: the last one)."""
    blank = read_fields(folder)["blank"]
    k = len(blank.times) - 1 if t is None else int(np.argmin(np.abs(blank.times - t)))
    return blank.points[:, :2], blank.displacement(k)


def summary(folder: Path, t: float | None = None) -> dict[str, float]:
    """Fill fraction at time t (history row nearest below; None: the end) and the preform metrics."""
    m = json.loads((folder / "metrics.json").read_text())
    if t is not None:
        h = np.genfromtxt(folder / "history.csv", delimiter=",", names=True)
        i = np.flatnonzero(h["time_s"] <= t * (1 + 1e-9))[-1]
        m["fill_fraction"] = float(h["fill_fraction"][i])
        m["unfilled_length_mm"] = float(h["unfilled_length_m"][i]) * 1e3
        m["apex_gap_final_mm"] = float(h["blank_apex_gap_m"][i]) * 1e3
    return m


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--durations", default="4e-3,8e-3", help="preform durations T (s)")
    ap.add_argument("--set", action="append", default=[], dest="sets")
    ap.add_argument("--reuse", action="store_true", help="keep finished runs in OUT")
    ap.add_argument("--baseline", default="", help="RESULTS@TIME: the first shape from an existing restrike run")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    extra = [x for s in args.sets for x in ("--set", s)]
    runs = []  # (label, folder, time of the preformed shape or None for the end)
    if args.baseline:
        folder, _, t = args.baseline.rpartition("@")
        runs.append((f"baseline {Path(folder).name} at {float(t) * 1e3:g} ms", Path(folder), float(t)))
    runs += [(f"T = {float(d) * 1e3:g} ms", run_preform(args.out, float(d), extra, args.reuse), None)
             for d in args.durations.split(",") if d]
    X0, u0 = blank_at(runs[0][1], runs[0][2])
    m0 = summary(runs[0][1], runs[0][2])
    for label, folder, t in runs:
        m = summary(folder, t)
        X, u = blank_at(folder, t)
        if X.shape != X0.shape or np.abs(X - X0).max() > 1e-12:
            raise SystemExit(f"{folder}: blank mesh differs from {runs[0][1]}")
        shift = float(np.linalg.norm(u - u0, axis=1).max())
        print(f"{label}: fill {m['fill_fraction']:.4f}, unfilled {m['unfilled_length_mm']:.2f} mm, apex gap "
              f"{m['apex_gap_final_mm']:.2f} mm, KE/internal max (p >= 10 %) {m.get('preform_kinetic_ratio_max', np.nan):.3g}, "
              f"(p >= 90 %) {m.get('preform_kinetic_ratio_top_max', np.nan):.3g}; max node shift vs the first: "
              f"{shift * 1e3:.3f} mm")
        if label != runs[0][0]:
            ok = shift <= SHAPE_TOL and abs(m["fill_fraction"] - m0["fill_fraction"]) < FILL_TOL
            print(f"quasi-static by ramp-rate independence (shift <= {SHAPE_TOL * 1e3:g} mm, fill within {FILL_TOL}): "
                  f"{'yes' if ok else 'NO'}")


if __name__ == "__main__":
    main()
