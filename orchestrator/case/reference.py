"""Generate the case-file reference (Markdown) from the schema declarations in :mod:`.case`.

``python -m pulseform.orchestrator.case.reference`` prints it; the documentation's case-file reference
page (docs/reference/case-file.md, written by scripts/update_reference.py) holds a copy between the
markers ``<!-- case-reference:start -->`` and ``<!-- case-reference:end -->``, kept in step by a test.
"""

from __future__ import annotations

import sys

from .model import Case
from .schema import PLAUSIBLE, PLAUSIBLE_OTHER, reference_rows

START, END = "<!-- case-reference:start -->", "<!-- case-reference:end -->"


def case_reference_markdown() -> str:
    """The table of every case key: key path, allowed values, unit, default, meaning. The cells other
    than the key are escaped Markdown text: ``\\|`` and ``\\[`` (``[a] [b]`` would be a reference link)."""
    lines = ["| key | allowed | unit | default | meaning |", "|---|---|---|---|---|"]
    for key, *cells in reference_rows(Case):
        allowed, unit, default, doc = (c.replace("|", "\\|").replace("[", "\\[") for c in cells)
        lines.append(f"| `{key}` | {allowed} | {unit} | {default} | {doc} |")
    return "\n".join(lines) + "\n"


def plausible_ranges_markdown() -> str:
    """The table of :data:`~.schema.PLAUSIBLE`: per unit, the smallest non-zero and the largest |value|."""
    lines = ["| unit | smallest non-zero \\|value\\| | largest \\|value\\| |", "|---|---|---|"]
    lines += [f"| `{unit}` | {lo:g} | {hi:g} |" for unit, (lo, hi) in PLAUSIBLE.items()]
    lines.append(f"| other (e.g. `geometry.parameters`) | - | {PLAUSIBLE_OTHER[1]:g} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":  # pragma: no cover
    sys.stdout.write(case_reference_markdown())
