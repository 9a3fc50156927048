"""The check shared by the bad-input tests of the case files: ``pulseform check CASE --set ...`` in process
ends with exit 2 and exactly one line on stderr, ``pulseform: error: <case.toml> ...``, naming the key."""
from __future__ import annotations

from pulseform.orchestrator.cli import main


def one_line_refusal(capsys, case: str, sets: list[str], says: str) -> str:
    """Run the check of ``case`` with the ``--set`` overrides ``sets``; assert the one-line refusal that
    contains ``says`` and names the case file; return the line."""
    args = ["check", case]
    for s in sets:
        args += ["--set", s]
    rc = main(args)
    _, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2, err
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("pulseform: error: ") and says in lines[0] and "case.toml" in lines[0], lines[0]
    return lines[0]
