"""The implicit solver's energy ledger and restart state (a part of :class:`~.implicit.ImplicitSteps`)."""
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
