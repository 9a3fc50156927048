"""Bending locking of 3D elements (issue 34, item 4): the static tip deflection of a cantilever strip
(tests/mechanics/cantilever_strip.py, the strip its tests check: 40 x 5 x 1 mm, built in at x = 0, a tip force) over beam theory's
P L^3 / (3 E I) (and with Timoshenko's shear term), for linear (tet4) and ten-node (tet10) tetrahedra on
``create_box`` meshes of n_length x n_width (half width) x n_thick bricks (six tetrahedra each), by the implicit
static solver (one Newton step: elastic); ``--explicit`` adds the explicit solver with kinetic damping (dynamic
relaxation to rest; slow: ~10^5 steps for the 40 mm strip). ``--plastic`` adds the elastic-perfectly plastic
strip (sigma_y 250 MPa) under static load steps of 0.005 P_p from 0.97 to 1.03 P_p (P_p = M_p / L): its tip
deflections and the load at which the compliance d delta / dP reaches ten times the elastic one (the tip
deflection runs away), beside beam theory's (``beam_plastic_deflection`` there); with ``--explicit`` (3D) also the
explicit solver's, each level relaxed to rest by kinetic damping from the previous one's state up to the runaway
(``relaxed_levels``; slow: ~100 (L / t)^2 steps per level on bricks of t / 3 through the thickness).

``--mass-scaling`` (with ``--plastic --explicit``): the explicit solver's ten-node strip with selective mass scaling
(``ExplicitSolver3D(mass_scaling_dt=)``) to the critical step of its regular bricks (``regular_step``: the
smallest of the outer half's cells), so that the root bricks of a graded mesh do not set the step; the target step,
the mass added and the wall time are printed. ``--levels-from f`` starts the load levels at f P_p (default 0.97),
``--no-elastic`` skips the elastic deflections, ``--rounds n`` caps each level's relaxation at n rounds of 500 steps
(default 400).

``--plane``: the same strip in 2D plane stress (the solver's thickness the width b; ``--meshes "40,3 80,6"``:
n_length x n_thick squares of two triangles), linear (tet4) and six-node (tri6) triangles.

Usage: .venv/bin/python bench/cantilever_locking.py [--meshes "40,2,3 80,4,6"] [--elements tet4 tet10]
[--length 0.04] [--width 0.005] [--grading 1] [--explicit] [--plastic] [--plane] [--mass-scaling]
[--levels-from 0.97] [--no-elastic] [--rounds 400]
"""
from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

import numpy as np

from pulseform.solvers.dolfinx import (ExplicitSolver, ExplicitSolver3D, ImplicitOptions, ImplicitSolver,
                                      ImplicitSolver3D, Material)
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "mechanics"))  # the tests' strip: one home
from cantilever_strip import (Strip, beam_deflection, beam_plastic_deflection, hinge_load,  # noqa: E402
                              plane_strip_body, regular_step, relax_to_rest, relaxed_levels, strip_body,
                              tip_deflection, tip_load)
from pulseform.solvers.dolfinx.implicit import ImplicitConvergenceError

E, NU = 200e9, 0.3
PLANE = False   # the 2D plane-stress strip (--plane)
G, K = E / (2 * (1 + NU)), E / (3 * (1 - 2 * NU))


def implicit_static(strip: Strip, material: Material, element: str, loads) -> list:
    """Tip deflections (m) of static steps to the tip forces ``loads`` (N), in order (None after a failure)."""
    opts = ImplicitOptions(dt=1.0, scheme="static", max_cuts=4)
    if PLANE:
        s = ImplicitSolver([plane_strip_body(strip, material, element)], opts, formulation="plane_stress",
                           thickness=strip.width)
    else:
        s = ImplicitSolver3D([strip_body(strip, material, element)], opts)
    b = s.bodies["strip"]
    out = []
    for P in loads:
        try:
            s.advance(1.0, 1, {"strip": tip_load(b, strip, P)})
        except ImplicitConvergenceError:
            out.extend([None] * (len(loads) - len(out)))
            break
        out.append(tip_deflection(b, strip))
    return out


def explicit_relaxed(strip: Strip, material: Material, element: str, P: float) -> tuple:
    """Tip deflection (m) at rest under the tip force ``P`` (N) by kinetic damping (``relax_to_rest``: a round of
    500 steps changes it by less than 1e-5 of beam theory's, out-of-balance force below 1e-3 of ``P``), and the
    steps taken."""
    s = (ExplicitSolver([plane_strip_body(strip, material, element)], cfl=0.8, formulation="plane_stress",
                        thickness=strip.width) if PLANE else ExplicitSolver3D([strip_body(strip, material, element)],
                                                                              cfl=0.8))
    d = relax_to_rest(s, strip, P, beam_deflection(strip, material, P, shear=False), 2000, residual=1e-3)
    return d, s.step_count


def runaway(f0: float, df: float, d) -> float:
    """The load fraction (of P_p) at which the tip's compliance (difference quotient of the deflections ``d``, in
    units of the elastic deflection at P_p, at the fractions f0, f0 + df, ...) first reaches 10 times the elastic
    one (linear interpolation between the quotients at the interval midpoints); nan if it does not."""
    q = np.diff(np.asarray(d, dtype=float)) / df
    mid = f0 + df * (np.arange(len(q)) + 0.5)
    k = np.flatnonzero(q >= 10.0)
    if not len(k):
        return float("nan")
    k = int(k[0])
    if k == 0:
        return float(mid[0])
    return float(mid[k - 1] + (10.0 - q[k - 1]) / (q[k] - q[k - 1]) * df)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", default="40,2,3 80,4,6")
    ap.add_argument("--elements", nargs="+", default=["tet4", "tet10"])
    ap.add_argument("--length", type=float, default=0.04)
    ap.add_argument("--width", type=float, default=0.005)
    ap.add_argument("--grading", type=float, default=1.0)
    ap.add_argument("--explicit", action="store_true")
    ap.add_argument("--plastic", action="store_true")
    ap.add_argument("--plane", action="store_true")
    ap.add_argument("--mass-scaling", action="store_true")
    ap.add_argument("--levels-from", type=float, default=0.97)
    ap.add_argument("--no-elastic", action="store_true")
    ap.add_argument("--rounds", type=int, default=400)
    a = ap.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s", force=True)
    for noisy in ("pulseform.solvers.dolfinx.body", "pulseform.solvers.dolfinx.implicit"):
        logging.getLogger(noisy).setLevel(logging.WARNING)
    global PLANE
    PLANE = a.plane
    if a.plane and a.meshes == ap.get_default("meshes"):
        a.meshes = "40,3 80,6"
    if a.plane and a.elements == ap.get_default("elements"):
        a.elements = ["tet4", "tri6"]
    elastic = Material(7800.0, G, K, 1e12, 0.0)
    for m in a.meshes.split():
        nl, nw, nt = (int(v) for v in m.split(",")) if not a.plane else (int(m.split(",")[0]), 1, int(m.split(",")[1]))
        st = Strip(length=a.length, width=a.width, n_length=nl, n_width=nw, n_thick=nt, grading=a.grading)
        eb = beam_deflection(st, elastic, 1.0, shear=False)
        tim = beam_deflection(st, elastic, 1.0)
        for el in a.elements if not a.no_elastic else ():
            t0 = time.perf_counter()
            d = implicit_static(st, elastic, el, [1.0])[0]
            mesh = f"{nl}x{nt} squares" if a.plane else f"{nl}x{nw}x{nt} bricks"
            line = (f"{el:5s} {mesh}: implicit d / EB {d / eb:.4f}  d / Timoshenko {d / tim:.4f}"
                    f"  ({time.perf_counter() - t0:.1f} s)")
            if a.explicit:
                t0 = time.perf_counter()
                de, n = explicit_relaxed(st, elastic, el, 1.0)
                line += f"; explicit d / EB {de / eb:.4f} ({n} steps, {time.perf_counter() - t0:.0f} s)"
            print(line, flush=True)
        if a.plastic:
            mat = Material(7800.0, G, K, 250e6, 0.0)
            Pp = hinge_load(st, mat)
            fr = np.round(np.arange(0.97, 1.0301, 0.005), 4)
            d_el = beam_deflection(st, mat, Pp, shear=False)
            beam = [beam_plastic_deflection(st, mat, f * Pp) / d_el for f in np.round(np.arange(0.97, 0.9976, 0.0005),
                                                                                     5)]
            print(f"beam theory: compliance 10x the elastic one at P / P_p = {runaway(0.97, 0.0005, beam):.4f}")
            for el in a.elements:
                ds = [d / d_el if d is not None else np.nan for d in implicit_static(st, mat, el, [f * Pp for f in fr])]
                print(f"{el:5s} {nl}x{nt if a.plane else f'{nw}x{nt}'} (b {st.width * 1e3:g} mm, grading {st.grading:g}): d / "
                      f"d_el(P_p) at P / P_p {' '.join(f'{f:g}:{d:.4f}' for f, d in zip(fr, ds))}; compliance 10x "
                      f"the elastic one at P / P_p = {runaway(fr[0], 0.005, ds):.4f}", flush=True)
                if a.explicit and not a.plane:
                    t0 = time.perf_counter()
                    s = ExplicitSolver3D([strip_body(st, mat, el)], cfl=0.8)
                    scaled = ""
                    if a.mass_scaling:
                        target = regular_step(s, st)
                        dt0 = s.stable_time_step()
                        s = ExplicitSolver3D([strip_body(st, mat, el)], cfl=0.8, mass_scaling_dt=target)
                        ms = s.mass_scaling["strip"]
                        scaled = (f", mass scaling to {target:.4g} s: {ms['cells']} cells, {ms['added_kg']:.4g} kg "
                                  f"added ({100 * ms['added_fraction']:.2f} %), stable step {dt0:.4g} -> "
                                  f"{s.stable_time_step():.4g} s")
                    f0 = a.levels_from
                    de = relaxed_levels(s, st, Pp, np.round(np.arange(f0, 1.0801, 0.005), 4), d_el,
                                        a.rounds)
                    print(f"      explicit, kinetic damping{scaled}: d / d_el(P_p) at P / P_p from {f0:g} "
                          f"{' '.join(f'{d:.4f}' for d in de)}; "
                          f"compliance 10x the elastic one at P / P_p = {runaway(f0, 0.005, de):.4f} "
                          f"({s.step_count} steps, {time.perf_counter() - t0:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
