"""
The sample-domain models of the early action (:mod:`amb_controller.early_action`) and their file.

The responses hold at one running speed only: sampled at ``N`` per revolution, they change with
the speed, and near a critical speed fast (the 430 g cm loss at the first critical speed, the
plant 1 % faster than the model: no decision; the second critical with the model 1 % off
either way: none; within 0.5 % the runs equal those with the exact model;
docs/controller_notes.md). An :class:`EarlyModelBank` holds models at several speeds; the
stage uses the one nearest the measured speed, and none farther than the early action's
``speed_tolerance``.

File: arrays ``bearing_markov`` and ``plane_responses`` (defined in :class:`EarlyActionModel`)
stacked over the bank's ``K`` speeds (a leading axis), and a JSON ``meta`` (samples per
revolution, planes, sensors, objective, clearance per sensor (null: none; one number in files
written before), slew rate (absent or null: not bounded), the ``K`` speeds, source) in an
``.npz``, read with ``allow_pickle=False``; a file of format 1 (one model, no leading axis)
reads as a bank of one. ``amb-early-model`` writes one from the FE route
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

__all__ = ["FORMAT", "EarlyActionModel", "EarlyModelBank"]

#: the ``format`` entry of the file's ``meta`` (a bank; "amb-early-action-1": one model)
FORMAT = "amb-early-action-2"
_FORMAT_ONE = "amb-early-action-1"


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
    clearance : float or sequence of float
        Per sensor (``n_s``, in ``sensors`` order), the room its reading has before the rotor
        touches the clearance bearing nearest it, m (the plan's check; on the FE route
        :attr:`amb_common.rig.Rig.probe_nearest_clearance`); one number: the same at every
        sensor. Stored as a tuple of ``n_s``; a file of one number reads so.
    omega : float
        Running speed the responses are for, rad/s.
    slew_rate : float
        Fastest change of a bearing axis's force the amplifiers can make, N/s
        (:attr:`amb_common.rig.AmbData.force_slew_rate`; inf: not bounded). With ``omega``
        it bounds the plan's steps per sample (:class:`~amb_controller.early_action
        .EarlyActionConfig`, ``slew_budget``).
    source : str
        Where the responses come from (e.g. ``"fe"``).
    """

    samples_per_rev: int
    bearing_markov: np.ndarray
    plane_responses: np.ndarray
    planes: tuple[str, ...]
    sensors: tuple[int, ...]
    objective: tuple[int, ...] = ()
    clearance: float | tuple[float, ...] = math.inf
    omega: float = 0.0
    slew_rate: float = math.inf
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
        if np.ndim(self.clearance) > 1 or np.size(self.clearance) not in (1, h.shape[1]):
            raise ShapeError(f"clearance: one or {h.shape[1]} values, got {self.clearance}")
        clearance = np.broadcast_to(np.asarray(self.clearance, dtype=float), (h.shape[1],))
        if not np.all(clearance > 0.0):
            raise ControllerValueError(f"clearances must be > 0 m (inf: none), got {clearance}")
        object.__setattr__(self, "clearance", tuple(float(c) for c in clearance))
        if not self.slew_rate > 0.0:
            raise ControllerValueError(f"slew_rate must be > 0 N/s, got {self.slew_rate}")
        if not (np.all(np.isfinite(h)) and np.all(np.isfinite(g))):
            raise ControllerValueError("early-action model contains NaN or inf")
        object.__setattr__(self, "bearing_markov", h)
        object.__setattr__(self, "plane_responses", g)

    def save(self, path: str | Path) -> Path:
        """Write the model as a bank of one (:meth:`EarlyModelBank.save`); return the path."""
        return EarlyModelBank((self,)).save(path)

    @classmethod
    def load(cls, path: str | Path) -> EarlyActionModel:
        """Read a file of one model (:meth:`EarlyModelBank.load` reads banks)."""
        bank = EarlyModelBank.load(path)
        if len(bank.models) != 1:
            raise ControllerValueError(
                f"{path}: a bank of {len(bank.models)} models; read it with EarlyModelBank.load"
            )
        return bank.models[0]


@dataclass(frozen=True)
class EarlyModelBank:
    """
    Early-action models of one rig at several running speeds (module docstring).

    Attributes
    ----------
    models : tuple of EarlyActionModel
        Sorted by ``omega`` on construction; the same ``samples_per_rev``, response lengths,
        planes, sensors, objective and clearance, distinct speeds (> 0 when more than one).
    """

    models: tuple[EarlyActionModel, ...]

    def __post_init__(self) -> None:
        models = tuple(sorted(self.models, key=lambda m: m.omega))
        if not models:
            raise ControllerValueError("an early-action model bank needs at least one model")
        first = models[0]
        for m in models[1:]:
            same = (
                m.samples_per_rev == first.samples_per_rev
                and m.bearing_markov.shape == first.bearing_markov.shape
                and m.plane_responses.shape == first.plane_responses.shape
                and (m.planes, m.sensors, m.objective) == (first.planes, first.sensors,
                                                           first.objective)
                and m.clearance == first.clearance
                and m.slew_rate == first.slew_rate
            )  # fmt: skip
            if not same:
                raise ShapeError(
                    f"the model at {m.omega:.6g} rad/s differs from the one at "
                    f"{first.omega:.6g} rad/s in more than its responses"
                )
        omegas = np.array([m.omega for m in models])
        if len(models) > 1 and (omegas[0] <= 0.0 or np.any(np.diff(omegas) <= 0.0)):
            raise ControllerValueError(
                f"a bank's speeds must be > 0 and distinct, got {omegas.tolist()} rad/s"
            )
        object.__setattr__(self, "models", models)

    @property
    def omegas(self) -> np.ndarray:
        """The models' speeds, rad/s, ascending."""
        return np.array([m.omega for m in self.models])

    def select(self, omega: float, tolerance: float, current: int | None = None) -> int | None:
        """
        Index of the model to use at the measured speed ``omega`` (rad/s), or None.

        The nearest model, if its speed is within ``tolerance`` (relative) of ``omega``; a
        bank of one model of speed 0 (unknown) is always used. ``current`` is kept while it
        is within the tolerance and no other model is nearer by a quarter of their spacing
        (no switching back and forth at a midpoint: each switch starts the test afresh).
        """
        omegas = self.omegas
        if len(omegas) == 1 and omegas[0] == 0.0:
            return 0
        off = np.abs(omegas - omega)
        best = int(np.argmin(off))
        if off[best] > tolerance * omega:
            return None
        if current is not None and current != best and off[current] <= tolerance * omega:
            if off[current] - off[best] < 0.25 * abs(omegas[current] - omegas[best]):
                return current
        return best

    def save(self, path: str | Path) -> Path:
        """Write the bank to ``path`` (``.npz``, arrays and a JSON ``meta``); return it."""
        m = self.models[0]
        meta = {
            "format": FORMAT,
            "samples_per_rev": int(m.samples_per_rev),
            "planes": list(m.planes),
            "sensors": [int(i) for i in m.sensors],
            "objective": [int(i) for i in m.objective],
            # JSON has no inf: null (no clearance bearing by that sensor)
            "clearance": [c if math.isfinite(c) else None for c in m.clearance],
            "slew_rate": float(m.slew_rate) if math.isfinite(m.slew_rate) else None,
            "omegas": [float(x.omega) for x in self.models],
            "source": m.source,
        }
        return write_npz(
            path,
            meta,
            bearing_markov=np.stack([x.bearing_markov for x in self.models]),
            plane_responses=np.stack([x.plane_responses for x in self.models]),
        )

    @classmethod
    def load(cls, path: str | Path) -> EarlyModelBank:
        """Read a bank (or a single model of format 1) written by :meth:`save`."""
        meta, arrays = read_npz(
            path, ("bearing_markov", "plane_responses"), "early-action model", "amb-early-model"
        )
        fmt = meta.get("format")
        h, g = arrays["bearing_markov"], arrays["plane_responses"]
        if fmt == _FORMAT_ONE:
            h, g, omegas = h[None], g[None], [meta["omega"]]
        elif fmt == FORMAT:
            omegas = meta["omegas"]
        else:
            raise ControllerValueError(
                f"{path}: format {fmt!r}, expected {FORMAT!r} (amb-early-model)"
            )
        # files written before the slew bound have none: not bounded
        slew = meta.get("slew_rate")
        slew = math.inf if slew is None else float(slew)
        # one number in files written before the per-sensor clearances
        clearance = meta["clearance"]
        if isinstance(clearance, list):
            clearance = tuple(math.inf if c is None else float(c) for c in clearance)
        if h.shape[0] != len(omegas) or g.shape[0] != len(omegas):
            raise ShapeError(
                f"{path}: {len(omegas)} speeds for {h.shape[0]} / {g.shape[0]} responses"
            )
        return cls(
            tuple(
                EarlyActionModel(
                    samples_per_rev=meta["samples_per_rev"],
                    bearing_markov=h[k],
                    plane_responses=g[k],
                    planes=tuple(meta["planes"]),
                    sensors=tuple(meta["sensors"]),
                    objective=tuple(meta["objective"]),
                    clearance=clearance,
                    omega=omegas[k],
                    slew_rate=slew,
                    source=meta["source"],
                )
                for k in range(len(omegas))
            )
        )
