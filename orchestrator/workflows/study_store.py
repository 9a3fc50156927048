"""A study's members on disk: folders named by what they run, records, what is left to run, the table.

Each member's folder is ``<values>_<hash>`` where ``hash`` is the first 12 hex digits of the SHA-256 of its
**resolved case** (the case file with the study's and the member's ``--set`` values applied and every default
filled in, :func:`..case.io.case_to_toml`) and of the content of every file that case names (decks, geometry
files); ``<values>`` (its swept values, shortened) is for people. The same member of an interrupted, repeated
or extended study (a longer list, a larger Sobol sample) therefore has the same folder, and a changed case
file or deck makes a new one.

When a member ends, the study writes ``member.json`` in its folder (its values, hash, exit code, error, log
tail, worker); the table ``sweep.csv`` is rebuilt from these records and the members' ``metrics.json``. At the
start, ``design.json`` lists the design (its arguments, every member's values and folder). A member is **done**
when its record says exit 0, or it has no record but its run's ``metrics.json`` says ``ok`` (a run that ended after
its study was killed, or on a remote worker of a stopped study: its folder's name is its case's hash, so the
result is this member's; the study records it then) or its record says it was stopped by a signal after its run
ended (``metrics.json`` ``ok``); **failed** with any other exit code (re-run only when asked: ``retry_failed``); a
member that was stopped (its run's ``metrics.json`` status ``interrupted`` with a ``checkpoint.npz``) continues
from its checkpoint (``pulseform run --resume``); any other member (never started, or its study was killed
before it ended) runs from the start.
"""

from __future__ import annotations

import hashlib
import json
import logging
import re
from pathlib import Path

from ..case.io import case_to_toml, load_case
from ..run.results import MARKER_NAME, atomic_write_text, read_metrics, write_csv
from ..run.warm import MEMBER_DEFAULTS

log = logging.getLogger(__name__)

__all__ = ["member_hash", "folder_name", "write_record", "read_record", "member_state", "write_design",
           "collect", "write_table", "RECORD", "DESIGN", "TABLE"]

RECORD = "member.json"
DESIGN = "design.json"
TABLE = "sweep.csv"
HASH_DIGITS = 12
#: exit codes of a member ended by a stop signal (SIGINT, SIGTERM: handled, 128 + n, or not, -n)
_STOPPED = (130, 143, -2, -15)
#: the record's fields copied to and from a member
_FIELDS = ("returncode", "error", "worker", "log_tail")


def member_hash(case: str | Path, overrides: list[str]) -> str:
    """The hex SHA-256 of the resolved case of ``case`` with ``overrides`` (after :data:`MEMBER_DEFAULTS`, as
    its run gets them) and of the bytes of every existing file the resolved case names. Raises the loader's
    ``CaseError`` for an invalid member."""
    resolved, _ = load_case(case, [*MEMBER_DEFAULTS, *overrides])
    text = case_to_toml(resolved)
    h = hashlib.sha256(text.encode())
    for path in sorted(_named_files(text)):
        h.update(path.encode())
        h.update(Path(path).read_bytes())
    return h.hexdigest()


def _named_files(toml_text: str) -> set[str]:
    """Absolute paths of existing files among the resolved case's strings (decks, geometry files)."""
    import tomllib

    found: set[str] = set()

    def walk(v) -> None:
        if isinstance(v, dict):
            for x in v.values():
                walk(x)
        elif isinstance(v, list):
            for x in v:
                walk(x)
        elif isinstance(v, str) and v.startswith("/") and len(v) < 4096:
            try:
                if Path(v).is_file():
                    found.add(v)
            except OSError:
                pass

    walk(tomllib.loads(toml_text))
    return found


def folder_name(values: dict[str, str], digest: str) -> str:
    """``<key-value>_..._<hash>``: the last part of each key and its value, at most 80 characters, then the
    first :data:`HASH_DIGITS` of ``digest`` (what makes it unique)."""
    label = "_".join(f"{k.split('.')[-1]}-{_slug(v)}" for k, v in values.items())[:80]
    return f"{label}_{digest[:HASH_DIGITS]}" if label else digest[:HASH_DIGITS]


def _slug(v: str) -> str:
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", v).strip("_") or "x"


def write_record(member) -> None:
    """``member.json`` of a member that ended (its folder is made if its run did not get that far)."""
    member.out.mkdir(parents=True, exist_ok=True)
    record = {"index": member.index, "values": member.values, "hash": member.digest,
              **{k: getattr(member, k) for k in _FIELDS}}
    atomic_write_text(member.out / RECORD, json.dumps(record, indent=1) + "\n")


def clear_lone_record(member) -> None:
    """Before a member runs from the start: a folder that holds only the study's own record (its run stopped or
    failed before it made its results folder) is given back empty, so that the run may take it (a run replaces
    only folders it made, marked by MARKER_NAME; the record is the study's file)."""
    folder = member.out
    if folder.is_dir() and not (folder / MARKER_NAME).exists() and [p.name for p in folder.iterdir()] == [RECORD]:
        (folder / RECORD).unlink()


def read_record(folder: Path) -> dict | None:
    """A member folder's record, or None (none yet, or unreadable: the member runs again)."""
    try:
        return json.loads((folder / RECORD).read_text())
    except (OSError, ValueError):
        return None


def member_state(member) -> str:
    """``"done"``, ``"failed"``, ``"stopped"`` (continues from its checkpoint) or ``"new"`` (runs from the start);
    fills in a recorded member's outcome and metrics."""
    record = read_record(member.out)
    stopped = _status(member.out) == "interrupted" and (member.out / "checkpoint.npz").is_file()
    if record is not None and record.get("hash") == member.digest and record.get("returncode") is not None:
        for k in _FIELDS:
            setattr(member, k, record.get(k, getattr(member, k)))
        member.metrics = _metrics(member.out)
        if record["returncode"] == 0:
            return "done"
        if record["returncode"] in _STOPPED and _status(member.out) == "ok":  # the stop came after its run ended
            log.info("member %d (%s): its run had ended before the stop signal", member.index, member.out.name)
            member.returncode, member.error, member.log_tail = 0, "", ""
            write_record(member)
            return "done"
        if record["returncode"] in _STOPPED and not stopped:   # a stop (Ctrl-C, SIGTERM) before its first checkpoint
            log.info("member %d (%s): stopped before a checkpoint; runs again from the start", member.index,
                     member.out.name)
            return "new"
        if not stopped:
            return "failed"
    elif _status(member.out) == "ok":  # its run ended well but its study did not record it (killed, a remote worker)
        member.returncode, member.error, member.log_tail = 0, "", ""
        member.metrics = _metrics(member.out)
        write_record(member)
        return "done"
    return "stopped" if stopped else "new"


def _status(folder: Path) -> str | None:
    """The ``status`` of a member's ``metrics.json`` (ok, interrupted, failed, ...), None without one."""
    try:
        return json.loads((folder / "metrics.json").read_text()).get("status")
    except (OSError, ValueError, AttributeError):
        return None


def _metrics(folder: Path) -> dict[str, float]:
    try:
        return read_metrics(folder / "metrics.json")
    except (OSError, ValueError):
        return {}


def write_design(root: Path, params: list, sample: int | None, design: str, seed: int, members: list) -> None:
    """``design.json``: the design's arguments and every member's index, values, folder and hash."""
    doc = {"design": "grid" if sample is None else design, "sample": sample, "seed": None if sample is None else seed,
           "params": [{"key": p.key, **({"lo": p.lo, "hi": p.hi, "integer": p.integer} if p.is_range
                                        else {"values": list(p.values)})} for p in params],
           "members": [{"index": m.index, "values": m.values, "folder": m.out.name, "hash": m.digest} for m in members]}
    atomic_write_text(root / DESIGN, json.dumps(doc, indent=1) + "\n")


def collect(members: list) -> list:
    """Each member's outcome and metrics read again from its folder (the table's source); a member without a
    record keeps what the study knows of it (rejected by validation: exit 2; not run: no exit code)."""
    for m in members:
        record = read_record(m.out)
        if record is not None and record.get("hash") == m.digest:
            for k in _FIELDS:
                setattr(m, k, record.get(k, getattr(m, k)))
        m.metrics = _metrics(m.out) or m.metrics
    return members


def write_table(members: list, keys: list[str], path: Path) -> None:
    """``sweep.csv``: parameters, exit code, error, worker, folder, then every numeric metric any member reported."""
    names = sorted({k for m in members for k in m.metrics})
    header = list(keys) + ["returncode", "error", "worker", "folder"] + names
    rows = [[m.values[k] for k in keys] + [m.returncode, m.error, m.worker, m.out.name] +
            [m.metrics.get(k, "") for k in names] for m in members]
    write_csv(path, header, rows)
