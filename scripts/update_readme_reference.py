"""Rewrite the generated case-file reference inside README.md (between its markers)."""

from pathlib import Path

from pulseform.orchestrator.case.reference import END, START, case_reference_markdown

readme = Path(__file__).resolve().parents[1] / "README.md"
text = readme.read_text()
head, rest = text.split(START, 1)
_, tail = rest.split(END, 1)
readme.write_text(head + START + "\n" + case_reference_markdown() + END + tail)
