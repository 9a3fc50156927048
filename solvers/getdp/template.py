"""Users' decks written on GetDP's standard template ``Lib_Magnetodynamics2D_av_Cir.pro``.

A GetDP user's deck defines its own groups (on its own physical ids), functions and constraints,
then includes the template, whose formulation ``Magnetodynamics2D_av`` (system ``A`` in its
Resolution) solves the transient a-v problem with an optional circuit.  Such a deck knows nothing
of pulseform: :class:`TemplateDeckSolver` runs it unchanged by writing a ``run.pro`` that
includes the deck and then appends pulseform's own part (:func:`wrapper_text`):

* groups ``PF_Coil_<k>`` / ``PF_Cond_<k>`` on the deck's own physical ids of coil k / conductor k
  (the mesh each run writes keeps the deck's ids: :attr:`TemplateDeckSolver.deck_ids`);
* a PostProcessing ``PF_Template`` on the user's formulation, using the template's quantities
  ``{a}``, ``{ur}``, ``{ir}``, ``{Is}``, ``{Us}``, ``{Iz}``, ``{Uz}`` and functions ``nu``,
  ``sigma``, ``js0``, ``CoefGeos``: in the massive conductors j = -sigma (Dt[{a}] + {ur}/CoefGeos[])
  (the template's ``j``), in the stranded coils js = (js0[] . e_z) {ir}; the Lorentz force density
  f = j x b, its per-element integrals, Joule power, magnetic energy, coil and circuit current and
  voltage, the nodal unknown r a_phi, whole-domain fields;
* the PostOperations ``EM_Step``, ``EM_Elem``, ``EM_State``, ``EM_Field`` writing exactly the
  tables of the deck contract (:mod:`.contract`), and ``EM_Values`` (the deck's own conductivity,
  turns and bank, compared with the case's by the orchestrator's deck check);
* a Resolution ``EM_Transient`` on the user's formulation (system name from the case): ``SetTime``,
  ``InitSolution``, ``NbSteps`` implicit-Euler steps from ``TimeInit`` to ``TimeFinal``.

The state is carried between getdp runs by ``-restart -res`` only; after a remesh (a new
connectivity) :meth:`TemplateDeckSolver.carry_to_mesh` renumbers the last ``.res`` to the new mesh's
dofs (:mod:`.res_remap`, from a ``-pre`` run) and the restarts go on.  The Init path of the built-in library cannot carry a template deck's circuit:
measured on GetDP 3.2.0, an ``Init`` constraint the wrapper adds to the template's ``Hregion_Z``
(``FunctionSpace { { Append 1; ... } }``) loses against the deck's own ``Voltage_Cir`` Init of the
bank (the capacitor restarts at the charging voltage), and a ``Constraint { { Append 1; Name
MagneticVectorPotential_2D; ... } }`` block had no effect at all; a restarted solution does win over
the deck's Init.  :meth:`TemplateDeckSolver.step` therefore refuses a step that would need the Init
path.  BDF2 (:mod:`.bdf2`: one implicit-Euler step of gamma dt from x_tilde = c1 x_{n-1} - c2 x_{n-2})
is done by restart too (:attr:`GetDPSolver.bdf2_by_restart`): pulseform writes x_tilde, the whole
solution vector combined from the last solutions of the two previous ``.res`` files
(:func:`read_solutions`, :func:`write_solution`; the same connectivity numbers the unknowns the
same), as a ``.res`` at t_n - gamma dt and restarts from it; the first run from rest saves x_0 (the
deck's own initial state, ``PF_SaveInit``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from .bdf2 import bdf2_coefficients
from .mesh import EMMesh, coil_tag, conductor_tag, write_msh22
from .model import Coil, DampedSine, EMModel, EMState, EMStepResult, mesh_signature
from .solver import GetDPSolver
from .template_guard import runner_guard_lines

__all__ = ["TemplateSpec", "TemplateDeckSolver", "TemplateDeckError", "wrapper_text", "current_mismatch",
           "VALUE_TABLES", "WRAPPER_NAMES", "CURRENT_RTOL"]

#: objects the wrapper defines after the user's deck (a deck must not define them itself)
WRAPPER_NAMES = ("PF_Template", "PF_Plane", "EM_Transient", "EM_Step", "EM_Elem", "EM_State", "EM_Field",
                 "EM_Values")
#: tables of ``EM_Values`` (first run from rest): the deck's own values the case must agree with
VALUE_TABLES = {"cond_sigma_<k>.txt": "integral of sigma[] over conductor k, then its area (S/m m^2, m^2)",
                "coil_turns_<k>.txt": "integral of js0[] . e_z over coil k (ampere-turns per ampere)",
                "cir_C.txt": "Capacitance[] of Capacitance_Cir (F)", "cir_R.txt": "Resistance[] (Ohm)",
                "cir_L.txt": "Inductance[] (H)", "cir_V0.txt": "U of Capacitance_Cir at TimeInit (V)",
                "geo_<region>.txt": "over coil / conductor k: integral of 1 with the deck's Jacobian Vol, its area, "
                                    "integral of x, integral of CoefGeos[] (m^2 or m^3)"}
#: largest relative difference between a coil current the deck prescribes and the case's source
CURRENT_RTOL = 1e-6
#: the template's groups a coil or conductor belongs to: all, massive conductors, stranded conductors
MEMBERSHIP_GROUPS = ("Vol_Mag", "Vol_C_Mag", "Vol_S_Mag")
#: table of the first run from rest: per coil k / conductor k (``coil_<k>``, ``cond_<k>``) a row of 0
#: (inside) or 1 (outside) for each of :data:`MEMBERSHIP_GROUPS`, written while the deck is parsed
GROUPS_TABLE = "groups.txt"
#: the getdp error of a case with a capacitor bank on a deck without the template's circuit coupling
NO_CIRCUIT_ERROR = "pulseform: the case has a capacitor bank, the deck no circuit"


def read_solutions(path: str | Path) -> list[tuple[float, np.ndarray]]:
    """The solutions of a GetDP 3.2.0 ASCII ``.res`` (``$Solution`` blocks of one DofData, real).

    Returns
    -------
    list of tuple
        (time (s), the solution vector) of every ``$Solution`` block, in the file's order.
    """
    out = []
    for block in Path(path).read_text().split("$Solution")[1:]:
        lines = block.split("$EndSolution")[0].splitlines()[1:]
        head = lines[0].split()
        if head[0] != "0":
            raise TemplateDeckError(f"{path}: a solution of DofData {head[0]}; BDF2 by restart needs one system")
        out.append((float(head[1]), np.array([float(v) for v in lines[1:] if v.strip()])))
    if not out:
        raise TemplateDeckError(f"{path}: no $Solution block")
    return out


def write_solution(path: str | Path, time: float, values: np.ndarray) -> Path:
    """Write one real solution at ``time`` (s) as a GetDP ASCII ``.res`` (what ``-restart -res`` reads)."""
    body = "\n".join(f"{v:.17g}" for v in np.asarray(values, float))
    Path(path).write_text("$ResFormat /* GetDP 3.2.0, ascii */\n1.1 0\n$EndResFormat\n"
                          f"$Solution  /* DofData #0 */\n0 {time:.17g} 0 0\n{body}\n$EndSolution\n")
    return Path(path)


class TemplateDeckError(ValueError):
    """A template deck asked for something this path does not do (one line)."""


@dataclass(frozen=True)
class TemplateSpec:
    """Which formulation of the user's deck pulseform drives.

    Attributes
    ----------
    formulation : str
        Name of the user's ``Formulation`` (the template's ``Magnetodynamics2D_av``).
    system : str
        Name of the system in pulseform's Resolution (the template's ``A``).
    """

    formulation: str = "Magnetodynamics2D_av"
    system: str = "A"


def _group(ids: Sequence[int]) -> str:
    return "Region[{" + ", ".join(str(int(i)) for i in ids) + "}]"


def wrapper_text(spec: TemplateSpec, coil_ids: Sequence[int], conductor_ids: Sequence[int], circuit: bool,
                 axisymmetric: bool = True) -> str:
    """pulseform's part of ``run.pro`` after the user's template deck.

    Parameters
    ----------
    spec : TemplateSpec
        The user's formulation and pulseform's system name.
    coil_ids, conductor_ids : sequence of int
        The deck's own physical id of coil k / massive conductor k (k = 1, 2, ...).
    circuit : bool
        The case has a capacitor bank: print ``cir_U.txt`` / ``cir_I.txt`` on ``Capacitance_Cir``.
    axisymmetric : bool
        Integrals are multiplied by 2 pi (totals per revolution) and the nodal unknown is r a_phi.

    Returns
    -------
    str
        GetDP text: groups, a Jacobian, PostProcessing ``PF_Template``, PostOperations and the
        Resolution ``EM_Transient`` (the names of :data:`WRAPPER_NAMES`).
    """
    f, sys_ = spec.formulation, spec.system
    coef = "2*Pi" if axisymmetric else "1"
    raz = "X[] * CompZ[{a}]" if axisymmetric else "CompZ[{a}]"
    jc = "(-sigma[] * (Dt[{a}] + {ur}/CoefGeos[]))"
    js = "((js0[]*Vector[0,0,1]) * {ir})"
    lines = ["", "// ---- pulseform's wrapper (pulseform.solvers.getdp.template): the deck above is the user's, unchanged",
             "DefineConstant[ NbSteps = 1, Flag_ElemOut = 1, Flag_FieldOut = 0, Flag_Values = 0, PF_SaveInit = 0, "
             "OutDir = \"\" ];",
             "Group {"]
    for k, i in enumerate(coil_ids, start=1):
        lines.append(f"  PF_Coil_{k} = {_group([i])};")
    for k, i in enumerate(conductor_ids, start=1):
        lines.append(f"  PF_Cond_{k} = {_group([i])};")
    nc, nk = len(coil_ids), len(conductor_ids)
    cs = ", ".join([f"PF_Coil_{k}" for k in range(1, nc + 1)] + [f"PF_Cond_{k}" for k in range(1, nk + 1)])
    conds = ", ".join(f"PF_Cond_{k}" for k in range(1, nk + 1))
    regs = [f"Coil_{k}" for k in range(1, nc + 1)] + [f"Cond_{k}" for k in range(1, nk + 1)]
    lines += [f"  PF_CS = Region[{{{cs}}}];", f"  PF_C = Region[{{{conds}}}];"]
    lines += [f"  PF_Out_{g}_{r} = Region[{{PF_{r}, -{g}}}];" for r in regs for g in MEMBERSHIP_GROUPS]
    lines += ["}", "If(Flag_Values) // where the deck puts each coil and conductor (GROUPS_TABLE, for the deck check)"]
    for i, r in enumerate(regs):
        counts = ", ".join(f"NbrRegions[PF_Out_{g}_{r}]" for g in MEMBERSHIP_GROUPS)
        lines.append(f'  Printf[Sprintf["{r.lower()}{" %g" * len(MEMBERSHIP_GROUPS)}", {counts}]] '
                     f'{">>" if i else ">"} StrCat[OutDir, "{GROUPS_TABLE}"];')
    lines.append("EndIf")
    if circuit:  # the case's bank needs the deck's circuit (else getdp stops at an unknown Capacitance_Cir)
        lines.append(f'If(!Flag_CircuitCoupling) Error["{NO_CIRCUIT_ERROR} (Flag_CircuitCoupling = 0)"]; EndIf')
        lines.append(f'If(NbrRegions[Capacitance_Cir] == 0) Error["{NO_CIRCUIT_ERROR} (Capacitance_Cir is empty)"]; '
                     "EndIf")
    lines += ["Jacobian { { Name PF_Plane; Case { { Region All; Jacobian Vol; } } } }",
              f"PF_CoefGeo = {coef};",
              "PostProcessing {",
              f"  {{ Name PF_Template; NameOfFormulation {f};",
              "    PostQuantity {",
              f"      {{ Name raz; Value {{ Term {{ [ {raz} ]; In Vol_Mag; Jacobian Vol; }} }} }}",
              "      { Name b; Value { Term { [ {d a} ]; In Vol_Mag; Jacobian Vol; } } }",
              f"      {{ Name f; Value {{ Term {{ [ {jc} /\\ {{d a}} ]; In Vol_C_Mag; Jacobian Vol; }}",
              f"          Term {{ [ {js} /\\ {{d a}} ]; In Vol_S_Mag; Jacobian Vol; }} }} }}",
              f"      {{ Name F; Value {{ Integral {{ [ PF_CoefGeo * {jc} /\\ {{d a}} ];",
              "            In Vol_C_Mag; Jacobian Vol; Integration Gauss_v; }",
              f"          Integral {{ [ PF_CoefGeo * {js} /\\ {{d a}} ]; In Vol_S_Mag; Jacobian Vol; "
              "Integration Gauss_v; } } }",
              "      { Name P; Value { Integral { [ PF_CoefGeo * sigma[] * SquNorm[Dt[{a}] + {ur}/CoefGeos[]] ];",
              "            In Vol_C_Mag; Jacobian Vol; Integration Gauss_v; }",
              f"          Integral {{ [ PF_CoefGeo * SquNorm[{js}] / sigma[] ]; In Vol_S_Mag; Jacobian Vol; "
              "Integration Gauss_v; } } }",
              "      { Name W; Value { Integral { [ PF_CoefGeo * 0.5 * nu[] * SquNorm[{d a}] ];",
              "            In Vol_Mag; Jacobian Vol; Integration Gauss_v; } } }",
              "      { Name I; Value { Term { [ {Is} ]; In Vol_S_Mag; }",
              "          If(Flag_CircuitCoupling) Term { [ {Iz} ]; In Domain_Cir; } EndIf } }",
              "      { Name U; Value { Term { [ {Us} ]; In Vol_S_Mag; }",
              "          If(Flag_CircuitCoupling) Term { [ {Uz} ]; In Domain_Cir; } EndIf } }",
              "      { Name sigma_A; Value { Integral { [ sigma[] ]; In PF_C; Jacobian PF_Plane; "
              "Integration Gauss_v; } } }",
              "      { Name area; Value { Integral { [ 1 ]; In PF_CS; Jacobian PF_Plane; Integration Gauss_v; } } }",
              "      { Name turns; Value { Integral { [ js0[]*Vector[0,0,1] ]; In Vol_S_Mag; Jacobian PF_Plane; "
              "Integration Gauss_v; } } }",
              "      { Name vol; Value { Integral { [ 1 ]; In PF_CS; Jacobian Vol; Integration Gauss_v; } } }",
              "      { Name xarea; Value { Integral { [ X[] ]; In PF_CS; Jacobian PF_Plane; Integration Gauss_v; } } }",
              "      { Name coefgeos; Value { Integral { [ CoefGeos[] ]; In PF_CS; Jacobian PF_Plane; "
              "Integration Gauss_v; } } }",
              "      If(Flag_CircuitCoupling)",
              "        { Name cir_C; Value { Term { Type Global; [ Capacitance[] ]; In Capacitance_Cir; } } }",
              "        { Name cir_R; Value { Term { Type Global; [ Resistance[] ]; In Resistance_Cir; } } }",
              "        { Name cir_L; Value { Term { Type Global; [ Inductance[] ]; In Inductance_Cir; } } }",
              "      EndIf",
              "    }", "  }", "}"]
    step = []
    for k in range(1, nc + 1):
        step += [f'      Print[ I, OnRegion PF_Coil_{k}, Format Table, File > StrCat[OutDir, "coil_I_{k}.txt"] ];',
                 f'      Print[ U, OnRegion PF_Coil_{k}, Format Table, File > StrCat[OutDir, "coil_U_{k}.txt"] ];',
                 f'      Print[ P[PF_Coil_{k}], OnGlobal, Format Table, File > StrCat[OutDir, "coil_P_{k}.txt"] ];',
                 f'      Print[ F[PF_Coil_{k}], OnGlobal, Format Table, File > StrCat[OutDir, "coil_F_{k}.txt"] ];']
    for k in range(1, nk + 1):
        step += [f'      Print[ P[PF_Cond_{k}], OnGlobal, Format Table, File > StrCat[OutDir, "cond_P_{k}.txt"] ];',
                 f'      Print[ F[PF_Cond_{k}], OnGlobal, Format Table, File > StrCat[OutDir, "cond_F_{k}.txt"] ];']
    if circuit:
        step += ['      Print[ U, OnRegion Capacitance_Cir, Format Table, File > StrCat[OutDir, "cir_U.txt"] ];',
                 '      Print[ I, OnRegion Capacitance_Cir, Format Table, File > StrCat[OutDir, "cir_I.txt"] ];']
    elem = [f'      Print[ {q}, OnElementsOf PF_C, Depth 0, Format ElementTable, File > StrCat[OutDir, "elem_{q}.txt"] ];'
            for q in ("f", "F", "P", "b")]
    values = [f'      Print[ sigma_A[PF_Cond_{k}], OnGlobal, Format Table, File StrCat[OutDir, "cond_sigma_{k}.txt"] ];\n'
              f'      Print[ area[PF_Cond_{k}], OnGlobal, Format Table, File > StrCat[OutDir, "cond_sigma_{k}.txt"] ];'
              for k in range(1, nk + 1)]
    values += [f'      Print[ turns[PF_Coil_{k}], OnGlobal, Format Table, File StrCat[OutDir, "coil_turns_{k}.txt"] ];'
               for k in range(1, nc + 1)]
    for reg in [f"Coil_{k}" for k in range(1, nc + 1)] + [f"Cond_{k}" for k in range(1, nk + 1)]:
        values += [f'      Print[ {q}[PF_{reg}], OnGlobal, Format Table, File {"> " if q != "vol" else ""}'
                   f'StrCat[OutDir, "geo_{reg.lower()}.txt"] ];' for q in ("vol", "area", "xarea", "coefgeos")]
    if circuit:
        values += [f'      Print[ cir_{q}, OnRegion {g}, Format Table, File StrCat[OutDir, "cir_{q}.txt"] ];'
                   for q, g in (("C", "Capacitance_Cir"), ("R", "Resistance_Cir"), ("L", "Inductance_Cir"))]
        values.append('      Print[ U, OnRegion Capacitance_Cir, Format Table, File StrCat[OutDir, "cir_V0.txt"] ];')
    post = ["PostOperation {",
            "  { Name EM_Step; NameOfPostProcessing PF_Template; LastTimeStepOnly 1;",
            "    Operation {",
            '      Print[ W[Vol_Mag], OnGlobal, Format Table, File > StrCat[OutDir, "W.txt"] ];'] + step + [
            "    }", "  }",
            "  { Name EM_Elem; NameOfPostProcessing PF_Template; LastTimeStepOnly 1;",
            "    Operation {"] + elem + ["    }", "  }",
            "  { Name EM_State; NameOfPostProcessing PF_Template; LastTimeStepOnly 1;",
            '    Operation { Print[ raz, OnElementsOf PF_CS, Format NodeTable, File StrCat[OutDir, "nodes_a.txt"] ]; }',
            "  }",
            "  { Name EM_Field; NameOfPostProcessing PF_Template; LastTimeStepOnly 1;",
            "    Operation {",
            '      Print[ b, OnElementsOf Vol_Mag, Depth 0, Format ElementTable, File StrCat[OutDir, "field_b.txt"] ];',
            '      Print[ raz, OnElementsOf Vol_Mag, Format NodeTable, File StrCat[OutDir, "field_a.txt"] ];',
            "    }", "  }",
            "  { Name EM_Values; NameOfPostProcessing PF_Template; LastTimeStepOnly 1;",
            "    Operation {"] + values + ["    }", "  }", "}"]
    res = ["Resolution {",
           "  { Name EM_Transient;",
           f"    System {{ {{ Name {sys_}; NameOfFormulation {f}; }} }}",
           "    Operation {",
           "      SetTime[TimeInit]; // before InitSolution: restarted time derivatives need it",
           f"      InitSolution[{sys_}];",
           f"      If(PF_SaveInit) SaveSolution[{sys_}]; EndIf // BDF2's x_0: the deck's own initial state",
           "      If(Flag_Values) PostOperation[EM_Values]; EndIf",
           "      TimeLoopTheta[TimeInit, TimeFinal - 0.5*(TimeFinal - TimeInit)/NbSteps,",
           "                    (TimeFinal - TimeInit)/NbSteps, 1] {",
           f"        Generate[{sys_}]; Solve[{sys_}]; SaveSolution[{sys_}];",
           "        PostOperation[EM_Step];",
           "        If(Flag_ElemOut == 1) PostOperation[EM_Elem]; EndIf",
           "      }",
           "      If(Flag_ElemOut == 2) PostOperation[EM_Elem]; EndIf",
           "      PostOperation[EM_State];",
           "      If(Flag_FieldOut) PostOperation[EM_Field]; EndIf",
           "    }", "  }", "}", ""]
    return "\n".join(lines + post + res)


def current_mismatch(coil: Coil, times: np.ndarray, currents: np.ndarray) -> tuple[float, float, float] | None:
    """The first time at which a coil's current differs from its prescribed source, or None.

    Parameters
    ----------
    coil : Coil
        The case's coil (its ``waveform`` (A over s) and ``sign``); a coil on a bank is never a mismatch.
    times, currents : ndarray
        Times (s) and the coil current (A) the deck computed there (its ``Current_2D``).

    Returns
    -------
    tuple of float or None
        ``(t, wanted, got)`` (s, A, A) of the first time where ``|got - sign * waveform(t)|`` exceeds
        :data:`CURRENT_RTOL` times the larger of ``max |sign * waveform|`` over ``times`` and the
        source's amplitude.
    """
    if coil.waveform is None:
        return None
    times, got = np.asarray(times, float), np.asarray(currents, float)
    want = coil.sign * np.asarray(coil.waveform(times), float)
    amp = abs(coil.waveform.I0) if isinstance(coil.waveform, DampedSine) else float(np.abs(coil.waveform.values).max())
    bad = np.flatnonzero(~(np.abs(got - want) <= CURRENT_RTOL * max(float(np.abs(want).max(initial=0.0)), amp)))
    return None if not len(bad) else (float(times[bad[0]]), float(want[bad[0]]), float(got[bad[0]]))


class TemplateDeckSolver(GetDPSolver):
    """:class:`GetDPSolver` on a user's deck written on ``Lib_Magnetodynamics2D_av_Cir.pro``.

    Parameters
    ----------
    model : EMModel
        The case's EM model (coils, conductors, circuit: they select the tables).
    work_dir : str or Path
        Folder of the run folders.
    deck : str or Path
        The user's .pro, included unchanged.
    spec : TemplateSpec
        The user's formulation and pulseform's system name.
    deck_ids : dict of int to int
        The runner's physical id (1 air, 101 coil 1, 201 workpiece, 11 axis, ...) -> the deck's own id
        of that group; every run writes its mesh with the deck's ids.
    check_currents : bool
        After every step, compare each prescribed coil current the deck computed (its own
        ``Current_2D``) with the model's source (:func:`current_mismatch`) and raise
        :class:`TemplateDeckError` on a difference (the orchestrator's deck check turns it off: it
        names the case's keys itself).
    **kwargs
        Passed to :class:`GetDPSolver` (``time_scheme`` ``"euler"`` or ``"bdf2"``: both by restart).
    """

    def __init__(self, model: EMModel, work_dir: str | Path, *, deck: str | Path, spec: TemplateSpec,
                 deck_ids: dict[int, int], check_currents: bool = True, **kwargs):
        extra = dict(kwargs.pop("extra_numbers", None) or {})
        extra.setdefault("Flag_FrequencyDomain", 0.0)
        super().__init__(model, work_dir, deck=deck, extra_numbers=extra, **kwargs)
        self.spec = spec
        self.deck_ids = {int(k): int(v) for k, v in deck_ids.items()}
        missing = [coil_tag(k) for k in range(1, len(model.coils) + 1) if coil_tag(k) not in self.deck_ids]
        missing += [conductor_tag(k) for k in range(1, len(model.conductors) + 1)
                    if conductor_tag(k) not in self.deck_ids]
        if missing:
            raise TemplateDeckError(f"deck_ids lacks the runner's ids {missing}")
        self._lut = None
        self._first_run = False
        self.check_currents = check_currents
        self.bdf2_by_restart = True  # the Init path would lose against the deck's own circuit Init

    def _write_mesh(self, mesh: EMMesh, path: Path) -> Path:
        """The run's mesh with the deck's own physical ids (same nodes and elements in the same order)."""
        top = int(max(int(mesh.tri_tags.max(initial=0)), int(mesh.line_tags.max(initial=0)))) + 1
        lut = np.arange(max(top, max(self.deck_ids) + 1), dtype=np.int64)
        for runner_id, own in self.deck_ids.items():
            lut[runner_id] = own
        return write_msh22(EMMesh(mesh.points, mesh.triangles, lut[mesh.tri_tags], mesh.lines, lut[mesh.line_tags]),
                           path)

    def checked_numbers(self) -> list[str]:
        """The runner's numbers a template deck reads while it is parsed (the extra numbers:
        ``Flag_FrequencyDomain``, ``[geometry.parameters]``, the role ids; with a shell ``Val_Rint``,
        ``Val_Rext``, ``Val_Cx``, ``Val_Cy``): a deck's own plain assignment of one that differs from
        the runner's value stops getdp (:func:`runner_guard_lines`). ``Flag_Axi`` is left to the
        deck's geometry check (``template_deck.check_deck_values``)."""
        names = list(self.extra_numbers)
        if self.model.shell is not None:
            names += ["Val_Rint", "Val_Rext", "Val_Cx", "Val_Cy"]
        return names

    def _run_pro_text(self, data_lines: list[str]) -> str:
        """``run.pro``: the data lines, the runner's numbers saved, the deck, the runner's numbers again
        (:func:`runner_guard_lines`), then pulseform's wrapper (:func:`wrapper_text`)."""
        model = self.model
        before, after = runner_guard_lines(self.checked_numbers())
        text = ("// generated by pulseform.solvers.getdp.template for one run\n" + "\n".join(data_lines + before)
                + f'\nInclude "{self.deck}";\n' + "\n".join(after) + "\n")
        first = int(self._first_run)
        text += f"Flag_Values = {first}; // the first run from rest prints the deck's own values (EM_Values)\n"
        text += f"PF_SaveInit = {int(bool(first) and self.time_scheme == 'bdf2')}; // and saves x_0 of a BDF2 history\n"
        return text + wrapper_text(self.spec, [self.deck_ids[coil_tag(k)] for k in range(1, len(model.coils) + 1)],
                                   [self.deck_ids[conductor_tag(k)] for k in range(1, len(model.conductors) + 1)],
                                   model.circuit is not None, model.axisymmetric)

    def _bdf2_restart(self, run_dir: Path, state: EMState, t_end: float) -> tuple[float, str]:
        """BDF2 by restart (:mod:`.bdf2`): write ``run_dir/bdf2_start.res`` holding x_tilde = c1 x_{n-1}
        - c2 x_{n-2} (every unknown: the nodal a, the coils' and the circuit's currents and voltages)
        at t_end - gamma dt, and ``run_dir/bdf2_prev.res`` holding x_{n-1} for the next step.

        Returns
        -------
        tuple
            (t_end - gamma dt (s), the path of ``bdf2_start.res``).
        """
        dt = t_end - state.t
        _, x1 = read_solutions(state.res_path)[-1]
        hist = state.res_prev_path is not None and Path(state.res_prev_path).is_file() and state.dt_prev
        gamma, c1, c2 = bdf2_coefficients(dt, state.dt_prev if hist else None)
        x = c1 * x1 - c2 * read_solutions(state.res_prev_path)[-1][1] if hist else x1
        t_init = t_end - gamma * dt
        write_solution(run_dir / "bdf2_prev.res", state.t, x1)
        return t_init, str(write_solution(run_dir / "bdf2_start.res", t_init, x))

    def carry_to_mesh(self, state: EMState, old_mesh: EMMesh, new_mesh: EMMesh, old_node: np.ndarray,
                      run_name: str) -> EMState:
        """``state`` on a new connectivity (a remesh that kept the coil and conductor nodes), still carried
        by ``-restart``: a ``-pre`` run on ``new_mesh`` in ``work_dir/run_name`` numbers its dofs, and the
        last solution of ``state.res_path`` (with BDF2 also ``state.res_prev_path``) is renumbered from
        the ``.pre`` beside it (:mod:`.res_remap`) into ``carried.res`` (``bdf2_prev.res``) there.

        Parameters
        ----------
        state : EMState
            The state after the last step on ``old_mesh``.
        old_mesh, new_mesh : EMMesh
            The meshes before and after the remesh, at the same time (m).
        old_node : ndarray of int
            For each node of ``new_mesh``, its node in ``old_mesh`` (-1: a new air node).
        run_name : str
            Folder (under the solver's ``work_dir``) of the ``-pre`` run and the carried ``.res``.
        """
        from dataclasses import replace

        from .res_remap import read_pre_dofs, remap_solution
        from .runner import run_getdp
        from .solver import RESOLUTION

        if state.res_path is None:
            return state
        run_dir = self.work_dir / run_name
        run_dir.mkdir(parents=True, exist_ok=True)
        msh = self._write_mesh(new_mesh, run_dir / "mesh.msh")
        numbers = self.run_numbers(new_mesh)
        numbers.update(Flag_ElemOut=0, Flag_FieldOut=0, TimeInit=state.t, TimeFinal=state.t, NbSteps=1)
        if self.model.circuit is not None:
            numbers.update(Init_Vc=state.capacitor_voltage, Init_I=state.current)
        wrapper = run_dir / "run.pro"
        wrapper.write_text(self._run_pro_text(self.preamble + self._table_lines()))
        run_getdp(wrapper, msh, run_dir, resolution=RESOLUTION, numbers=numbers,
                  strings={"OutDir": str(run_dir) + "/"}, extra_args=self.petsc_args, executable=self.executable,
                  timeout=self.timeout, pre_only=True)
        new = read_pre_dofs(run_dir / "em.pre")

        def carry(res: str, name: str) -> str:
            old = read_pre_dofs(Path(res).parent / "em.pre")
            t, x = read_solutions(res)[-1]
            x_new = remap_solution(old, new, x, old_node, old_mesh.points, new_mesh.points)
            return str(write_solution(run_dir / name, t, x_new))

        prev = None
        if state.res_prev_path is not None and Path(state.res_prev_path).is_file():
            prev = carry(state.res_prev_path, "bdf2_prev.res")
        return replace(state, res_path=carry(state.res_path, "carried.res"), res_prev_path=prev,
                       mesh_signature=mesh_signature(new_mesh), pre_path=None)

    def step(self, mesh: EMMesh, state: EMState, t_end: float, n_sub: int = 1, *,
             material_points: np.ndarray | None = None, run_name: str | None = None,
             force_init_path: bool = False, element_output: str = "all",
             field_output: bool = False) -> tuple[EMStepResult, EMState]:
        """:meth:`GetDPSolver.step`, refusing a step that would need the Init path (a new connectivity,
        nodes that are not the previous material points, ``force_init_path``): a template deck's state
        travels by ``-restart`` only (module docstring)."""
        if state.res_path is not None:
            same = state.mesh_signature == mesh_signature(mesh) and Path(state.res_path).exists()
            if same and material_points is not None:
                same = self._nodes_are_material(mesh, np.asarray(material_points, float), state)
            if force_init_path or not same:
                raise TemplateDeckError("a template deck carries its state by -restart -res only (same mesh "
                                        "connectivity, nodes moving with the material); this step would need the "
                                        "Init path (InitA_List), which a template deck's circuit does not follow")
        self._first_run = state.res_path is None
        try:
            result, new_state = super().step(mesh, state, t_end, n_sub, material_points=material_points,
                                             run_name=run_name, force_init_path=force_init_path,
                                             element_output=element_output, field_output=field_output)
        finally:
            self._first_run = False
        if self.time_scheme == "bdf2":  # the whole x_{n-1} (x_0 after a start from rest) for the next step
            run_dir = Path(result.path)
            prev = run_dir / "bdf2_prev.res"
            if state.res_path is None:
                write_solution(prev, *read_solutions(run_dir / "em.res")[0])
            new_state.res_prev_path = str(prev)
        for k, coil in enumerate(self.model.coils if self.check_currents else [], start=1):  # the deck's own
            bad = current_mismatch(coil, result.times, result.coil_current[:, k - 1])
            if bad is not None:
                raise TemplateDeckError(f"coil {k}: the deck's Current_2D gives {bad[2]:.6g} A at t = {bad[0]:.6g} s, "
                                        f"the case's source {bad[1]:.6g} A (the deck's own current is used: make "
                                        "them agree)")
        return result, new_state
