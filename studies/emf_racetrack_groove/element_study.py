"""Linear against ten-node tetrahedra in the coupled racetrack (issue 34 item 4: "the racetrack's plastic strain
shows no element-to-element checkerboard").

Runs ``pulseform run cases/emf_racetrack_groove`` with the sheet's ``element`` = "tet4" and "tet10" on the same
meshes (:data:`MESHES`): to ``T_END`` = 30 µs without ``[[contact]]`` (``--set contact=[]``: the sheet's free
forming, which is the case's own until the first contact, 38 µs on the coarse linear mesh, ~31 µs on the design
mesh) on three meshes, and the whole case (``T_FULL`` = 60 µs, the sheet drawn into the die's groove through soft
contact) on two. For each run: the sheet's largest draw ``sheet_max_uz_m``, the plastic work, the first contact,
the energy balance, and the checkerboard index of its cell plastic strain over the plastically strained cells
(:func:`pulseform.orchestrator.mech.checkerboard.checkerboard_index`) at the run's end, printed as a table and
written to ``reference/element_study.json``; the picture pairs ``docs/assets/racetrack_plastic_strain_tet4_tet10.png``
(30 µs) and ``..._60us.png`` (the whole case): the sheet's lower face and the section y = 0 on the design mesh.

Meshes: ``coarse`` (the tests' sizes, element sizes x 2: sheet 1.6k tetrahedra, 2 through the thickness),
``design`` (the case file's: 8.9k, 3 through the thickness) and ``design6`` (6 through the thickness: 17.8k; its EM
is the design mesh's to 0.02 % in the peak force, reference/em_convergence_6_layers.json, so what changes is the
mechanics' resolution of the bending); ``coarse_full``, ``design_full`` and ``design6_full`` the whole case. Usage::

    .venv/bin/python studies/emf_racetrack_groove/element_study.py OUT_FOLDER [coarse design design6_full:tet4 ...]

(``mesh:element`` runs one element only; without names: all of :data:`MESHES`; runs already in OUT_FOLDER are
kept.)
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from pulseform.orchestrator.mech.checkerboard import checkerboard_index
from pulseform.orchestrator.run.mech_fields import read_fields

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
T_END = 30e-6
#: the whole case (its first current half-wave, with [[contact]])
T_FULL = 60e-6
#: the sections' thickness drawn this many times its length scale
SECTION_STRETCH = 4.0
COARSE = ["geometry.parameters.h_sheet=4e-3", "geometry.parameters.sheet_layers=2", "geometry.parameters.h_coil=6e-3",
          "geometry.parameters.h_die=8e-3"]
#: run name -> (--set overrides, end time s, with the case's [[contact]])
MESHES = {"coarse": (COARSE, T_END, False), "design": ([], T_END, False),
          "design6": (["geometry.parameters.sheet_layers=6"], T_END, False),
          "coarse_full": (COARSE, T_FULL, True), "design_full": ([], T_FULL, True),
          "design6_full": (["geometry.parameters.sheet_layers=6"], T_FULL, True)}


def run(out: Path, mesh: str, element: str) -> Path:
    """The run of ``mesh`` with the sheet's ``element`` in ``out/<mesh>_<element>`` (kept if already there)."""
    folder = out / f"{mesh}_{element}"
    if (folder / "metrics.json").exists():
        return folder
    extra, t_end, contact = MESHES[mesh]
    sets = [*extra, f"time.end={t_end}", "output.field_interval=10e-6", f"bodies.sheet.element='{element}'",
            *(() if contact else ("contact=[]",))]
    argv = [str(Path(sys.executable).with_name("pulseform")), "run", str(REPO / "cases/emf_racetrack_groove"),
            "--out", str(folder), "--quiet"] + [a for s in sets for a in ("--set", s)]
    subprocess.run(argv, check=True, timeout=3600)
    return folder


def figures(folder: Path, t_end: float) -> dict[str, float]:
    """The run's draw (m), plastic work (J, device), sheet cells and the checkerboard index at ``t_end`` (s)."""
    m = json.loads((folder / "metrics.json").read_text())
    sheet = read_fields(folder)["sheet"]
    k = int(np.argmin(np.abs(sheet.times - t_end)))
    p = sheet.read(k, ("plastic_strain",))["plastic_strain"]
    return {"sheet_max_uz_mm": float(m["sheet_max_uz_mm"]), "plastic_work_J": float(m["plastic_work_J"]),
            "sheet_tets": float(len(sheet.triangles)), "plastic_cells": float((p > 0).sum()),
            "plastic_strain_max": float(p.max()),
            "checkerboard_index": checkerboard_index(sheet.points, sheet.triangles, p),
            "energy_error_rel": float(m["energy_error_rel"]), "ledger_rel": float(m["conservation_error_rel"]),
            "first_contact_us": float(m.get("first_contact_s") or np.nan) * 1e6,
            "wall_time_s": float(m["wall_time_s"])}


def picture(folders: dict[str, Path], path: Path, mesh: str, t_end: float) -> None:
    """The sheet's cell plastic strain at ``t_end`` (s) on its lower face (z = 0) and in the section y = 0
    (thickness stretched :data:`SECTION_STRETCH` times), per element, of the runs ``mesh``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    sys.path.insert(0, str(HERE))
    from racetrack_pictures import plane_faces

    fig, axes = plt.subplots(2, 2, figsize=(12, 8.5), gridspec_kw={"height_ratios": [3, 1]}, constrained_layout=True)
    data = {}
    for element, folder in folders.items():
        sheet = read_fields(folder)["sheet"]
        k = int(np.argmin(np.abs(sheet.times - t_end)))
        data[element] = (sheet, sheet.read(k, ("plastic_strain", "displacement_m")))
    top = max(float(d["plastic_strain"].max()) for _, d in data.values())
    for col, (element, (sheet, d)) in enumerate(data.items()):
        x = sheet.points + d["displacement_m"][:len(sheet.points)]
        for row, (axis, value, ij) in enumerate(((2, 0.0, (0, 1)), (1, 0.0, (0, 2)))):
            faces, owner = plane_faces(sheet.points, sheet.triangles, axis, value)
            ax = axes[row, col]
            pc = PolyCollection(x[faces][:, :, ij] * 1e3, array=d["plastic_strain"][owner], cmap="viridis",
                                edgecolors="face", linewidths=0.2)
            pc.set_clim(0.0, top)
            ax.add_collection(pc)
            ax.autoscale_view()
            ax.set_aspect("equal" if row == 0 else SECTION_STRETCH)
            ax.set_xlabel("x [mm]")
            ax.set_ylabel("y [mm]" if row == 0 else f"z [mm], drawn x {SECTION_STRETCH:g}")
            index = checkerboard_index(sheet.points, sheet.triangles, d["plastic_strain"])
            ax.set_title(f"{element}: " + ("lower face z = 0" if row == 0 else "section y = 0")
                         + (f" (checkerboard index {index:.2f})" if row == 0 else ""))
    fig.colorbar(pc, ax=axes, label=f"equivalent plastic strain at {t_end * 1e6:.0f} µs [-]", shrink=0.8)
    fig.suptitle(f"Coupled racetrack, {mesh} mesh: the sheet's cell plastic strain, linear vs ten-node tetrahedra")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str]) -> None:
    out = Path(argv[0])
    meshes = argv[1:] or list(MESHES)
    table = {}
    for item in meshes:
        mesh, _, only = item.partition(":")
        for element in (only,) if only else ("tet4", "tet10"):
            table[f"{mesh}_{element}"] = figures(run(out, mesh, element), MESHES[mesh][1])
    print(f"{'run':18s} {'draw mm':>9s} {'plastic J':>10s} {'tets':>6s} {'plastic cells':>13s} {'checkerboard':>12s} "
          f"{'contact us':>10s} {'energy':>8s} {'wall s':>7s}")
    for name, f in table.items():
        print(f"{name:18s} {f['sheet_max_uz_mm']:9.4f} {f['plastic_work_J']:10.4f} {f['sheet_tets']:6.0f} "
              f"{f['plastic_cells']:13.0f} {f['checkerboard_index']:12.3f} {f['first_contact_us']:10.1f} "
              f"{f['energy_error_rel']:8.1e} {f['wall_time_s']:7.0f}")
    (HERE / "reference").mkdir(exist_ok=True)
    (HERE / "reference" / "element_study.json").write_text(json.dumps(
        {"t_end_s": {m: MESHES[m][1] for m in MESHES}, "runs": table}, indent=1))
    for mesh, name in (("design", "racetrack_plastic_strain_tet4_tet10.png"),
                       ("design_full", "racetrack_plastic_strain_tet4_tet10_60us.png")):
        if mesh in meshes:
            picture({e: out / f"{mesh}_{e}" for e in ("tet4", "tet10")}, REPO / "docs/assets" / name,
                    mesh.replace("_full", ""), MESHES[mesh][1])


if __name__ == "__main__":
    main(sys.argv[1:])
