"""``coaxial_coils`` with ``planar = true`` is the plane half model of ``planar_coil_blank_die``: the same
six turns as one coil of six windings on a sine source equal to the prescribed current
I0 e^(−βt) sin(ωt), over the same blank (no die), give the same run — the same mesh (gmsh gets the same
rectangles and sizes) and the same model; the source's ω = 2π f is rebuilt from f = ω / 2π, so the
two may differ by round-off only (1e-12 here). A planar bank is refused (per metre of depth)."""
from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from pulseform.orchestrator.cli import main

REPO = Path(__file__).resolve().parents[2]
BASE = tomllib.loads((REPO / "cases/emf_corner_fill/case.toml").read_text())


def _cases(tmp_path: Path) -> tuple[Path, Path]:
    base = {k: BASE[k] for k in ("case", "time", "mechanics", "materials", "coupling")}
    base["time"] = dict(BASE["time"], end=4e-6)
    base["output"] = {"field_interval": 2e-6, "plots": False}
    base["bodies"] = [{"name": "blank", "material": "al", "region": "workpiece",
                       "fixed": [{"where": {"xmax": 1e-9}, "components": [0]},
                                 {"where": {"xmin": 0.135}, "components": [0, 1]}]}]
    g = {k: v for k, v in BASE["geometry"].items() if k not in ("die", "mesh_size_die")}
    cur = BASE["em"]["current"]
    old = dict(base, geometry=g, em={"current": cur, "time_scheme": "bdf2"})
    y0 = g["blank_thickness"] + g["coil_gap"]
    windings = [[g["coil_inner_x"] + k * (g["turn_width"] + g["turn_gap"]), y0,
                 g["coil_inner_x"] + k * (g["turn_width"] + g["turn_gap"]) + g["turn_width"], y0 + g["turn_height"]]
                for k in range(g["turns"])]
    new = dict(base, geometry={"type": "coaxial_coils", "planar": True, "air_radius": g["air_radius"],
                               "shell_radius": g["shell_radius"], "mesh_size_coil": g["mesh_size_coil"],
                               "mesh_size_air": g["mesh_size_air"],
                               "workpiece": {"r0": 0.0, "z0": 0.0, "r1": g["blank_half_width"],
                                             "z1": g["blank_thickness"], "mesh_size": g["mesh_size_blank"]},
                               "coils": [{"name": "coil", "turns": g["turns"], "windings": windings}]},
               em={"time_scheme": "bdf2",
                   "sources": [{"name": "s", "type": "sine", "amplitude": cur["amplitude"], "decay": cur["beta"],
                                "frequency": cur["omega"] / (2 * math.pi)}],
                   "coils": [{"name": "coil", "source": "s"}]})
    paths = []
    for name, data in (("old", old), ("new", new)):
        data["case"] = dict(data["case"], name=name)
        p = tmp_path / f"{name}.toml"
        p.write_text(tomli_w.dumps(data))
        paths.append(p)
    return paths[0], paths[1]


@pytest.mark.getdp
def test_planar_coaxial_coils_equal_the_planar_coil_geometry(tmp_path, capsys):
    old, new = _cases(tmp_path)
    hist = {}
    for p in (old, new):
        assert main(["run", str(p), "--out", str(tmp_path / p.stem), "--quiet"]) == 0, capsys.readouterr().err
        hist[p.stem] = np.genfromtxt(tmp_path / p.stem / "history.csv", delimiter=",", names=True)
        m = json.loads((tmp_path / p.stem / "metrics.json").read_text())
        print(f"\n{p.stem}: impulse {m['force_impulse_Ns']:.10g} N s, blank max uy {m['blank_max_uy_mm']:.10g} mm")
    a, b = hist["old"], hist["new"]
    assert len(a) == len(b) and np.array_equal(a["time_s"], b["time_s"])
    for col in ("force_y_N", "force_x_N", "blank_max_uy_m", "coil_current_A", "magnetic_energy_J"):
        scale = np.abs(a[col]).max()
        assert scale > 0.0, col
        assert np.abs(a[col] - b[col]).max() <= 1e-12 * scale, col


def test_planar_coaxial_coils_refuse_a_bank(tmp_path, capsys):
    _, new = _cases(tmp_path)
    data = tomllib.loads(new.read_text())
    data["em"]["sources"] = [{"name": "s", "type": "bank", "capacitance": 1e-4, "voltage": 1e3}]
    new.write_text(tomli_w.dumps(data))
    assert main(["check", str(new)]) == 2
    assert "em.sources[0].type" in capsys.readouterr().err
