"""Generate the docs' gallery (docs/gallery/) from real runs of every shipped case in cases/.

Run it from the repository as::

    .venv/bin/python scripts/gallery.py [--only CASE ...] [--out-runs DIR] [--rerun] [--no-run]

For every case folder in ``cases/`` (its ``case.toml``, and the variant ``.toml`` files the settings
table lists) it runs ``pulseform run`` as a subprocess (an argv list, no shell, a time limit, a log per
run, its return code checked) into a scratch folder outside the repository (default
``/tmp/pulseform-gallery/<case>/<entry>``). A complete earlier run with the same case file and the same
overrides is reused unless ``--rerun``. The per-case settings — coarse ``--set`` overrides where a full
run takes more than a few minutes and why, the pictures to show, the headline metrics — are the data
table ``scripts/gallery.toml`` next to this script.

It then writes ``docs/gallery/<case>.md`` per case (description, the command a user types and, when the
gallery's run was coarse, the coarse command, the headline figures with units, the wall time, up to
four pictures copied from the run's ``plots/`` folder and downscaled with Pillow, the reference files),
``docs/gallery/index.md`` (a table of every case with a thumbnail) and ``docs/gallery/runs.json`` (per
case: git commit, overrides, wall time, date, pulseform version).

One line of progress per run goes to standard output; a failing run is one ``FAILED`` line, the
others go on, and the failures are listed again at the end (exit code 1).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import hashlib
import json
import logging
import os
import shlex
import signal
import subprocess
import sys
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
CASES = REPO / "cases"
SETTINGS = Path(__file__).resolve().with_name("gallery.toml")
GALLERY = REPO / "docs" / "gallery"
DEFAULT_RUNS = Path("/tmp/pulseform-gallery")
COMMAND = ".venv/bin/python scripts/gallery.py"

#: the most pictures a case's page shows (its variants' included)
MAX_PICTURES = 4
#: a picture's largest width (px) and size (bytes) in docs/gallery/
MAX_WIDTH = 900
MAX_BYTES = 150_000
#: the index's thumbnails
THUMB_WIDTH = 240
THUMB_BYTES = 40_000
#: the file a finished gallery run leaves in its results folder (what reuse compares)
STAMP = "gallery_run.json"

#: keys a case's table may have, and a variant's
CASE_KEYS = {"kind", "shows", "set", "reason", "full_run", "pictures", "headline", "time_limit_s", "variants"}
VARIANT_KEYS = {"set", "reason", "full_run", "pictures", "headline", "time_limit_s", "skip"}
PICTURE_KEYS = {"file", "caption"}

log = logging.getLogger("gallery")


# ----------------------------------------------------------------------------------------------- settings
@dataclass(frozen=True)
class Picture:
    """A picture of a run's ``plots/`` folder the page shows.

    Attributes
    ----------
    file : str
        Path inside ``plots/`` (``"deformed_von_mises.png"``, ``"mechanics/plastic_strain_0002.png"``).
    caption : str
        The text under it (default: from the file name).
    """

    file: str
    caption: str


@dataclass(frozen=True)
class Entry:
    """One run on a case's page: the case file itself or one variant file of its folder.

    Attributes
    ----------
    case : str
        The case folder's name under ``cases/``.
    name : str
        ``"case"`` for ``case.toml``, else the variant file's stem (``"two_bodies"``).
    file : Path
        The case file.
    overrides : tuple of str
        ``--set`` values of the gallery's run (empty: the full run).
    reason : str
        Why the run is coarse (empty for a full run).
    full_run : str
        What a full run costs (text, e.g. ``"~6-7 min on 2 cores"``); shown with a coarse run.
    pictures : tuple of Picture
        Pictures to show (empty: chosen from :data:`PREFERRED`).
    headline : tuple of str
        metrics.json keys shown as headline figures.
    time_limit_s : float
        The run is stopped after this many seconds.
    skip : str
        Non-empty: the variant is not run (the text says why).
    """

    case: str
    name: str
    file: Path
    overrides: tuple[str, ...] = ()
    reason: str = ""
    full_run: str = ""
    pictures: tuple[Picture, ...] = ()
    headline: tuple[str, ...] = ()
    time_limit_s: float = 900.0
    skip: str = ""

    @property
    def label(self) -> str:
        """``case`` or ``case/variant`` (progress lines, logs)."""
        return self.case if self.name == "case" else f"{self.case}/{self.name}"

    @property
    def coarse(self) -> bool:
        """True when the gallery's run differs from the case file (``--set`` overrides)."""
        return bool(self.overrides)

    def case_arg(self) -> str:
        """The CASE argument a user types (repository-relative)."""
        rel = self.file.relative_to(REPO)
        return str(rel.parent) if self.name == "case" else str(rel)

    def command(self, coarse: bool) -> str:
        """The ``pulseform run`` command line, with the gallery's overrides when ``coarse``."""
        parts = ["pulseform", "run", self.case_arg()]
        if coarse:
            for o in self.overrides:
                parts += ["--set", o]
        return shlex.join(parts)


@dataclass(frozen=True)
class CaseSettings:
    """A case's row of the settings table and its entries.

    Attributes
    ----------
    case : str
        Folder name under ``cases/``.
    kind : str
        The index's "kind" column.
    shows : str
        The index's "what it shows" (default: the case file's ``[case] description``).
    entries : tuple of Entry
        The case file first, then its variants in the table's order.
    """

    case: str
    kind: str
    shows: str
    entries: tuple[Entry, ...]


class SettingsError(ValueError):
    """The settings table names a missing case, file or picture key, or a key it does not know."""


def _pictures(value: Any, where: str) -> tuple[Picture, ...]:
    """The ``pictures`` list of a table row (names or ``{file, caption}`` tables) as :class:`Picture` s."""
    if not isinstance(value, list):
        raise SettingsError(f"{where}.pictures: a list of file names or {{file, caption}} tables")
    out = []
    for item in value:
        if isinstance(item, str):
            out.append(Picture(item, _caption(item)))
        elif isinstance(item, dict) and set(item) <= PICTURE_KEYS and "file" in item:
            out.append(Picture(item["file"], item.get("caption") or _caption(item["file"])))
        else:
            raise SettingsError(f"{where}.pictures: {item!r}: a file name or a {{file, caption}} table")
    return tuple(out)


def _caption(file: str) -> str:
    """``"mechanics/plastic_strain_0002.png"`` -> ``"mechanics: plastic strain 0002"``."""
    stem = file[:-4] if file.endswith(".png") else file
    return stem.replace("/", ": ").replace("_", " ")


def _entry(case: str, name: str, file: Path, row: dict[str, Any], allowed: set[str], where: str) -> Entry:
    """An :class:`Entry` from a table row; its keys checked against ``allowed`` (``where`` names the row)."""
    unknown = set(row) - allowed
    if unknown:
        raise SettingsError(f"{where}: unknown key(s) {', '.join(sorted(unknown))}; allowed: "
                            f"{', '.join(sorted(allowed))}")
    overrides = row.get("set", [])
    if not isinstance(overrides, list) or not all(isinstance(o, str) and "=" in o for o in overrides):
        raise SettingsError(f"{where}.set: a list of 'key.path=value' strings")
    if overrides and not row.get("reason"):
        raise SettingsError(f"{where}: a coarse run (set) needs its reason")
    return Entry(case=case, name=name, file=file, overrides=tuple(overrides), reason=row.get("reason", ""),
                 full_run=row.get("full_run", ""), pictures=_pictures(row.get("pictures", []), where),
                 headline=tuple(row.get("headline", [])), time_limit_s=float(row.get("time_limit_s", 900.0)),
                 skip=row.get("skip", ""))


def load_settings(path: Path = SETTINGS, cases_root: Path = CASES) -> dict[str, CaseSettings]:
    """Read the settings table and check its names against ``cases_root``.

    Parameters
    ----------
    path : Path
        The TOML table (``scripts/gallery.toml``).
    cases_root : Path
        The folder of case folders.

    Returns
    -------
    dict of str to CaseSettings
        Every case folder of ``cases_root`` (sorted), with its settings (defaults for a case the table
        does not name).

    Raises
    ------
    SettingsError
        The table names a case folder or variant file that does not exist, or a key it does not know.
    """
    table = tomllib.loads(path.read_text())
    rows = table.get("cases", {})
    folders = sorted(p.parent.name for p in cases_root.glob("*/case.toml"))
    for name in rows:
        if name not in folders:
            raise SettingsError(f"{path.name}: cases.{name}: no folder cases/{name} with a case.toml")
    out: dict[str, CaseSettings] = {}
    for case in folders:
        row = dict(rows.get(case, {}))
        where = f"{path.name}: cases.{case}"
        variants = row.pop("variants", {})
        kind, shows = row.pop("kind", ""), row.pop("shows", "")
        entries = [_entry(case, "case", cases_root / case / "case.toml", row, CASE_KEYS, where)]
        for stem, vrow in variants.items():
            vfile = cases_root / case / f"{stem}.toml"
            if not vfile.is_file():
                raise SettingsError(f"{where}.variants.{stem}: no file {vfile.relative_to(cases_root.parent)}")
            entries.append(_entry(case, stem, vfile, vrow, VARIANT_KEYS, f"{where}.variants.{stem}"))
        out[case] = CaseSettings(case=case, kind=kind, shows=shows, entries=tuple(entries))
    return out


# ------------------------------------------------------------------------------------------- case files
def case_text(file: Path) -> tuple[str, str]:
    """The ``[case] description`` of a case file and its header comment (the leading ``#`` lines).

    Parameters
    ----------
    file : Path
        A case TOML file.

    Returns
    -------
    (str, str)
        The description (one line) and the header comment without its ``#`` marks (lines kept).
    """
    text = file.read_text()
    header = []
    for line in text.splitlines():
        if not line.startswith("#"):
            break
        header.append(line[1:][1:] if line.startswith("# ") else line[1:])
    while header and not header[-1].strip():
        header.pop()
    description = tomllib.loads(text).get("case", {}).get("description", "")
    return description, "\n".join(header)


def extra_case_files(case_dir: Path) -> list[Path]:
    """The variant case files of a folder: its ``.toml`` files other than ``case.toml``."""
    return sorted(p for p in case_dir.glob("*.toml") if p.name != "case.toml")


# ------------------------------------------------------------------------------------------------ runs
@dataclass
class RunRecord:
    """What one gallery run of an :class:`Entry` gave.

    Attributes
    ----------
    entry : Entry
        The run's entry.
    out : Path
        Its results folder.
    ok : bool
        True when ``pulseform run`` exited 0 and wrote metrics.json.
    reused : bool
        True when an earlier complete run was taken.
    stamp : dict
        The run's record (commit, overrides, wall time, date, version, return code).
    error : str
        One line on what went wrong (empty when ``ok``).
    """

    entry: Entry
    out: Path
    ok: bool
    reused: bool = False
    stamp: dict[str, Any] = field(default_factory=dict)
    error: str = ""


def _git(*args: str) -> str:
    """The output of ``git ARGS`` in the repository (empty if git fails)."""
    return subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True, check=False).stdout.strip()


def git_state() -> dict[str, Any]:
    """The commit the runs are made at, and whether the code a run uses (orchestrator, solvers,
    cases, pyproject.toml) differs from it."""
    dirty = _git("status", "--porcelain", "--", "orchestrator", "solvers", "cases", "pyproject.toml")
    return {"commit": _git("rev-parse", "HEAD"), "code_clean": not dirty}


def pulseform_exe() -> Path:
    """The ``pulseform`` console script next to this interpreter (the venv's)."""
    exe = Path(sys.executable).parent / "pulseform"
    if not exe.is_file():
        raise SystemExit(f"gallery: no pulseform next to {sys.executable}: run it with the venv's python")
    return exe


def pulseform_version(exe: Path) -> str:
    """``pulseform --version`` (``"0.1.0"``)."""
    out = subprocess.run([str(exe), "--version"], capture_output=True, text=True, check=False, timeout=60)
    return out.stdout.strip().removeprefix("pulseform ").strip() or "unknown"


def file_digest(file: Path) -> str:
    """SHA-256 of a case file and of the other files of its folder (geometry, decks): a change reruns."""
    h = hashlib.sha256()
    for p in [file] + sorted(q for q in file.parent.iterdir() if q.is_file() and q != file and q.suffix != ".toml"):
        h.update(p.name.encode())
        h.update(p.read_bytes())
    return h.hexdigest()


def _complete(out: Path, entry: Entry) -> dict[str, Any] | None:
    """The stamp of a complete earlier run of ``entry`` in ``out`` (same file contents and overrides)."""
    try:
        stamp = json.loads((out / STAMP).read_text())
        metrics = json.loads((out / "metrics.json").read_text())
    except (OSError, ValueError):
        return None
    if metrics.get("status") != "ok" or stamp.get("returncode") != 0:
        return None
    if stamp.get("overrides") != list(entry.overrides) or stamp.get("case_digest") != file_digest(entry.file):
        return None
    return stamp


def _last_error(log_file: Path) -> str:
    """The run's ``pulseform: error:`` line, else its last non-empty line."""
    try:
        lines = [ln.strip() for ln in log_file.read_text(errors="replace").splitlines() if ln.strip()]
    except OSError:
        return "no log"
    for ln in reversed(lines):
        if ln.startswith("pulseform: error:"):
            return ln.removeprefix("pulseform: error:").strip()
    return lines[-1] if lines else "no output"


def _stop(proc: subprocess.Popen) -> None:
    """Stop a timed-out run and its children (its own process group): SIGINT (pulseform saves its
    checkpoint and ends its children), then SIGKILL after 30 s."""
    for sig, wait in ((signal.SIGINT, 30.0), (signal.SIGKILL, 10.0)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            return
        try:
            proc.wait(timeout=wait)
            return
        except subprocess.TimeoutExpired:
            continue


def draw_pictures(out: Path, exe: Path, log_file: Path, limit_s: float = 600.0) -> str:
    """``pulseform plot`` on a results folder whose ``plots/`` has no picture (a case file with
    ``output.plots = false``). Returns an empty string, or one line on what failed."""
    argv = [str(exe), "plot", str(out)]
    log.info("%s: no pictures: %s", out, shlex.join(argv))
    with open(log_file, "a") as fh:
        fh.write(f"# {shlex.join(argv)}\n")
        fh.flush()
        try:
            code = subprocess.run(argv, cwd=REPO, stdout=fh, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                  timeout=limit_s, check=False).returncode
        except subprocess.TimeoutExpired:
            return f"pulseform plot {out}: stopped at the time limit {limit_s:.0f} s"
    return "" if code == 0 else f"pulseform plot {out} exited {code}: {_last_error(log_file)}"


def _has_pictures(out: Path) -> bool:
    """True when the results folder's ``plots/`` holds a picture."""
    return any((out / "plots").rglob("*.png"))


def run_entry(entry: Entry, runs_root: Path, exe: Path, version: str, rerun: bool = False,
              no_run: bool = False) -> RunRecord:
    """Run (or reuse) one entry's ``pulseform run``.

    Parameters
    ----------
    entry : Entry
        What to run.
    runs_root : Path
        Scratch folder; the run goes to ``runs_root/<case>/<entry.name>``, its log next to it.
    exe : Path
        The ``pulseform`` console script.
    version : str
        pulseform's version (recorded).
    rerun : bool
        Run again even when a complete run exists.
    no_run : bool
        Never run: take a complete run or report none.

    Returns
    -------
    RunRecord
    """
    out = runs_root / entry.case / entry.name
    log_file = runs_root / entry.case / f"{entry.name}.log"
    if not rerun:
        stamp = _complete(out, entry)
        if stamp is not None:
            error = ""
            if not _has_pictures(out):   # output.plots = false in the case file: draw them from the results
                error = draw_pictures(out, exe, log_file)
                if not error:
                    stamp["pictures_by"] = "pulseform plot"
                    (out / STAMP).write_text(json.dumps(stamp, indent=1) + "\n")
            return RunRecord(entry, out, ok=not error, reused=True, stamp=stamp, error=error)
    if no_run:
        return RunRecord(entry, out, ok=False, error=f"no complete run in {out} (--no-run)")
    out.parent.mkdir(parents=True, exist_ok=True)
    argv = [str(exe), "run", entry.case_arg(), "--out", str(out), "--quiet"]
    if out.exists():
        argv.append("--force")   # replaces only a folder pulseform made (an earlier, incomplete gallery run)
    for o in entry.overrides:
        argv += ["--set", o]
    state = git_state()
    date = _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()
    log.info("%s: %s (limit %.0f s, log %s)", entry.label, shlex.join(argv), entry.time_limit_s, log_file)
    t0 = time.monotonic()
    with open(log_file, "w") as fh:
        fh.write(f"# {date}  {shlex.join(argv)}\n")
        fh.flush()
        proc = subprocess.Popen(argv, cwd=REPO, stdout=fh, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                start_new_session=True)
        try:
            code = proc.wait(timeout=entry.time_limit_s)
            timed_out = False
        except subprocess.TimeoutExpired:
            _stop(proc)
            code, timed_out = proc.returncode, True
    wall = time.monotonic() - t0
    stamp = {"case": entry.case, "entry": entry.name, "file": str(entry.file.relative_to(REPO)),
             "overrides": list(entry.overrides), "coarse": entry.coarse, "reason": entry.reason,
             "argv": [Path(argv[0]).name] + argv[1:], "returncode": code, "wall_time_s": round(wall, 1),
             "date": date, "pulseform_version": version, **state, "case_digest": file_digest(entry.file)}
    if timed_out:
        return RunRecord(entry, out, ok=False, stamp=stamp,
                         error=f"stopped at the time limit {entry.time_limit_s:.0f} s (log {log_file})")
    if code != 0:
        return RunRecord(entry, out, ok=False, stamp=stamp,
                         error=f"pulseform run exited {code} after {wall:.0f} s: {_last_error(log_file)} "
                               f"(log {log_file})")
    try:
        metrics = json.loads((out / "metrics.json").read_text())
    except (OSError, ValueError) as exc:
        return RunRecord(entry, out, ok=False, stamp=stamp, error=f"no readable metrics.json in {out}: {exc}")
    stamp["run_wall_time_s"] = metrics.get("wall_time_s")
    (out / STAMP).write_text(json.dumps(stamp, indent=1) + "\n")
    if not _has_pictures(out):   # output.plots = false in the case file: draw them from the results
        error = draw_pictures(out, exe, log_file)
        if error:
            return RunRecord(entry, out, ok=False, stamp=stamp, error=error)
        stamp["pictures_by"] = "pulseform plot"
        (out / STAMP).write_text(json.dumps(stamp, indent=1) + "\n")
    return RunRecord(entry, out, ok=True, stamp=stamp)


# -------------------------------------------------------------------------------------------- pictures
#: pictures chosen when the table names none (the first that exist)
PREFERRED = ("deformed_plastic_strain.png", "deformed_von_mises.png", "shapes.png", "energies.png")


def save_picture(src: Path, dst: Path, max_width: int = MAX_WIDTH, max_bytes: int = MAX_BYTES) -> int:
    """Copy a PNG downscaled to at most ``max_width`` px wide and (about) ``max_bytes``.

    The picture is scaled (Lanczos) to fit the width and saved as an optimised PNG on an adaptive palette
    of 256 colours (plots and rendered fields lose nothing visible; half the bytes of true colour); if that
    is too large, on 128, then 64 colours, then scaled down further.

    Parameters
    ----------
    src, dst : Path
        Source picture, destination (``.png``).
    max_width : int
        Largest width in pixels.
    max_bytes : int
        Largest size in bytes.

    Returns
    -------
    int
        The size written, in bytes.
    """
    from PIL import Image

    with Image.open(src) as im:
        img = im.convert("RGBA")
    background = Image.new("RGBA", img.size, (255, 255, 255, 255))
    img = Image.alpha_composite(background, img).convert("RGB")
    width = min(max_width, img.width)
    while True:
        scaled = img if width == img.width else img.resize((width, max(1, round(img.height * width / img.width))),
                                                              Image.Resampling.LANCZOS)
        for colours in (256, 128, 64):
            candidate = scaled.quantize(colors=colours, dither=Image.Dither.NONE)
            candidate.save(dst, format="PNG", optimize=True)
            size = dst.stat().st_size
            if size <= max_bytes:
                return size
        if width <= 200:
            return size
        width = int(width * 0.8)


def choose_pictures(entry: Entry, out: Path) -> tuple[list[Picture], list[str]]:
    """The pictures of ``entry``'s run to show, and warnings (a named picture the run did not draw)."""
    plots = out / "plots"
    warnings, chosen = [], []
    for pic in entry.pictures:
        if (plots / pic.file).is_file():
            chosen.append(pic)
        else:
            warnings.append(f"{entry.label}: no plots/{pic.file} in {out}")
    if not chosen:
        chosen = [Picture(name, _caption(name)) for name in PREFERRED if (plots / name).is_file()][:2]
    return chosen, warnings


def _picture_name(entry: Entry, pic: Picture) -> str:
    """The picture's file name in ``docs/gallery/<case>/`` (a variant's prefixed ``<variant>--``)."""
    stem = pic.file.replace("/", "-")
    return stem if entry.name == "case" else f"{entry.name}--{stem}"


# --------------------------------------------------------------------------------------------- markdown
def _fmt(value: float) -> str:
    """4 significant digits; scientific notation outside 1e-3 .. 1e6."""
    if value == 0.0:
        return "0"
    a = abs(value)
    return f"{value:.4g}" if 1e-3 <= a < 1e6 else f"{value:.3e}"


def shown_value(name: str, value: float) -> tuple[str, str]:
    """A metric's value and unit as pulseform's plots show them
    (:func:`pulseform.orchestrator.run.units.unit_of`: Pa as MPa, m as mm, A as kA...); instants below
    a second in ms or µs."""
    from pulseform.orchestrator.run.units import unit_of

    u = unit_of(name)
    unit = {"-": "", "count": "", "?": ""}.get(u.shown, u.shown)
    value = float(value) * u.scale
    if unit == "s" and 0.0 < abs(value) < 1.0:   # instants of a pulse: in ms or µs, as the plots' time axes
        value, unit = (value * 1e6, "µs") if abs(value) < 1e-3 else (value * 1e3, "ms")
    return _fmt(value), unit


def metric_rows(names: tuple[str, ...], metrics: dict[str, Any],
                reference: dict[str, Any] | None = None) -> list[tuple[str, str, str, str]]:
    """``(name, value, unit, reference value)`` of the headline metrics (:func:`shown_value`); the
    reference value (same unit) is ``""`` without ``reference`` or when it lacks the metric."""
    rows = []
    for name in names:
        if name not in metrics or not isinstance(metrics[name], (int, float)):
            rows.append((name, "—", "not in this run's metrics.json", ""))
            continue
        value, unit = shown_value(name, metrics[name])
        ref = ""
        if reference is not None and isinstance(reference.get(name), (int, float)):
            ref = shown_value(name, reference[name])[0]
        rows.append((name, value, unit, ref))
    return rows


#: a case's stored metrics of a full run (compared with a coarse gallery run)
FULL_RUN_METRICS = "reference/metrics_cli_run.json"


def full_run_metrics(entry: Entry) -> dict[str, Any] | None:
    """The metrics of a full run of ``entry``'s case stored in its folder (:data:`FULL_RUN_METRICS`), for a
    coarse run of the case file itself; ``None`` otherwise."""
    file = entry.file.parent / FULL_RUN_METRICS
    if not entry.coarse or entry.name != "case" or not file.is_file():
        return None
    try:
        return json.loads(file.read_text())
    except ValueError:
        return None


def summary_lines(entry: Entry, out: Path, metrics: dict[str, Any]) -> list[str]:
    """pulseform's own headline lines of a run (what ``pulseform run`` prints under ``summary:``), from the
    case file with the run's overrides (the results folder's case.toml of a 3D case does not load again:
    it holds the 2D-only ``mechanics.thickness``)."""
    from pulseform.orchestrator.case.io import load_case
    from pulseform.orchestrator.run.history import History
    from pulseform.orchestrator.run.summary import headline

    try:
        case, _ = load_case(entry.file, list(entry.overrides))
        history = History.read(out / "history.csv")
        return [h.text() for h in headline(case, metrics, history)]
    except Exception as exc:  # the summary is a courtesy: a page without it is still a page
        log.warning("%s: no summary (%s: %s)", out, type(exc).__name__, exc)
        return []


def duration(seconds: float) -> str:
    """``"37 s"``, ``"4 min 05 s"``."""
    s = int(round(seconds))
    return f"{s} s" if s < 60 else f"{s // 60} min {s % 60:02d} s"


def entry_markdown(rec: RunRecord, pictures: list[tuple[str, Picture]], level: int) -> list[str]:
    """The markdown of one entry: command(s), headline figures, wall time, pictures."""
    entry, stamp = rec.entry, rec.stamp
    metrics = json.loads((rec.out / "metrics.json").read_text())
    h = "#" * level
    md = [f"{h} Run it", "", "```bash", entry.command(False), "```", ""]
    if entry.coarse:
        cost = f" A full run takes {entry.full_run}." if entry.full_run else ""
        md += [f"**coarse run**: the pictures and figures below are from a coarse run, not the case as shipped: "
               f"{entry.reason}.{cost} The gallery ran:", "", "```bash", entry.command(True), "```", ""]
    else:
        md += ["The pictures and figures below are from this full run.", ""]
    when = stamp.get("date", "")[:10]
    commit = stamp.get("commit", "")[:10] + ("" if stamp.get("code_clean", True) else " + local changes")
    md += [f"Gallery run: **{duration(stamp.get('wall_time_s', 0.0))}** wall on 2 shared cores "
           f"({when}, commit `{commit}`, pulseform {stamp.get('pulseform_version', '?')}).", ""]
    if stamp.get("pictures_by"):
        md += ["The case file sets `output.plots = false`; the gallery drew the pictures afterwards with "
               "`pulseform plot RESULTS_DIR`.", ""]
    full = full_run_metrics(entry)
    rows = metric_rows(entry.headline, metrics, full)
    if rows and full is not None:
        ref = f"`cases/{entry.case}/{FULL_RUN_METRICS}`"
        md += [f"{h} Headline figures", "",
               f"The coarse run beside the full run stored in {ref}:", "",
               "| metrics.json | coarse run | full run | unit |", "|---|---:|---:|---|"]
        md += [f"| `{n}` | {v} | {r or '—'} | {u} |" for n, v, u, r in rows]
        md.append("")
    elif rows:
        md += [f"{h} Headline figures", "", "| metrics.json | value | unit |", "|---|---:|---|"]
        md += [f"| `{n}` | {v} | {u} |" for n, v, u, _ in rows]
        md.append("")
    summary = summary_lines(entry, rec.out, metrics)
    if summary:
        md += ["pulseform's summary of the run:", "", "```text", *summary, "```", ""]
    if pictures:
        md += [f"{h} Pictures", ""]
        for rel, pic in pictures:
            md += [f"![{pic.caption}]({rel})", "", f"*{pic.caption}* (`plots/{pic.file}`)", ""]
    return md


def case_page(settings: CaseSettings, records: dict[str, RunRecord],
              pictures: dict[str, list[tuple[str, Picture]]]) -> str:
    """The markdown page of one case (``docs/gallery/<case>.md``)."""
    main = settings.entries[0]
    description, header = case_text(main.file)
    md = [f"# {settings.case}", "",
          f"*Generated by `scripts/gallery.py` from a real run (`{COMMAND} --only {settings.case}`); "
          "do not edit by hand.*", "",
          f"**{description}**" if description else "", "",
          f"Kind: {settings.kind or 'see the case file'}. Case file: `{main.file.relative_to(REPO)}`.", ""]
    if header:
        md += ["From the case file's header:", "",
               "```text", header, "```", ""]
    md += entry_markdown(records[main.name], pictures.get(main.name, []), 2)
    ref = main.file.parent / "reference"
    if ref.is_dir():
        files = sorted(p for p in ref.rglob("*") if p.is_file())
        figs = [p for p in files if p.suffix.lower() in (".png", ".svg", ".jpg")]
        md += ["## Reference", "",
               "Reference figures and data of this case (in the repository, outside the docs):", ""]
        md += [f"- `{p.relative_to(REPO)}`" + (" (figure)" if p in figs else "") for p in files]
        md.append("")
    variants = settings.entries[1:]
    listed = {e.file.name for e in variants}
    others = [p for p in extra_case_files(main.file.parent) if p.name not in listed]
    if variants or others:
        md += ["## Variants in this folder", ""]
    for e in variants:
        vdesc, vheader = case_text(e.file)
        md += [f"### {e.file.name}", "", f"**{vdesc}**" if vdesc else "", ""]
        if vheader:
            md += ["From its header:", "", "```text", vheader, "```", ""]
        if e.skip or e.name not in records:
            md += ["```bash", e.command(False), "```", "",
                   f"Not run for the gallery: {e.skip or 'no complete run'}.", ""]
            continue
        md += entry_markdown(records[e.name], pictures.get(e.name, []), 4)
    for p in others:
        md += [f"### {p.name}", "", f"**{case_text(p)[0]}**", "", "```bash",
               shlex.join(["pulseform", "run", str(p.relative_to(REPO))]), "```", "",
               "Not run for the gallery.", ""]
    return "\n".join(_squeeze(md)).rstrip() + "\n"


def _squeeze(lines: list[str]) -> list[str]:
    """No two blank lines in a row (an empty description leaves one)."""
    out: list[str] = []
    for ln in lines:
        if ln == "" and out and out[-1] == "":
            continue
        out.append(ln)
    return out


def index_page(all_settings: dict[str, CaseSettings], runs: dict[str, Any]) -> str:
    """``docs/gallery/index.md``: one row per case (thumbnail, case, what it shows, kind, run, link)."""
    cases = runs.get("cases", {})
    total = sum(e.get("wall_time_s", 0.0) for c in cases.values() for e in c.get("entries", {}).values())
    md = ["# Gallery", "",
          f"*Generated by `scripts/gallery.py` from real runs of every case in `cases/` (`{COMMAND}`); do not "
          "edit by hand.* Each page has the case's description, the command to run it, its headline figures "
          "and pictures from the gallery's own run. Where a full run takes more than a few minutes the "
          "gallery ran it coarse and the page says so.", "",
          _coarse_text(all_settings, cases), "",
          f"{len(all_settings)} cases, {sum(len(s.entries) for s in all_settings.values())} runs listed; the "
          f"gallery's runs took {duration(total)} of wall time on 2 shared cores. What each run used "
          "(commit, overrides, wall time, date, version) is in `docs/gallery/runs.json`.", "",
          "| | case | what it shows | kind | gallery run | page |", "|---|---|---|---|---|---|"]
    for name, s in all_settings.items():
        info = cases.get(name, {})
        thumb = info.get("thumbnail")
        cell = f"![{name}]({thumb})" if thumb else ""
        shows = s.shows or case_text(s.entries[0].file)[0]
        extra = [e.file.name for e in s.entries[1:] if e.name in info.get("entries", {})]
        case_cell = f"`{name}`" + (f" (+ {', '.join(f'`{x}`' for x in extra)})" if extra else "")
        runs_text = []
        for e in s.entries:
            st = info.get("entries", {}).get(e.name)
            if st:
                runs_text.append(f"{'coarse' if st.get('coarse') else 'full'}, {duration(st.get('wall_time_s', 0))}")
        page = f"[{name}]({name}.md)" if (GALLERY / f"{name}.md").is_file() else "no page yet (no complete run)"
        md.append(f"| {cell} | {case_cell} | {_cell(shows)} | {_cell(s.kind)} | {'; '.join(runs_text) or 'not run'} "
                  f"| {page} |")
    return "\n".join(md) + "\n"


def _coarse_text(all_settings: dict[str, CaseSettings], cases: dict[str, Any]) -> str:
    """One sentence: which runs were coarse, and how (or that every run was full)."""
    coarse = [f"`{e.label}` ({' '.join(f'`--set {o}`' for o in e.overrides)})" for s in all_settings.values()
              for e in s.entries if e.coarse and e.name in cases.get(s.case, {}).get("entries", {})]
    if not coarse:
        return "Every run is the case file as shipped (no coarse run)."
    return (f"Coarse runs: {', '.join(coarse)}; every other run is the case file as shipped.")


def _cell(text: str) -> str:
    """Text safe in one markdown table cell."""
    return text.replace("|", "\\|").replace("\n", " ")


# -------------------------------------------------------------------------------------------------- main
def write_case(settings: CaseSettings, records: dict[str, RunRecord], runs: dict[str, Any],
               gallery: Path = GALLERY) -> list[str]:
    """Write one case's pictures, thumbnail and page; update its part of ``runs``. Returns warnings."""
    folder = gallery / settings.case
    folder.mkdir(parents=True, exist_ok=True)
    warnings: list[str] = []
    chosen: dict[str, list[tuple[str, Picture]]] = {}
    budget = MAX_PICTURES
    written: set[str] = set()
    for e in settings.entries:
        rec = records.get(e.name)
        if rec is None or not rec.ok:
            continue
        pics, warn = choose_pictures(e, rec.out)
        warnings += warn
        chosen[e.name] = []
        for pic in pics[:max(budget, 0)]:
            name = _picture_name(e, pic)
            size = save_picture(rec.out / "plots" / pic.file, folder / name)
            log.info("%s: %s (%d kB)", e.label, name, size // 1000)
            written.add(name)
            chosen[e.name].append((f"{settings.case}/{name}", pic))
        budget -= len(chosen[e.name])
    first = next((rel for lst in chosen.values() for rel, _ in lst), None)
    if first is not None:
        save_picture(gallery / first, folder / "thumb.png", THUMB_WIDTH, THUMB_BYTES)
        written.add("thumb.png")
    for old in folder.glob("*.png"):
        if old.name not in written:
            old.unlink()
    (gallery / f"{settings.case}.md").write_text(case_page(settings, records, chosen))
    entry = runs.setdefault("cases", {}).setdefault(settings.case, {})
    entry["thumbnail"] = f"{settings.case}/thumb.png" if first else None
    entry["pictures"] = sorted(written - {"thumb.png"})
    entries = entry.setdefault("entries", {})
    for name in list(entries):
        if name not in records:
            del entries[name]
    for name, rec in records.items():
        keep = ("file", "overrides", "coarse", "reason", "commit", "code_clean", "wall_time_s", "run_wall_time_s",
                "date", "pulseform_version", "argv", "pictures_by")
        entries[name] = {k: rec.stamp.get(k) for k in keep}
        entries[name]["argv"] = [a.removeprefix(f"{REPO}/") for a in entries[name].get("argv") or []]
    return warnings


def main(argv: list[str] | None = None) -> int:
    """The command line: run the cases, write the pages. Returns 0, or 1 when a case failed."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--only", nargs="+", metavar="CASE", default=[], help="only these case folders")
    p.add_argument("--out-runs", type=Path, default=DEFAULT_RUNS, metavar="DIR",
                   help=f"scratch folder for the runs (default {DEFAULT_RUNS})")
    p.add_argument("--rerun", action="store_true", help="run again even where a complete run exists")
    p.add_argument("--no-run", action="store_true", help="only write pages from complete runs")
    p.add_argument("--settings", type=Path, default=SETTINGS, metavar="FILE",
                   help=f"the settings table (default {SETTINGS.relative_to(REPO)})")
    p.add_argument("-v", "--verbose", action="store_true", help="log every step")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(asctime)s %(levelname)s %(name)s: %(message)s", stream=sys.stderr)
    try:
        all_settings = load_settings(args.settings)
    except (SettingsError, tomllib.TOMLDecodeError) as exc:
        print(f"gallery: error: {exc}", file=sys.stderr)
        return 2
    unknown = [c for c in args.only if c not in all_settings]
    if unknown:
        print(f"gallery: error: --only: no case folder {', '.join(unknown)} in cases/; known: "
              f"{', '.join(all_settings)}", file=sys.stderr)
        return 2
    runs_root = args.out_runs.resolve()
    if runs_root == REPO or REPO in runs_root.parents:
        print(f"gallery: error: --out-runs {runs_root}: must be outside the repository", file=sys.stderr)
        return 2
    selected = [s for name, s in all_settings.items() if not args.only or name in args.only]
    exe = pulseform_exe()
    version = pulseform_version(exe)
    GALLERY.mkdir(parents=True, exist_ok=True)
    runs_file = GALLERY / "runs.json"
    runs = json.loads(runs_file.read_text()) if runs_file.is_file() else {}
    failures: list[str] = []
    todo = [e for s in selected for e in s.entries if not e.skip]
    done = 0
    for s in selected:
        records: dict[str, RunRecord] = {}
        for e in s.entries:
            if e.skip:
                continue
            done += 1
            rec = run_entry(e, runs_root, exe, version, rerun=args.rerun, no_run=args.no_run)
            mode = f"coarse ({' '.join(e.overrides)})" if e.coarse else "full"
            if rec.ok:
                how = "reused" if rec.reused else "ran"
                print(f"[{done}/{len(todo)}] {e.label}: ok, {mode}, {how}, "
                      f"{duration(rec.stamp.get('wall_time_s', 0.0))}", flush=True)
                records[e.name] = rec
            else:
                line = f"FAILED {e.label}: {rec.error}"
                print(f"[{done}/{len(todo)}] {line}", flush=True)
                failures.append(line)
        if s.entries[0].name not in records:
            log.warning("%s: its case file has no complete run: page left as it was", s.case)
            continue
        for w in write_case(s, records, runs):
            print(f"warning: {w}", file=sys.stderr)
            failures.append(f"picture missing: {w}")
        runs["command"] = COMMAND
        runs.pop("generated", None)   # each run has its date: a page written again changes nothing here
        runs_file.write_text(json.dumps(runs, indent=1, sort_keys=True) + "\n")
    runs["cases"] = {k: v for k, v in sorted(runs.get("cases", {}).items()) if k in all_settings}
    runs_file.write_text(json.dumps(runs, indent=1, sort_keys=True) + "\n")
    (GALLERY / "index.md").write_text(index_page(all_settings, runs))
    size = sum(p.stat().st_size for p in GALLERY.rglob("*") if p.is_file())
    failed_runs = sum(1 for f in failures if f.startswith("FAILED"))
    print(f"gallery: {GALLERY.relative_to(REPO)} ({size / 1e6:.2f} MB), {len(todo) - failed_runs} of "
          f"{len(todo)} runs ok")
    if failures:
        print(f"gallery: {len(failures)} problem(s):", file=sys.stderr)
        for f in failures:
            print(f"  {f}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
