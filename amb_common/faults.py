"""
Fault types and the fault event record of the core (mirrors ``amb_msgs/FaultEvent``).

Times are kept as sample indices; the node maps them onto message stamps and the evaluation
onto seconds (``sample_index / fs`` at constant speed).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from enum import IntEnum
from typing import Any

__all__ = ["FINAL", "PROVISIONAL", "WITHDRAWN", "FaultEvent", "FaultType", "event_status"]

#: ``evidence["status"]`` of the events of a monitor with provisional classes
#: (``MonitorConfig.provisional_revs``): an early class, the decision that confirms or revises
#: it (with ``provisional_class`` and ``revised``), and a copy of a provisional event that the
#: decision found void (another fault's consequence). Events without it are final.
PROVISIONAL, FINAL, WITHDRAWN = "provisional", "final", "withdrawn"


def event_status(evidence: Mapping[str, Any]) -> tuple[str, bool]:
    """
    ``(status, revised)`` of an event's evidence (``""`` and False when it has none).

    Takes the core's :attr:`FaultEvent.evidence` (``revised`` a bool) or a ``FaultEvent``
    message's key-value pairs as a dict (values as text: ``"True"``).
    """
    revised = evidence.get("revised", False)
    return str(evidence.get("status", "")), revised is True or revised == "True"


class FaultType(IntEnum):
    """Fault classes; values equal the ``amb_msgs/FaultEvent`` constants."""

    UNKNOWN = 0
    MASS_LOSS = 1
    AUX_BEARING_CONTACT = 2
    SENSOR_FAULT = 3
    BASE_MOTION = 4
    COIL_FAILURE = 5
    TRIP = 6


@dataclass
class FaultEvent:
    """
    One classified fault (thesis chapter 5, Table 5.1).

    Attributes
    ----------
    fault_type : FaultType
    onset_sample_index : int
        Estimated onset: the first crossing back-dated within the support of the wavelet
        that saw it, to the time centre of its atom (the strongest of the coefficients that
        crossed first; see :func:`amb_fault_monitor.onset.estimate_onset`).
    detection_sample_index : int
        The sample at which the detection was confirmed (alarm).
    decision_sample_index : int
        The sample at which the class was decided (the event is emitted then).
    samples_per_rev : int
    omega : float
        Running speed at the decision, rad/s.
    plane : int
        Sensor plane 1..4 most affected, 0 = all / none.
    channel : int
        Sensor channel 0..7 (sensor faults), -1 = none.
    bearing : int
        Clearance bearing nearest the largest fine-level response (contacts): 1, 2 = auxiliary
        bearings in AMB 1, 2; 3, 4 = retainers at planes 1, 4; 0 = none.
    severity : float
        m, size of the change in the deciding (normalised) coefficient.
    confidence : float
        0..1, margin-based (``1 - exp(-(r - 1))`` with ``r`` the deciding ratio to its
        threshold); an ordering of certainty, not a calibrated probability.
    count : int
        Occurrences in this event (contact bursts), >= 1.
    evidence : dict
        Levels, frames, ratios and thresholds that decided (str -> str/float).
    description : str
    event_id : int
        Assigned by the event log (0 until logged).
    """

    fault_type: FaultType
    onset_sample_index: int
    detection_sample_index: int
    decision_sample_index: int
    samples_per_rev: int
    omega: float
    plane: int = 0
    channel: int = -1
    bearing: int = 0
    severity: float = 0.0
    confidence: float = 0.0
    count: int = 1
    evidence: dict[str, Any] = field(default_factory=dict)
    description: str = ""
    event_id: int = 0

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able mapping (``fault_type`` as its name)."""
        d = asdict(self)
        d["fault_type"] = self.fault_type.name
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> FaultEvent:
        """Inverse of :meth:`to_dict`."""
        d = dict(d)
        d["fault_type"] = FaultType[d["fault_type"]]
        known = set(cls.__dataclass_fields__)
        return cls(**{k: v for k, v in d.items() if k in known})
