"""The case-specific analyses a case file may name in ``analysis = [...]``, and where each lives.

Data only (no imports): the case model checks the names against it while validating a case file
(which must not import the solvers), and :mod:`pulseform.orchestrator.run.analyses` creates an
analysis from it, importing its module only then.
"""

from __future__ import annotations

__all__ = ["ANALYSES", "ANALYSIS_PAIRS"]

#: name -> "module:Class" of its implementation inside ``pulseform.orchestrator.run.analyses``
ANALYSES: dict[str, str] = {
    "corner_fill": "corner_fill:CornerFill",
    "tube_press_fit": "tube_press_fit:TubePressFit",
}

#: name -> the (slave, master) bodies whose soft-contact pair the analysis reads: both deformable
#: bodies of the case, with a [[contact]] pair slave -> master
ANALYSIS_PAIRS: dict[str, tuple[str, str]] = {
    "corner_fill": ("blank", "die"),
    "tube_press_fit": ("inner", "outer"),
}
