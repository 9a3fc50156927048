"""The replay log of a persistent getdp segment: what a resume needs to bring a new process into the
uninterrupted run's state bit for bit without ending the running one at every checkpoint.

A *segment* is one getdp process's life: it starts from a seed (an :class:`~.model.EMState`, fresh
or with its nodal BDF2 history, and the mesh's node positions) and then receives one message per EM
step (the mesh's new node positions, t_end). getdp is deterministic, so a new process started from
the same seed and sent the same messages reaches the same unknowns, bit for bit; a process seeded
with the state at the checkpoint instead differs at round-off (docs/getdp.md). A checkpoint therefore
stores the segment's seed state and its messages so far (:meth:`ReplayLog.to_arrays`), and a resume
replays them (:meth:`~.persistent.PersistentGetDPSolver.step`).

A segment ends after :func:`segment_length` steps (a bound on the replay's getdp time and on the
checkpoint's size, from the node count alone, so that a run and its resume end it at the same step):
the next step starts a new process seeded with the exact state there, in both runs.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from .model import EMState

#: node-steps a segment may hold: ~15 s of getdp replay on this machine (~15 µs per node and step,
#: bench/em_step.py) and ~16 MB of node positions in a checkpoint
REPLAY_NODE_STEPS = 1_000_000
#: the shortest segment (a process start costs ~0.1 s; per step 12-500 ms)
MIN_SEGMENT_STEPS = 20


def segment_length(n_nodes: int) -> int:
    """EM steps after which a persistent getdp segment ends (a new process is seeded): depends on the
    mesh's node count only, so a run and its resume end segments at the same steps."""
    return max(MIN_SEGMENT_STEPS, REPLAY_NODE_STEPS // max(int(n_nodes), 1))


def connectivity_signature(triangles: np.ndarray, tags: np.ndarray) -> np.ndarray:
    """A short fingerprint of a mesh's connectivity (the replay's mesh must be the segment's)."""
    tri = np.ascontiguousarray(triangles, np.int64)
    return np.array([len(tri), int(tri.sum()), int((tri[:, 0] * 3 + tri[:, 1] * 7 + tri[:, 2] * 11).sum()),
                     int(np.asarray(tags, np.int64).sum())], np.int64)


@dataclass
class ReplayLog:
    """A segment's seed and the steps sent since.

    Attributes
    ----------
    seed : EMState
        The state the segment's process started from (JSON round trip exact: plain floats).
    material : ndarray (N, 2)
        The material coordinates given at the start (m).
    signature : ndarray
        :func:`connectivity_signature` of the segment's mesh.
    points : list of ndarray (N, 2)
        The node positions each step moved the mesh to (m), in order (a redone step appears twice);
        the process started on the first step's positions.
    t_end : list of float
        End time of each step (s).
    base : list of int
        ``step_index`` of the state each step started from (a redo repeats the previous one).
    fields : list of bool
        Whether the step computed the field outputs (the same message flags on replay).
    coil_sigma, sigma : list of list of float, list of ndarray
        With σ(T) laws: each step's coil conductivities and the per-element conductivities its message carried
        (S/m; the element temperatures behind them are gone at a resume); empty without.
    """

    seed: EMState
    material: np.ndarray
    signature: np.ndarray
    points: list[np.ndarray] = field(default_factory=list)
    t_end: list[float] = field(default_factory=list)
    base: list[int] = field(default_factory=list)
    fields: list[bool] = field(default_factory=list)
    coil_sigma: list[list[float]] = field(default_factory=list)
    sigma: list[np.ndarray] = field(default_factory=list)

    def add(self, points: np.ndarray, t_end: float, base: int, fields: bool,
            sigma: tuple[list[float], np.ndarray] | None = None) -> None:
        """Record one step message (a copy of the node positions; ``sigma``: its coil and element
        conductivities, with σ(T) laws)."""
        if sigma is not None:
            self.coil_sigma.append([float(v) for v in sigma[0]])
            self.sigma.append(np.array(sigma[1], float))
        self.points.append(np.array(points, float))
        self.t_end.append(float(t_end))
        self.base.append(int(base))
        self.fields.append(bool(fields))

    def __len__(self) -> int:
        return len(self.t_end)

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The log as arrays for a checkpoint (``.npz``); :meth:`from_arrays` reads them back."""
        n = len(self.material)
        seed = json.dumps(self.seed.to_dict()).encode()
        return {"seed_json": np.frombuffer(seed, np.uint8), "material": self.material.copy(), "signature": self.signature.copy(),
                "points": np.array(self.points, float).reshape(len(self), n, 2),
                "t_end": np.array(self.t_end, float), "base": np.array(self.base, np.int64),
                "fields": np.array(self.fields, bool),
                **({"coil_sigma": np.array(self.coil_sigma, float), "sigma": np.array(self.sigma, float)}
                   if self.sigma else {})}

    @classmethod
    def from_arrays(cls, d: dict[str, np.ndarray]) -> "ReplayLog":
        """A log written by :meth:`to_arrays`."""
        seed = EMState.from_dict(json.loads(bytes(d["seed_json"]).decode()))
        log = cls(seed, np.array(d["material"], float), np.array(d["signature"], np.int64))
        log.points = [np.array(p) for p in d["points"]]
        log.t_end = [float(t) for t in d["t_end"]]
        log.base = [int(b) for b in d["base"]]
        log.fields = [bool(f) for f in d["fields"]]
        if "sigma" in d:
            log.coil_sigma = [[float(v) for v in row] for row in d["coil_sigma"]]
            log.sigma = [np.array(row, float) for row in d["sigma"]]
        return log

    def ends_at(self) -> tuple[int, float] | None:
        """(step_index, t) of the state after the last logged step, None if no step was logged."""
        if not len(self):
            return None
        return self.base[-1] + 1, self.t_end[-1]
