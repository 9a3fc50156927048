"""The README demo (cases/emf_sheet_bulge) end to end, today's per-process getdp vs the persistent
getdp (adapter.py swapped into the unchanged coupled loop, in a child process), alternately,
``--repeat`` times; prints the wall times (medians), the EM time split and the metrics side by side.

Usage: .venv/bin/python studies/persistent_getdp/demo.py [--repeat 3] [--out DIR] [--set key=value ...]
       (inner use: demo.py --inner persistent OUT [--set ...])
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
CASE = REPO / "cases" / "emf_sheet_bulge"
KEYS = ["coil_current_peak_kA", "force_impulse_z_Ns", "max_deflection_mm", "coil_joule_heat_J",
        "conservation_error_rel", "em_steps", "mech_steps"]


def inner(mode: str, out: str, sets: list[str]) -> int:
    sys.path.insert(0, str(HERE))
    if mode.startswith("persistent"):
        from adapter import install

        install(lean=mode == "persistent-lean")
    from pulseform.orchestrator.cli import main

    argv = ["run", str(CASE), "--out", out, "--force", "--quiet"]
    for s in sets:
        argv += ["--set", s]
    return main(argv)


def run(mode: str, out: Path, sets: list[str]) -> dict:
    argv = [sys.executable, str(Path(__file__).resolve()), "--inner", mode, str(out)]
    for s in sets:
        argv += ["--set", s]
    t0 = time.perf_counter()
    subprocess.run(argv, check=True)
    m = json.loads((out / "metrics.json").read_text())
    m["process_wall_s"] = time.perf_counter() - t0
    return m


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", type=Path, default=REPO / "results" / "study_persistent_demo")
    ap.add_argument("--set", action="append", default=[])
    ap.add_argument("--modes", nargs="+", default=["per-process", "persistent", "persistent-lean"],
                    help="per-process, persistent (today's outputs each step), persistent-lean (only what the loop needs)")
    ap.add_argument("--inner", nargs=2, metavar=("MODE", "OUT"))
    args = ap.parse_args(argv)
    if args.inner:
        return inner(args.inner[0], args.inner[1], args.set)
    import numpy as np

    res = {mode: [] for mode in args.modes}
    for rep in range(args.repeat):
        for mode in res:
            m = run(mode, args.out / f"{mode}_{rep}", args.set)
            res[mode].append(m)
            print(f"run {rep} {mode:>11}: wall {m['process_wall_s']:.2f} s, EM {m['load_time_s']:.2f} s "
                  f"(getdp {m['em_getdp_process_s']:.2f} s, getdp files {m['em_getdp_io_s']:.2f} s), "
                  f"mechanics {m['mech_time_s']:.2f} s, load average {os.getloadavg()[0]:.2f}", flush=True)
    print(f"\nmedians of {args.repeat} runs each (alternating):")
    med = {}
    for mode, ms in res.items():
        med[mode] = {k: float(np.median([m[k] for m in ms])) for k in
                     ("process_wall_s", "load_time_s", "em_getdp_process_s", "em_getdp_io_s", "mech_time_s",
                      "setup_time_s")}
        d = med[mode]
        n = ms[0]["em_steps"]
        print(f"  {mode:>11}: wall {d['process_wall_s']:.2f} s; EM {d['load_time_s']:.2f} s = "
              f"{1e3 * d['load_time_s'] / n:.1f} ms per EM step (getdp {1e3 * d['em_getdp_process_s'] / n:.1f} ms, "
              f"files {1e3 * d['em_getdp_io_s'] / n:.1f} ms); mechanics {d['mech_time_s']:.2f} s; "
              f"set-up {d['setup_time_s']:.2f} s")
    a = med["per-process"]
    for mode in res:
        if mode != "per-process":
            b = med[mode]
            print(f"  speed-up of {mode}: wall {a['process_wall_s'] / b['process_wall_s']:.2f}x, EM time "
                  f"{a['load_time_s'] / b['load_time_s']:.2f}x")
    print("\nmetrics (first run of each; relative difference to per-process):")
    print(f"  {'':28} " + " ".join(f"{m:>22}" for m in res))
    for k in KEYS:
        vals = [res[m][0].get(k) for m in res]
        x = vals[0]
        cells = [f"{v:22.15g}" for v in vals]
        rels = [abs(v - x) / abs(x) if x else abs(v) for v in vals[1:]]
        print(f"  {k:<28} " + " ".join(cells) + "   " + " ".join(f"{r:.1e}" for r in rels))
    (args.out / "summary.json").write_text(json.dumps({"runs": res, "medians": med}, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
