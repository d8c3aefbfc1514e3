"""
What a controller configuration selects: bases, force waveform, prescribed response.

The control and measurement bases, the control force's waveform and the alpha(z) of eq.
8.6-8.7 a :class:`~amb_controller.config.ControllerConfig` asks for. Shared by the controller
pipeline, the baselines and the applications that rebuild a configuration's layout
(:mod:`amb_apps.closed_loop`, :mod:`amb_apps.compare_runs`).
"""

from __future__ import annotations

from amb_controller.basis import BasisSet, control_basis, measurement_basis
from amb_controller.config import N_AXES, SENSOR_NAMES, ControllerConfig
from amb_controller.fourier_basis import sinusoid_control_basis
from amb_controller.response import PrescribedResponse

__all__ = [
    "control_waveform",
    "prescribed_response",
    "selected_control_basis",
    "selected_measurement_basis",
]


def selected_control_basis(config: ControllerConfig) -> BasisSet:
    """
    Control-coefficient basis of the configuration (its waveforms and labels).

    ``output_basis = "wavelet"``: :func:`amb_controller.basis.control_basis` of the configured
    wavelet, levels and quadratures (the thesis); ``"sinusoid"``: the 1 x cosine / sine per
    axis in the same layout (:func:`amb_controller.fourier_basis.sinusoid_control_basis`).
    """
    n = config.period_samples
    if config.output_basis == "sinusoid":
        return sinusoid_control_basis(n, N_AXES, config.quadratures)
    return control_basis(config.wavelet, n, config.levels, N_AXES, config.quadratures)


def control_waveform(config: ControllerConfig) -> str:
    """The control force's waveform (``ControlCommand.wavelet``): the wavelet, or sinusoid."""
    return "sinusoid" if config.output_basis == "sinusoid" else config.wavelet


def selected_measurement_basis(config: ControllerConfig) -> BasisSet:
    """
    Measured-coefficient basis of the configured levels, quadratures and sensors.

    The rows of :func:`amb_controller.basis.measurement_basis` (8 sensor channels) whose
    channel is in ``config.sensors``, in the same order (level, translation, quadrature,
    channel); labels keep the physical channel (``c2`` = x2).
    """
    full = measurement_basis(
        config.wavelet, config.period_samples, config.levels, len(SENSOR_NAMES), config.quadratures
    )
    keep = [i for i, lab in enumerate(full.labels) if int(lab.split("/c")[-1]) in config.sensors]
    return BasisSet(full.weights[keep], full.offset, tuple(full.labels[i] for i in keep))


def prescribed_response(config: ControllerConfig) -> PrescribedResponse:
    """Return the alpha(z) of eq. 8.6-8.7 the configuration asks for."""
    if config.response == "exponential":
        return PrescribedResponse.exponential(config.w, config.v)
    if config.response == "linear":
        return PrescribedResponse.linear_decay(config.rate)
    return PrescribedResponse.from_series(config.series)
