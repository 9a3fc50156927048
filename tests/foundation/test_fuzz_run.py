"""Slow tier (issue 13): a sample of the fuzz mutations of tests/foundation/test_fuzz_check.py goes
through `pulseform run` as its own process under a 3 GB address-space limit and a wall-time limit.

Whatever the mutation, the run must end by itself with 0 (it ran), 1 (it started and failed: one
`pulseform: error:` line, optionally followed by an external program's log tail) or 2 (refused: one
line), never by a signal, never with a traceback, and a refused mutation (see `must_refuse`) with 2.
"""

from __future__ import annotations

import random
import resource
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from test_fuzz_check import Mutation, must_refuse, mutations

REPO = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).with_name("pulseform"))
MEMORY_LIMIT = 3 * 1024 ** 3  # bytes of address space (a normal run of these cases needs < 2 GB)
RUN_LIMIT_S = 600.0
#: (case, mutations drawn): a mechanics case and the coupled demo
SAMPLE = {"bar_impact": 20, "emf_sheet_bulge": 12}
#: mutation kinds that leave a case `check` may accept
MAY_RUN = {"scaled", "zero_negative", "delete", "set", "tiny", "tiny_length", "long_time", "unicode", "truncated"}


def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def _loads(original: Path, m: Mutation) -> bool:
    """Whether the case of mutation ``m`` validates (so that `run` really runs it)."""
    import tempfile

    from pulseform.orchestrator.case.io import CaseError, load_case

    with tempfile.TemporaryDirectory() as tmp:
        file = Path(tmp) / "case.toml"
        text = original.read_text() if m.text is None else m.text
        (file.write_bytes if isinstance(text, bytes) else file.write_text)(text)
        try:
            load_case(file, list(m.sets))
        except CaseError:
            return False
    return True


def _sample() -> list[tuple[str, int, Mutation]]:
    out = []
    for case, n in SAMPLE.items():
        file = REPO / "cases" / case / "case.toml"
        text = file.read_text()
        all_ = mutations(tomllib.loads(text), text, random.Random(f"pulseform-fuzz/{case}/case.toml"), 500)
        rng = random.Random(f"pulseform-fuzz-run/{case}")
        # mostly mutations that load (they run); the refused ones are covered in-process by test_fuzz_check
        runs = [i for i, m in enumerate(all_) if m.kind in MAY_RUN and _loads(file, m)]
        refused = [i for i, m in enumerate(all_) if m.kind not in MAY_RUN]
        picked = rng.sample(runs, n - n // 4) + rng.sample(refused, n // 4)
        out += [(case, i, all_[i]) for i in sorted(picked)]
    return out


@pytest.mark.slow
@pytest.mark.parametrize("case,index,m", _sample(), ids=lambda v: v if isinstance(v, (str, int)) else v.kind)
def test_fuzzed_case_runs_or_fails_cleanly(tmp_path, case, index, m):
    folder = tmp_path / case
    folder.mkdir()
    file = folder / "case.toml"
    if m.text is None:
        file.write_text((REPO / "cases" / case / "case.toml").read_text())
    else:
        (file.write_bytes if isinstance(m.text, bytes) else file.write_text)(m.text)
    argv = [EXE, "run", str(file), "--out", str(tmp_path / "out"), "--quiet", *(f"--set={s}" for s in m.sets)]
    try:
        r = subprocess.run(argv, capture_output=True, text=True, timeout=RUN_LIMIT_S, preexec_fn=_limit_memory)
    except subprocess.TimeoutExpired:
        pytest.fail(f"mutation #{index} ({m.kind} at {m.key}) ran over {RUN_LIMIT_S} s")
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    print(f"#{index} {m.kind} at {m.key}: exit {r.returncode} {lines[0][:150] if lines else ''}")
    assert r.returncode in (0, 1, 2), (r.returncode, r.stderr[-2000:])
    assert "Traceback" not in r.stderr, r.stderr[-2000:]
    if r.returncode:
        assert lines and lines[0].startswith("pulseform: error: ") and len(lines[0]) <= 300, r.stderr[-2000:]
        assert len(lines) == 1 or lines[1].strip() == "--- log tail ---", r.stderr[-2000:]
    if must_refuse(m):
        assert r.returncode == 2, (m.kind, m.key, r.stderr[-500:])
