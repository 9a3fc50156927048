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
   axisymmetric or planar (the deck's Jacobian ``Vol``) and its ``CoefGeos[]``, the conductivity of
   every conductor, the turns of every coil (the ampere-turns per ampere of ``js0``), the bank (C, R,
   L, charging voltage) or the current a coil's ``Current_2D`` prescribes: a template deck keeps its
   own numbers, so a case that says otherwise is refused, naming both values. A value the case leaves
   out is the deck's (a conductivity, the turns; the bank or the current: :mod:`.deck_sources`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pulseform.solvers.getdp.template import TemplateDeckSolver, TemplateSpec, current_mismatch

from ..mesh.em_geometry import EMGeometry
from .deck_check import DeckContractError
from .deck_sources import source_summary, sources_left_to_deck

log = logging.getLogger(__name__)

#: largest relative difference between a deck's own value and the case's
VALUE_RTOL = 1e-6
#: a conductivity (S/m) or turns the case leaves to a template deck, before the deck check has read it
UNREAD = float("nan")
#: relative tolerance of the geometry kind (:func:`_geometry_kind`): axisymmetric and planar differ by the
#: region's mean x in metres (0.04 for the example's die)
KIND_RTOL = 1e-3


@dataclass
class DeckGeometry(EMGeometry):
    """:class:`EMGeometry` of a template deck, with the deck's own physical ids.

    ``deck_ids``: the runner's id of each mapped group (1 air, 101 coil 1, 201 workpiece, 11 axis, ...)
    -> the id the deck's mesh gives it (the deck's ``Region[...]`` use these)."""

    deck_ids: dict[int, int] = field(default_factory=dict)
    #: the deck's own values (:func:`deck_values`) read by the deck check
    deck_values: dict[str, float | str] = field(default_factory=dict)
    #: the deck's ``DefineConstant`` numbers as getdp reads them with the run's numbers (:func:`deck_constants`)
    deck_constants: dict[str, float] = field(default_factory=dict)


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

    names = {name: int(v[0]) for name, v in meshio.read(path, file_format="gmsh").field_data.items()}
    return {new_id: names[name] for _, name, _, new_id in groups}


def template_solver(case, model, work_dir: Path, deck_ids: dict[int, int], numbers: dict[str, float]
                    ) -> TemplateDeckSolver:
    """The per-step getdp solver on the case's template deck (``em.time_scheme``, both carried by ``-restart``).

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


def _conductor_material(case, k: int) -> str:
    """The material name of conductor k's body."""
    role = case.geometry.conductor_roles()[k - 1]
    return next(b for b in case.bodies if b.region == role).material


def _conductivity_key(case, k: int) -> str:
    return f"materials.{_conductor_material(case, k)}.electrical_conductivity"


def _geometry_kind(rows: np.ndarray) -> tuple[str, float]:
    """(``"axisymmetric"``, ``"planar"``, ``"either"`` or ``"neither"``, mean CoefGeos[]) of one region's
    ``geo_*.txt`` rows: the integral of 1 with the deck's Jacobian ``Vol``, the area, the integral of x
    (m^2), the integral of CoefGeos[]. ``VolAxiSqu`` integrates 1 to the integral of x (per radian; to
    9e-7 relative on the die of cases/template_sheet_bulge/with_die.toml, whose curved edge its
    quadrature does not follow exactly), ``Vol`` to the area: :data:`KIND_RTOL` tells them apart
    unless the region's mean x is within it of 1 m ("either")."""
    vol, area, xarea, coef = (float(v) for v in rows[:4, -1])
    axi, plane = abs(vol - xarea) <= KIND_RTOL * abs(xarea), abs(vol - area) <= KIND_RTOL * abs(area)
    kind = "either" if axi and plane else "axisymmetric" if axi else "planar" if plane else "neither"
    return kind, coef / area


def deck_values(out: Path, n_coils: int, n_conductors: int, circuit: bool) -> dict[str, float | str]:
    """The deck's own values printed by the first run from rest (``EM_Values`` into ``out``).

    Returns
    -------
    dict
        ``"sigma_<k>"`` (S/m, mean over conductor k), ``"turns_<k>"`` (the integral of js0 . e_z over
        coil k: ampere-turns per ampere), with a circuit ``"C"`` (F), ``"R"`` (Ohm), ``"L"`` (H)
        summed over the template's ``Capacitance_Cir`` / ``Resistance_Cir`` / ``Inductance_Cir``
        regions, and ``"V0"`` (V, the capacitor's voltage at the start); ``"kind_<region>"``
        (``"axisymmetric"``, ``"planar"`` or ``"neither"``: the deck's Jacobian ``Vol`` there) and
        ``"coefgeos_<region>"`` (mean CoefGeos[]) for every coil (``coil_<k>``) and conductor (``cond_<k>``).
    """
    vals: dict[str, float | str] = {}
    for reg in [f"coil_{k}" for k in range(1, n_coils + 1)] + [f"cond_{k}" for k in range(1, n_conductors + 1)]:
        vals[f"kind_{reg}"], vals[f"coefgeos_{reg}"] = _geometry_kind(_last(out / f"geo_{reg}.txt"))
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


def deck_constants(deck: Path, argv: list[str], work: Path, time_limit: float) -> dict[str, float]:
    """The numbers the deck declares with ``DefineConstant`` (and its Includes but GetDP's template,
    :func:`~pulseform.orchestrator.case.deck_files.define_constant_names`) as getdp evaluates them with
    the run's ``-setnumber`` numbers (those of ``argv``, a check run's command line): a parse-only getdp
    run of a file that includes the deck and prints them (``work/constants.pro``, log
    ``work/constants.log``). A constant getdp cannot print is left out; a failed run gives {} (the
    values are shown, never checked).

    Returns
    -------
    dict
        Name -> value, in the deck's order.
    """
    from ..case.deck_files import define_constant_names
    from .deck_sources import parse_deck

    numbers = [a for i, tok in enumerate(argv[:-2]) if tok == "-setnumber" for a in argv[i:i + 3]]
    lines = [f'If(Exists[{n}]) Printf[Sprintf["{n} %.17g", {n}]] >> "{{table}}"; EndIf'
             for n in define_constant_names(Path(deck))]
    text = parse_deck(Path(deck), numbers, lines, "constants.txt", work, time_limit)
    if text is None:
        return {}
    out = {}
    for row in text.splitlines():
        name, _, value = row.partition(" ")
        try:
            out[name] = float(value)
        except ValueError:
            continue
    return out


def deck_summary(case, geometry: DeckGeometry) -> list[str]:
    """What ``pulseform check`` shows of a template deck: its constants as getdp reads them (those a
    ``--set geometry.parameters.<name>=...`` changes, then those the runner sets), and the values the
    case leaves to the deck (a conductivity left at 0, ``geometry.turns`` not given, the bank or the
    prescribed current: :func:`.deck_sources.source_summary`)."""
    from ..case.deck_files import is_reserved_parameter

    g = case.geometry
    deck = Path(g.pro).name
    consts = geometry.deck_constants
    own = {n: v for n, v in consts.items() if not (is_reserved_parameter(n) or n == "Flag_FrequencyDomain")}
    runner = {n: v for n, v in consts.items() if n not in own}
    lines = []
    if consts:
        lines.append(f"# {deck}: its constants as getdp reads them (--set geometry.parameters.<name>=... changes "
                     "one): " + (", ".join(f"{n} = {v:.6g}" for n, v in own.items()) or "none")
                     + ("; set by the runner: " + ", ".join(f"{n} = {v:.6g}" for n, v in runner.items())
                        if runner else ""))
    vals, taken = geometry.deck_values, []
    for k in range(1, len(g.conductor_roles()) + 1):
        if case.materials[_conductor_material(case, k)].electrical_conductivity <= 0.0 and f"sigma_{k}" in vals:
            group = getattr(g.regions, g.conductor_roles()[k - 1])
            taken.append(f"{_conductivity_key(case, k)} = {vals[f'sigma_{k}']:.6g} S/m (sigma[] on {group})")
    for k, (key, _, group, turns) in enumerate(g.coil_groups(), start=1):
        if turns is None and f"turns_{k}" in vals:
            taken.append(f"geometry.turns = {vals[f'turns_{k}']:.6g} (js0[] over {group})")
    taken += source_summary(case, vals)
    if taken:
        lines.append(f"# the case takes from {deck}: " + ", ".join(taken))
    return lines


def _source_key(case, k: int) -> str:
    """The case-file key of coil k's prescribed source (``em.current``, ``em.sources[i]``)."""
    em = case.em
    if not em.sources:
        return "em.current"
    name = case.geometry.coils[k - 1].name if case.geometry.coils else em.coils[0].name
    source = next(c.source for c in em.coils if c.name == name)
    i = next(i for i, src in enumerate(em.sources) if src.name == source)
    return f"em.sources[{i}] ({source})"


def current_differences(case, model, out: Path) -> list[str]:
    """Coil k's current in the deck (``coil_I_<k>.txt`` of a check run) against the case's prescribed
    source times the coil's sign (:func:`pulseform.solvers.getdp.template.current_mismatch`), as the
    phrases of :func:`check_deck_values`; coils on a bank are the circuit's and not compared."""
    diffs = []
    if sources_left_to_deck(case):  # the deck's own current, read after the check (.deck_sources)
        return diffs
    coils = [c[2] for c in case.geometry.coil_groups()]
    for k, coil in enumerate(model.coils, start=1):
        if coil.waveform is None:
            continue
        rows = _last(out / f"coil_I_{k}.txt")
        bad = current_mismatch(coil, rows[:, 0], rows[:, -1])
        if bad is not None:
            t, want, got = bad
            diffs.append(f"{_source_key(case, k)} gives {want:.6g} A at t = {t:.3g} s, the deck's Current_2D on "
                         f"{coils[k - 1]} = {got:.6g} A")
    return diffs


class DeckValueConflict(DeckContractError):
    """A value the case states differs from the template deck's own (the CLI names the case file)."""


def _deck_constant(constants: dict[str, float] | None, value: float) -> str:
    """`` (its NAME)`` when exactly one of the deck's ``DefineConstant`` numbers (:func:`deck_constants`, as
    the run reads them) equals ``value`` to :data:`VALUE_RTOL` relative, else ``""``."""
    from ..case.deck_files import is_reserved_parameter

    hits = [n for n, v in (constants or {}).items()
            if not is_reserved_parameter(n) and abs(v - value) <= VALUE_RTOL * max(abs(value), 1e-300)]
    return f" (its {hits[0]})" if len(hits) == 1 else ""


def check_deck_values(case, model, out: Path, constants: dict[str, float] | None = None) -> dict[str, float | str]:
    """Refuse a template deck whose own values differ from the case's (relative :data:`VALUE_RTOL`).

    Compares the deck's geometry (its Jacobian ``Vol`` axisymmetric or planar as ``geometry.planar``
    says, ``CoefGeos[]`` = 2 pi or 1 per metre of depth on every coil and conductor), conductor k's
    mean conductivity with its material's ``electrical_conductivity``, coil k's ampere-turns per ampere
    with its turns (``geometry.turns`` / ``geometry.coils[i].turns``), with a bank its C, R, L and
    charging voltage with ``em.circuit`` (or the bank source), and a prescribed coil current at the
    check's step with its source (:func:`current_differences`). Returns the deck's values; raises
    :class:`DeckValueConflict` listing every difference in one line: the case's key and value, the deck's
    value and the ``DefineConstant`` that holds it (``constants``, :func:`deck_constants`, when one alone
    has that value), and that a key left out of the case takes the deck's.
    """
    g = case.geometry
    vals = deck_values(out, len(model.coils), len(model.conductors), model.circuit is not None)
    names = {f"coil_{k}": c[2] for k, c in enumerate(g.coil_groups(), start=1)}
    names.update({f"cond_{k}": getattr(g.regions, role) for k, role in enumerate(g.conductor_roles(), start=1)})
    kind, coef = ("planar", 1.0) if g.planar else ("axisymmetric", 2.0 * np.pi)
    diffs = []
    for reg, group in names.items():
        if vals[f"kind_{reg}"] not in (kind, "either"):
            diffs.append(f"geometry.planar = {str(g.planar).lower()} ({kind}), the deck's Jacobian Vol on {group} is "
                         f"{vals[f'kind_{reg}']} (Flag_Axi)")
        elif abs(vals[f"coefgeos_{reg}"] - coef) > VALUE_RTOL * coef:
            diffs.append(f"geometry.planar = {str(g.planar).lower()} (CoefGeos[] = {coef:.6g}), the deck's CoefGeos[] "
                         f"on {group} = {vals[f'coefgeos_{reg}']:.6g}")
    want: list[tuple[str, str, float, str]] = []  # (value key, case key, case value, unit): what the case gives
    for k in range(1, len(model.conductors) + 1):
        ckey = _conductivity_key(case, k)
        sigma = case.materials[_conductor_material(case, k)].electrical_conductivity
        if sigma > 0.0:  # 0: left to the deck
            want.append((f"sigma_{k}", ckey, sigma, "S/m"))
    for k, (key, _, _, turns) in enumerate(g.coil_groups(), start=1):
        tkey = key[:-len(".group")] + ".turns" if key.startswith("geometry.coils") else "geometry.turns"
        if turns is not None:  # None: left to the deck
            want.append((f"turns_{k}", tkey, float(turns), "turns"))
    if model.circuit is not None and not sources_left_to_deck(case):  # left: the deck's bank (.deck_sources)
        bank = "em.circuit" if case.em.circuit is not None else "em.sources (bank)"
        cir = model.circuit
        want += [("C", f"{bank}.capacitance", cir.C, "F"), ("R", f"{bank}.resistance", cir.R_ext, "Ohm"),
                 ("L", f"{bank}.inductance", cir.L_ext, "H"), ("V0", f"{bank}.voltage", cir.V0, "V")]
    for vkey, ckey, expected, unit in want:
        got = vals[vkey]
        if not np.isfinite(got) or abs(got - expected) > VALUE_RTOL * max(abs(expected), 1e-300):
            base, _, k = vkey.partition("_")
            what = {"sigma": f"sigma[] on {names.get(f'cond_{k}')}", "turns": f"js0[] over {names.get(f'coil_{k}')}",
                    "C": "Capacitance[]", "R": "Resistance[]", "L": "Inductance[]",
                    "V0": "Init of the capacitor's voltage"}[base]
            diffs.append(f"{ckey} = {expected:.6g} {unit}, the deck's {what} = {got:.6g} {unit}"
                         + _deck_constant(constants, got))
    diffs += current_differences(case, model, out)
    if diffs:
        raise DeckValueConflict(f"deck {Path(g.pro).name} and the case differ: " + "; ".join(diffs)
                                + " (the deck's values are used: make them agree, or leave the key out)")
    log.info("template deck %s agrees with the case: %s", Path(g.pro).name,
             ", ".join(f"{k} = {v:.6g}" if isinstance(v, float) else f"{k} = {v}" for k, v in vals.items()))
    return vals
