"""
amb_wavelet: the wavelet core of amb_wavelet_control (thesis chapter 4 and section 6.1).

ROS-free numpy/scipy building blocks; the ``wavelet_filterbank`` node (``node.py``) maps
topics and parameters onto them.

* :mod:`~amb_wavelet.filters` - orthogonal filters from PyWavelets' tables.
* :mod:`~amb_wavelet.levels` - level <-> pseudo-frequency <-> thesis ``p`` map, delays.
* :mod:`~amb_wavelet.analysis` - causal polyphase analysis filterbank, streaming + block.
* :mod:`~amb_wavelet.synthesis` - causal synthesis (reconstruction), streaming + block.
* :mod:`~amb_wavelet.frames` - synchronously rotating frame (eq. 2.26, 5.1-5.2).
* :mod:`~amb_wavelet.frontend` - channel set: frames x even/odd quadrature (section 4.3).
* :mod:`~amb_wavelet.period` - period-sampled x_{p,q}(kT) and x0(kT) (eq. 6.1-6.4).
* :mod:`~amb_wavelet.uncertainty` - Table 4.1 measures (eq. 4.29-4.36).
* :mod:`~amb_wavelet.info_cli` - the ``amb-wavelet-info`` command.
"""

from amb_wavelet.analysis import AnalysisFilterbank, Coefficient, Decomposition, analyze_block
from amb_wavelet.errors import LevelError, SampleIndexError, WaveletNameError
from amb_wavelet.filters import FilterSet, get_filters, orthogonal_wavelet_names
from amb_wavelet.frames import to_fixed_frame, to_rotating_frame
from amb_wavelet.frontend import ChannelFrontEnd, QuarterPeriodDelay
from amb_wavelet.levels import (
    check_level,
    harmonic_of_level,
    level_from_thesis_p,
    pseudo_frequency,
    revolution_level,
    support_length,
    synthesis_delay,
    thesis_p,
)
from amb_wavelet.period import (
    PeriodCoefficients,
    PeriodSampler,
    period_coefficients,
    period_position,
)
from amb_wavelet.synthesis import SynthesisFilterbank, basis_function, synthesize_block
from amb_wavelet.uncertainty import Uncertainty, filter_uncertainty, uncertainty

__all__ = [
    "AnalysisFilterbank",
    "ChannelFrontEnd",
    "Coefficient",
    "Decomposition",
    "FilterSet",
    "LevelError",
    "PeriodCoefficients",
    "PeriodSampler",
    "QuarterPeriodDelay",
    "SampleIndexError",
    "SynthesisFilterbank",
    "Uncertainty",
    "WaveletNameError",
    "analyze_block",
    "basis_function",
    "check_level",
    "filter_uncertainty",
    "get_filters",
    "harmonic_of_level",
    "level_from_thesis_p",
    "orthogonal_wavelet_names",
    "period_coefficients",
    "period_position",
    "pseudo_frequency",
    "revolution_level",
    "support_length",
    "synthesis_delay",
    "synthesize_block",
    "thesis_p",
    "to_fixed_frame",
    "to_rotating_frame",
    "uncertainty",
]
