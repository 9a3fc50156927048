"""Bending locking of 3D elements (issue 34, item 4): the static tip deflection of a cantilever strip
(:mod:`pulseform.solvers.dolfinx.cantilever`: 40 x 5 x 1 mm, built in at x = 0, a tip force) over beam theory's
P L^3 / (3 E I) (and with Timoshenko's shear term), for linear (tet4) and ten-node (tet10) tetrahedra on
``create_box`` meshes of n_length x n_width (half width) x n_thick bricks (six tetrahedra each), by the implicit
static solver (one Newton step: elastic); ``--explicit`` adds the explicit solver with kinetic damping (dynamic
relaxation to rest; slow: ~10^5 steps for the 40 mm strip). Also the elastic-perfectly plastic strip's tip
deflection along a load ramp against beam theory's (``--plastic``).

Usage: .venv/bin/python bench/cantilever_locking.py [--meshes "40,2,3 80,4,6"] [--elements tet4 tet10]
[--length 0.04] [--explicit] [--plastic]
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.integrate import quad

from pulseform.solvers.dolfinx import ExplicitSolver3D, ImplicitOptions, ImplicitSolver3D, Material
from pulseform.solvers.dolfinx.cantilever import (Strip, beam_deflection, hinge_load, strip_body, tip_deflection,
                                                  tip_load)
from pulseform.solvers.dolfinx.implicit import ImplicitConvergenceError

E, NU = 200e9, 0.3
G, K = E / (2 * (1 + NU)), E / (3 * (1 - 2 * NU))


def implicit_static(strip: Strip, material: Material, element: str, loads) -> list:
    """Tip deflections (m) of static steps to the tip forces ``loads`` (N), in order (None after a failure)."""
    s = ImplicitSolver3D([strip_body(strip, material, element)], ImplicitOptions(dt=1.0, scheme="static",
                                                                                 max_cuts=4))
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
    """Tip deflection (m) at rest under the tip force ``P`` (N) by kinetic damping, and the steps taken."""
    s = ExplicitSolver3D([strip_body(strip, material, element)], cfl=0.9)
    s.kinetic_damping = True
    b = s.bodies["strip"]
    f = {"strip": tip_load(b, strip, P)}
    prev, d = math.inf, 0.0
    for _ in range(2000):
        s.advance(s.stable_time_step(), 500, f)
        d = tip_deflection(b, strip)
        if abs(d - prev) < 1e-5 * abs(d) and s.energies()["kinetic_J"] < 1e-9:
            break
        prev = d
    return d, s.step_count


def beam_plastic_deflection(strip: Strip, material: Material, P: float) -> float:
    """Beam theory's tip deflection (m) of the elastic-perfectly plastic strip under P < M_p / L (the rectangle's
    moment-curvature law kappa = kappa_y / sqrt(3 - 2 M / M_y) past first yield)."""
    d_el = beam_deflection(strip, material, 1.0, shear=False)          # m per N: L^3 / (3 E I)
    L = strip.length
    My = material.yield_stress * strip.width * strip.thickness ** 2 / 6.0
    EI = L ** 3 / (3.0 * d_el)

    def kappa(x):
        M = P * (L - x)
        return M / EI if M <= My else My / EI / math.sqrt(3.0 - 2.0 * M / My)

    pts = [L * (1.0 - My / (P * L))] if P * L > My else None
    return quad(lambda x: kappa(x) * (L - x), 0.0, L, points=pts, limit=200)[0]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", default="40,2,3 80,4,6")
    ap.add_argument("--elements", nargs="+", default=["tet4", "tet10"])
    ap.add_argument("--length", type=float, default=0.04)
    ap.add_argument("--explicit", action="store_true")
    ap.add_argument("--plastic", action="store_true")
    a = ap.parse_args()
    elastic = Material(7800.0, G, K, 1e12, 0.0)
    for m in a.meshes.split():
        nl, nw, nt = (int(v) for v in m.split(","))
        st = Strip(length=a.length, n_length=nl, n_width=nw, n_thick=nt)
        eb = beam_deflection(st, elastic, 1.0, shear=False)
        tim = beam_deflection(st, elastic, 1.0)
        for el in a.elements:
            t0 = time.perf_counter()
            d = implicit_static(st, elastic, el, [1.0])[0]
            line = (f"{el:5s} {nl}x{nw}x{nt} bricks: implicit d / EB {d / eb:.4f}  d / Timoshenko {d / tim:.4f}"
                    f"  ({time.perf_counter() - t0:.1f} s)")
            if a.explicit:
                t0 = time.perf_counter()
                de, n = explicit_relaxed(st, elastic, el, 1.0)
                line += f"; explicit d / EB {de / eb:.4f} ({n} steps, {time.perf_counter() - t0:.0f} s)"
            print(line, flush=True)
        if a.plastic:
            mat = Material(7800.0, G, K, 250e6, 0.0)
            Pp = hinge_load(st, mat)
            fr = [0.8, 0.9, 0.95, 0.98, 0.99, 1.0, 1.01, 1.02, 1.04, 1.07]
            d_el = beam_deflection(st, mat, Pp, shear=False)
            for el in a.elements:
                ds = implicit_static(st, mat, el, [f * Pp for f in fr])
                for f, d in zip(fr, ds):
                    beam = beam_plastic_deflection(st, mat, f * Pp) / d_el if f < 1 else (
                        20.0 / 27.0 * 2.0 if f == 1 else np.inf)
                    print(f"{el:5s} {nl}x{nw}x{nt} P / P_p {f:.3f}: d / d_el(P_p) "
                          f"{'failed' if d is None else f'{d / d_el:.4f}'}  beam theory {beam:.4f}", flush=True)


if __name__ == "__main__":
    main()
