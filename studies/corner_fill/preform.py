"""Is the restrike case's preform quasi-static? Ramp-rate independence of the preformed shape.

    .venv/bin/python studies/corner_fill/preform.py OUT [--durations 4e-3,8e-3] [--set k=v ...]
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
import logging
from pathlib import Path

import numpy as np

from pulseform.orchestrator.run.analyses.corner_fill_preform import FILL_TOL, SHAPE_TOL, blank_at, run_preform, summary


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--durations", default="4e-3,8e-3", help="preform durations T (s)")
    ap.add_argument("--set", action="append", default=[], dest="sets")
    ap.add_argument("--reuse", action="store_true", help="keep finished runs in OUT")
    ap.add_argument("--baseline", default="", help="RESULTS@TIME: the first shape from an existing restrike run")
    args = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")  # each run's exit and wall time
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
