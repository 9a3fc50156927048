"""The README's case-file reference is the one generated from the schema."""

from pathlib import Path

from pulseform.orchestrator.case.reference import END, START, case_reference_markdown

README = Path(__file__).resolve().parents[2] / "README.md"


def test_readme_reference_in_step_with_schema():
    text = README.read_text()
    inside = text.split(START, 1)[1].split(END, 1)[0]
    assert inside.strip() == case_reference_markdown().strip(), \
        "README case reference is stale: run .venv/bin/python scripts/update_readme_reference.py"


def test_readme_names_the_two_commands():
    text = README.read_text()
    assert "bash scripts/demo.sh" in text and "bash scripts/test.sh" in text

