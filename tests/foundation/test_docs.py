"""The documentation: the generated reference pages are the ones the schema and the parser give, the
README stays short and names its commands, and (marker ``docs``) the site builds with no warning."""

import importlib.util
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pulseform.orchestrator.case.reference import END, START, case_reference_markdown

REPO = Path(__file__).resolve().parents[2]
README = REPO / "README.md"
README_MAX_BYTES = 15 * 1024


def _generator():
    spec = importlib.util.spec_from_file_location("update_reference", REPO / "scripts/update_reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_case_file_reference_in_step_with_schema():
    text = (REPO / "docs/reference/case-file.md").read_text()
    inside = text.split(START, 1)[1].split(END, 1)[0]
    assert inside.strip() == case_reference_markdown().strip(), \
        "docs/reference/case-file.md is stale: run .venv/bin/python scripts/update_reference.py"


def test_generated_pages_in_step():
    gen = _generator()
    stale = "is stale: run .venv/bin/python scripts/update_reference.py"
    assert gen.CASE_FILE_PAGE.read_text() == gen.case_file_page(), f"{gen.CASE_FILE_PAGE} {stale}"
    assert gen.CLI_PAGE.read_text() == gen.cli_page(), f"{gen.CLI_PAGE} {stale}"


def test_readme_names_the_two_commands():
    text = README.read_text()
    assert "bash scripts/demo.sh" in text and "bash scripts/test.sh" in text


def test_readme_is_short_and_names_the_docs_command():
    size = README.stat().st_size
    assert size <= README_MAX_BYTES, f"README.md is {size} bytes, above {README_MAX_BYTES}: move text to docs/"
    text = README.read_text()
    assert "bash scripts/docs.sh" in text and "site/index.html" in text


def test_readme_links_resolve():
    """Relative links and pictures of the README point at files of the repository."""
    for target in re.findall(r"\]\(([^)#\s]+)", README.read_text()):
        if "://" not in target:
            assert (REPO / target).exists(), target


@pytest.mark.docs
def test_site_builds_strict(tmp_path):
    """`mkdocs build --strict` (what scripts/docs.sh runs) into a temporary folder: no warning."""
    if importlib.util.find_spec("mkdocs") is None:  # (Debian's mkdocs-material has no entry point to look for)
        pytest.fail("mkdocs missing: run `bash scripts/docs.sh` once (installs Debian's mkdocs packages)")
    start = time.monotonic()
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                       cwd=REPO, capture_output=True, text=True, env={**os.environ, "NO_COLOR": "1"}, timeout=600)
    log = r.stdout + r.stderr
    assert r.returncode == 0, log[-3000:]
    assert "WARNING" not in log, log[-3000:]
    assert (tmp_path / "site/index.html").is_file() and (tmp_path / "site/reference/api/case.html").is_file()
    print(f"site built in {time.monotonic() - start:.1f} s")


def test_current_keys_say_peak_per_turn():
    """Issue 32, item 10: what a prescribed current means (the peak current of one turn, not rms) is said at each
    key that sets one, so the generated reference carries it (it was in one case file's comment only)."""
    from pulseform.orchestrator.case.model import Case
    from pulseform.orchestrator.case.schema import reference_rows

    rows = {}
    for key, *_, doc in reference_rows(Case):
        rows.setdefault(key, []).append(doc)
    for key in ("em.current.amplitude", "em.sources[].amplitude"):
        assert any("peak current of one turn, not rms" in d for d in rows[key]), (key, rows[key])
    assert any("of one turn" in d for d in rows["em.sources[].current"])
