"""Corner filling (paper sec. 5, Figures 3 and 4): fill fraction, die stress, blank speed, contact.

The case must have a body ``blank``, a body ``die`` and a contact pair blank -> die (the first pair
whose slave is the blank). Definitions (documented in docs/cases.md):

* cavity profile: the die's exterior segments (initial configuration) whose outward normal points
  upwards (n_y > 0.1) and that lie below the flange top (y < y_max - 1e-6): the groove walls, the
  rounded apex and the lower part of the entry fillet;
* touched: a cavity-profile segment whose midpoint is within ``FILL_GAP_FACTOR`` x h0 of the
  blank's boundary (current configuration, point-to-segment distance);
  ``contact_fraction``: length fraction of the profile touched *now* (it flickers while the formed
  blank rings elastically on the die); ``fill_fraction``: length fraction touched at some recorded
  time so far (how far the blank has been formed into the die, insensitive to the ringing);
  ``unfilled_length_mm``: the profile length never touched. ``--resume`` restarts the "so far"
  record at the resume time (the history before it is not re-read).
* die stress: von Mises = sqrt(3 J2) per die cell, maximum over the die; the paper plots J2(sigma)
  (its figures' unit is MPa, so we report sqrt(J2) = von Mises / sqrt(3) beside it).
* blank speed: largest nodal speed of the blank (``blank_speed_max_m_s``; it spikes for a few
  steps when the blank strikes the die, single nodes are thrown by the contact layer) and the
  mass-weighted rms speed sqrt(2 KE / m) (``blank_rms_speed_max_m_s``, the blank's flight speed).
* contact pressure on the die: largest soft-contact stress of the blank -> die pair.

Maxima over time are taken over the history rows (every ``output.history_every`` steps).
Serial runs only (the geometry queries use this rank's nodes).
"""

from __future__ import annotations

import numpy as np

FILL_GAP_FACTOR = 2.0  # a profile point counts as touched when the blank is within 2 h0 of it


def _point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) of each point p (P, 2) to the nearest segment a-b (S, 2)."""
    t = b - a
    L2 = np.maximum((t ** 2).sum(axis=1), 1e-300)
    d = p[:, None, :] - a[None, :, :]
    xi = np.clip((d * t[None]).sum(axis=2) / L2[None], 0.0, 1.0)
    q = a[None] + xi[..., None] * t[None]
    return np.sqrt(((p[:, None, :] - q) ** 2).sum(axis=2)).min(axis=1)


class CornerFill:
    """History columns, metrics and plots of the corner-filling cases."""

    def __init__(self, case) -> None:
        self.case = case
        self.pair = next(i for i, c in enumerate(case.contact) if c.slave == "blank" and c.master == "die")
        self.h0 = case.contact[self.pair].h0
        self._profile = None
        self._ever = None  # per profile segment: touched at some recorded time so far

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
        blank = solver.bodies["blank"]
        self._blank_segs = blank.segments

    def touched(self, solver) -> np.ndarray:
        """Per cavity-profile segment: is the blank within FILL_GAP_FACTOR h0 of its midpoint."""
        if self._profile is None:
            self._setup(solver)
        die, blank = solver.bodies["die"], solver.bodies["blank"]
        mid = 0.5 * (die.x[self._profile[:, 0]] + die.x[self._profile[:, 1]])
        bs = self._blank_segs
        dist = _point_segment_distance(mid, blank.x[bs[:, 0]], blank.x[bs[:, 1]])
        return dist <= FILL_GAP_FACTOR * self.h0

    # ------------------------------------------------------------------ hooks
    def record(self, solver) -> dict[str, float]:
        touched = self.touched(solver)
        self._ever = touched if self._ever is None else (self._ever | touched)
        die, blank = solver.bodies["die"], solver.bodies["blank"]
        vm = float(die.von_mises.max()) if len(die.cells) else 0.0
        _, _, p, _ = solver.contact_pressure(self.pair)
        speed = float(np.sqrt((blank.v[: blank.n_owned] ** 2).sum(axis=1)).max())
        ke = solver.energies()
        ratio = ke["kinetic_J"] / max(ke["elastic_J"] + ke["plastic_J"], 1e-300)
        return {
            "fill_fraction": float(self._profile_len0[self._ever].sum() / self._profile_len0.sum()),
            "contact_fraction": float(self._profile_len0[touched].sum() / self._profile_len0.sum()),
            "unfilled_length_m": float(self._profile_len0[~self._ever].sum()),
            "die_von_mises_max_Pa": vm,
            "die_sqrt_J2_max_Pa": vm / np.sqrt(3.0),
            "blank_speed_max_m_s": speed,
            "blank_rms_speed_m_s": float(np.sqrt((blank.mass[: blank.n_owned] * (blank.v[: blank.n_owned] ** 2).sum(axis=1)).sum()
                                                 / blank.mass[: blank.n_owned].sum())),
            "die_contact_pressure_max_Pa": float(p.max()) if len(p) else 0.0,
            "blank_apex_gap_m": self._apex_gap(solver),
            "kinetic_to_deformation_ratio": float(ratio),
        }

    def _apex_gap(self, solver) -> float:
        """Distance (m) from the die's deepest profile point (the apex) to the blank."""
        if self._profile is None:
            self._setup(solver)
        die, blank = solver.bodies["die"], solver.bodies["blank"]
        pts = die.x[self._profile.ravel()]
        apex = pts[np.argmin(pts[:, 1])][None]
        bs = self._blank_segs
        return float(_point_segment_distance(apex, blank.x[bs[:, 0]], blank.x[bs[:, 1]])[0])

    def metrics(self, solver, history) -> dict[str, float]:
        ff = history.column("fill_fraction")
        cf = history.column("contact_fraction")
        vm = history.column("die_von_mises_max_Pa")
        sp = history.column("blank_speed_max_m_s")
        cp = history.column("die_contact_pressure_max_Pa")
        out = {
            "fill_fraction": float(ff[-1]),
            "contact_fraction_final": float(cf[-1]),
            "unfilled_length_mm": float(history.column("unfilled_length_m")[-1]) * 1e3,
            "apex_gap_final_mm": float(history.column("blank_apex_gap_m")[-1]) * 1e3,
            "die_mises_max_MPa": float(vm.max()) / 1e6,
            "die_sqrt_J2_max_MPa": float(vm.max()) / np.sqrt(3.0) / 1e6,
            "blank_speed_max_m_s": float(sp.max()),
            "blank_rms_speed_max_m_s": float(history.column("blank_rms_speed_m_s").max()),
            "die_contact_pressure_max_MPa": float(cp.max()) / 1e6,
            "die_plastic_strain_max": float(solver.bodies["die"].eps_p.max()),
            "blank_plastic_strain_max": float(solver.bodies["blank"].eps_p.max()),
        }
        out.update(self._per_pulse(history))
        out.update(self._quasi_static(history))
        return out

    def _quasi_static(self, history) -> dict[str, float]:
        """Preforming check (cases with mass damping and a first, slowly ramped pulse): the kinetic /
        (elastic + plastic) energy ratio while the damping acts,

        * ``preform_kinetic_ratio_top_max``: largest ratio while the preform pressure is >= 90 % of
          its amplitude (the top of the ramp, where the preformed shape is set);
        * ``preform_kinetic_ratio_max``: largest ratio while it is >= 10 % (includes the start of
          the ramp, where the slack blank moves with hardly any internal energy: large ratios);
        * ``preform_kinetic_ratio_end``: at the end of the damping window.
        Milestone rows (load columns 0 there) are skipped."""
        mo = self.case.mechanics
        if mo.mass_damping <= 0.0 or not self.case.loads or "load0_pressure_Pa" not in history.columns:
            return {}
        t = history.column("time_s")
        p = history.column("load0_pressure_Pa")
        r = history.column("kinetic_to_deformation_ratio")
        amp = self.case.loads[0].amplitude
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
            out[f"pulse{k}_contact_fraction_end"] = float(history.column("contact_fraction")[m][-1])
            out[f"pulse{k}_start_time_s"] = a
        return out

    # ------------------------------------------------------------------ plots
    def plots(self, history, shapes, folder) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        t = history.column("time_s") * 1e6
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
        ax[2].set_xlabel("time (µs)")
        for a, _ in self._windows(history):
            for x in ax:
                x.axvline(a * 1e6, color="0.7", lw=0.8, ls="--")
        fig.suptitle("Corner filling: die stress, blank speed, fill (cf. paper Fig. 3/4)")
        fig.tight_layout()
        fig.savefig(folder / "corner_fill_history.png", dpi=110)
        plt.close(fig)
        if shapes:
            self._plot_shapes(history, shapes, folder, plt)

    def _plot_shapes(self, history, shapes, folder, plt) -> None:
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
                    label=f"t = {ts * 1e6:.0f} µs")
        ax.set_aspect("equal")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        ax.legend(fontsize=7, markerscale=8)
        ax.set_title("blank shapes (half model, symmetry at x = 0)")
        fig.tight_layout()
        fig.savefig(folder / "corner_fill_shapes.png", dpi=110)
        plt.close(fig)
