"""
Classification of a detected episode (thesis Table 5.1 and section 5.4).

Table 5.1 compares the wavelet coefficients in the fixed and the synchronously rotating
frames: a transient in the rotating frame with a new *steady state* in the fixed frame is a
sudden mass loss; a transient in *both* frames with no lasting change is a rotor/bearing
contact; a steady change in the rotating frame is "unidentified". Section 5.4 adds that
mass loss and contact excite many pseudo-frequencies, which separates them from
band-limited vibration such as base motion; chapter 3 characterises sensor faults as an
inconsistent or constant signal of one transducer. The rules, in order:

1. ``SENSOR_FAULT``: one channel carries at least ``isolation`` of the fixed-frame change
   energy (each channel's change normalised by its plane threshold), i.e. it disagrees with
   its plane partner and with the other planes while the rotor is not disturbed; or it
   carries that share at the finest level monitored alone. The second test is for the probes
   the bearings' PID closes its loop on (planes 2 and 3): there the loop turns the probe's
   error into bearing force, so the rotor really moves and its response spreads the change
   over every channel at and below 1 x. The rotor's mass filters that response as ``1 /
   omega**2``, so at the finest level (8-16 x running speed at 32 samples per revolution) the
   error of the probe itself still dominates, while a contact, the other local fault, moves
   the rotor and so the neighbouring planes and the partner axis with it (the finest-level
   shares measured on the suite: ``docs/fault_monitor_notes.md``, "Sensor faults inside the
   PID loop").
2. ``BASE_MOTION``: fixed-frame levels below 1 x cross on at least 3 of the 4 planes, the
   changes there are coherent across the planes (``low_coherence >= base_coherence``) and
   their largest value (m) is at least ``base_dominance`` times the larger of the lasting
   1 x phasor change and the largest fixed-frame change above 1 x (slow motion dominates;
   an impulse that happens to move the planes together, as in a rigid-rotor model, puts as
   much into the levels above 1 x; the ratios measured on the suite:
   ``docs/fault_monitor_notes.md``, "Classifier: base motion").
   Base motion enters eq. 3.6 as the inertial load ``-M y''`` of a housing translation
   ``y``, distributed with the rotor's mass, and is "typically low frequency" (Table 3.2):
   the motion relative to the housing moves all four planes together, in phase, below
   running speed. A sudden unbalance change is synchronous and excites the bending modes
   (planes in and out of phase: a low coherence, measured in the same notes); a contact is
   local to one bearing. Decision: section 5.4 separates base motion by its band ("nothing
   above 1 x"), but with Haar (one vanishing moment) the one-revolution change of the slope
   of a slow motion crosses the levels above 1 x too, so the band test cannot hold; the plane
   coherence of the slow part is the discriminating feature.
   With ``a_{p,k}`` the fixed-frame change of plane ``p`` along one axis at the ``k``-th
   coefficient below 1 x of the episode, ``low_coherence = sum_k (sum_p a_{p,k})**2 /
   (P sum_k sum_p a_{p,k}**2)`` over both axes (``P`` the planes in use), 1 when the planes
   move alike.
3. ``MASS_LOSS``: the rotating frame shows a transient (a crossing) and the fixed-frame
   synchronous phasor moved to a new level: ``sync_ratio >= sync_change`` on the two latest
   revolutions (Table 5.1, "sudden mass loss"; figure 5.29).
4. ``AUX_BEARING_CONTACT``: crossings at levels above 1 x in *both* frames (figure 5.30, the
   4 Omega coefficients) without a lasting synchronous change; the count is the number of
   separate bursts.
   Contacts *during* another fault's ring-down are found by the monitor's rise test
   (:mod:`amb_fault_monitor.bursts`) and reported as their own event.
5. ``UNKNOWN``: anything else (Table 5.1 "unidentified").

A *provisional* class (:func:`classify_provisional`) is given a revolution or two after the
onset, before the 1 x level can have settled and before the coefficients below 1 x (supports
of two revolutions and more) have seen much of a slow motion: rules 1 and 5 as above; rule 2
also when the fixed-frame changes at *every* level are coherent across the planes
(``coherence >= base_coherence``: a housing's translation moves the four probes alike, a
sudden unbalance excites the bending and conical modes, a contact is local); and rules 3-4 by
the frame the change above 1 x appears in. A sudden unbalance change adds a synchronous force,
``dF exp(j Omega t)`` from the onset on; in the rotating frame (multiplied by ``exp(-j Omega
t)``) that force is a step at 0 Hz, so its response's growth at and near 1 x, which the
fixed-frame levels just above 1 x take in (the filters' pass bands overlap), falls to the
rotating frame's levels below 1 x. A contact's impulses are broadband in both frames. The
largest change-to-threshold ratio above 1 x in the fixed frame over that in the rotating frame,
``fixed_over_rotating``, is therefore large for a mass loss and near 1 for a contact; at
``provisional_ratio`` or more the provisional class is ``MASS_LOSS``, else
``AUX_BEARING_CONTACT``. That is the rule without the probe readings. With long filters (db4)
and near a mode (67 Hz) the levels above 1 x have not told the two apart at 1.5
revolutions; the raw readings have: a loss's change over the last revolution is a sinusoid at
1 x on a slow drift, a contact's is not (:mod:`amb_fault_monitor.revolution_change`). Given the
readings, the provisional class of a change in both frames is ``MASS_LOSS`` when what a
sinusoid and a line leave of it, ``residual_ratio``, is at most ``provisional_residual``, else
``AUX_BEARING_CONTACT``; ``fixed_over_rotating`` is then reported, not used. The measured
ratios are in ``docs/fault_monitor_notes.md`` ("Provisional classes", "The change's shape").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np

from amb_common.faults import FaultType

__all__ = [
    "ClassifierThresholds",
    "Decision",
    "EpisodeEvidence",
    "classify",
    "classify_provisional",
    "ratio_confidence",
]


class ClassifierThresholds(Protocol):
    """
    The thresholds :func:`classify` reads.

    :class:`~amb_fault_monitor.config.MonitorConfig` has them; its docstring says what each
    means.
    """

    isolation: float
    base_coherence: float
    base_dominance: float
    confirm_ratio: float
    sync_change: float
    provisional_ratio: float
    provisional_residual: float


@dataclass
class EpisodeEvidence:
    """
    What the monitor saw during an episode.

    Attributes
    ----------
    revolution_level : int
        ``R``: level at 1 x running speed.
    max_ratio : dict
        ``(level, frame) -> (4,)`` largest change-to-threshold ratio per plane.
    channel_energy : numpy.ndarray
        (8,) sum of squared fixed-frame changes over crossing coefficients, each normalised by
        its plane threshold.
    fine_energy : numpy.ndarray
        (8,) the same at the finest level monitored alone (rule 1's second test).
    sync_ratio : numpy.ndarray
        (4,) synchronous phasor change / threshold per plane (smaller of the two latest
        revolutions).
    sync_change : numpy.ndarray
        (4,) synchronous phasor change per plane, m.
    bursts : list of tuple
        ``(start, end, max ratio fixed, max ratio rotating)`` of crossings above 1 x.
    mask : numpy.ndarray
        (8,) channels in use.
    low_coherence : float
        Plane coherence of the fixed-frame changes below 1 x (0..1, module docstring rule 2).
    low_peak : float
        Largest fixed-frame change below 1 x of any channel, m.
    high_peak : float
        Largest fixed-frame change above 1 x of any channel, m.
    coherence : float
        Plane coherence (as ``low_coherence``) of the fixed-frame changes at every level.
    residual_ratio : float or None
        What a 1 x sinusoid and a straight line leave of the probe readings' change in the
        last revolution, over the sinusoid (:mod:`amb_fault_monitor.revolution_change`;
        provisional classes only, None without the readings).
    """

    revolution_level: int
    max_ratio: dict[tuple[int, str], np.ndarray]
    channel_energy: np.ndarray
    sync_ratio: np.ndarray
    sync_change: np.ndarray
    bursts: list[tuple] = field(default_factory=list)
    mask: np.ndarray = field(default_factory=lambda: np.ones(8, dtype=bool))
    low_coherence: float = 0.0
    low_peak: float = 0.0
    high_peak: float = 0.0
    fine_energy: np.ndarray = field(default_factory=lambda: np.zeros(8))
    coherence: float = 0.0
    residual_ratio: float | None = None

    def peak(self, frame: str, which: str) -> np.ndarray:
        """Largest ratio per plane over levels ``above`` / ``below`` / ``at`` 1 x in ``frame``."""
        R = self.revolution_level
        sel = {
            "above": lambda j: j < R,
            "below": lambda j: j > R,
            "at": lambda j: j == R,
            "all": lambda j: True,
        }[which]
        out = np.zeros(4)
        for (j, f), r in self.max_ratio.items():
            if f == frame and sel(j):
                out = np.maximum(out, r)
        return out


@dataclass
class Decision:
    """
    Result of :func:`classify` (fields as in :class:`~amb_common.faults.FaultEvent`).

    No ``bearing``: the clearance bearing of a contact comes from the rig, which the monitor
    has (:class:`~amb_fault_monitor.monitor.FaultMonitor`, ``plane_bearings``).
    """

    fault_type: FaultType
    plane: int = 0
    channel: int = -1
    severity: float = 0.0
    confidence: float = 0.0
    count: int = 1
    evidence: dict[str, Any] = field(default_factory=dict)
    description: str = ""


def ratio_confidence(ratio: float) -> float:
    """
    Confidence of a decision from a test's ratio to its limit: ``1 - exp(-(ratio - 1))``.

    0 at the limit (``ratio`` 1), 0.63 at twice it, towards 1 beyond; clipped to [0, 1]. The
    confidence of every event the monitor emits.
    """
    return float(min(max(1.0 - math.exp(-(ratio - 1.0)), 0.0), 1.0))


def _isolated_channel(
    energy: np.ndarray, prefix: str, evidence: dict[str, Any]
) -> tuple[int, float, float]:
    """
    The channel with the largest share of ``energy`` (8,): ``(channel, share, its energy)``.

    ``(-1, 0, 0)`` when there is none; the channel and share go to ``evidence`` under
    ``{prefix}largest_channel`` and ``{prefix}largest_channel_share``.
    """
    total = float(energy.sum())
    if total <= 0:
        return -1, 0.0, 0.0
    ch = int(np.argmax(energy))
    share = float(energy[ch] / total)
    evidence[f"{prefix}largest_channel"] = ch
    evidence[f"{prefix}largest_channel_share"] = share
    return ch, share, float(energy[ch])


def _levels_crossed(ev: EpisodeEvidence, frame: str) -> list[int]:
    return sorted({j for (j, f), r in ev.max_ratio.items() if f == frame and r.max() > 1.0})


def classify(ev: EpisodeEvidence, config: ClassifierThresholds) -> Decision:
    """
    Classify an episode (rules in the module docstring).

    Parameters
    ----------
    ev : EpisodeEvidence
    config : ClassifierThresholds
        A :class:`~amb_fault_monitor.config.MonitorConfig`, or anything with its thresholds.
        Uses ``isolation``, ``base_coherence``, ``base_dominance``, ``sync_change`` and
        ``confirm_ratio``.

    Returns
    -------
    Decision
    """
    above_fixed = ev.peak("fixed", "above")
    above_rot = ev.peak("rotating", "above")
    below_fixed = ev.peak("fixed", "below")
    all_rot = ev.peak("rotating", "all")
    base = {
        "levels_crossed_fixed": ",".join(map(str, _levels_crossed(ev, "fixed"))),
        "levels_crossed_rotating": ",".join(map(str, _levels_crossed(ev, "rotating"))),
        "peak_ratio_above_1x_fixed": float(above_fixed.max()),
        "peak_ratio_above_1x_rotating": float(above_rot.max()),
        "peak_ratio_below_1x_fixed": float(below_fixed.max()),
        "sync_ratio": float(ev.sync_ratio.max()),
        "sync_change_m": float(ev.sync_change.max()),
        "revolution_level": ev.revolution_level,
        "low_coherence": float(ev.low_coherence),
        "coherence": float(ev.coherence),
        "low_peak_m": float(ev.low_peak),
        "high_peak_m": float(ev.high_peak),
    }
    isolated = _isolated_channel(ev.channel_energy, "", base)
    fine = _isolated_channel(ev.fine_energy, "finest_level_", base)
    for (ch, share, energy), where in ((isolated, "the"), (fine, "the finest-level")):
        if ch >= 0 and share >= config.isolation:
            plane = ch // 2 + 1
            return Decision(
                FaultType.SENSOR_FAULT,
                plane=plane,
                channel=ch,
                severity=float(math.sqrt(energy)),
                confidence=share,
                evidence={
                    **base,
                    "rule": f"one channel inconsistent with its partner and planes ({where} "
                    "fixed-frame change)",
                },
                description=(
                    f"sensor channel {ch} (plane {plane} {'xy'[ch % 2]}) carries {share:.0%} of "
                    f"{where} fixed-frame change: a transducer fault"
                ),
            )
    n_low_planes = int(np.count_nonzero(below_fixed > 1.0))
    coherence = float(ev.low_coherence)
    fast = max(float(ev.sync_change.max()), float(ev.high_peak))
    dominance = float(ev.low_peak / max(fast, 1e-300))
    if (
        n_low_planes >= 3
        and coherence >= config.base_coherence
        and dominance >= config.base_dominance
    ):
        r = float(below_fixed.max())
        return Decision(
            FaultType.BASE_MOTION,
            plane=0,
            severity=float(ev.low_peak),
            confidence=ratio_confidence(r) * coherence,
            evidence={
                **base,
                "planes_below_1x": n_low_planes,
                "low_dominance": dominance,
                "rule": "planes move together below 1 x (fixed frame)",
            },
            description=(
                f"the {n_low_planes} planes move together below 1 x (coherence {coherence:.2f}, "
                f"largest change {ev.low_peak:.3g} m, {dominance:.1f} x the changes at and above "
                "1 x): base motion"
            ),
        )
    sync = float(ev.sync_ratio.max())
    strong = [b for b in ev.bursts if min(b[2], b[3]) >= config.confirm_ratio]
    if sync >= config.sync_change and all_rot.max() > 1.0:
        plane = int(np.argmax(ev.sync_change)) + 1
        return Decision(
            FaultType.MASS_LOSS,
            plane=plane,
            severity=float(ev.sync_change.max()),
            confidence=ratio_confidence(sync / config.sync_change),
            count=1,
            evidence={
                **base,
                "rule": "rotating transient + new fixed-frame 1 x level (Table 5.1)",
                "contact_bursts_after_onset": max(len(strong) - 1, 0),
            },
            description=(
                f"sudden unbalance change: 1 x level moved by {ev.sync_change.max():.3g} m "
                f"(ratio {sync:.1f}) at plane {plane}, transient in the rotating frame"
            ),
        )
    if above_fixed.max() > 1.0 and above_rot.max() > 1.0:
        both = np.maximum(above_fixed, above_rot)
        plane = int(np.argmax(both)) + 1
        count = max(1, len([b for b in ev.bursts if min(b[2], b[3]) > 1.0]))
        r = float(min(above_fixed.max(), above_rot.max()))
        return Decision(
            FaultType.AUX_BEARING_CONTACT,
            plane=plane,
            severity=0.0,
            confidence=ratio_confidence(r),
            count=count,
            evidence={**base, "bursts": count, "rule": "transient above 1 x in both frames"},
            description=(
                f"{count} short transient(s) above 1 x in both frames, no lasting 1 x change: "
                f"rotor/bearing contact, largest at plane {plane}"
            ),
        )
    return Decision(
        FaultType.UNKNOWN,
        confidence=0.5,
        evidence={**base, "rule": "none of Table 5.1"},
        description="a confirmed detection that fits no class of Table 5.1",
    )


def classify_provisional(ev: EpisodeEvidence, config: ClassifierThresholds) -> Decision:
    """
    Provisional class of an episode whose 1 x level has not settled (module docstring).

    Parameters
    ----------
    ev : EpisodeEvidence
        The evidence so far; its ``sync_ratio`` is not used (the level has not settled).
    config : ClassifierThresholds
        Uses ``provisional_residual``, ``provisional_ratio``, ``base_coherence`` and what
        :func:`classify` uses.

    Returns
    -------
    Decision
        ``SENSOR_FAULT``, ``BASE_MOTION`` and ``UNKNOWN`` as :func:`classify` decides them
        without a lasting 1 x change; ``BASE_MOTION`` also for ``coherence >=
        base_coherence``; else a change above 1 x in both frames is ``MASS_LOSS`` when
        ``residual_ratio <= provisional_residual`` or, without the readings
        (``residual_ratio`` None), when ``fixed_over_rotating >= provisional_ratio`` (both in
        ``evidence``), else ``AUX_BEARING_CONTACT``.
    """
    d = classify(replace(ev, sync_ratio=np.zeros(4), sync_change=np.zeros(4)), config)
    if d.fault_type in (FaultType.SENSOR_FAULT, FaultType.BASE_MOTION):
        return d
    if ev.coherence >= config.base_coherence:
        return Decision(
            FaultType.BASE_MOTION,
            plane=0,
            severity=float(max(ev.low_peak, ev.high_peak)),
            confidence=float(ev.coherence),
            evidence={**d.evidence, "rule": "the planes move together (fixed frame, every level)"},
            description=(
                f"the planes move together (coherence {ev.coherence:.2f} of the fixed-frame "
                "changes at every level): base motion"
            ),
        )
    if d.fault_type != FaultType.AUX_BEARING_CONTACT:
        return d
    above_fixed = ev.peak("fixed", "above")
    ratio = float(above_fixed.max() / max(float(ev.peak("rotating", "above").max()), 1e-300))
    d.evidence["fixed_over_rotating"] = ratio
    rho = ev.residual_ratio
    if rho is not None:
        d.evidence["residual_ratio"] = rho
        if rho > config.provisional_residual:
            d.description += f" (not a 1 x sinusoid on a drift: residual {rho:.2f} of it)"
            return d
        return _synchronous_change(d, rho, int(np.argmax(above_fixed)) + 1, config)
    if ratio < config.provisional_ratio:
        d.description += f" (fixed over rotating frame above 1 x {ratio:.2f})"
        return d
    plane = int(np.argmax(above_fixed)) + 1
    return Decision(
        FaultType.MASS_LOSS,
        plane=plane,
        confidence=ratio_confidence(ratio / config.provisional_ratio),
        evidence={**d.evidence, "rule": "change above 1 x mostly in the fixed frame"},
        description=(
            f"the change above 1 x is {ratio:.2f} x larger in the fixed frame than in the "
            f"rotating frame, largest at plane {plane}: a synchronous (unbalance) change"
        ),
    )


def _synchronous_change(
    d: Decision, rho: float, plane: int, config: ClassifierThresholds
) -> Decision:
    """The provisional ``MASS_LOSS`` of a change that is a 1 x sinusoid on a slow drift."""
    return Decision(
        FaultType.MASS_LOSS,
        plane=plane,
        confidence=ratio_confidence(config.provisional_residual / max(rho, 1e-300)),
        evidence={**d.evidence, "rule": "the change of the last revolution is a 1 x sinusoid"},
        description=(
            f"the probes' change over the last revolution is a sinusoid at 1 x on a slow drift "
            f"(what is left, {rho:.2f} of it, shows no impact): a synchronous (unbalance) change"
        ),
    )
