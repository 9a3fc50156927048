"""Magnetic materials on a user's deck (issue 35): what the case loader reads in a ``.pro`` on ``PulseformLib``
before any getdp run.

The runner's magnetic block (``solvers/getdp/decks/em_magnetic.pro``, the string ``PulseformMagneticLib`` of
``run.pro``) defines ``nu[]`` on every region of the deck's ``Vol_Mag`` from the numbers the runner passes (each
conductor's ``Cond_Mag_<k>``, ``Cond_MuR_<k>``, the B–H tables ``Cond_BH_<k>()``), and ``Vol_NL_Mag`` with the
curve's ``dnudb2[]`` / ``wmag[]`` (Newton's iterations of ``Lib_Newton.pro``, whose ``newton.txt`` the runner
reads). A deck that keeps ``nu[]`` of its own would run the case's magnetic material in vacuum without a word,
and a deck's own ``Vol_NL_Mag`` would run Newton's iterations whose convergence the runner never reads: both are
refused here in one line (and the deck check confirms the Newton table at run time,
:mod:`pulseform.orchestrator.em.deck_check`). docs/workflow.md, "Magnetic materials on a user deck".
"""

from __future__ import annotations

from pathlib import Path

from .deck_files import _assigned, assignment_sites, deck_files_tokens

__all__ = ["MAGNETIC_LIB", "deck_magnetic_problem", "magnetic_deck_refusal", "own_nu_sites"]

#: the runner's name of its magnetic block (an absolute path in ``run.pro``)
MAGNETIC_LIB = "PulseformMagneticLib"
#: the block's numbers a deck must not assign itself (a plain assignment beats ``-setnumber``), per conductor role
_BLOCK_NUMBERS = tuple(f"{n}_{k}" for n in ("Cond_Mag", "Cond_MuR") for k in (1, 2)) + ("NL_tol_rel", "NL_tol_abs",
                                                                                       "NL_iter_max")


def _shown(deck: Path, file: Path) -> str:
    """``file`` named from the deck's folder when it lies inside it."""
    return str(file.relative_to(deck.parent) if file.is_relative_to(deck.parent) else file)


def own_nu_sites(deck: Path) -> list[str]:
    """``file:line`` of every ``nu[...] = ...`` definition in the deck ``deck`` and the files it ``Include``s by
    name (not the runner's libraries), in reading order."""
    out = []
    for file, tokens in deck_files_tokens(Path(deck)):
        for i, (kind, tok, line) in enumerate(tokens):
            if kind != "id" or tok != "nu" or i + 1 >= len(tokens) or tokens[i + 1][1] != "[":
                continue
            depth, j = 0, i + 1
            while j < len(tokens):
                if tokens[j][0] == "other" and tokens[j][1] == "[":
                    depth += 1
                elif tokens[j][0] == "other" and tokens[j][1] == "]":
                    depth -= 1
                    if depth == 0:
                        break
                j += 1
            if j + 1 < len(tokens) and tokens[j + 1][1] == "=" and (j + 2 >= len(tokens) or tokens[j + 2][1] != "="):
                out.append(f"{_shown(Path(deck), file)}:{line}")
    return out


def _includes_block(deck: Path) -> bool:
    """The deck (or a file it includes by name) has ``Include PulseformMagneticLib``."""
    for _, tokens in deck_files_tokens(Path(deck)):
        if any(a[1] == "Include" and b[1] == MAGNETIC_LIB for a, b in zip(tokens, tokens[1:])):
            return True
    return False


def deck_magnetic_problem(deck: Path) -> str | None:
    """Why a deck on ``PulseformLib`` misuses the magnetic names (one phrase naming ``file:line`` and the fix), or
    None: its own ``Vol_NL_Mag`` (Newton's iterations the runner would not check), an assignment of the block's
    numbers (it beats the runner's ``-setnumber``), ``nu[]`` of its own beside ``Include PulseformMagneticLib``."""
    deck = Path(deck)
    for file, tokens in deck_files_tokens(deck):
        for i, (kind, tok, line) in enumerate(tokens):
            if kind == "id" and tok == "Vol_NL_Mag" and _assigned(tokens, i):
                return (f"{_shown(deck, file)}:{line} assigns Vol_NL_Mag (Newton's iterations the runner does not "
                        f"check): give the curve as materials.<name>.bh_curve and Include {MAGNETIC_LIB}")
    sites = assignment_sites(deck, _BLOCK_NUMBERS)
    if sites:
        name, file, line, _ = sites[0]
        return (f"{_shown(deck, file)}:{line} assigns {name}, which the runner sets from the case's materials "
                "(a plain assignment beats -setnumber); remove it")
    own = own_nu_sites(deck)
    if own and _includes_block(deck):
        return (f"{own[0]} defines nu[] and the deck includes {MAGNETIC_LIB}, which defines nu[] on every region of "
                "Vol_Mag: remove the deck's own nu[]")
    return None


def magnetic_deck_refusal(g, key: str) -> str | None:
    """Why the user deck ``g`` (a ``[geometry] type = "user_deck"``) cannot run the magnetic material of the case
    key ``key`` (``materials.<name>.relative_permeability`` / ``.bh_curve``; one phrase naming the deck and the
    fix), or None when it includes the runner's magnetic block (and has no nu[] of its own:
    :func:`deck_magnetic_problem`, checked when the case is loaded)."""
    deck = Path(g.pro)
    if getattr(g, "library", "pulseform") == "getdp_template":
        return (f"a deck on GetDP's template ({deck.name}) keeps its own materials: set its nu[] in the deck, or put "
                f"the deck on PulseformLib and Include {MAGNETIC_LIB}")
    if not _includes_block(deck):
        own = own_nu_sites(deck)
        where = f" (its nu[] at {own[0]} runs this material in vacuum)" if own else ""
        return f"deck {deck.name} has no Include {MAGNETIC_LIB}{where}: write it in place of its nu[]"

    return None
