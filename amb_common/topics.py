"""
Topic and service names, each stream's message type, and the exchange's default delay.

One home for the names of ARCHITECTURE.md's topic table: every node, the replay bridge, the
recorder, the in-process loop's bag, ``amb-run`` and the bag reader take them from here. So
does :data:`DELAY_PERIODS`, the default delay both ends of ``/amb/control/command`` must agree
on (the plant refuses a command made for another delay).
"""

from __future__ import annotations

__all__ = [
    "CLOCK",
    "COEFFICIENTS",
    "COMMAND",
    "DELAY_PERIODS",
    "DIAGNOSTICS",
    "FAULT_EVENTS",
    "INJECT_FAULT",
    "MEASUREMENT",
    "PREFIX",
    "SET_MODE",
    "START_IDENTIFICATION",
    "STATUS",
    "STREAM_TYPES",
]

#: Prefix of the system's own topics (the recorder's default pattern is ``PREFIX + "*"``).
PREFIX = "/amb/"
#: One sample of the rig: displacements, currents, forces, angle, speed (plant or bridge).
MEASUREMENT = "/amb/measurement"
#: The filterbank's wavelet coefficients of the measurement stream.
COEFFICIENTS = "/amb/wavelet/coefficients"
#: The controller's wavelet force for one control period.
COMMAND = "/amb/control/command"
#: The controller's state, once a period.
STATUS = "/amb/control/status"
#: The fault monitor's classified events.
FAULT_EVENTS = "/amb/fault/events"
#: Every node's health report.
DIAGNOSTICS = "/diagnostics"
#: Simulated time (plant_sim).
CLOCK = "/clock"
#: Services.
INJECT_FAULT = "/amb/plant/inject_fault"
SET_MODE = "/amb/control/set_mode"
START_IDENTIFICATION = "/amb/control/start_identification"

#: Default control delay i in periods (thesis section 8.5.1: "the controller evaluation time
#: required there to be a 2 cycle delay in control action"): the command computed from measured
#: period k is applied in period k + i. Default of ``ControllerConfig.delay_periods`` and of the
#: plant's ``delay_periods`` parameter; ``config/amb_params.yaml`` sets both nodes under ``/**``.
DELAY_PERIODS: int = 2

#: The streams a run's bag holds, with their rosbag2 message types.
STREAM_TYPES = {
    MEASUREMENT: "amb_msgs/msg/Measurement",
    COEFFICIENTS: "amb_msgs/msg/WaveletCoefficients",
    COMMAND: "amb_msgs/msg/ControlCommand",
    STATUS: "amb_msgs/msg/ControllerStatus",
    FAULT_EVENTS: "amb_msgs/msg/FaultEvent",
}
