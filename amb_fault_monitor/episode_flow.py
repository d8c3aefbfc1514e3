"""
An episode's course in the fault monitor: evidence, contact bursts, decision and tail.

The steps 1-8 of :mod:`amb_fault_monitor.monitor`'s module notes, for its
:class:`~amb_fault_monitor.monitor.FaultMonitor`.

:class:`EpisodeFlow` is the monitor's base: it works on the state the monitor keeps
(:meth:`FaultMonitor.reset <amb_fault_monitor.monitor.FaultMonitor.reset>` sets it), and the
monitor's :meth:`~amb_fault_monitor.monitor.FaultMonitor.step` calls :meth:`_evidence` per
monitored feature and :meth:`_advance` once per sample. Kept apart from the feeding and the
calibration so that each module reads on its own.
"""

from __future__ import annotations

import numpy as np

from amb_common.faults import FINAL, PROVISIONAL, FaultEvent, FaultType
from amb_fault_monitor.classifier import Decision, classify
from amb_fault_monitor.episodes import Episode
from amb_fault_monitor.features import normalise
from amb_fault_monitor.onset import onset_sample

__all__ = ["EpisodeFlow"]


class EpisodeFlow:
    """
    Steps 1-8 of an episode (:mod:`amb_fault_monitor.monitor`), on the monitor's state.

    Needs, set by the monitor: ``_config``, ``_R``, ``_finest``, ``_centres``, ``_sync``,
    ``_control``, ``_bias``, ``_early``, ``_mask``, ``_episode``, ``_rearm_until``,
    ``_omega``, ``_coil_onsets``, ``_plane_bearings``, the counters ``unconfirmed`` and
    ``coil_explained``, and ``_recalibrate`` (step 8: the monitor's calibration state).
    """

    def _evidence(self, n, level, frame, s, ratio, delta, thr) -> None:
        crossed = bool(np.count_nonzero(ratio > 1.0))  # (a third of ndarray.any's cost)
        ep = self._episode
        if ep is None:
            if not crossed:
                return
            ep = self._episode = Episode(start=n, last_crossing=n)
            ep.p_ref = self._sync.reference(s.first_sample_index)
            ep.strong_only = n < self._rearm_until
        if level == self._finest:
            self._contact_burst(ep, n, s, ratio, frame)
        if ep.decided is not None:  # tail
            if crossed:
                ep.last_crossing = n
            return
        ep.track(level, frame, ratio)
        if not crossed:
            return
        ep.add_crossings(
            n, level, frame, s, ratio, delta, thr, self._centres.centre(s), self._R,
            self._mask, self._config, self._finest,
        )  # fmt: skip

    def _contact_burst(self, ep: Episode, n: int, s, ratio: np.ndarray, frame: str) -> None:
        """Rise test of a finest-level coefficient for a contact (module notes, step 4)."""
        fine = None
        if frame == "fixed":
            fine = normalise(self._finest, s.values) * self._mask
        if not ep.contacts.rises(n, ratio, fine, self._config):
            return
        if self._control_run(ep) and self._control.in_window(n):
            return  # the response to a control step (module notes, step 5)
        first, last = s.first_sample_index, s.last_sample_index
        if self._control.kink_near(first, last):
            return  # the force's own kink (step 5, control_transients "Kinks")
        if frame != "fixed" and self._control.limit_near(first, last):
            return  # the bend of the force at its limit (control_transients "Limits")
        if ep.decided is not None:
            ep.last_crossing = n
        onset = ep.contacts.onset
        if ep.contacts.onset < 0:  # at the time centre of the coefficient (estimate_onset)
            onset = onset_sample(self._centres.centre(s))
        ep.contacts.add(n, ratio, onset, self._config)

    def _advance(self, n: int, events: list[FaultEvent]) -> None:
        ep = self._episode
        if ep is None:
            return
        cfg = self._config
        spr = cfg.samples_per_rev
        quiet = n - ep.last_crossing >= cfg.quiet_revs * spr
        if ep.alarm is None:
            if n - ep.start > cfg.confirm_revs * spr:
                self.unconfirmed += 1
                self._episode = None
            return
        if ep.decided is None:
            # confirmed, so it has crossings (Episode.add_crossings): the onset once per sample
            onset = ep.onset()  # estimate_onset(ep.crossings), kept as crossings come
            provisional = cfg.provisional_revs > 0 and ep.provisional_due
            if provisional and n - onset >= cfg.provisional_revs * spr:
                self._provisional(n, ep, onset, events)
            status = self._sync.series(ep.p_ref, onset, self._mask)[0]
            extra = max(self._sync.support - spr, 0)
            waited = n - ep.alarm
            due = waited >= cfg.decision_revs * spr + extra and not (
                self._sync.moving(ep.p_ref, onset, self._mask)
                and waited < cfg.decision_max_revs * spr + extra
            )
            if status is not None or due:
                ev = self._decide(n, ep, onset)
                ep.control = self._control_run(ep) or False
                ep.decided = ev
                if ep.control:
                    self._control.count(ep.control, ev)
                    events += ep.withdrawal("CONTROL_TRANSIENT")
                    if ep.contacts.count:
                        self._report_contacts(ep, n, events)
                    if quiet:
                        self._end_tail(n, events)
                    return
                if ev.fault_type != FaultType.AUX_BEARING_CONTACT and self._coil_explains(ev):
                    ep.explained = FaultType.COIL_FAILURE.name
                    self.coil_explained += 1
                    events += ep.withdrawal(ep.explained)
                    self._landed(ep)
                    if ep.contacts.count:
                        self._report_contacts(ep, n, events)
                    if quiet:
                        self._end_tail(n, events)
                    return
                if self._bias is not None:  # step 7
                    ev = ep.decided = self._bias.revise(ev, ep.start, self._mask)
                if ep.provisional is not None:
                    ev.evidence.update(
                        status=FINAL,
                        provisional_class=ep.provisional.fault_type.name,
                        revised=ev.fault_type != ep.provisional.fault_type,
                    )
                events.append(ev)
                if ev.fault_type == FaultType.SENSOR_FAULT and ev.channel >= 0:
                    self._mask[ev.channel] = False
                    if self._bias is not None and ev.channel in self._bias.channels:
                        self._recalibrate(ev)  # step 8
                        return
                if ev.fault_type == FaultType.SENSOR_FAULT:
                    # bursts so far came from the failing channel (a noisy or offset probe
                    # spikes its finest level), not from the rotor: step 4
                    ep.contacts.clear()
                if ev.fault_type == FaultType.AUX_BEARING_CONTACT:
                    ev.count = max(ev.count, ep.contacts.count)
                    ep.contacts.reported = True
                elif ep.contacts.count:
                    self._report_contacts(ep, n, events)
                if quiet:
                    self._end_tail(n, events)
            return
        if ep.contacts.count and not ep.contacts.reported:
            self._report_contacts(ep, n, events)
        if quiet or n - ep.decided.decision_sample_index >= cfg.max_tail_revs * spr:
            self._end_tail(n, events)

    def _landed(self, ep: Episode) -> None:
        """A coil failure's episode without a contact burst: its landing is the contact (step 6)."""
        if not ep.contacts.count and ep.landing is not None:
            ep.contacts.land(*ep.landing)

    def _provisional(self, n: int, ep: Episode, onset: int, events: list[FaultEvent]) -> None:
        """
        Emit the provisional class of an undecided episode (module notes, step 3).

        None for an episode that a control step or a coil failure explains: those are counted,
        not reported, at the decision.
        """
        ep.provisional_due = False
        if self._control_run(ep):
            return
        zero = np.zeros(4)
        evidence = ep.evidence(self._R, zero, zero, self._mask)
        decision = self._early.decide(n, onset, evidence, self._mask)
        ev = self._event(n, ep, onset, decision)
        if self._coil_explains(ev):
            return
        ev.evidence["status"] = PROVISIONAL
        ep.provisional = ev
        events.append(ev)

    def _coil_explains(self, ev: FaultEvent) -> bool:
        """Whether a coil failure's onset lies within a revolution of the episode's (step 6)."""
        spr = self._config.samples_per_rev
        return any(abs(ev.onset_sample_index - c) <= spr for c in self._coil_onsets)

    def _control_run(self, ep: Episode) -> list | None:
        """The control step run that explains ``ep`` (looked up until its decision), or None."""
        if ep.control is not None or ep.decided is not None:
            return ep.control or None
        return self._control.run_explaining(ep.crossings, ep.start)

    def _end_tail(self, n: int, events: list[FaultEvent]) -> None:
        ep = self._episode
        self._episode = None
        self._rearm_until = n + self._config.rearm_revs * self._config.samples_per_rev
        if ep is not None and ep.contacts.count and not ep.contacts.reported:
            self._report_contacts(ep, n, events)

    def _report_contacts(self, ep: Episode, n: int, events: list[FaultEvent]) -> None:
        """One ``AUX_BEARING_CONTACT`` event for the contact bursts found so far (step 4)."""
        after = "CONTROL_TRANSIENT" if ep.control else ep.explained or ep.decided.fault_type.name
        ev = ep.contacts.event(n, self._omega, after, self._config)
        ev.bearing = self._bearing(ev.plane)
        events.append(ev)

    def _decide(self, n: int, ep: Episode, onset: int) -> FaultEvent:
        cfg = self._config
        status, sync_ratio, sync_change = self._sync.series(ep.p_ref, onset, self._mask, True)
        if status != "settled":
            sync_ratio = np.zeros(4)
        decision = classify(ep.evidence(self._R, sync_ratio, sync_change, self._mask), cfg)
        return self._event(n, ep, onset, decision)

    def _event(self, n: int, ep: Episode, onset: int, decision: Decision) -> FaultEvent:
        """The event of ``decision`` on ``ep`` at sample ``n``."""
        return FaultEvent(
            decision.fault_type,
            onset_sample_index=onset,
            detection_sample_index=int(ep.alarm),
            decision_sample_index=n,
            samples_per_rev=self._config.samples_per_rev,
            omega=self._omega,
            plane=decision.plane,
            channel=decision.channel,
            bearing=(
                self._bearing(decision.plane)
                if decision.fault_type == FaultType.AUX_BEARING_CONTACT
                else 0
            ),
            severity=decision.severity,
            confidence=decision.confidence,
            count=decision.count,
            evidence=decision.evidence,
            description=decision.description,
        )

    def _bearing(self, plane: int) -> int:
        """The clearance bearing nearest sensor ``plane`` (1-4), 0 if not known."""
        return self._plane_bearings[plane - 1] if 0 < plane <= len(self._plane_bearings) else 0
