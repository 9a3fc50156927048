"""Figures of a run as PNGs (matplotlib, Agg backend, no display needed)."""

from __future__ import annotations

import logging
from collections.abc import Collection
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..case.io import CaseError, load_resolved_case  # noqa: E402
from ..mech.forming_limit import flc_bodies  # noqa: E402
from .analyses import create  # noqa: E402
from .history import History  # noqa: E402
from .units import TimeAxis, label, shown, time_axis, unit_of  # noqa: E402

log = logging.getLogger(__name__)


DPI = 100


def _save(fig, path: Path, close: bool = True) -> Path:
    """Write ``fig`` atomically; fixed margins (no ``bbox_inches="tight"``, which draws twice)."""
    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp, dpi=DPI, pil_kwargs={"compress_level": 1})   # fast zlib level: encoding dominated
    if close:
        plt.close(fig)
    tmp.replace(path)
    return path


def _figure(height: float = 4.0):
    fig, ax = plt.subplots(figsize=(7, height))
    fig.subplots_adjust(left=0.13, right=0.97, bottom=0.13, top=0.91)
    return fig, ax


def _time_axis(history: History, axis: TimeAxis | None) -> TimeAxis:
    """The run's time unit; from the history's last time when the caller does not give it."""
    if axis is not None:
        return axis
    t = history.column("time_s")
    return time_axis(float(t[-1]) if len(t) else 0.0)


def plot_energies(history: History, folder: Path, axis: TimeAxis | None = None) -> Path:
    """Energy ledger (J) vs time (the run's time unit)."""
    axis = _time_axis(history, axis)
    t = history.column("time_s") * axis.scale
    fig, ax = _figure()
    for c in history.columns:
        if c.startswith("energy_"):
            ax.plot(t, shown(c, history.column(c)), label=c.removeprefix("energy_").removesuffix("_J"))
    ax.set_xlabel(axis.label)
    ax.set_ylabel(f"energy [{unit_of('energy_kinetic_J').shown}]")
    ax.set_title("Energy ledger")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, folder / "energies.png")


def columns_without_meaning(case) -> set[str]:
    """History columns a coupled load writes for every case that mean nothing in ``case`` (None: the case is
    unknown, none): ``capacitor_voltage_V`` without a capacitor bank (a prescribed current, sine, dc or table
    sources; the column is 0 there), whose picture would be a flat zero."""
    em = getattr(case, "em", None) if case is not None else None
    return {"capacitor_voltage_V"} if em is not None and not em.has_bank else set()


#: history columns without a plot of their own (counters, the time axis, the energies' own plot)
NOT_PLOTTED = ("time_s", "step", "dt_s", "substeps", "iterations", "em_remeshes", "em_factorisations", "em_corrections",
               "coil_current_abs_max_A")


def plot_probes(history: History, folder: Path, references: dict[str, float] | None = None,
                axis: TimeAxis | None = None, leave_out: Collection[str] = ()) -> list[Path]:
    """One figure per history column (probes, body extremes, load values) but those in ``leave_out``
    (:func:`columns_without_meaning`), labelled with the unit of :mod:`.units` (``[?]`` for a column it does
    not know); ``references`` maps a column to a horizontal reference line (stored unit)."""
    references = references or {}
    axis = _time_axis(history, axis)
    t = history.column("time_s") * axis.scale
    paths = []
    fig, ax = _figure()   # one figure, its line updated per column (rebuilding axes costs more than drawing)
    (line,) = ax.plot(t, t, lw=1.0, label="computed")
    ax.set_xlabel(axis.label)
    ax.grid(alpha=0.3)
    try:
        for c in history.columns:
            if c in NOT_PLOTTED or c.startswith("energy_") or c in leave_out:
                continue
            scale = unit_of(c).scale
            line.set_ydata(history.column(c) * scale)
            extra = []
            if c in references:
                extra = [ax.axhline(references[c] * scale, color="k", ls="--", label="reference"), ax.legend()]
            ax.relim()
            ax.autoscale_view()
            ax.set_ylabel(label(c))
            paths.append(_save(fig, folder / f"{c}.png", close=False))
            for artist in extra:
                artist.remove()
    finally:
        plt.close(fig)
    return paths


def plot_time_step(history: History, folder: Path, axis: TimeAxis | None = None) -> Path:
    """Mechanical time step (µs) vs time (the run's time unit)."""
    axis = _time_axis(history, axis)
    t = history.column("time_s") * axis.scale
    fig, ax = _figure(3.0)
    fig.subplots_adjust(bottom=0.18)  # room for the time label on the lower figure
    dt = shown("dt_s", history.column("dt_s")[1:])
    ax.plot(t[1:], dt)
    if len(dt) and np.ptp(dt) <= 1e-9 * np.abs(dt).max():  # a constant step: no axis of round-off digits
        ax.set_ylim(0.0, 1.2 * float(np.abs(dt).max()) or 1.0)
    ax.ticklabel_format(axis="y", useOffset=False)
    ax.set_xlabel(axis.label)
    ax.set_ylabel(f"dt [{unit_of('dt_s').shown}]")
    ax.grid(alpha=0.3)
    return _save(fig, folder / "time_step.png")


def plot_rigid_motion(history: History, folder: Path, body: str, axis: TimeAxis | None = None) -> Path:
    """``<body>_motion.png``: a rigid body's translation (mm), velocity (m/s), acceleration (m/s²) and
    applied Lorentz force (kN) per free component vs time (the run's time unit), stacked."""
    axis = _time_axis(history, axis)
    t = history.column("time_s") * axis.scale
    quantities = ("position", "velocity", "acceleration", "force")
    fig, axes = plt.subplots(len(quantities), 1, figsize=(7, 8.5), sharex=True)
    fig.subplots_adjust(left=0.14, right=0.97, bottom=0.07, top=0.95, hspace=0.12)
    for ax, q in zip(axes, quantities):
        cols = [c for c in history.columns if c.startswith(f"{body}_{q}_")]
        # a force below 1 kN in N (a levitated ring's is a few N), else the unit's usual scale
        small = q == "force" and cols and max(np.abs(history.column(c)).max() for c in cols) < 1e3
        for c in cols:
            y = history.column(c) if small else shown(c, history.column(c))
            ax.plot(t, y, lw=1.0, label=c.removeprefix(f"{body}_{q}_").split("_")[0])
        ax.set_ylabel(f"{q} [{'N' if small else unit_of(cols[0]).shown}]" if cols else q)
        ax.grid(alpha=0.3)
        if len(cols) > 1:
            ax.legend(fontsize=8)
    axes[0].set_title(f"Rigid body {body}")
    axes[-1].set_xlabel(axis.label)
    return _save(fig, folder / f"{body}_motion.png")


# ---------------------------------------------------------------------------------------------------
# every picture of a results folder: the end of a run and `pulseform plot` call this

#: modules of other pictures, drawn when present: (module, function(results_dir) -> list[Path])
PICTURE_MODULES = (("pictures_mech", "draw_mechanics"), ("pictures_em", "draw_em"))


@dataclass
class Drawn:
    """What :func:`draw_all` did.

    Attributes
    ----------
    paths : list of Path
        The pictures written.
    skipped : list of str
        One line per picture group not drawn, and why (a module not there yet, no fields, ...).
    failed : list of str
        One line per picture group that raised (the traceback is in the log at DEBUG).
    stopped : bool
        ``stop`` said so: the remaining picture groups were not drawn.
    """

    paths: list[Path] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    stopped: bool = False


class NotAResultsFolder(ValueError):
    """The folder holds no ``history.csv`` (or no ``case.toml``) of a pulseform run."""


def check_results_folder(results_dir: Path) -> Path:
    """``results_dir`` as a Path if it holds a run's ``case.toml`` and ``history.csv``; else raise
    :class:`NotAResultsFolder` with a one-line reason."""
    root = Path(results_dir)
    if not root.is_dir():
        raise NotAResultsFolder(f"{root}: not a results folder (no such folder)")
    missing = [n for n in ("case.toml", "history.csv") if not (root / n).is_file()]
    if missing:
        raise NotAResultsFolder(f"{root}: not a results folder of pulseform (no {' or '.join(missing)})")
    return root


def draw_all(results_dir: Path, *, case=None, history: History | None = None, shapes: list | None = None,
             analyses: list | None = None, stop=None, renderer=None) -> Drawn:
    """Draw every picture of a results folder into its ``plots/`` (atomically, replacing old ones).

    Reads what is not given: the resolved ``case.toml``, ``history.csv``, the fields. The end of a
    run passes what it holds in memory (case, history, node positions at the output times
    ``shapes``, its analyses) and draws the same pictures as ``pulseform plot`` does later from the files. Pictures: energies, time
    step, one per history column but those without meaning in the case (:func:`columns_without_meaning`; units from :mod:`.units`, one time unit per run), the case's
    analyses, the forming limit diagrams (:mod:`.pictures_flc`), then ``pictures_mech.draw_mechanics`` and ``pictures_em.draw_em`` when those modules
    exist (until then the older shapes picture; the EM pictures are ``pictures_em``'s, from
    ``fields/em/``). A picture group that fails
    is reported in :attr:`Drawn.failed` and the others are still drawn. ``stop``: a function asked
    before each picture group; when it returns true the remaining groups are skipped
    (:attr:`Drawn.stopped`) and the 3D renderer is killed (a stop signal at the end of a run).
    ``renderer``: a ``pictures_mech.Renderer`` the caller started earlier (the end of a run), used
    for the 3D pictures instead of starting one now.
    """
    root = check_results_folder(results_dir)
    folder = root / "plots"
    folder.mkdir(exist_ok=True)
    done = Drawn()

    def attempt(what: str, fn, *args, **kw):
        if stop is not None and not done.stopped and stop():
            done.stopped = True
            if finish_mech is not None and hasattr(finish_mech, "cancel"):
                finish_mech.cancel()
        if done.stopped:
            return None
        try:
            out = fn(*args, **kw)
        except Exception as exc:  # one picture group must not cost the others
            text = " ".join(str(exc).split()) or type(exc).__name__
            done.failed.append(f"{what}: {type(exc).__name__}: {text[:200]}")
            log.warning("pictures: %s failed: %s", what, text[:200])
            log.debug("pictures: %s failed", what, exc_info=True)
            return None
        if isinstance(out, Path):
            done.paths.append(out)
        elif isinstance(out, (list, tuple)):
            done.paths.extend(Path(p) for p in out)
        return out

    def skip(line: str) -> None:
        done.skipped.append(line)
        log.info("pictures: %s", line)

    if case is None:
        case = _read_case(root, skip)
    if history is None:
        history = History.read(root / "history.csv")
    if not history.rows:
        skip("history.csv has no rows: no history plots")
        return done
    end = case.time.end if case is not None else float(history.column("time_s")[-1])
    axis = time_axis(end)
    deformable = case is None or any(not b.rigid for b in case.bodies)
    mech = _picture_module(*PICTURE_MODULES[0], skip) if deformable else None
    if not deformable:
        skip("every body is rigid: no field files, no mechanics field pictures (the bodies' motion: "
             "plots/<body>_motion.png)")
    # the 3D pictures render in a child process while this one draws the rest
    finish_mech = None
    kw = {"renderer": renderer} if renderer is not None else {}
    finish_mech = attempt("mechanics pictures", mech, root, wait=False, **kw) if mech is not None else None
    attempt("energies", plot_energies, history, folder, axis)
    attempt("time step", plot_time_step, history, folder, axis)
    attempt("history columns", plot_probes, history, folder, None, axis, columns_without_meaning(case))
    for b in case.bodies if case is not None else ():
        if b.rigid:
            attempt(f"motion of {b.name}", plot_rigid_motion, history, folder, b.name, axis)

    if case is not None and analyses is None:
        analyses = [create(name, case) for name in case.analysis]
    if shapes is None and case is not None and (analyses or (mech is None and deformable)):
        shapes = read_shapes(root, case, skip)
    for a in analyses or []:
        before = _stamps(folder)
        attempt(f"analysis {type(a).__name__}", a.plots, history, shapes or [], folder)
        done.paths.extend(p for p, s in _stamps(folder).items() if before.get(p) != s)
    if case is not None and deformable and flc_bodies(case):   # bodies with a forming limit curve
        from .pictures_flc import draw_fld

        attempt("forming limit diagram", draw_fld, root, case)
    if case is not None and deformable and (getattr(case, "springback", None) is not None
                                            or any(st.kind == "springback" for st in getattr(case, "stages", ()))):
        from .pictures_springback import draw_springback

        attempt("springback", draw_springback, root, case)
    if case is not None and case.case.kind == "coupled" and case.coupling.load == "getdp":  # EM fields exist
        three_d = case.mechanics.formulation == "3d"  # a 3D model: the force density on its bodies
        em = _picture_module(*(("pictures_em3d", "draw_em3d") if three_d else PICTURE_MODULES[1]), skip)
        if em is not None:
            attempt("EM pictures", em, root)
    if finish_mech is not None:  # shapes.png (workpiece outlines) and the 3D pictures, from fields/
        attempt("mechanics pictures", finish_mech)
    done.paths = list(dict.fromkeys(done.paths))
    return done


def _stamps(folder: Path) -> dict[Path, int]:
    """Modification times (ns) of the pictures in ``folder``. Another process may be writing pictures there
    meanwhile (the renderer child draws the 3D and mechanics pictures while the run ends): its hidden
    temporary files (``.NAME.tmp.png``, renamed when written) are not pictures, and a file that vanishes
    between the listing and its stat is skipped."""
    out = {}
    for p in folder.glob("*.png"):
        if p.name.startswith("."):
            continue
        try:
            out[p] = p.stat().st_mtime_ns
        except FileNotFoundError:
            continue
    return out


def _read_case(root: Path, skip):
    """The run's resolved case from ``case.toml`` (None, with a skip line, if it cannot be read)."""
    try:
        return load_resolved_case(root / "case.toml")
    except CaseError as exc:
        skip(f"case.toml unreadable ({exc}): only the history plots")
        return None


def _picture_module(module: str, function: str, skip):
    """``pulseform.orchestrator.<module>.<function>``, imported lazily; None (with a skip line) while
    the module does not exist or cannot be imported."""
    import importlib
    import importlib.util

    name = f"{__package__}.{module}"
    try:
        if importlib.util.find_spec(name) is None:
            skip(f"{module}.{function}: not available yet, skipped")
            return None
        return getattr(importlib.import_module(name), function)
    except (ImportError, AttributeError) as exc:
        skip(f"{module}.{function}: cannot be imported ({exc}), skipped")
        return None


def read_shapes(root: Path, case, skip) -> list | None:
    """Node positions of every body at each stored field time, from ``fields/`` (:mod:`.mech_fields`):
    ``[(t, {body: (N, 2) positions}), ...]``; None (with a skip line) if the fields cannot be read."""
    try:
        from .mech_fields import read_fields

        bodies = read_fields(root)
        per_time: dict[float, dict] = {}
        for name, bf in bodies.items():
            for k, t in enumerate(bf.times):
                per_time.setdefault(float(t), {})[name] = bf.current(k)
        shapes = [(t, pos) for t, pos in sorted(per_time.items()) if len(pos) == len(bodies)]
    except Exception as exc:  # an older or damaged folder: the other pictures are still drawn
        skip(f"body shapes not readable from fields/ ({type(exc).__name__}: {str(exc)[:120]}): shape plots skipped")
        return None
    if not shapes:
        skip("no body shapes in fields/: shape plots skipped")
        return None
    return shapes
