"""The runner's numbers a template deck cannot take over: a plain assignment in a deck (``TimeFinal = 10e-6;``,
as GetDP's own examples set their time window) beats getdp's ``-setnumber``, so the generated ``run.pro`` saves
the runner's numbers before ``Include "<deck>";`` and assigns them again after it, and stops getdp where a deck
changed one that it reads itself while parsed (issue 32)."""
from __future__ import annotations

from typing import Sequence

__all__ = ["RESTORED_NUMBERS", "RESTORED_STRINGS", "SAVED_PREFIX", "OVERRIDE_ERROR", "OVERRIDE_RTOL",
           "runner_guard_lines"]

#: the runner's numbers pulseform's wrapper reads after the deck: a deck's own plain assignment of one
#: (``TimeFinal = 10e-6;``, as GetDP's examples set their time window) beats ``-setnumber``, so ``run.pro``
#: saves them before the deck and assigns them again after it (:func:`runner_guard_lines`)
RESTORED_NUMBERS = ("TimeInit", "TimeFinal", "NbSteps", "Flag_ElemOut", "Flag_FieldOut")
#: the runner's strings restored the same way
RESTORED_STRINGS = ("OutDir",)
#: prefix of the saved copies in ``run.pro``
SAVED_PREFIX = "PF_Runner_"
#: the first words of the getdp error of a deck that assigned a number the runner sets and the deck
#: itself reads (:func:`runner_guard_lines`): ``<OVERRIDE_ERROR> NAME = deck value, runner value``
OVERRIDE_ERROR = "pulseform: the deck overrides"
#: relative difference above which a deck's value of a runner number counts as its own
OVERRIDE_RTOL = 1e-12


def runner_guard_lines(checked: Sequence[str]) -> tuple[list[str], list[str]]:
    """The lines of ``run.pro`` around ``Include "<deck>";`` that keep the runner's numbers the runner's.

    A plain assignment in a deck (``TimeFinal = 10e-6;``) beats getdp's ``-setnumber``. The lines
    before the deck save every runner number and string of :data:`RESTORED_NUMBERS`,
    :data:`RESTORED_STRINGS` and ``checked`` (all given with ``-setnumber`` / ``-setstring`` in every
    run) as ``PF_Runner_<name>``; the lines after it assign the restored ones again (the wrapper reads
    them only after the deck: the deck runs unchanged) and stop getdp with an ``Error`` starting with
    :data:`OVERRIDE_ERROR` when a ``checked`` number (one the deck or GetDP's template reads while the
    deck is parsed: the shell radii, ``Flag_FrequencyDomain``, ``[geometry.parameters]``) differs from
    the runner's by more than :data:`OVERRIDE_RTOL` relative: the runner cannot undo that.

    Returns
    -------
    tuple of list of str
        (lines before the deck, lines after it).
    """
    checked = [n for n in dict.fromkeys(checked) if n not in RESTORED_NUMBERS]
    before = [f"{SAVED_PREFIX}{n} = {n};" for n in (*RESTORED_NUMBERS, *checked)]
    before += [f"{SAVED_PREFIX}{n} = Str[{n}];" for n in RESTORED_STRINGS]
    after = ["// the runner's numbers win over the deck's own assignments (pulseform.solvers.getdp.template)"]
    after += [f"{n} = {SAVED_PREFIX}{n};" for n in RESTORED_NUMBERS]
    after += [f"{n} = Str[{SAVED_PREFIX}{n}];" for n in RESTORED_STRINGS]
    for n in checked:
        s = SAVED_PREFIX + n
        after.append(f"If(Fabs[{n} - {s}] > {OVERRIDE_RTOL:g} * (Fabs[{n}] + Fabs[{s}])) "
                     f'Error[Sprintf["{OVERRIDE_ERROR} {n} = %.17g, runner %.17g", {n}, {s}]]; EndIf')
    return before, after
