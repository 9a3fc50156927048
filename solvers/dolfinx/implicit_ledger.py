"""The implicit solver's energy ledger, the commit of a converged step and the restart state (a part of
:class:`~.implicit.ImplicitSteps`). Under MPI the ledger's sums run over the owned rows and cells and are summed
over the ranks; positions, velocities and accelerations are updated on every local row (the ghosts' inputs equal
their owners')."""
from __future__ import annotations

from typing import Dict, Mapping

import numpy as np

__all__ = ["ImplicitLedger"]

#: the implicit ledger's accumulators (J), in the order of the checkpoint's ``implicit/acc``
IACC_KEYS = ("internal_work_J", "support_work_J", "contact_work_J", "wall_work_J")


class ImplicitLedger:
    """Energies and state of the implicit steps, over those of the explicit solver they extend."""

    def energies(self) -> Dict[str, float]:
        """The explicit solver's ledger (J) plus ``internal_work_J`` (trapezoidal work of the internal
        forces), ``support_work_J`` (work of the reactions on prescribed motions, part of
        ``external_work_J``), ``contact_work_J`` and ``wall_work_J`` (trapezoidal work of the contact forces and
        of the walls' reactions; ``wall_dissipated_J`` is minus the latter) and ``algorithmic_dissipation_J``
        (external, contact and wall work - kinetic energy change - internal work: 0 to the Newton tolerance
        for the trapezoidal rule, what HHT-alpha damps), which ``balance_error_J`` counts as dissipated."""
        e = super().energies()
        e.update(self._iacc)
        diss = (e["external_work_J"] + self._iacc["contact_work_J"] + self._iacc["wall_work_J"]
                - (e["kinetic_J"] - self._KE0) - self._iacc["internal_work_J"])
        e["algorithmic_dissipation_J"] = diss
        e["balance_error_J"] += diss
        return e

    def _commit(self, trial, dt: float, s0: float, s1: float) -> None:
        """Take the converged iterate ``trial`` of a step of ``dt`` (s) taking the load fraction from ``s0`` to
        ``s1``: positions, velocities, accelerations, stresses, plastic strain and the ledger (J)."""
        o = self.options
        static = o.scheme == "static"
        beta, gamma = o.beta, o.gamma
        w_int = w_sup = w_ext = w_p = w_con = w_wall = 0.0
        r_end, x_end = {}, {}
        for n, b in self.bodies.items():
            no = b.n_owned
            du = trial.du[n]
            res = trial.results[n]
            fint, fcon = res.force_nodal, trial.contact.force[n]
            if static:
                a_new = np.zeros_like(b.x)
                v_new = np.zeros_like(b.x)
            else:
                a_new = (du - dt * b.v - dt * dt * (0.5 - beta) * b.a) / (beta * dt * dt)
                v_new = b.v + dt * ((1.0 - gamma) * b.a + gamma * a_new)
                ke = 0.5 * float(np.sum(b.mass[:no, None] * v_new[:no] ** 2))
                trial.walls.stop(n, v_new, a_new)
                w_wall -= ke - 0.5 * float(np.sum(b.mass[:no, None] * v_new[:no] ** 2))   # the wall's impact
            m = self._mask[n][:no]
            # supports and walls: their reaction R = M a + f_int - f_c - F (trapezoidal average) works on the
            # prescribed motion
            F0, F1 = self._load(n, s0), self._load(n, s1)
            r_old = b.mass[:, None] * b.a + self._fint[n] - self._fcon[n] - F0
            r_end[n] = b.mass[:, None] * a_new + fint - fcon - F1
            w_sup += float(np.sum((du * 0.5 * (r_old + r_end[n]))[:no][m]))
            w_int += float(np.sum(du[:no] * 0.5 * (self._fint[n][:no] + fint[:no])))
            w_con += float(np.sum(du[:no] * 0.5 * (self._fcon[n][:no] + fcon[:no])))
            w_ext += float(np.sum(du[:no] * 0.5 * (F0[:no] + F1[:no])))
            w_p += float(np.sum(res.plastic_work))
            b.x += du
            x_end[n] = b.x
            b.v[...] = v_new
            b.a[...] = a_new
            b.cell_stress[...] = np.real(res.stress)
            b.eps_p += res.deps_p
            self._fint[n] = fint
            self._fcon[n] = fcon
        fwall = trial.walls.wall_force(r_end)
        for n, b in self.bodies.items():
            no = b.n_owned
            w_wall += float(np.sum(trial.du[n][:no] * 0.5 * (self._fwall[n][:no] + fwall[n][:no])))
            self._fwall[n] = fwall[n]
        if self.comm.size > 1:
            w_int, w_sup, w_ext, w_p, w_con, w_wall = (float(v) for v in self._linear.sums(
                [w_int, w_sup, w_ext, w_p, w_con, w_wall]))
        self._wall_out = trial.walls.pressures(r_end, x_end)
        self._active, self._contact_out = trial.contact.active, trial.contact.out
        self._contact_stored = trial.contact.stored
        self._contact_work += w_con
        self._iacc["contact_work_J"] += w_con
        self._iacc["wall_work_J"] += w_wall
        self._acc["wall_dissipated_J"] -= w_wall
        self._iacc["internal_work_J"] += w_int
        self._iacc["support_work_J"] += w_sup
        self._acc["external_work_J"] += w_ext + w_sup
        self._acc["plastic_J"] += w_p
        self.time += dt
        self.step_count += 1

    def state_dict(self) -> Dict[str, np.ndarray]:
        """The explicit solver's state plus the internal, contact and wall forces of the last step, the
        implicit ledger and the adaptive step's controller."""
        d = super().state_dict()
        for n in self.bodies:
            d[f"{n}/implicit_fint"] = self._fint[n].copy()
            d[f"{n}/implicit_fcon"] = self._fcon[n].copy()
            d[f"{n}/implicit_fwall"] = self._fwall[n].copy()
            d[f"{n}/implicit_f_from"] = self._f_from[n].copy()
        d["implicit/acc"] = np.array([self._iacc[k] for k in IACC_KEYS] + [self._KE0])
        d["implicit/adapt"] = self.adapt_state()
        return d

    def load_state_dict(self, d: Mapping[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict`."""
        super().load_state_dict(d)
        for n in self.bodies:
            self._fint[n] = np.array(d[f"{n}/implicit_fint"], dtype=float)
            self._fcon[n] = np.array(d[f"{n}/implicit_fcon"], dtype=float)
            self._fwall[n] = np.array(d[f"{n}/implicit_fwall"], dtype=float)
            self._f_from[n][...] = np.asarray(d[f"{n}/implicit_f_from"], dtype=float)
        acc = [float(v) for v in np.asarray(d["implicit/acc"], dtype=float)]
        for k, v in zip(IACC_KEYS, acc):
            self._iacc[k] = v
        self._KE0 = acc[-1]
        if "implicit/adapt" in d:   # (checkpoints before the adaptive step: the fixed step)
            self.load_adapt_state(d["implicit/adapt"])
