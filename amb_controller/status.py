"""The ``ControllerStatus`` fields of a controller pipeline, wavelet or 1 x Fourier baseline.

One function for both pipelines (:class:`amb_controller.pipeline.ControllerPipeline` and
:class:`amb_controller.baselines.HarmonicPipeline`), so that the node's status message and the
in-process runner's records read the same counters the same way.
"""

from __future__ import annotations

import numpy as np

from amb_common.names import N_AXES

__all__ = ["status_fields"]


def status_fields(pipeline, identification_progress: float, model_file: str) -> dict:
    """The ``ControllerStatus`` fields of a pipeline (this one or a baseline's).

    Parameters
    ----------
    pipeline : ControllerPipeline or amb_controller.baselines.HarmonicPipeline
        Anything with ``config``, ``supervisor``, ``_last_command``, ``_last_period``,
        ``_compute_time`` (s) and ``_stats`` (commands_sent, commands_late, inputs_rejected).
    identification_progress : float
        0..1.
    model_file : str
        Model file in use ('' = none).

    Returns
    -------
    dict
        Keys as the message fields (see :meth:`ControllerPipeline.status`).
    """
    sup = pipeline.supervisor
    cmd = pipeline._last_command
    peak = np.zeros(N_AXES) if cmd is None else np.max(np.abs(cmd.force), axis=1)
    stats = pipeline._stats
    return {
        "mode": int(sup.mode),
        "controller": pipeline.config.controller,
        "period_index": int(pipeline._last_period),
        "delay_periods": int(pipeline.config.delay_periods),
        "compute_time": float(pipeline._compute_time),
        "peak_wavelet_force": peak.astype(float),
        "saturated": bool(cmd is not None and np.any(cmd.saturated)),
        "guard_tripped": bool(sup.guard is not None and sup.guard.tripped),
        "identification_progress": float(identification_progress),
        "commands_sent": int(stats["commands_sent"]),
        "commands_late": int(stats["commands_late"]),
        "commands_partial": int(stats["commands_partial"]),
        "inputs_rejected": int(stats["inputs_rejected"]),
        "model_file": model_file,
        "message": (cmd.message if cmd is not None and cmd.message else sup.message),
    }
