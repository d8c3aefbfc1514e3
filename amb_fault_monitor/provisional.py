"""
The provisional class of an undecided episode and the probe readings it reads (monitor step 3).

1.5 revolutions after an episode's onset (``provisional_revs``) the 1 x level has not
settled, so the final rules of :mod:`amb_fault_monitor.classifier` cannot apply yet. What can
be told then, in this order:

1. a probe whose reading alone jumped within a quarter revolution of the onset reads off:
   ``SENSOR_FAULT`` of its channel (:mod:`amb_fault_monitor.probe_jumps`);
2. otherwise :func:`~amb_fault_monitor.classifier.classify_provisional` decides from the
   episode's coefficients and the shape of the readings' change over the last revolution
   (:mod:`amb_fault_monitor.revolution_change`): a 1 x sinusoid on a slow drift is a mass
   loss, anything more a contact.

Both read the measured probe readings, fed sample by sample (:meth:`ProvisionalClass.add`);
without them the class comes from the coefficients alone.
"""

from __future__ import annotations

import numpy as np

from amb_fault_monitor.classifier import Decision, EpisodeEvidence, classify_provisional
from amb_fault_monitor.probe_jumps import ProbeJumps, jump_decision
from amb_fault_monitor.revolution_change import RevolutionChange

__all__ = ["ProvisionalClass"]


class ProvisionalClass:
    """
    The jump test and the change's shape over the probe readings, and the class they give.

    Parameters
    ----------
    config : MonitorConfig
        May be replaced (``config``); the readings kept are sized from ``samples_per_rev``
        and ``provisional_revs``.
    """

    def __init__(self, config) -> None:
        self.jumps = ProbeJumps(config)
        self.change = RevolutionChange(config)

    @property
    def config(self):
        """The parameters, those of the jump test and of the change's shape."""
        return self.jumps.config

    @config.setter
    def config(self, config) -> None:
        self.jumps.config = self.change.config = config

    def reset(self) -> None:
        """Forget the readings, the jumps and the calibration (a restart of the stream)."""
        self.jumps.reset()
        self.change.reset()

    def add(self, n: int, displacement: np.ndarray) -> None:
        """Sample ``n``'s probe readings (8,), m, ``[x1, y1, ..., x4, y4]``."""
        self.jumps.add(n, displacement)
        self.change.add(n, displacement)

    def calibrate(self, end: int) -> None:
        """Set the jump test's thresholds from the calibration window ending at ``end``."""
        self.jumps.calibrate(end)

    def decide(self, n: int, onset: int, evidence: EpisodeEvidence, mask: np.ndarray) -> Decision:
        """
        The provisional class at sample ``n`` of an episode with estimated ``onset``.

        Parameters
        ----------
        n, onset : int
            Sample indices.
        evidence : EpisodeEvidence
            The episode's coefficients so far (its ``residual_ratio`` is set here).
        mask : numpy.ndarray
            Channels in use (8,), bool.
        """
        config = self.config
        quarter = config.samples_per_rev // 4
        jump = self.jumps.single_channel(onset - quarter, onset + quarter, mask)
        if jump is not None:
            return jump_decision(jump, config.jump_factor)
        evidence.residual_ratio = self.change.residual_ratio(onset, n, mask)
        return classify_provisional(evidence, config)
