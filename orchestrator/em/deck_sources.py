"""The source of a deck on GetDP's template, read from the deck (issue 32, item 2).

A case on a template deck (``geometry.library = "getdp_template"``, one coil: ``geometry.regions.coil``)
may leave out ``em.circuit`` and ``em.current``: the deck's own source is read through getdp and the
case takes it, so that a number the deck holds is stated once, and ``--set geometry.parameters.<name>=...``
changes the deck and the case at once.

* **Which source**: a parse-only getdp run of the deck with the run's ``-setnumber`` numbers
  (:func:`deck_has_bank`) prints the template's ``Flag_CircuitCoupling`` and the number of regions of
  its ``Capacitance_Cir``: both non-zero, the deck has a capacitor bank.
* **A bank**: the deck check's first run prints the deck's own C, R, L and the capacitor's voltage at
  the start (:func:`.template_deck.deck_values`, the ``EM_Values`` tables ``cir_*.txt``); they become
  ``em.circuit`` (:func:`with_deck_sources`). GetDP prints them with 16 digits: the shipped example's
  50e-6 F, 6e3 V, 0.01 Ohm, 2e-6 H are read exactly.
* **A prescribed current** (the template's ``Current_2D`` on the coil, no circuit): getdp runs the deck
  for :data:`SAMPLES` steps from rest and prints the coil current it imposes after each; a damped sine
  I0 e^(-beta t) sin(omega t) sampled at t_k = k h obeys x_(k+1) = p x_k - q x_(k-1) exactly, with
  p = 2 e^(-beta h) cos(omega h) and q = e^(-2 beta h) (:func:`damped_sine_from_samples`). Samples at
  the check's step :data:`~.deck_check.CHECK_STEP_S` give a first estimate; a second run at
  h = 1/max(omega, beta) (a well-conditioned angle) gives the values, and every sample of both runs must
  then follow the fitted current to :data:`SAMPLE_RTOL` of the largest, else the deck's current is
  not of that form and the case must state its source. Measured on
  tests/workflow/template_decks/current_template.pro (20 kA, 1e4 1/s, 1e5 rad/s): the values to
  ~1e-15 relative, the samples to ~1e-15 of the largest.
"""

from __future__ import annotations

import logging
import math
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..case.em_table import CapacitorBank, DampedSineCurrent
from .deck_check import CHECK_STEP_S, DeckContractError

log = logging.getLogger(__name__)

#: steps of one sampling run of a deck's prescribed current (four give p and q, the fifth checks them)
SAMPLES = 5
#: largest difference between a sample of the deck's current and the fitted damped sine, relative to the
#: largest sample (measured ~1e-15 on the test deck: getdp prints 16 digits)
SAMPLE_RTOL = 1e-9
#: the bank's keys in ``em.circuit``, the deck's value key (:func:`.template_deck.deck_values`), unit, and
#: the deck's name of it
BANK_KEYS = (("capacitance", "C", "F", "Capacitance[] of Capacitance_Cir"),
             ("voltage", "V0", "V", "the capacitor's Init voltage"),
             ("resistance", "R", "Ohm", "Resistance[] of Resistance_Cir"),
             ("inductance", "L", "H", "Inductance[] of Inductance_Cir"))
#: the prescribed current's keys in ``em.current``, the deck's value key, unit
CURRENT_KEYS = (("amplitude", "I0", "A"), ("beta", "beta", "1/s"), ("omega", "omega", "rad/s"))


def sources_left_to_deck(case) -> bool:
    """The case is coupled on a deck on GetDP's template and states no source (no ``em.circuit``,
    ``em.current`` nor ``[[em.sources]]``): the deck's own is read (:func:`with_deck_sources`)."""
    g, em = case.geometry, case.em
    return (case.case.kind == "coupled" and getattr(g, "library", None) == "getdp_template" and em is not None
            and not (em.circuit or em.current or em.sources))


def parse_deck(deck: Path, numbers: list[str], lines: list[str], table: str, work: Path,
               time_limit: float) -> str | None:
    """Parse ``deck`` with getdp (no mesh, no resolution) and the ``-setnumber`` arguments ``numbers``,
    followed by ``lines`` that write ``work/<table>`` (``{table}`` in them is that path): the table's
    text, or None when getdp failed or wrote nothing (log ``work/<table stem>.log``)."""
    from pulseform.solvers.getdp.runner import find_getdp, run_logged

    work = Path(work).resolve()
    work.mkdir(parents=True, exist_ok=True)
    out, stem = work / table, Path(table).stem
    pro = work / f"{stem}.pro"
    pro.write_text("\n".join([f'Include "{Path(deck).resolve()}";'] + [ln.replace("{table}", str(out))
                                                                         for ln in lines]) + "\n")
    out.unlink(missing_ok=True)
    try:
        code, _ = run_logged([find_getdp(), str(pro), *numbers, "-v", "2"], work, work / f"{stem}.log", time_limit)
    except (OSError, subprocess.TimeoutExpired, RuntimeError) as exc:
        log.debug("getdp could not parse %s: %s", deck, exc)
        return None
    if code != 0 or not out.is_file():
        log.debug("getdp could not parse %s: exit code %s (%s)", deck, code, work / f"{stem}.log")
        return None
    return out.read_text()


def setnumber_args(numbers: dict[str, float]) -> list[str]:
    """``-setnumber NAME value`` for every number, as the runner passes them."""
    return [a for k, v in numbers.items() for a in ("-setnumber", k, repr(float(v)))]


def deck_has_bank(solver, mesh, work: Path, time_limit: float) -> bool:
    """Whether the template deck of ``solver`` has a capacitor bank with the run's numbers (those of
    ``solver.run_numbers(mesh)``): its ``Flag_CircuitCoupling`` and a non-empty ``Capacitance_Cir``
    (a parse-only getdp run in ``work``). False also when getdp cannot parse it: the deck check then
    names the error."""
    lines = ["PF_Bank = 0;", "If(Exists[Flag_CircuitCoupling])", "  If(Flag_CircuitCoupling)",
             "    PF_Bank = NbrRegions[Capacitance_Cir];", "  EndIf", "EndIf",
             'Printf[Sprintf["%g", PF_Bank]] > "{table}";']
    text = parse_deck(solver.deck, setnumber_args(solver.run_numbers(mesh)), lines, "bank.txt", work, time_limit)
    try:
        return text is not None and float(text.split()[0]) > 0
    except (IndexError, ValueError):
        return False


def damped_sine_from_samples(h: float, x: np.ndarray) -> tuple[float, float, float]:
    """(I0 (A), beta (1/s), omega (rad/s)) of I(t) = I0 e^(-beta t) sin(omega t) from its samples
    x_k = I(k h), k = 1 ... n (n >= 4), through the recurrence x_(k+1) = p x_k - q x_(k-1) of the
    first four (module docstring).

    Raises
    ------
    ValueError
        The samples are not of that form (not oscillating, growing, not zero at t = 0, a negative
        amplitude, or a later sample off the recurrence by more than :data:`SAMPLE_RTOL`): the message
        says which.
    """
    x = np.asarray(x, float)
    scale = float(np.abs(x).max(initial=0.0))
    if len(x) < 4 or not np.all(np.isfinite(x)) or scale == 0.0:
        raise ValueError("no current" if scale == 0.0 else "too few or not finite samples")
    x1, x2, x3, x4 = x[:4]
    det = x1 * x3 - x2 * x2
    if det == 0.0:
        raise ValueError("not oscillating")
    p, q = (x1 * x4 - x2 * x3) / det, (x2 * x4 - x3 * x3) / det
    if not q > 0.0:
        raise ValueError("not a damped oscillation")
    c = p / (2.0 * math.sqrt(q))
    if not -1.0 < c < 1.0:
        raise ValueError("not oscillating (a sum of exponentials)")
    beta, omega = -math.log(q) / (2.0 * h), math.acos(c) / h
    if beta < 0.0:
        if beta * h < -1e-12:
            raise ValueError(f"growing (beta = {beta:.6g} 1/s)")
        beta = 0.0
    amp = x1 / (math.exp(-beta * h) * math.sin(omega * h))
    t = h * np.arange(0, len(x) + 1)
    fit = amp * np.exp(-beta * t) * np.sin(omega * t)
    x0 = (p * x1 - x2) / q
    if abs(x0) > SAMPLE_RTOL * scale:
        raise ValueError(f"I(0) = {x0:.6g} A, not 0")
    off = float(np.abs(fit[1:] - x).max())
    if off > SAMPLE_RTOL * scale:
        raise ValueError(f"a sample is off by {off / scale:.2g} of the largest")
    if amp < 0.0:
        raise ValueError(f"a negative amplitude {amp:.6g} A")
    return float(amp), float(beta), float(omega)


def _samples(solver, mesh, h: float, run_name: str) -> np.ndarray:
    """The deck's coil current after each of :data:`SAMPLES` steps of ``h`` (s) from rest."""
    result, _ = solver.step(mesh, solver.initial_state(0.0), SAMPLES * h, SAMPLES, run_name=run_name,
                            element_output="none")
    return np.asarray(result.coil_current[:, 0], float)


def deck_current(solver, mesh, group: str) -> dict[str, float]:
    """The damped sine the template deck of ``solver`` prescribes on its one coil (``Current_2D``), as
    ``{"I0": A, "beta": 1/s, "omega": rad/s}``: two sampling runs in ``solver.work_dir`` (module
    docstring). ``group``: the coil's physical group (messages).

    Raises
    ------
    DeckContractError
        One line: the deck's current is not a damped sine I0 e^(-beta t) sin(omega t), and what to state.
    """
    deck = Path(solver.deck).name
    solver.check_currents = False  # the model's current is a placeholder until read here
    x1 = _samples(solver, mesh, CHECK_STEP_S, "source_samples_1")
    try:
        _, beta, omega = damped_sine_from_samples(CHECK_STEP_S, x1)
        h = 1.0 / max(omega, beta)
        x2 = _samples(solver, mesh, h, "source_samples_2")
        amp, beta, omega = damped_sine_from_samples(h, x2)
        t1 = CHECK_STEP_S * np.arange(1, SAMPLES + 1)
        off = float(np.abs(amp * np.exp(-beta * t1) * np.sin(omega * t1) - x1).max())
        if off > SAMPLE_RTOL * float(np.abs(x1).max()):
            raise ValueError(f"its first microseconds are off the fitted current by {off:.3g} A")
    except ValueError as exc:
        raise DeckContractError(
            f"deck {deck}: the current its Current_2D prescribes on {group} is not I0 e^(-beta t) sin(omega t) "
            f"({exc}): state the coil's source in case.toml, em.current (amplitude, beta, omega) or [[em.sources]] "
            "with [[em.coils]]") from None
    log.info("deck %s prescribes I(t) = %.9g A e^(-%.9g t) sin(%.9g t) on %s", deck, amp, beta, omega, group)
    return {"I0": amp, "beta": beta, "omega": omega}


def with_deck_sources(case, values: dict[str, float | str]):
    """``case`` with the source its template deck holds (``values``: :func:`.template_deck.deck_values`
    with ``C``, ``R``, ``L``, ``V0`` of a bank or ``I0``, ``beta``, ``omega`` of :func:`deck_current`) as
    ``em.circuit`` or ``em.current``; ``case`` itself when it states a source.

    Raises
    ------
    DeckContractError
        The deck's bank has a value the case's keys refuse (C or V0 <= 0, R or L < 0), or the geometry is
        planar (a case's bank is axisymmetric only).
    """
    if not sources_left_to_deck(case):
        return case
    deck = Path(case.geometry.pro).name
    if "C" in values:
        bank = {key: float(values[v]) for key, v, _, _ in BANK_KEYS}
        for key, v, unit, what in BANK_KEYS:
            strict = key in ("capacitance", "voltage")
            if not (bank[key] > 0.0 if strict else bank[key] >= 0.0):
                raise DeckContractError(f"deck {deck}: its bank's {what} = {bank[key]:.6g} {unit}; em.circuit.{key} "
                                        f"must be {'>' if strict else '>='} 0: state em.circuit in case.toml")
        if case.geometry.planar:
            raise DeckContractError(f"deck {deck}: a planar deck's capacitor bank (per metre of depth) is not "
                                    "pulseform's: state a prescribed em.current in case.toml")
        return replace(case, em=replace(case.em, circuit=CapacitorBank(**bank)))
    if "I0" in values:
        current = {key: float(values[v]) for key, v, _ in CURRENT_KEYS}
        return replace(case, em=replace(case.em, current=DampedSineCurrent(**current)))
    raise DeckContractError(f"deck {deck}: no source was read from it (neither a bank nor a prescribed current): "
                            "state em.circuit or em.current in case.toml")


def unread_sources(case, bank: bool):
    """``case`` with a placeholder for the source it leaves to its deck, before the deck check has read it:
    a bank or a prescribed current whose values are :data:`.template_deck.UNREAD` (NaN; a template deck reads
    none of the runner's source numbers, and the check compares only what the case states)."""
    from .template_deck import UNREAD

    if not sources_left_to_deck(case):
        return case
    if bank:
        em = replace(case.em, circuit=CapacitorBank(capacitance=UNREAD, voltage=UNREAD, resistance=UNREAD,
                                                    inductance=UNREAD))
    else:
        em = replace(case.em, current=DampedSineCurrent(amplitude=UNREAD, beta=UNREAD, omega=UNREAD))
    return replace(case, em=em)


def source_summary(case, values: dict[str, float | str]) -> list[str]:
    """The phrases of ``pulseform check``'s "the case takes from <deck>" line for the source the case
    leaves to the deck: ``em.circuit.capacitance = 5e-05 F (Capacitance[] of Capacitance_Cir)``, ..."""
    if not sources_left_to_deck(case):
        return []
    if "C" in values:
        return [f"em.circuit.{key} = {float(values[v]):.6g} {unit} ({what})" for key, v, unit, what in BANK_KEYS]
    if "I0" in values:
        group = case.geometry.regions.coil
        return [", ".join(f"em.current.{key} = {float(values[v]):.9g} {unit}" for key, v, unit in CURRENT_KEYS)
                + f" (Current_2D on {group})"]
    return []


def resolve_deck_sources(case):
    """``case`` with its template deck's source (:func:`with_deck_sources`) when it leaves it to the deck:
    the deck is meshed and checked once in a temporary folder (:func:`.user_deck.checked_in_temporary`,
    the source read there), which is removed. ``case`` itself otherwise (no getdp run).

    Raises
    ------
    DeckContractError
        One line naming what is wrong with the deck or its source.
    """
    if not sources_left_to_deck(case):
        return case
    from .user_deck import checked_in_temporary

    return with_deck_sources(case, checked_in_temporary(case).deck_values)
