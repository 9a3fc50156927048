"""Electrical conductivity that follows temperature, σ(T), of a coil or a massive conductor (issue 33).

Two laws:

* :class:`ConductivityTable`: σ(T) piecewise linear through (temperature, conductivity) points, the end
  values held outside the table;
* :class:`LinearResistivity`: the resistivity grows linearly, ρ(T) = ρ_ref (1 + α (T − T_ref)), i.e.
  σ(T) = σ_ref / (1 + α (T − T_ref)) (copper: α = 3.9e-3 /K at 293 K).

How GetDP receives them: a coil is one lumped body (its temperature uniform, adiabatic during a shot: the
Joule heat so far over m c_p), so its σ is one number per EM step (``Coil_sigma_k``); a massive conductor's
σ is one value per element, ``Cond_SigmaList_k() = {element tag, σ, ...}`` read by the built-in deck with
``InterpolationLinear[ElementNum[]]`` (exact at the listed tags: no grouping of elements into bins).
Both are evaluated at the step's start temperatures (explicit in temperature, like the mechanics' heating).
The same functions serve the 3D per-step getdp (a :class:`~.mesh3d.Mesh3D`: tetrahedra keyed by their gmsh
numbers, the coil's m c_p and heat those of the modelled sector; ``em_case3d.pro``).
The persistent getdp (2D and 3D) cannot read a new ``run.pro`` per step: its step messages carry σ of every element
of the regions with a law (:func:`message_sigma`, :func:`persistent_numbers`; ``decks/Lib_PersistentSigma.pro``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

import numpy as np

from .bdf2 import trapezoid_mean
from .files import element_volumes
from .mesh import EMMesh, coil_tag, conductor_tag

if TYPE_CHECKING:
    from .model import EMModel, EMState

__all__ = ["ConductivityTable", "LinearResistivity", "ConductivityLaw", "law_from_dict", "element_list_line",
           "has_laws", "coil_mass_cp", "coil_heat_step", "coil_temperature", "step_sigma", "step_inputs",
           "persistent_numbers", "message_tags", "message_sigma", "checked_temperatures", "start_power", "check_deck"]


@dataclass(frozen=True)
class ConductivityTable:
    """σ(T) piecewise linear through the points (``temperatures`` K, strictly increasing; ``values`` S/m,
    > 0), the end values held outside the table."""

    temperatures: tuple[float, ...]
    values: tuple[float, ...]

    def __post_init__(self) -> None:
        t = np.asarray(self.temperatures, float)
        v = np.asarray(self.values, float)
        if t.ndim != 1 or t.shape != v.shape or len(t) < 1:
            raise ValueError("a conductivity table needs as many conductivities as temperatures (at least one)")
        if np.any(np.diff(t) <= 0) or np.any(t <= 0):
            raise ValueError("a conductivity table's temperatures must be > 0 K and strictly increasing")
        if np.any(v <= 0) or not np.all(np.isfinite(v)):
            raise ValueError("a conductivity table's values must be finite and > 0 (S/m)")
        object.__setattr__(self, "temperatures", tuple(float(x) for x in t))
        object.__setattr__(self, "values", tuple(float(x) for x in v))

    def __call__(self, temperature: float | np.ndarray) -> np.ndarray:
        """σ (S/m) at ``temperature`` (K)."""
        return np.interp(np.asarray(temperature, float), self.temperatures, self.values)


@dataclass(frozen=True)
class LinearResistivity:
    """σ(T) = σ_ref / (1 + α (T − T_ref)): ``sigma_ref`` S/m at ``reference_temperature`` K, ``alpha`` 1/K.
    Refused where the resistivity would not stay positive (a temperature below T_ref − 1/α is an error)."""

    sigma_ref: float
    alpha: float
    reference_temperature: float = 293.15

    def __post_init__(self) -> None:
        if not (self.sigma_ref > 0 and np.isfinite(self.sigma_ref)):
            raise ValueError("LinearResistivity: sigma_ref must be finite and > 0 (S/m)")
        if not self.reference_temperature > 0:
            raise ValueError("LinearResistivity: reference_temperature must be > 0 (K)")

    def __call__(self, temperature: float | np.ndarray) -> np.ndarray:
        """σ (S/m) at ``temperature`` (K)."""
        f = 1.0 + self.alpha * (np.asarray(temperature, float) - self.reference_temperature)
        if np.any(f <= 0):
            raise ValueError(f"LinearResistivity: 1 + alpha (T - T_ref) <= 0 at T = "
                             f"{float(np.min(temperature)):.6g} K (alpha = {self.alpha:g} /K)")
        return self.sigma_ref / f


ConductivityLaw = ConductivityTable | LinearResistivity


def law_from_dict(d: dict | ConductivityLaw | None) -> ConductivityLaw | None:
    """A law from its ``dataclasses.asdict`` form (an :class:`~.model.EMModel` read back from JSON)."""
    if d is None or isinstance(d, (ConductivityTable, LinearResistivity)):
        return d
    if "temperatures" in d:
        return ConductivityTable(tuple(d["temperatures"]), tuple(d["values"]))
    return LinearResistivity(**d)


def element_list_line(name: str, tags: Sequence[int] | np.ndarray, sigma: Sequence[float] | np.ndarray) -> str:
    """``<name>() = {tag, σ, ...};`` sorted by tag, for ``InterpolationLinear[ElementNum[]]`` (one element is
    listed twice, at tag and tag + 1: the interpolation needs two points)."""
    tags = np.asarray(tags, np.int64)
    sigma = np.asarray(sigma, float)
    if tags.shape != sigma.shape or tags.ndim != 1 or len(tags) == 0:
        raise ValueError("element_list_line needs as many conductivities as element tags (at least one)")
    order = np.argsort(tags, kind="stable")
    tags, sigma = tags[order], sigma[order]
    if np.any(np.diff(tags) == 0):
        raise ValueError("element_list_line: an element tag is listed twice")
    if len(tags) == 1:
        tags, sigma = np.array([tags[0], tags[0] + 1]), np.array([sigma[0], sigma[0]])
    pairs = [f"{t}, {s:.17g}" for t, s in zip(tags.tolist(), sigma.tolist())]
    body = ",\n  ".join(", ".join(pairs[j:j + 8]) for j in range(0, len(pairs), 8))
    return f"{name}() = {{\n  {body}}};"


def has_laws(model) -> bool:
    """True when a coil or a conductor of ``model`` (2D or 3D) has a σ(T) law."""
    return any(c.conductivity_law is not None for c in list(model.coils) + list(model.conductors))


# The EM mesh is a 2D EMMesh (triangles, element tag = row + 1) or a 3D Mesh3D (tetrahedra with their gmsh ids):
# the helpers below are the only places that tell them apart.
def _cell_tags(mesh) -> np.ndarray:
    """The physical id of every EM cell (triangle or tetrahedron)."""
    return mesh.tet_tags if hasattr(mesh, "tet_tags") else mesh.tri_tags


def _element_ids(mesh, rows: np.ndarray) -> np.ndarray:
    """GetDP's element numbers (``ElementNum[]``) of the cells ``rows``."""
    return np.asarray(mesh.tet_ids)[rows] if hasattr(mesh, "tet_ids") else rows + 1


def _region_volume(model, mesh, tag: int) -> float:
    """Volume (m³) of region ``tag``: 2πr-weighted in axisymmetry, per metre in planar, the modelled part in 3D."""
    rows = np.flatnonzero(_cell_tags(mesh) == tag)
    if hasattr(mesh, "tet_tags"):
        return float(mesh.volumes(rows).sum())
    return float(element_volumes(mesh, rows, model.axisymmetric).sum())


def coil_mass_cp(model: "EMModel", mesh: EMMesh) -> np.ndarray:
    """m c_p (J/K) of every coil of ``model``: density × heat capacity × the coil region's volume (2πr-weighted in
    axisymmetry, per metre in planar; in 3D the modelled sector's, whose Joule power is the sector's too)."""
    return np.array([c.density * c.heat_capacity * _region_volume(model, mesh, coil_tag(k))
                     for k, c in enumerate(model.coils, start=1)])


def coil_heat_step(state: "EMState", coil_sigma: Sequence[float], power_end: np.ndarray, dt: float,
                   bdf2: bool) -> np.ndarray:
    """The coils' Joule heat (J) after a step of ``dt`` s from ``state`` whose end power is ``power_end`` (W):
    the heat so far plus the rectangle rule (implicit Euler) or the trapezoid from :func:`start_power` (BDF2)."""
    power_end = np.asarray(power_end, float)
    heat = np.asarray(state.coil_heat or [0.0] * len(power_end), float)
    if not bdf2:
        return heat + power_end * dt
    return heat + trapezoid_mean(start_power(state, coil_sigma), power_end[None, :]) * dt


def coil_temperature(model: "EMModel", mesh: EMMesh, state: "EMState") -> np.ndarray:
    """The coils' lumped temperatures (K) at ``state``: initial temperature + Joule heat so far / (m c_p)."""
    heat = np.asarray(state.coil_heat or [0.0] * len(model.coils), float)
    t0 = np.array([c.initial_temperature for c in model.coils], float)
    return t0 + heat / coil_mass_cp(model, mesh) if len(model.coils) else t0


def step_sigma(model: "EMModel", mesh: EMMesh, state: "EMState", dt: float,
               elem_temperature: tuple[np.ndarray, np.ndarray] | None
               ) -> tuple[dict[int, float], list[tuple[int, np.ndarray, np.ndarray]]]:
    """The σ (S/m) of the σ(T) laws for a step of ``dt`` (s) from ``state`` on ``mesh``: {coil k: σ} and
    [(conductor k, its EM cell rows, σ per row)], only for the coils and conductors with a law.

    Each coil: σ at its lumped temperature predicted for the step's middle, T + P dt / (2 m c_p), P its Joule
    power at the step's start (``state.coil_power``; 0 from rest). Each conductor: σ per element at the
    temperatures ``elem_temperature`` = (EM cell rows: triangles in 2D, tetrahedra in 3D; K), an element not
    listed at the conductor's ``initial_temperature``.
    """
    coils: dict[int, float] = {}
    if any(c.conductivity_law is not None for c in model.coils):
        power = np.asarray(state.coil_power if state.coil_power is not None else [0.0] * len(model.coils), float)
        temp = coil_temperature(model, mesh, state) + 0.5 * dt * power / coil_mass_cp(model, mesh)
        for k, c in enumerate(model.coils, start=1):
            if c.conductivity_law is not None:
                coils[k] = float(c.conductivity_law(temp[k - 1]))
    conductors = []
    for k, c in enumerate(model.conductors, start=1):
        if c.conductivity_law is None:
            continue
        tags = _cell_tags(mesh)
        rows = np.flatnonzero(tags == conductor_tag(k))
        temp = np.full(len(rows), float(c.initial_temperature))
        if elem_temperature is not None:
            lookup = np.full(len(tags), np.nan)
            lookup[elem_temperature[0]] = elem_temperature[1]
            given = lookup[rows]
            temp = np.where(np.isnan(given), temp, given)
        conductors.append((k, rows, np.asarray(c.conductivity_law(temp), float)))
    return coils, conductors


def step_inputs(model: "EMModel", mesh: EMMesh, state: "EMState", dt: float,
                elem_temperature: tuple[np.ndarray, np.ndarray] | None) -> tuple[dict[str, float], list[str]]:
    """The numbers and ``run.pro`` lines of the σ(T) laws for a step of ``dt`` (s) from ``state`` (getdp per
    step; :func:`step_sigma`): ``Coil_sigma_k`` per coil with a law; per conductor with a law
    ``Cond_SigmaElem_k = 1`` and the list ``Cond_SigmaList_k`` of σ per element. Nothing without a law.
    """
    coils, conductors = step_sigma(model, mesh, state, dt, elem_temperature)
    numbers: dict[str, float] = {f"Coil_sigma_{k}": s for k, s in coils.items()}
    lines: list[str] = []
    for k, rows, sigma in conductors:
        numbers[f"Cond_SigmaElem_{k}"] = 1
        lines.append(element_list_line(f"Cond_SigmaList_{k}", _element_ids(mesh, rows), sigma))
    return numbers, lines


def persistent_numbers(model: "EMModel") -> dict[str, float]:
    """The ``-setnumber`` values of a persistent getdp whose step messages carry σ per element
    (``decks/Lib_PersistentSigma.pro``, ``PF_SigmaElem``): ``Coil_SigmaElem_k`` / ``Cond_SigmaElem_k`` = 2 for each coil
    and conductor with a law; empty without a law."""
    if not model.has_conductivity_laws:
        return {}
    out = {"PF_SigmaElem": 1.0}
    out.update({f"Coil_SigmaElem_{k}": 2.0 for k, c in enumerate(model.coils, start=1) if c.conductivity_law})
    out.update({f"Cond_SigmaElem_{k}": 2.0 for k, c in enumerate(model.conductors, start=1) if c.conductivity_law})
    return out


def message_tags(model: "EMModel", mesh: EMMesh) -> np.ndarray:
    """Element tags (``ElementNum[]``) of every element of the regions with a law, in the order of
    :func:`message_sigma`'s values: the coils with a law, then the conductors with one, each by number."""
    tags = [_element_ids(mesh, np.flatnonzero(_cell_tags(mesh) == coil_tag(k)))
            for k, c in enumerate(model.coils, start=1) if c.conductivity_law is not None]
    tags += [_element_ids(mesh, np.flatnonzero(_cell_tags(mesh) == conductor_tag(k)))
             for k, c in enumerate(model.conductors, start=1) if c.conductivity_law is not None]
    return np.concatenate(tags).astype(np.int64) if tags else np.zeros(0, np.int64)


def message_sigma(model: "EMModel", mesh: EMMesh, coils: dict[int, float],
                  conductors: list[tuple[int, np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """(element tags, σ S/m) of every element of the regions with a law, for a persistent getdp's step message
    (:func:`message_tags`' order): a coil's elements all at its σ, a conductor's at their own (:func:`step_sigma`'s
    values)."""
    values = [np.full(int(np.count_nonzero(_cell_tags(mesh) == coil_tag(k))), sigma) for k, sigma in coils.items()]
    values += [np.asarray(sigma, float) for _, _, sigma in conductors]
    values = np.concatenate(values).astype(float) if values else np.zeros(0)
    tags = message_tags(model, mesh)
    if len(tags) != len(values):
        raise ValueError("message_sigma: the σ given are not those of every coil and conductor with a law")
    return tags, values


def checked_temperatures(elements: np.ndarray, temperature: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(element rows, temperatures K) as flat arrays, refused unless one finite temperature > 0 per element."""
    elements = np.asarray(elements, np.int64).ravel()
    temperature = np.asarray(temperature, float).ravel()
    if elements.shape != temperature.shape:
        raise ValueError("element temperatures: one temperature per element")
    if not np.all(np.isfinite(temperature)) or np.any(temperature <= 0):
        raise ValueError("element temperatures must be finite and > 0 K")
    return elements, temperature


def start_power(state: "EMState", coil_sigma: Sequence[float]) -> np.ndarray:
    """The coils' Joule power (W) at the start of a BDF2 step, for its trapezoid: the state's end power of the
    step before (0 from rest), taken at this step's σ (``coil_sigma``, S/m) where a σ(T) changed it (P ∝ 1/σ at a
    given current): the heat of the circuit the step solves."""
    p = np.asarray(state.coil_power if state.coil_power is not None else [0.0] * len(coil_sigma), float)
    if state.coil_sigma is not None:
        p = p * np.asarray(state.coil_sigma, float) / np.asarray(coil_sigma, float)
    return p


def check_deck(model: "EMModel", deck: Path, builtin: Path) -> None:
    """Refuse a σ(T) law on a deck other than the built-in ``builtin`` (it alone reads per-element σ)."""
    if model.has_conductivity_laws and Path(deck).resolve() != Path(builtin).resolve():
        raise ValueError("a conductivity that follows temperature needs the built-in deck (em_case.pro): "
                         f"{Path(deck).name} has no per-element conductivity")
