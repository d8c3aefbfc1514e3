"""
Identified wavelet-domain model file (``.npz``).

Written after identification and loaded at start by the ``wavelet_controller`` node.

Arrays: ``markov`` (A^(k), eq. 6.34), ``inverse`` (B^(k), eq. 6.35), ``offset`` and
``residual_rms`` of the fit. Metadata (JSON string ``meta``): wavelet, samples_per_rev,
omega (rad/s), levels, quadratures, n_axes, n_sensor_channels, delay, date (ISO 8601,
UTC), source, and the control/measured coefficient labels. Loaded with
``allow_pickle=False``. :func:`write_npz` and :func:`read_npz` (arrays and a JSON ``meta``)
serve the early action's model file too (:mod:`amb_controller.early_model`).
"""

from __future__ import annotations

import datetime as _dt
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from amb_common.topics import DELAY_PERIODS
from amb_controller.errors import ControllerValueError

FORMAT_VERSION = 1


def write_npz(path: str | Path, meta: dict, **arrays: np.ndarray) -> Path:
    """Write ``arrays`` and ``meta`` (a JSON string array ``meta``) to ``path``; return it."""
    path = Path(path)
    with path.open("wb") as fh:
        np.savez(fh, **arrays, meta=np.array(json.dumps(meta)))
    return path


def read_npz(path: str | Path, names, what: str, hint: str) -> tuple[dict, dict]:
    """
    Read ``meta`` and the arrays ``names`` of a file :func:`write_npz` wrote.

    ``allow_pickle=False``. A missing file, array or a file of another kind raises
    :class:`ControllerValueError` "cannot read {what} {path}: ...; expected an .npz written by
    {hint}".
    """
    try:
        with np.load(path, allow_pickle=False) as data:
            return json.loads(str(data["meta"])), {k: data[k] for k in names}
    except (OSError, KeyError, ValueError) as exc:
        raise ControllerValueError(
            f"cannot read {what} {path}: {exc}; expected an .npz written by {hint}"
        ) from exc


@dataclass(frozen=True)
class WaveletModel:
    """
    An identified (or modelled) wavelet-domain plant and its truncated inverse.

    Attributes
    ----------
    markov : numpy.ndarray
        ``(M+1, n_y, n_u)``.
    inverse : numpy.ndarray
        ``(K+1, n_u, n_y)``.
    wavelet : str
        PyWavelets name.
    samples_per_rev : int
        Samples per revolution (period).
    omega : float
        Running speed in rad/s at identification.
    levels : tuple of int
        Thesis levels p.
    quadratures : tuple of str
        ``("even", "odd")`` or a subset.
    n_axes, n_sensor_channels : int
        Physical channels of the control and measured layouts.
    delay : int
        Evaluation delay the model is meant for (periods).
    offset, residual_rms : numpy.ndarray
        Identification background and fit residual (``(n_y,)``; zeros if modelled).
    date : str
        ISO 8601 UTC time stamp.
    source : str
        ``"identification"``, ``"model"`` or free text.
    control_labels, measured_labels : tuple of str
        Coefficient labels (see :mod:`amb_controller.basis`).

    """

    markov: np.ndarray
    inverse: np.ndarray
    wavelet: str
    samples_per_rev: int
    omega: float
    levels: tuple[int, ...]
    quadratures: tuple[str, ...] = ("even", "odd")
    n_axes: int = 4
    n_sensor_channels: int = 8
    delay: int = DELAY_PERIODS
    offset: np.ndarray | None = None
    residual_rms: np.ndarray | None = None
    date: str = field(
        default_factory=lambda: _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    )
    source: str = "identification"
    control_labels: tuple[str, ...] = ()
    measured_labels: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        # C order always: a model used straight from its computation and the same model
        # loaded from its file must give bit-identical commands, and BLAS sums in a
        # layout-dependent order (a Fortran-ordered inverse differed by an ulp).
        markov = np.ascontiguousarray(self.markov, dtype=float)
        inverse = np.ascontiguousarray(self.inverse, dtype=float)
        if markov.ndim != 3 or inverse.ndim != 3 or inverse.shape[1:] != markov.shape[2:0:-1]:
            raise ControllerValueError(
                f"markov (M+1, n_y, n_u) and inverse (K+1, n_u, n_y) disagree: {markov.shape}, "
                f"{inverse.shape}"
            )
        n_y = markov.shape[1]
        object.__setattr__(self, "markov", markov)
        object.__setattr__(self, "inverse", inverse)
        for name in ("offset", "residual_rms"):
            value = getattr(self, name)
            object.__setattr__(
                self, name, np.zeros(n_y) if value is None else np.ascontiguousarray(value, float)
            )

    def save(self, path: str | Path) -> Path:
        """Write the model to ``path`` (``.npz``); return the path written."""
        meta = {
            "format_version": FORMAT_VERSION,
            "wavelet": self.wavelet,
            "samples_per_rev": int(self.samples_per_rev),
            "omega": float(self.omega),
            "levels": [int(p) for p in self.levels],
            "quadratures": list(self.quadratures),
            "n_axes": int(self.n_axes),
            "n_sensor_channels": int(self.n_sensor_channels),
            "delay": int(self.delay),
            "date": self.date,
            "source": self.source,
            "control_labels": list(self.control_labels),
            "measured_labels": list(self.measured_labels),
        }
        return write_npz(
            path,
            meta,
            markov=self.markov,
            inverse=self.inverse,
            offset=self.offset,
            residual_rms=self.residual_rms,
        )

    @classmethod
    def load(cls, path: str | Path) -> WaveletModel:
        """Read a model written by :meth:`save`."""
        meta, arrays = read_npz(
            path,
            ("markov", "inverse", "offset", "residual_rms"),
            "wavelet model",
            "WaveletModel.save (identify again to create one)",
        )
        if meta.get("format_version") != FORMAT_VERSION:
            raise ControllerValueError(
                f"model {path} has format_version {meta.get('format_version')}, expected "
                f"{FORMAT_VERSION}"
            )
        return cls(
            markov=arrays["markov"],
            inverse=arrays["inverse"],
            wavelet=meta["wavelet"],
            samples_per_rev=meta["samples_per_rev"],
            omega=meta["omega"],
            levels=tuple(meta["levels"]),
            quadratures=tuple(meta["quadratures"]),
            n_axes=meta["n_axes"],
            n_sensor_channels=meta["n_sensor_channels"],
            delay=meta["delay"],
            offset=arrays["offset"],
            residual_rms=arrays["residual_rms"],
            date=meta["date"],
            source=meta["source"],
            control_labels=tuple(meta["control_labels"]),
            measured_labels=tuple(meta["measured_labels"]),
        )

    def check_compatible(
        self, wavelet: str, samples_per_rev: int, omega: float, rtol: float = 0.05
    ):
        """
        Raise :class:`ControllerValueError` if the model does not fit the running setup.

        Parameters
        ----------
        wavelet : str
            Wavelet in use.
        samples_per_rev : int
            Samples per revolution in use.
        omega : float
            Current running speed in rad/s.
        rtol : float
            Relative speed tolerance (the wavelet-domain dynamics change with speed).

        """
        if wavelet != self.wavelet or samples_per_rev != self.samples_per_rev:
            raise ControllerValueError(
                f"model is for wavelet={self.wavelet!r}, samples_per_rev={self.samples_per_rev}; "
                f"running {wavelet!r}, {samples_per_rev}: identify again at this setting"
            )
        if abs(omega - self.omega) > rtol * abs(self.omega):
            raise ControllerValueError(
                f"model identified at omega={self.omega:.4g} rad/s, running at {omega:.4g} rad/s "
                f"(tolerance {rtol:.0%}): identify again at this speed"
            )
