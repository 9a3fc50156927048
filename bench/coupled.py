"""Benchmark of the README demo (cases/emf_sheet_bulge): wall time split into EM, mechanics and
transfer/orchestration, then the same case driven by an eq. (7) pressure pulse of equal impulse
through the identical loop, and the difference in max deflection.

Run: .venv/bin/python bench/coupled.py [--out DIR] [--set key=value ...] [--profile] [--no-pressure]
``--set`` goes to both runs (e.g. ``--set coupling.n=20 --set coupling.em_substeps=1``);
``--profile`` runs the coupled case under cProfile (slower; the split is then not the target's)
and prints the largest cumulative entries.
Targets (issue 5): demo < 60 s on this 2-core machine; orchestration overhead (all but getdp and
the mechanical steps) < 10 % of the wall time.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
EXE = str(Path(sys.executable).with_name("pulseform"))
sys.path.insert(0, str(REPO))


def run(out: Path, *sets: str, profile: Path | None = None) -> dict:
    argv = [EXE, "run", str(REPO / "cases/emf_sheet_bulge"), "--out", str(out), "--force", "--quiet"]
    if profile is not None:
        argv = [sys.executable, "-m", "cProfile", "-o", str(profile), "-m", "pulseform.orchestrator"] + argv[1:]
    for s in sets:
        argv += ["--set", s]
    t0 = time.perf_counter()
    subprocess.run(argv, check=True)
    metrics = json.loads((out / "metrics.json").read_text())
    metrics["process_wall_s"] = time.perf_counter() - t0
    return metrics


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=REPO / "results" / "bench_coupled")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="case override for both runs")
    p.add_argument("--profile", action="store_true", help="cProfile the coupled run, print the top entries")
    p.add_argument("--no-pressure", action="store_true", help="skip the equal-impulse pressure run")
    args = p.parse_args()

    prof = args.out / "coupled.prof" if args.profile else None
    if prof is not None:
        args.out.mkdir(parents=True, exist_ok=True)
    m = run(args.out / "coupled", *args.set, profile=prof)
    wall = m["process_wall_s"]
    parts = {
        "getdp processes": m["em_getdp_process_s"],
        "getdp files (mesh out, tables in)": m["em_getdp_io_s"],
        "EM mesh motion": m["em_mesh_motion_s"],
        "force transfer": m["em_transfer_s"],
        "mechanics (explicit steps)": m["mech_time_s"],
        "setup (meshing, solver, JIT)": m["setup_time_s"],
    }
    rest = wall - sum(parts.values())
    parts["rest (python start-up, output, plots)"] = rest
    print(f"demo: {m['em_steps']:.0f} EM steps, {m['mech_steps']:.0f} mechanical steps, wall {wall:.2f} s "
          f"(target < 60 s)")
    for k, v in parts.items():
        print(f"  {k:<40} {v:8.2f} s  {100 * v / wall:5.1f} %")
    overhead = wall - m["em_getdp_process_s"] - m["mech_time_s"]
    print(f"orchestration overhead (all but getdp processes and mechanical steps): {overhead:.2f} s = "
          f"{100 * overhead / wall:.1f} % of wall (target < 10 %)")
    print(f"  per EM step: getdp process {1e3 * m['em_getdp_process_s'] / m['em_steps']:.1f} ms, "
          f"other EM work {1e3 * (m['em_time_s'] - m['em_getdp_process_s']) / m['em_steps']:.1f} ms")
    if prof is not None:
        import pstats

        pstats.Stats(str(prof)).sort_stats("cumulative").print_stats(r"pulseform|orchestrator|solvers", 30)
    if args.no_pressure:
        return

    # equal-impulse pressure pulse, eq. (7), uniform on the sheet's lower face over the coil
    from pulseform.orchestrator.caseio import load_case
    from pulseform.orchestrator.case import Box, PulseSin2
    from pulseform.orchestrator.loads import pulse_impulse_per_area

    case, _ = load_case(REPO / "cases/emf_sheet_bulge")
    g = case.geometry
    r1 = g.coil_inner_radius
    r2 = g.coil_inner_radius + g.turns * g.turn_width + (g.turns - 1) * g.turn_gap
    area = math.pi * (r2 ** 2 - r1 ** 2)
    # force ~ I², I ~ e^(-αt) sin(ω_d t): take ω from the current's first peak time, β = 1e4 1/s
    peak_t = _peak_time(args.out / "coupled" / "history.csv")
    omega = math.pi / (2 * peak_t)
    zface = g.coil_gap
    box = Box(xmin=r1, xmax=r2, ymin=zface - 1e-6, ymax=zface + 1e-6)
    unit = PulseSin2(type="pulse_sin2", body="sheet", surface=box, amplitude=1.0, beta=1e4, omega=omega,
                     t_end=case.time.end)
    p0 = m["force_impulse_z_Ns"] / (area * pulse_impulse_per_area(unit))
    load = (f'{{type = "pulse_sin2", body = "sheet", surface = {{xmin = {r1}, xmax = {r2}, ymin = {zface - 1e-6}, '
            f'ymax = {zface + 1e-6}}}, amplitude = {p0:.6g}, beta = 1e4, omega = {omega:.6g}, t_end = {case.time.end}}}')
    mp = run(args.out / "pressure", *args.set, "coupling.load=pressure", f"loads=[{load}]")
    d_c, d_p = m["max_deflection_mm"], mp["max_deflection_mm"]
    print(f"equal-impulse pressure pulse eq. (7): P0 = {p0 / 1e6:.2f} MPa, omega = {omega:.4g} rad/s on "
          f"{r1 * 1e3:.0f}-{r2 * 1e3:.0f} mm; impulse {mp['force_impulse_z_Ns']:.4f} vs coupled "
          f"{m['force_impulse_z_Ns']:.4f} N s")
    print(f"max deflection at t_end: coupled {d_c:.4f} mm, pressure {d_p:.4f} mm, difference "
          f"{d_p - d_c:+.4f} mm ({100 * (d_p - d_c) / d_c:+.1f} %); wall {m['process_wall_s']:.1f} s vs "
          f"{mp['process_wall_s']:.1f} s")


def _peak_time(history: Path) -> float:
    import numpy as np

    h = np.genfromtxt(history, delimiter=",", names=True)
    return float(h["time_s"][np.argmax(np.abs(h["coil_current_A"]))])


if __name__ == "__main__":
    main()
