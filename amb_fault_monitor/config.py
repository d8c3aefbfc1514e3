"""
Parameters of the fault monitor (:class:`MonitorConfig`), all times in revolutions of the rotor.

Where each parameter acts is documented with the part that uses it: the features and the
episode logic in :mod:`amb_fault_monitor.monitor`, the calibration window in
:mod:`amb_fault_monitor.calibration`, the synchronous level in :mod:`amb_fault_monitor.phasor`,
the contact bursts in :mod:`amb_fault_monitor.bursts`, the control transients in
:mod:`amb_fault_monitor.control_transients`, the stuck channels in
:mod:`amb_fault_monitor.dead_channels` and the classification in
:mod:`amb_fault_monitor.classifier`.

The fields the ``fault_monitor`` node declares as ROS parameters carry their default, a
description with its unit, the range the ROS descriptor enforces and whether they may change at
run time (:func:`~amb_common.config_fields.param` metadata, one home for each): the node declares
them from :func:`~amb_common.config_fields.parameter_fields` and builds :class:`MonitorConfig`
from them by name. The other fields are not ROS parameters (set in code, or per scenario by
``amb-fault-eval``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from amb_common.config_fields import param
from amb_fault_monitor.errors import FaultMonitorError

__all__ = ["FRAMES", "MonitorConfig", "with_levels"]

FRAMES = ("fixed", "rotating")


@dataclass(frozen=True)
class MonitorConfig:
    """
    Parameters of :class:`FaultMonitor` (all times in revolutions of the rotor).

    The ROS parameters' description, unit, range and run-time flag are their
    :func:`~amb_common.config_fields.param` metadata; the notes below add where each acts.
    Validated on construction (:class:`~amb_fault_monitor.errors.FaultMonitorError`).

    Attributes
    ----------
    samples_per_rev : int
        Power of two >= 4 (no default: the monitor must be told its stream's).
    levels : tuple of int
        Empty = every level received.
    settle_ratio : float
        Stationarity test of the calibration window: the median feature of its first half may
        exceed that of its second half by at most this factor (per level and frame, planes
        pooled), or the window slides on by one revolution (a start-up transient still decaying).
    k, threshold_floor
        The thresholds (:mod:`amb_fault_monitor.calibration`); the floor for noise-free signals.
    confirm_ratio, confirm_features, confirm_revs
        Detection confirmation (:mod:`amb_fault_monitor.monitor`, step 2).
    quiet_revs, decision_revs, max_tail_revs
        Episode timing (:mod:`amb_fault_monitor.monitor`, steps 3-4).
    decision_max_revs : float
        Longest wait for the decision while the 1 x level is still moving far from its
        reference (:mod:`amb_fault_monitor.phasor`); at least ``decision_revs``.
    rearm_revs : float
        After an episode ends, a new one needs a strong crossing (``confirm_ratio``) for this
        many revolutions: the ring-down of a large transient hovers at the threshold and would
        otherwise confirm on two weak features (:mod:`amb_fault_monitor.monitor`, step 4).
    isolation : float
        Share of the fixed-frame change energy in one channel that makes a sensor fault.
    base_coherence : float
        Plane coherence (0..1) of the fixed-frame changes below 1 x that makes base motion
        (classifier rule 2): 1 when the four planes move alike along x and along y.
    base_dominance : float
        Base motion also needs the largest change below 1 x (m) to be at least this multiple
        of the larger of the lasting 1 x phasor change and the largest change above 1 x (m):
        the slow motion dominates.
    sync_change : float
        Ratio over threshold of the synchronous phasor change that makes a new steady level.
    sync_relative_floor : float
        Smallest synchronous change counted, as a fraction of the pre-fault 1 x level.
    sustain : float
        The mean synchronous change over the latest ``settle_revs`` revolutions must be at
        least this fraction of the mean over the ``settle_revs`` before (a new level is
        sustained; a ring-down after a contact decays).
    settle_revs : int
        Revolutions of the synchronous-level settling test (:mod:`amb_fault_monitor.phasor`).
    settle_spread : float
        The synchronous change has settled when its spread (max - min) over the latest
        ``settle_revs`` revolutions is at most this fraction of its mean.
    burst_gap_revs : float
        Quiet gap separating two fine-level bursts (contacts).
    tail_rise : float
        A finest-level coefficient one revolution or more into an episode counts as a contact
        burst if its ratio is at least this many times the largest finest-level ratio of the
        preceding revolution (its last quarter excluded): a new impulse above the ringing's
        own envelope (:mod:`amb_fault_monitor.bursts`).
    tail_rise_median : float
        From a quarter revolution into an episode, a fixed-frame finest-level coefficient is also
        a contact burst if its ratio, or its change from the previous coefficient, is at least
        this many times the *median* of the same quantity since the episode began (at most one
        revolution back, its last eighth excluded): the robust envelope that an earlier contact
        spike does not inflate (:mod:`amb_fault_monitor.bursts`).
    weak_burst_ratio : float
        A burst needs a finest-level ratio of at least ``confirm_ratio``, or of at least this
        in the fixed frame with all three rises above (ring-down envelope, median, change):
        a light touch of a rotor already ringing (:mod:`amb_fault_monitor.bursts`).
    landing_fraction : float
        A probe plane whose radial displacement reaches this fraction of its nearest auxiliary
        bearing's radial clearance in a coil failure's episode has landed on that bearing: a
        contact, counted when the rise test found none in the episode (monitor notes, step 6;
        needs the clearances, :meth:`FaultMonitor.from_rig`).
    dead_fraction, dead_revs
        Stuck/zero channel test (:mod:`amb_fault_monitor.dead_channels`).
    control_step : float
        N, change of the applied control force on an axis from one revolution to the next
        that makes a control step (:mod:`amb_fault_monitor.control_transients`). The default
        lies well above the steady per-revolution adjustments of the controller and below the
        smallest drop that made an event (measurements: ``docs/fault_monitor_notes.md``).
    control_kink : float
        N, second difference of the applied control force on an axis from one sample to the
        next that makes a kink: a contact burst at a kink is the force's own response
        (:mod:`amb_fault_monitor.control_transients`). Default as ``control_step``: in steady
        control the sinusoidal force's second difference stays under 0.5 N at 64 samples per
        revolution; a law's command meeting the previous one while it reacts kinks ~20 N.
    control_window_revs : float
        How long after a step run an episode's estimated onset may lie to be its transient
        (:mod:`amb_fault_monitor.control_transients`). One revolution (one control period)
        leaves a margin and keeps short the time in which a real fault would be taken for the
        step.
    coil_floor, coil_factor, coil_confirm_revs
        Coil/amplifier check (:mod:`amb_fault_monitor.coil_check`): the smallest threshold of
        the demanded-minus-measured current, A; the threshold's factor over the largest healthy
        difference of the calibration window; how long it must hold, revolutions.
    bias_floor, bias_factor, bias_steady
        Biased probe inside the PID loop (:mod:`amb_fault_monitor.loop_bias`): the smallest
        step of an axis's one-revolution mean bearing force that counts, N; the threshold's
        factor over the largest healthy change of that mean from one revolution to the next
        in the calibration window; how far the last two revolutions' means may differ, as a
        share of the step (the new level is held). The floor is about a tenth of the step a 20 um
        offset gave on the suite (``docs/fault_monitor_notes.md``).
    provisional_revs : float
        Revolutions after an episode's estimated onset (at the alarm if later) at which a
        provisional class is published, to be confirmed or revised at the decision
        (:mod:`amb_fault_monitor.monitor`, step 3; 0: none). Its event's ``evidence`` has
        ``status: provisional``.
    provisional_ratio : float
        Fixed-frame over rotating-frame peak change above 1 x from which the provisional
        class of a change in both frames is a mass loss rather than a contact
        (:func:`~amb_fault_monitor.classifier.classify_provisional`; measured ratios:
        ``docs/fault_monitor_notes.md``, "Provisional classes").
    provisional_residual : float
        What a 1 x sinusoid and a straight line leave of the probe readings' change over the
        last revolution, over the sinusoid, at or below which the provisional class of a
        change in both frames is a mass loss rather than a contact
        (:mod:`amb_fault_monitor.revolution_change`; with the readings it replaces
        ``provisional_ratio``). Between the largest loss (0.10) and the smallest contact
        (0.12) of the suites (``docs/fault_monitor_notes.md``, "The change's shape").
    jump_factor, jump_isolation, jump_lasting
        The jump test of one probe's reading (:mod:`amb_fault_monitor.probe_jumps`): the
        smallest jump over the largest healthy one of its channel; how large another channel's
        (over its own) may be, as a share of it; how large the lasting change of slope may be,
        as a share of the jump. A provisional class is ``SENSOR_FAULT`` of the channel whose
        jumps alone lie within a quarter revolution of the episode's estimated onset. The
        factor lies between what offsets of 20 um and brief contacts gave on the suites
        (``docs/fault_monitor_notes.md``, "Jumps of one probe").
    """

    samples_per_rev: int = param(
        description="samples per revolution of the coefficient stream, power of two",
        ints=(4, 4096),
    )
    levels: tuple[int, ...] = param((), description="detail levels used, 1..log2(spr)+2")
    frames: tuple[str, ...] = param(FRAMES, description="fixed, rotating")
    calibration_revs: float = param(
        16.0, description="healthy calibration window, revolutions", floats=(1.0, 1e4)
    )
    settle_ratio: float = 2.0
    k: float = param(
        8.0, description="robust standard deviations of the thresholds", floats=(1.0, 100.0)
    )
    threshold_floor: float = param(2.0e-8, description="smallest threshold, m", floats=(0.0, 1e-3))
    confirm_ratio: float = 3.0
    confirm_features: int = 2
    confirm_revs: float = 1.0
    quiet_revs: float = param(
        2.0,
        description="hold-off: quiet revolutions that end an episode",
        floats=(0.25, 1e3),
    )
    decision_revs: float = param(
        16.0,
        description="longest wait from alarm to decision, revolutions",
        floats=(0.5, 1e3),
    )
    max_tail_revs: float = 200.0
    decision_max_revs: float = param(
        32.0,
        description="longest wait while the 1 x level still moves far from its reference, "
        "revolutions (>= decision_revs)",
        floats=(0.5, 1e3),
    )
    rearm_revs: float = 16.0
    isolation: float = 0.9
    base_coherence: float = 0.8
    base_dominance: float = 2.0
    sync_change: float = 1.5
    sync_relative_floor: float = 0.05
    sustain: float = 0.8
    settle_revs: int = 4
    settle_spread: float = 0.25
    burst_gap_revs: float = 0.5
    tail_rise: float = 1.7
    tail_rise_median: float = param(
        3.0,
        description="contact burst: finest-level ratio (or its change) over its median since "
        "the episode began",
        floats=(1.0, 100.0),
    )
    weak_burst_ratio: float = 1.5
    landing_fraction: float = 0.9
    dead_fraction: float = 0.02
    dead_revs: float = 1.0
    control_step: float = param(
        2.0,
        description="control step: change of the applied wavelet force on an axis from one "
        "revolution to the next, N",
        floats=(1e-3, 1e5),
        runtime=True,
    )
    control_kink: float = 2.0
    control_window_revs: float = 1.0
    coil_floor: float = param(
        0.1,
        description="coil check: smallest threshold of the demanded minus measured control "
        "current of an axis, A",
        floats=(1e-6, 100.0),
    )
    coil_factor: float = 4.0
    coil_confirm_revs: float = 0.25
    bias_floor: float = 20.0
    bias_factor: float = 4.0
    bias_steady: float = 0.25
    provisional_revs: float = param(
        0.0,
        description="publish a provisional class this many revolutions after the alarm (0: none)",
        floats=(0.0, 1e3),
    )
    provisional_ratio: float = 1.3
    provisional_residual: float = 0.115
    jump_factor: float = 4.0
    jump_isolation: float = 0.3
    jump_lasting: float = 0.75

    def __post_init__(self) -> None:
        spr = self.samples_per_rev
        if isinstance(spr, bool) or not isinstance(spr, int) or spr < 4 or spr & (spr - 1):
            raise FaultMonitorError(f"samples_per_rev must be a power of two >= 4, got {spr!r}")
        bad = [f for f in self.frames if f not in FRAMES]
        if bad or not self.frames:
            raise FaultMonitorError(
                f"frames must be a non-empty subset of {FRAMES}, got {self.frames}"
            )
        if any(int(j) != j or j < 1 for j in self.levels):
            raise FaultMonitorError(f"levels must be integers >= 1, got {self.levels}")
        positive = (
            "calibration_revs", "settle_ratio", "k", "confirm_ratio", "confirm_revs", "quiet_revs",
            "decision_revs", "max_tail_revs", "isolation", "sync_change", "burst_gap_revs",
            "tail_rise", "tail_rise_median", "weak_burst_ratio", "landing_fraction", "dead_revs",
            "base_coherence", "base_dominance", "rearm_revs", "control_step", "control_kink",
            "control_window_revs",
            "coil_floor", "coil_factor", "coil_confirm_revs", "bias_floor", "bias_factor",
            "bias_steady", "provisional_ratio", "provisional_residual", "jump_factor",
            "jump_isolation", "jump_lasting",
        )  # fmt: skip
        for name in positive:
            if not getattr(self, name) > 0:
                raise FaultMonitorError(f"{name} must be > 0, got {getattr(self, name)}")
        if self.settle_ratio < 1:
            raise FaultMonitorError(f"settle_ratio must be >= 1, got {self.settle_ratio}")
        if (
            self.threshold_floor < 0
            or self.sync_relative_floor < 0
            or self.dead_fraction < 0
            or self.provisional_revs < 0
        ):
            raise FaultMonitorError(
                "threshold_floor, sync_relative_floor, dead_fraction and provisional_revs must "
                "be >= 0"
            )
        if self.settle_revs < 2 or not self.settle_spread > 0:
            raise FaultMonitorError(
                f"settle_revs must be >= 2 and settle_spread > 0, got {self.settle_revs}, "
                f"{self.settle_spread}"
            )
        if self.decision_max_revs < self.decision_revs:
            raise FaultMonitorError(
                f"decision_max_revs ({self.decision_max_revs}) must be >= decision_revs "
                f"({self.decision_revs})"
            )
        if self.confirm_features < 1:
            raise FaultMonitorError(f"confirm_features must be >= 1, got {self.confirm_features}")
        if self.isolation > 1 or self.base_coherence > 1:
            raise FaultMonitorError(
                f"isolation and base_coherence are shares in (0, 1], got {self.isolation}, "
                f"{self.base_coherence}"
            )


def with_levels(config: MonitorConfig, levels: tuple[int, ...]) -> MonitorConfig:
    """Copy of ``config`` using ``levels``."""
    return replace(config, levels=tuple(levels))
