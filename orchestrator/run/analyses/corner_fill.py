"""Corner filling (paper sec. 5, Figures 3 and 4): fill fraction, die stress, blank speed, contact.

The case must have a body ``blank``, a body ``die`` and a contact pair blank -> die (the first pair
whose slave is the blank). Definitions (documented in docs/cases.md):

* cavity profile: the die's exterior segments (initial configuration) whose outward normal points
  upwards (n_y > 0.1) and that lie below the flange top (y < y_max - 1e-6): the groove walls, the
  rounded apex and the lower part of the entry fillet;
* touched: a point of the cavity profile within ``FILL_GAP_FACTOR`` x h0 of the blank's boundary
  (current configuration, point-to-segment distance). The profile is sampled every
  ``FILL_SAMPLE_SPACING`` of arc length (material points of the die's profile segments, moving with
  the die), so the measure does not depend on the die's mesh;
  ``contact_fraction``: length fraction of the profile touched *now* (it flickers while the formed
  blank rings elastically on the die); ``fill_fraction``: length fraction touched at some recorded
  time so far (how far the blank has been formed into the die, insensitive to the ringing);
  ``unfilled_length_mm``: the profile length never touched. The "so far" record is restart state
  (the analysis' restart state, :meth:`CornerFill.state_dict`: ``--resume`` continues it).
  ``fill_fraction_segments``: the former measure (a die segment counts as touched when its
  midpoint is), kept for comparison: it depends on the die's mesh (4 mm die segments count a
  whole 4 mm as touched when their midpoint is).
* corner: the middle of the rounded corner between the flat bottom and the wall (the profile
  points inclined between 1 and 49 degrees within 5 mm of the bottom); ``corner_gap_m`` is the
  distance from it to the blank (``corner_gap_min_mm``: its minimum over time: the corner counts as
  reached when it is <= 2 h0), ``blank_corner_kinetic_J`` the kinetic energy of the blank's nodes
  within ``CORNER_RADIUS`` of it (the momentum that wraps the blank into the corner).
* die stress: von Mises = sqrt(3 J2) per die cell, maximum over the die; the paper plots J2(sigma)
  (its figures' unit is MPa, so we report sqrt(J2) = von Mises / sqrt(3) beside it).
* blank speed: largest nodal speed of the blank (``blank_speed_max_m_s``; it spikes for a few
  steps when the blank strikes the die, single nodes are thrown by the contact layer) and the
  mass-weighted rms speed sqrt(2 KE / m) (``blank_rms_speed_max_m_s``, the blank's flight speed).
* contact pressure on the die: largest soft-contact stress of the blank -> die pair.
* how much of the die yields: ``die_yielded_volume_fraction``, the volume fraction of die cells
  with plastic strain > 0 at the end (plastic strain only grows: every cell that ever yielded),
  beside ``die_plastic_strain_max`` (the von Mises peak is capped near the die's yield stress).

Maxima over time are taken over the history rows (every ``output.history_every`` steps).
Serial runs only (the geometry queries use this rank's nodes).
"""

from __future__ import annotations

import numpy as np

from pulseform.solvers.dolfinx.cell_fields import von_mises_max
from pulseform.solvers.dolfinx.cell_list import new_grid

from ..units import time_axis
from . import Analysis
from .corner_fill_kernel import (blank_motion, build_midpoint_grid, distances_within, min_distances,
                                 profile_samples)

FILL_GAP_FACTOR = 2.0  # a profile point counts as touched when the blank is within 2 h0 of it
FILL_SAMPLE_SPACING = 1.0e-4  # m: arc-length spacing of the profile samples (h0 of the case)
CORNER_RADIUS = 1.0e-2  # m: blank nodes this close to the corner count for its kinetic energy
STATE_KEY = "ever"  # restart state (state_dict): touched so far, per profile sample
STATE_KEY_SEGMENTS = "ever_segments"  # (per profile segment, the former measure)


def _saved_mask(saved: dict, key: str, n: int) -> np.ndarray:
    """The boolean record ``key`` restored from a checkpoint (:meth:`CornerFill.load_state_dict`), or all False."""
    arr = saved.get(key)
    return np.asarray(arr, dtype=bool).copy() if arr is not None and len(arr) == n else np.zeros(n, dtype=bool)


def _segment_distances(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) of each point p (P, 2) to each of its own K segments a-b (P, K, 2): (P, K)."""
    t = b - a
    L2 = np.maximum((t ** 2).sum(axis=2), 1e-300)
    xi = np.clip(((p[:, None, :] - a) * t).sum(axis=2) / L2, 0.0, 1.0)
    q = a + xi[..., None] * t
    return np.sqrt(((p[:, None, :] - q) ** 2).sum(axis=2))


def _point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) of each point p (P, 2) to the nearest segment a-b (S, 2)."""
    t = b - a
    L2 = np.maximum((t ** 2).sum(axis=1), 1e-300)
    d = p[:, None, :] - a[None, :, :]
    xi = np.clip((d * t[None]).sum(axis=2) / L2[None], 0.0, 1.0)
    q = a[None] + xi[..., None] * t[None]
    return np.sqrt(((p[:, None, :] - q) ** 2).sum(axis=2)).min(axis=1)


def _yielded_fraction(body) -> float:
    """Volume fraction of the body's cells that have yielded (plastic strain > 0) at some time."""
    vol = body.cell_volumes()
    return float(vol[body.eps_p > 0.0].sum() / vol.sum()) if len(vol) else 0.0


class CornerFill(Analysis):
    """History columns, metrics and plots of the corner-filling cases."""

    def __init__(self, case) -> None:
        self._saved: dict = {}  # restart state from a checkpoint, used at the first record
        self.case = case
        self.pair = next(i for i, c in enumerate(case.contact) if c.slave == "blank" and c.master == "die")
        self.h0 = case.contact[self.pair].h0
        self._profile = None
        self._ever = None  # per profile sample: touched at some recorded time so far (restart state)

    # ------------------------------------------------------------------ geometry
    def _setup(self, solver) -> None:
        if solver.comm.size > 1:
            raise NotImplementedError("corner_fill analysis: serial runs only")
        die = solver.bodies["die"]
        segs = die.segments
        X = die.X0
        pa, pb = X[segs[:, 0]], X[segs[:, 1]]
        t = pb - pa
        ln = np.linalg.norm(t, axis=1)
        ny = -t[:, 0] / ln  # outward normal (t_y, -t_x) / |t|
        ymid = 0.5 * (pa[:, 1] + pb[:, 1])
        keep = (ny > 0.1) & (ymid < X[:, 1].max() - 1e-6)
        self._profile = segs[keep]
        self._profile_len0 = ln[keep]
        mids = 0.5 * (pa + pb)[keep]
        self.profile_x0 = mids[:, 0]
        # samples: FILL_SAMPLE_SPACING apart along each profile segment, weight = their arc length
        n = np.maximum(1, np.ceil(self._profile_len0 / FILL_SAMPLE_SPACING).astype(int))
        self._sample_seg = np.repeat(np.arange(len(n)), n)
        self._sample_xi = np.concatenate([(np.arange(k) + 0.5) / k for k in n])
        self._sample_w = (self._profile_len0 / n)[self._sample_seg]
        self._sample_ends = (self._profile[self._sample_seg, 0], self._profile[self._sample_seg, 1])
        self._corner = self._find_corner(X)
        blank = solver.bodies["blank"]
        self._blank_segs = blank.segments
        self._blank_seg_len_max = float(np.linalg.norm(blank.X0[self._blank_segs[:, 1]]
                                                       - blank.X0[self._blank_segs[:, 0]], axis=1).max())
        # scratch of the compiled queries: the blank segments' midpoints and their cell-list grid
        m = len(self._blank_segs)
        self._mid = (np.empty(m), np.empty(m))
        self._grid = new_grid(m)
        self._scratch = (np.empty(blank.n_owned), np.empty(blank.n_owned))

    def _sample_points(self, x: np.ndarray) -> np.ndarray:
        """Profile samples (S, 2), m, for die node positions x."""
        ia, ib = self._sample_ends
        out = np.empty((len(ia), 2))
        profile_samples(x, ia, ib, self._sample_xi, out)
        return out

    def _find_corner(self, X0: np.ndarray) -> int | None:
        """Index of the sample in the middle of the rounded corner between the flat bottom and the
        wall (inclination 1-49 degrees, within 5 mm of the bottom); None if the profile has none."""
        p = self._sample_points(X0)
        t = X0[self._profile[:, 1]] - X0[self._profile[:, 0]]
        ang = np.degrees(np.arctan2(np.abs(t[:, 1]), np.abs(t[:, 0])))[self._sample_seg]
        arc = np.flatnonzero((ang > 1.0) & (ang < 49.0) & (p[:, 1] < p[:, 1].min() + 5e-3))
        return int(arc[len(arc) // 2]) if len(arc) else None

    def _bound(self) -> float:
        """Search radius (m) around a point for the midpoints of the blank segments that may lie
        within FILL_GAP_FACTOR h0 of it (half the longest initial segment, with a 1.5 stretch allowance)."""
        return FILL_GAP_FACTOR * self.h0 + 0.5 * self._blank_seg_len_max * 1.5

    def _build_grid(self, blank) -> None:
        """The blank segments' current midpoints in the cell-list grid of :meth:`_blank_distance`."""
        build_midpoint_grid(blank.x, self._blank_segs, self._bound(), *self._mid, *self._grid)

    def _blank_distance(self, p: np.ndarray, blank, grid_ready: bool = False) -> np.ndarray:
        """Distance (m) from points p (P, 2) to the blank's boundary, exact where it is below
        FILL_GAP_FACTOR h0 (every segment whose midpoint is within :meth:`_bound` is searched),
        else >= that bound or ``inf``. ``grid_ready``: :meth:`_build_grid` ran for the current positions."""
        if not grid_ready:
            self._build_grid(blank)
        out = np.empty(len(p))
        distances_within(np.ascontiguousarray(p, dtype=float), blank.x, self._blank_segs, self._bound(),
                         *self._mid, *self._grid, out)
        return out

    def touched(self, solver) -> np.ndarray:
        """Per profile sample: is the blank within FILL_GAP_FACTOR h0 of it."""
        if self._profile is None:
            self._setup(solver)
        p = self._sample_points(solver.bodies["die"].x)
        return self._blank_distance(p, solver.bodies["blank"]) <= FILL_GAP_FACTOR * self.h0

    def _touched_segments(self, solver, grid_ready: bool = False) -> np.ndarray:
        """The former measure: per profile segment, is the blank within FILL_GAP_FACTOR h0 of its midpoint."""
        die, blank = solver.bodies["die"], solver.bodies["blank"]
        mid = 0.5 * (die.x[self._profile[:, 0]] + die.x[self._profile[:, 1]])
        return self._blank_distance(mid, blank, grid_ready) <= FILL_GAP_FACTOR * self.h0

    def _gaps(self, solver, samples: np.ndarray) -> tuple[float, float]:
        """(corner gap, apex gap), m: distances from the corner sample (NaN without a corner) and
        from the die's deepest profile point to the blank's boundary (all its segments)."""
        die, blank = solver.bodies["die"], solver.bodies["blank"]
        pts = die.x[self._profile.ravel()]
        q = np.empty((2, 2))
        q[0] = samples[self._corner] if self._corner is not None else 0.0
        q[1] = pts[np.argmin(pts[:, 1])]
        out = np.empty(2)
        min_distances(q, blank.x, self._blank_segs, out)
        return (float(out[0]) if self._corner is not None else float("nan")), float(out[1])

    def _blank_motion(self, solver, samples: np.ndarray) -> tuple[float, float, float]:
        """(largest nodal speed m/s, mass-weighted rms speed m/s, kinetic energy J of the nodes
        within CORNER_RADIUS of the corner, NaN without a corner) of the blank's owned nodes."""
        blank = solver.bodies["blank"]
        no = blank.n_owned
        if len(self._scratch[0]) < no:
            self._scratch = (np.empty(no), np.empty(no))
        c = samples[self._corner] if self._corner is not None else (np.nan, np.nan)
        mv2, near = self._scratch
        speed, k = blank_motion(blank.x, blank.v, blank.mass, no, float(c[0]), float(c[1]), CORNER_RADIUS,
                                mv2, near)
        ke = 0.5 * float(near[:k].sum()) if self._corner is not None else float("nan")
        return float(speed), float(np.sqrt(mv2[:no].sum() / blank.mass[:no].sum())), ke

    # ------------------------------------------------------------------ hooks
    def record(self, solver, row: dict[str, float] | None = None) -> dict[str, float]:
        """This row's columns; ``row``: the driver's columns so far (its ``energy_*`` are reused)."""
        if self._profile is None:
            self._setup(solver)
        die, blank = solver.bodies["die"], solver.bodies["blank"]
        samples = self._sample_points(die.x)
        self._build_grid(blank)  # once for both measures
        touched = self._blank_distance(samples, blank, grid_ready=True) <= FILL_GAP_FACTOR * self.h0
        if self._ever is None:  # a fresh run, or the first record after --resume (checkpointed state)
            self._ever = _saved_mask(self._saved, STATE_KEY, len(touched))
            self._ever_segments = _saved_mask(self._saved, STATE_KEY_SEGMENTS, len(self._profile))
        self._ever = self._ever | touched
        self._ever_segments = self._ever_segments | self._touched_segments(solver, grid_ready=True)
        vm = von_mises_max(die.cell_stress) if len(die.cells) else 0.0
        _, _, p, _ = solver.contact_pressure(self.pair)
        speed, rms, corner_ke = self._blank_motion(solver, samples)
        if row is not None and "energy_kinetic_J" in row:
            ke = {k: row[f"energy_{k}"] for k in ("kinetic_J", "elastic_J", "plastic_J")}
        else:
            ke = solver.energies()
        ratio = ke["kinetic_J"] / max(ke["elastic_J"] + ke["plastic_J"], 1e-300)
        w = self._sample_w
        gap, apex_gap = self._gaps(solver, samples)
        return {
            "fill_fraction": float(w[self._ever].sum() / w.sum()),
            "contact_fraction": float(w[touched].sum() / w.sum()),
            "unfilled_length_m": float(w[~self._ever].sum()),
            "fill_fraction_segments": float(self._profile_len0[self._ever_segments].sum() / self._profile_len0.sum()),
            "corner_gap_m": gap,
            "blank_corner_kinetic_J": corner_ke,
            "die_von_mises_max_Pa": vm,
            "die_sqrt_J2_max_Pa": vm / np.sqrt(3.0),
            "blank_speed_max_m_s": speed,
            "blank_rms_speed_m_s": rms,
            "die_contact_pressure_max_Pa": float(p.max()) if len(p) else 0.0,
            "blank_apex_gap_m": apex_gap,
            "kinetic_to_deformation_ratio": float(ratio),
        }

    def state_dict(self) -> dict[str, np.ndarray]:
        """The touched-so-far records (bool per profile sample and per segment), once recorded."""
        if self._ever is None:
            return {}
        return {STATE_KEY: self._ever.copy(), STATE_KEY_SEGMENTS: self._ever_segments.copy()}

    def load_state_dict(self, state: dict) -> None:
        """The records of a checkpoint, taken up at the next :meth:`record`."""
        self._saved = dict(state)
        self._ever = self._ever_segments = None

    def metrics(self, solver, history) -> dict[str, float]:
        ff = history.column("fill_fraction")
        cf = history.column("contact_fraction")
        vm = history.column("die_von_mises_max_Pa")
        sp = history.column("blank_speed_max_m_s")
        cp = history.column("die_contact_pressure_max_Pa")
        out = {
            "fill_fraction": float(ff[-1]),
            "fill_fraction_segments": float(history.column("fill_fraction_segments")[-1]),
            "corner_gap_min_mm": float(np.nanmin(history.column("corner_gap_m"))) * 1e3,
            "blank_corner_kinetic_max_J": float(np.nanmax(history.column("blank_corner_kinetic_J"))),
            "contact_fraction_final": float(cf[-1]),
            "unfilled_length_mm": float(history.column("unfilled_length_m")[-1]) * 1e3,
            "apex_gap_final_mm": float(history.column("blank_apex_gap_m")[-1]) * 1e3,
            "die_mises_max_MPa": float(vm.max()) / 1e6,
            "die_sqrt_J2_max_MPa": float(vm.max()) / np.sqrt(3.0) / 1e6,
            "blank_speed_max_m_s": float(sp.max()),
            "blank_rms_speed_max_m_s": float(history.column("blank_rms_speed_m_s").max()),
            "die_contact_pressure_max_MPa": float(cp.max()) / 1e6,
            "die_plastic_strain_max": float(solver.bodies["die"].eps_p.max()),
            "die_yielded_volume_fraction": _yielded_fraction(solver.bodies["die"]),
            "blank_plastic_strain_max": float(solver.bodies["blank"].eps_p.max()),
        }
        out.update(self._per_pulse(history))
        out.update(self._quasi_static(history))
        return out

    def _quasi_static(self, history) -> dict[str, float]:
        """Preforming check (cases with kinetic or mass damping and a first, slowly ramped pulse): the
        kinetic / (elastic + plastic) energy ratio while the damping acts (the kinetic damping window
        when there is one),

        * ``preform_kinetic_ratio_top_max``: largest ratio while the preform pressure is >= 90 % of
          its amplitude (the top of the ramp, where the preformed shape is set);
        * ``preform_kinetic_ratio_max``: largest ratio while it is >= 10 % (includes the start of
          the ramp, where the slack blank moves with hardly any internal energy: large ratios);
        * ``preform_kinetic_ratio_end``: at the end of the damping window.
        Milestone rows (load columns 0 there) are skipped."""
        mo = self.case.mechanics
        if (mo.mass_damping <= 0.0 and mo.kinetic_damping_until <= 0.0) or not self.case.loads \
                or "load0_pressure_Pa" not in history.columns:
            return {}
        t = history.column("time_s")
        p = history.column("load0_pressure_Pa")
        r = history.column("kinetic_to_deformation_ratio")
        amp = self.case.loads[0].amplitude
        if mo.kinetic_damping_until > 0.0:
            damped = t < mo.kinetic_damping_until
        else:
            damped = (t >= mo.mass_damping_from) & (t < mo.mass_damping_until)
        out = {}
        for name, frac in (("preform_kinetic_ratio_top_max", 0.9), ("preform_kinetic_ratio_max", 0.1)):
            m = damped & (p >= frac * amp)
            if m.any():
                out[name] = float(r[m].max())
        if damped.any():
            out["preform_kinetic_ratio_end"] = float(r[np.flatnonzero(damped)[-1]])
        return out

    def _windows(self, history) -> list[tuple[float, float]]:
        """(start, end) time (s) of each pulse phase: from a pulse's first non-zero pressure to the
        next pulse's (the last one to the end of the run)."""
        t = history.column("time_s")
        starts = []
        i = 0
        while f"load{i}_pressure_Pa" in history.columns:
            p = history.column(f"load{i}_pressure_Pa")
            nz = np.flatnonzero(p > 0)
            if len(nz):
                starts.append(float(t[max(nz[0] - 1, 0)]))
            i += 1
        return [(s, starts[k + 1] if k + 1 < len(starts) else float(t[-1]) + 1.0) for k, s in enumerate(starts)]

    def _per_pulse(self, history) -> dict[str, float]:
        w = self._windows(history)
        if len(w) < 2:
            return {}
        t = history.column("time_s")
        out = {}
        for k, (a, b) in enumerate(w):
            m = (t >= a) & (t < b)
            out[f"pulse{k}_die_mises_max_MPa"] = float(history.column("die_von_mises_max_Pa")[m].max()) / 1e6
            out[f"pulse{k}_blank_speed_max_m_s"] = float(history.column("blank_speed_max_m_s")[m].max())
            out[f"pulse{k}_blank_rms_speed_max_m_s"] = float(history.column("blank_rms_speed_m_s")[m].max())
            out[f"pulse{k}_fill_fraction_end"] = float(history.column("fill_fraction")[m][-1])
            out[f"pulse{k}_corner_gap_min_mm"] = float(np.nanmin(history.column("corner_gap_m")[m])) * 1e3
            out[f"pulse{k}_corner_kinetic_max_J"] = float(np.nanmax(history.column("blank_corner_kinetic_J")[m]))
            out[f"pulse{k}_contact_fraction_end"] = float(history.column("contact_fraction")[m][-1])
            out[f"pulse{k}_start_time_s"] = a
        return out

    # ------------------------------------------------------------------ plots
    def plots(self, history, shapes, folder) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        axis = time_axis(self.case.time.end)  # the run's time unit, as on its other plots
        t = history.column("time_s") * axis.scale
        fig, ax = plt.subplots(3, 1, figsize=(7, 8), sharex=True)
        ax[0].plot(t, history.column("die_von_mises_max_Pa") / 1e6, label="von Mises = sqrt(3 J2)")
        ax[0].plot(t, history.column("die_sqrt_J2_max_Pa") / 1e6, label="sqrt(J2)")
        ax[0].set_ylabel("die, max over cells (MPa)")
        ax[0].legend()
        ax[1].plot(t, history.column("blank_speed_max_m_s"), lw=0.8, label="max over nodes")
        ax[1].plot(t, history.column("blank_rms_speed_m_s"), label="mass-weighted rms")
        ax[1].set_ylabel("blank speed (m/s)")
        ax[1].legend()
        ax[2].plot(t, history.column("fill_fraction"), label="fill (touched so far)")
        ax[2].plot(t, history.column("contact_fraction"), lw=0.8, label="in contact now")
        ax[2].set_ylabel("fraction of die profile")
        ax[2].legend()
        ax[2].set_xlabel(axis.label)
        for a, _ in self._windows(history):
            for x in ax:
                x.axvline(a * axis.scale, color="0.7", lw=0.8, ls="--")
        fig.suptitle("Corner filling: die stress, blank speed, fill (cf. paper Fig. 3/4)")
        fig.tight_layout()
        fig.savefig(folder / "corner_fill_history.png", dpi=110)
        plt.close(fig)
        if shapes:
            self._plot_shapes(history, shapes, folder, plt, axis)

    def _plot_shapes(self, history, shapes, folder, plt, axis) -> None:
        windows = self._windows(history)
        fig, ax = plt.subplots(figsize=(9, 5))
        die0 = shapes[0][1]["die"]
        ax.plot(die0[:, 0] * 1e3, die0[:, 1] * 1e3, ",", color="0.6")
        picks = []
        if len(windows) > 1:  # the shape just before each next pulse, and the final one
            for a, _ in windows[1:]:
                before = [s for s in shapes if s[0] <= a]
                if before:
                    picks.append(before[-1])
            picks.append(shapes[-1])
        else:
            n = len(shapes)
            picks = [shapes[i] for i in sorted(set(np.linspace(0, n - 1, min(n, 8)).astype(int)))]
        cmap = plt.get_cmap("viridis")
        for k, (ts, pos) in enumerate(picks):
            b = pos["blank"]
            ax.plot(b[:, 0] * 1e3, b[:, 1] * 1e3, ".", ms=1.0, color=cmap(k / max(1, len(picks) - 1)),
                    label=f"t = {ts * axis.scale:.4g} {axis.unit}")
        ax.set_aspect("equal")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        ax.legend(fontsize=7, markerscale=8)
        ax.set_title("blank shapes (half model, symmetry at x = 0)")
        fig.tight_layout()
        fig.savefig(folder / "corner_fill_shapes.png", dpi=110)
        plt.close(fig)
