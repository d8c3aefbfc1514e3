"""
The sample-domain model of the early action (:mod:`amb_controller.early_action`) and its file.

Arrays ``bearing_markov`` and ``plane_responses`` (defined in :class:`EarlyActionModel`) and a
JSON ``meta`` (samples per revolution, planes, sensors, objective, clearance, speed, source) in
an ``.npz``, read with ``allow_pickle=False``. ``amb-early-model`` writes one from the FE route
(:func:`amb_apps.plant_models.early_action_model`); the ``wavelet_controller`` node reads it
(parameter ``early_model_file``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from amb_controller.errors import ControllerValueError, ShapeError
from amb_controller.model_file import read_npz, write_npz

__all__ = ["FORMAT", "EarlyActionModel"]

#: the ``format`` entry of the file's ``meta``
FORMAT = "amb-early-action-1"


@dataclass(frozen=True)
class EarlyActionModel:
    """
    Sample-domain responses of the PID loop at one running speed (module docstring, "Model").

    Attributes
    ----------
    samples_per_rev : int
        ``N``, samples per revolution (= per control period).
    bearing_markov : numpy.ndarray
        Shape ``(L, n_s, 4)``: sensor response to 1 N held over sample 0 per bearing axis
        ``[b1x, b1y, b2x, b2y]``, m/N.
    plane_responses : numpy.ndarray
        Shape ``(n_planes, L_p, n_s, 2)``: sensor response to a unit sudden unbalance (1 kg m)
        appearing at sample 0 with angle 0 and pi/2, m/(kg m); ``L_p >= L + 2 N``.
    planes : tuple of str
        The planes' names (the rig's disk tags).
    sensors : tuple of int
        The ``n_s`` sensor channels of the responses (indices of ``[x1, y1, .., x4, y4]``):
        the estimate and the clearance check use them all.
    objective : tuple of int
        Positions in ``sensors`` whose displacement the plan minimises (E2-E3); empty: all.
    clearance : float
        The rig's smallest auxiliary-bearing or retainer clearance, m (the plan's check).
    omega : float
        Running speed the responses are for, rad/s.
    source : str
        Where the responses come from (e.g. ``"fe"``).
    """

    samples_per_rev: int
    bearing_markov: np.ndarray
    plane_responses: np.ndarray
    planes: tuple[str, ...]
    sensors: tuple[int, ...]
    objective: tuple[int, ...] = ()
    clearance: float = math.inf
    omega: float = 0.0
    source: str = "fe"

    def __post_init__(self) -> None:
        h = np.asarray(self.bearing_markov, dtype=float)
        g = np.asarray(self.plane_responses, dtype=float)
        n = int(self.samples_per_rev)
        if h.ndim != 3 or h.shape[2] != 4:
            raise ShapeError(f"bearing_markov must be (L, n_s, 4), got {h.shape}")
        if g.ndim != 4 or g.shape[2] != h.shape[1] or g.shape[3] != 2:
            raise ShapeError(
                f"plane_responses must be (n_planes, L_p, {h.shape[1]}, 2), got {g.shape}"
            )
        if len(self.sensors) != h.shape[1]:
            raise ShapeError(f"{len(self.sensors)} sensors for {h.shape[1]} response columns")
        objective = tuple(int(i) for i in self.objective) or tuple(range(h.shape[1]))
        if any(not 0 <= i < h.shape[1] for i in objective):
            raise ShapeError(f"objective {objective} outside the {h.shape[1]} sensors")
        object.__setattr__(self, "objective", objective)
        if len(self.planes) != g.shape[0]:
            raise ShapeError(f"{len(self.planes)} plane names for {g.shape[0]} planes")
        if n < 4 or h.shape[0] < 2 * n or g.shape[1] < h.shape[0] + 2 * n:
            raise ShapeError(
                f"need L >= 2 N and L_p >= L + 2 N (N = {n}), got L = {h.shape[0]}, "
                f"L_p = {g.shape[1]}"
            )
        if not (np.all(np.isfinite(h)) and np.all(np.isfinite(g))):
            raise ControllerValueError("early-action model contains NaN or inf")
        object.__setattr__(self, "bearing_markov", h)
        object.__setattr__(self, "plane_responses", g)

    def save(self, path: str | Path) -> Path:
        """Write the model to ``path`` (``.npz``, arrays and a JSON ``meta``); return it."""
        meta = {
            "format": FORMAT,
            "samples_per_rev": int(self.samples_per_rev),
            "planes": list(self.planes),
            "sensors": [int(i) for i in self.sensors],
            "objective": [int(i) for i in self.objective],
            "clearance": float(self.clearance),
            "omega": float(self.omega),
            "source": self.source,
        }
        return write_npz(
            path, meta, bearing_markov=self.bearing_markov, plane_responses=self.plane_responses
        )

    @classmethod
    def load(cls, path: str | Path) -> EarlyActionModel:
        """Read a model written by :meth:`save` (``allow_pickle=False``)."""
        meta, arrays = read_npz(
            path, ("bearing_markov", "plane_responses"), "early-action model", "amb-early-model"
        )
        if meta.get("format") != FORMAT:
            raise ControllerValueError(
                f"{path}: format {meta.get('format')!r}, expected {FORMAT!r} (amb-early-model)"
            )
        return cls(
            samples_per_rev=meta["samples_per_rev"],
            bearing_markov=arrays["bearing_markov"],
            plane_responses=arrays["plane_responses"],
            planes=tuple(meta["planes"]),
            sensors=tuple(meta["sensors"]),
            objective=tuple(meta["objective"]),
            clearance=meta["clearance"],
            omega=meta["omega"],
            source=meta["source"],
        )
