"""The resolved case a run writes (``results/<case>/case.toml``) reads back as the same case.

:func:`load_resolved_case` (what ``pulseform plot`` and the pictures read) gives back the case of every shipped
case file; where the case names no file of its own (decks, geometry files, tables: those are stored by absolute
path), the resolved text is also a valid case file again: ``pulseform run results/<case>/case.toml`` repeats the
run. A 3D case is written without the 2D-only keys the loader refuses in a 3D file (``mechanics.thickness``).
"""

from pathlib import Path

import pytest

from pulseform.orchestrator.case.io import case_to_toml, load_case, load_resolved_case

REPO = Path(__file__).resolve().parents[2]
CASE_FILES = sorted((REPO / "cases").glob("*/*.toml"))


def _names_files(text: str) -> bool:
    return str(REPO / "cases") in text


@pytest.mark.parametrize("file", CASE_FILES, ids=[f"{f.parent.name}/{f.name}" for f in CASE_FILES])
def test_the_resolved_case_reads_back_as_the_case(tmp_path, file):
    case = load_case(str(file), [])[0]
    text = case_to_toml(case)
    stored = tmp_path / "case.toml"
    stored.write_text(text, encoding="utf-8")
    assert load_resolved_case(stored) == case
    if not _names_files(text):
        assert load_case(str(stored), [])[0] == case


def test_a_3d_case_is_written_without_2d_only_keys():
    case = load_case(str(REPO / "cases/bar_impact_3d"), [])[0]
    text = case_to_toml(case)
    assert "thickness" not in text.split("[mechanics]", 1)[1].split("\n[", 1)[0]
