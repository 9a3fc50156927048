"""Users' decks on GetDP's standard template (``[geometry] library = "getdp_template"``).

The deck (its own groups on its own physical ids, functions, constraints, then ``Include
"Lib_Magnetodynamics2D_av_Cir.pro"``) runs unchanged: the runner

1. maps the roles' physical groups by name as for any user deck, and keeps the deck's own ids in the
   mesh each getdp run reads (:func:`deck_physical_ids`; the runner's ids 1, 101, 201, ... stay the
   Python side's);
2. runs :class:`pulseform.solvers.getdp.template.TemplateDeckSolver`, whose ``run.pro`` includes the
   deck and appends pulseform's PostProcessing and Resolution on the formulation and system named by
   ``[geometry.template]``;
3. checks the deck like any user deck (:mod:`.deck_check`; the state carry through the restart
   path only) and then compares the deck's own values with the case's (:func:`check_deck_values`):
   the conductivity of every conductor, the turns of every coil (the ampere-turns per ampere of
   ``js0``), and the bank (C, R, L, charging voltage): a template deck keeps its own numbers, so a
   case that says otherwise is refused, naming both values.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pulseform.solvers.getdp.template import TemplateDeckSolver, TemplateSpec

from ..mesh.em_geometry import EMGeometry
from .deck_check import DeckContractError

log = logging.getLogger(__name__)

#: largest relative difference between a deck's own value and the case's
VALUE_RTOL = 1e-6


@dataclass
class DeckGeometry(EMGeometry):
    """:class:`EMGeometry` of a template deck, with the deck's own physical ids.

    ``deck_ids``: the runner's id of each mapped group (1 air, 101 coil 1, 201 workpiece, 11 axis, ...)
    -> the id the deck's mesh gives it (the deck's ``Region[...]`` use these)."""

    deck_ids: dict[int, int] = field(default_factory=dict)


def deck_physical_ids(path: Path, groups: list[tuple[str, str, int, int]]) -> dict[int, int]:
    """The runner's id -> the mesh's own physical id, for every mapped group.

    Parameters
    ----------
    path : Path
        The deck's MSH 2.2 mesh (with ``$PhysicalNames``).
    groups : list of tuple
        ``(case-file key, group name, dimension, runner's id)`` (:func:`.user_deck.group_map`).
    """
    import meshio

    names = {name: int(v[0]) for name, v in meshio.read(path).field_data.items()}
    return {new_id: names[name] for _, name, _, new_id in groups}


def template_solver(case, model, work_dir: Path, deck_ids: dict[int, int], numbers: dict[str, float]
                    ) -> TemplateDeckSolver:
    """The per-step getdp solver on the case's template deck (implicit Euler, ``-restart`` carry).

    ``numbers``: the ``-setnumber`` extras of a user deck (role ids, ``[geometry.parameters]``)."""
    g = case.geometry
    t = g.template_spec()
    return TemplateDeckSolver(model, work_dir, deck=g.pro, spec=TemplateSpec(t.formulation, t.system),
                              deck_ids=deck_ids, extra_numbers=numbers, time_scheme=case.em.time_scheme)


def _last(path: Path) -> np.ndarray:
    """The rows of a getdp table (``Format Table``): time, then values."""
    if not path.is_file():
        raise DeckContractError(f"the deck check wrote no {path.name} (EM_Values of the template wrapper)")
    return np.loadtxt(path, ndmin=2)


def _conductivity_key(case, k: int) -> str:
    role = case.geometry.conductor_roles()[k - 1]
    body = next(b for b in case.bodies if b.region == role)
    return f"materials.{body.material}.electrical_conductivity"


def deck_values(out: Path, n_coils: int, n_conductors: int, circuit: bool) -> dict[str, float]:
    """The deck's own values printed by the first run from rest (``EM_Values`` into ``out``).

    Returns
    -------
    dict
        ``"sigma_<k>"`` (S/m, mean over conductor k), ``"turns_<k>"`` (the integral of js0 . e_z over
        coil k: ampere-turns per ampere), and with a circuit ``"C"`` (F), ``"R"`` (Ohm), ``"L"`` (H)
        summed over the template's ``Capacitance_Cir`` / ``Resistance_Cir`` / ``Inductance_Cir``
        regions, and ``"V0"`` (V, the capacitor's voltage at the start).
    """
    vals: dict[str, float] = {}
    for k in range(1, n_conductors + 1):
        rows = _last(out / f"cond_sigma_{k}.txt")
        vals[f"sigma_{k}"] = float(rows[0, -1] / rows[1, -1])
    for k in range(1, n_coils + 1):
        vals[f"turns_{k}"] = float(_last(out / f"coil_turns_{k}.txt")[0, -1])
    if circuit:
        for q in ("C", "R", "L"):
            vals[q] = float(_last(out / f"cir_{q}.txt")[:, -1].sum())
        vals["V0"] = float(_last(out / "cir_V0.txt")[0, -1])
    return vals


def check_deck_values(case, model, out: Path) -> dict[str, float]:
    """Refuse a template deck whose own values differ from the case's (relative :data:`VALUE_RTOL`).

    Compares conductor k's mean conductivity with its material's ``electrical_conductivity``, coil
    k's ampere-turns per ampere with its turns (``geometry.turns`` / ``geometry.coils[i].turns``) and,
    with a bank, its C, R, L and charging voltage with ``em.circuit`` (or the bank source). Returns
    the deck's values; raises :class:`DeckContractError` listing every difference in one line.
    """
    g = case.geometry
    vals = deck_values(out, len(model.coils), len(model.conductors), model.circuit is not None)
    want: list[tuple[str, str, float, str]] = []  # (value key, case key, case value, unit)
    for k, c in enumerate(model.conductors, start=1):
        want.append((f"sigma_{k}", _conductivity_key(case, k), c.sigma, "S/m"))
    for k, (key, _, _, turns) in enumerate(g.coil_groups(), start=1):
        tkey = key[:-len(".group")] + ".turns" if key.startswith("geometry.coils") else "geometry.turns"
        want.append((f"turns_{k}", tkey, float(turns), "turns"))
    if model.circuit is not None:
        bank = "em.circuit" if case.em.circuit is not None else "em.sources (bank)"
        cir = model.circuit
        want += [("C", f"{bank}.capacitance", cir.C, "F"), ("R", f"{bank}.resistance", cir.R_ext, "Ohm"),
                 ("L", f"{bank}.inductance", cir.L_ext, "H"), ("V0", f"{bank}.voltage", cir.V0, "V")]
    groups = [case.geometry.regions.workpiece, case.geometry.regions.die]
    coils = [c[2] for c in g.coil_groups()]
    diffs = []
    for vkey, ckey, expected, unit in want:
        got = vals[vkey]
        if not np.isfinite(got) or abs(got - expected) > VALUE_RTOL * max(abs(expected), 1e-300):
            base, _, k = vkey.partition("_")
            what = {"sigma": f"sigma[] on {groups[int(k or 1) - 1]}", "turns": f"js0[] over {coils[int(k or 1) - 1]}",
                    "C": "Capacitance[]", "R": "Resistance[]", "L": "Inductance[]",
                    "V0": "Init of the capacitor's voltage"}[base]
            diffs.append(f"{ckey} = {expected:.6g} {unit}, the deck's {what} = {got:.6g} {unit}")
    if diffs:
        raise DeckContractError(f"deck {Path(g.pro).name} and the case differ: " + "; ".join(diffs)
                                + " (the deck's own values are used: make them agree)")
    log.info("template deck %s agrees with the case: %s", Path(g.pro).name,
             ", ".join(f"{k} = {v:.6g}" for k, v in vals.items()))
    return vals
