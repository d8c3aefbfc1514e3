"""
What a controller configuration selects: bases, force waveform, prescribed response, guard.

The control and measurement bases, the control force's waveform, the alpha(z) of eq. 8.6-8.7
and the divergence guard a :class:`~amb_controller.config.ControllerConfig` asks for. Shared
by the controller pipeline, the baselines and the applications that rebuild a configuration's
layout (:mod:`amb_apps.closed_loop`, :mod:`amb_apps.compare_runs`).
"""

from __future__ import annotations

from amb_controller.basis import BasisSet, control_basis, measurement_basis
from amb_controller.config import N_AXES, SENSOR_NAMES, ControllerConfig
from amb_controller.fourier_basis import sinusoid_control_basis
from amb_controller.guard import DivergenceGuard, GuardConfig
from amb_controller.response import PrescribedResponse

__all__ = [
    "control_waveform",
    "controller_guard",
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


def controller_guard(
    config: ControllerConfig, probe_clearance: tuple[float, ...] | None = None
) -> DivergenceGuard:
    """
    The divergence guard of a controller pipeline, from its configuration and the rig.

    Parameters
    ----------
    config : ControllerConfig
        ``coefficient_bound``, ``displacement_bound``, ``growth_factor``, ``growth_periods``
        and ``contact_guard``.
    probe_clearance : tuple of float, optional
        Per probe channel, the clearance of the auxiliary bearing next to it, m (inf: none;
        :attr:`amb_common.rig.Rig.probe_clearance`; None: not known). With ``contact_guard`` a
        probe that reads it trips the guard: the rotor is at or next to that bearing, where the
        model the controller was designed on no longer holds (the contact stiffens the rotor's
        support) and a controller that goes on integrating drives it from contact to contact
        (thesis 3.3.2 stops the transient controller on contact).

    Returns
    -------
    DivergenceGuard
    """
    return DivergenceGuard(
        GuardConfig(
            coefficient_bound=config.coefficient_bound,
            displacement_bound=config.displacement_bound,
            growth_factor=config.growth_factor,
            growth_periods=config.growth_periods,
            probe_clearance=(
                tuple(float(c) for c in probe_clearance)
                if config.contact_guard and probe_clearance is not None
                else None
            ),
        )
    )
