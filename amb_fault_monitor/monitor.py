"""
Fault detection from wavelet coefficients in the fixed and rotating frames (thesis chapter 5).

:class:`FaultMonitor` runs the algorithm sample by sample; each job lives in its own module:

* features, the one-revolution change of each coefficient against its threshold:
  :mod:`amb_fault_monitor.features`;
* the thresholds, from a healthy calibration window: :mod:`amb_fault_monitor.calibration`;
* the synchronous (1 x) level, settled or returned after an episode:
  :mod:`amb_fault_monitor.phasor`;
* an episode's course (the steps below): :mod:`amb_fault_monitor.episode_flow`; its evidence
  and onset: :mod:`amb_fault_monitor.episodes`, :mod:`amb_fault_monitor.onset`; its class:
  :mod:`amb_fault_monitor.classifier`;
* contact bursts in a ring-down: :mod:`amb_fault_monitor.bursts`;
* transients of the controller's own force: :mod:`amb_fault_monitor.control_transients`;
* stuck or zero channels: :mod:`amb_fault_monitor.dead_channels`;
* coil and amplifier failures, from the measured against the demanded currents:
  :mod:`amb_fault_monitor.coil_check`;
* a biased probe inside the PID loop, from a lasting step of a bearing axis's mean force:
  :mod:`amb_fault_monitor.loop_bias`;
* the provisional class, from a probe's jump or the readings' change:
  :mod:`amb_fault_monitor.provisional`.

Episodes
--------
1. *Onset candidate*: the first crossing opens an episode.
2. *Detection (alarm)*: confirmed when a crossing has ``r >= confirm_ratio`` or crossings
   occurred in ``confirm_features`` different (level, frame) features; otherwise the episode
   is dropped after ``confirm_revs`` revolutions (an isolated noise crossing).
3. *Decision*: when the synchronous (1 x) level has either *settled* or *returned*, or at the
   latest ``decision_revs`` revolutions after the alarm, the evidence is classified
   (:mod:`amb_fault_monitor.classifier`) and one event emitted. The wait is extended up to
   ``decision_max_revs`` while the 1 x level stays far from its reference and still moves
   (:mod:`amb_fault_monitor.phasor`). With ``provisional_revs`` > 0, a provisional class
   (:mod:`amb_fault_monitor.provisional`) is emitted that many revolutions after the
   episode's estimated onset, at the alarm if that is later, if the episode is undecided then
   (``evidence["status"]`` ``provisional``); the decision's event then says ``final``, with
   the provisional class (``provisional_class``) and whether it was revised (``revised``),
   or, where the episode turns out to be another fault's consequence and no class is
   reported (steps 5-6, a stuck channel), a copy of the provisional event says
   ``withdrawn``.
4. *Contacts inside an episode and tail*: the disturbance may ring on; no new episode starts
   until ``quiet_revs`` pass without a crossing (at most ``max_tail_revs``), and for
   ``rearm_revs`` after that a new episode needs a strong crossing (``confirm_ratio``) to be
   confirmed (the end of a long ring-down hovers at the threshold). Contacts in the ring-down
   are found by a rise test (:mod:`amb_fault_monitor.bursts`): if the episode is decided a
   contact, they add to its count; otherwise they are reported as one
   ``AUX_BEARING_CONTACT`` event right after the decision (or at the first contact found in
   the tail). Bursts found before an episode is decided a sensor fault are dropped (the
   failing probe's own spikes; the channel is masked from then on).
5. *Control transients*: an episode that a step of the applied control force explains is
   counted, not reported (:mod:`amb_fault_monitor.control_transients`); contact bursts in
   the step's window are the response to it and not counted.
6. *Coil failures*: a ``COIL_FAILURE`` (:meth:`FaultMonitor.currents`) comes a quarter
   revolution after the failure; the episode the rotor's response then opens (its estimated
   onset within a revolution of the failure's) is its consequence, counted
   (``coil_explained``), not reported as a class of Table 5.1 (the one-sided pull of a lost
   coil changes the 1 x level for good, as a mass loss does). Contacts in it are reported:
   the rotor does touch. Where the touch begins the episode (the remaining coil pulls the
   rotor onto its auxiliary bearing within a few samples, before the rise test starts) and the
   rise test finds no burst, a probe plane at ``landing_fraction`` of its nearest clearance
   (given ``clearances``) is the contact (:mod:`amb_fault_monitor.bursts`).
7. *Biased probes in the loop*: an episode decided a contact is a ``SENSOR_FAULT`` of the
   bearing-plane probe of the axis whose one-revolution mean force has stepped to a new, held
   level since before the episode (:mod:`amb_fault_monitor.loop_bias`; needs the currents, as
   step 6): the displacements of a biased probe in the loop look like a contact (rule 4),
   but a contact is over within a few revolutions. Not a mass loss: a probe's offset leaves
   the 1 x level as it was, while a rotor latched on an auxiliary bearing after a loss holds
   a bearing at a new mean force too (up to its 1 kN limit in the suite's 516 g cm case).
   Not ``UNKNOWN`` either: the one such episode seen (a 15 Hz run in contact from its start,
   calibrated in it) stepped by 1.7 kN.

8. *A feedback probe's fault*: a decided ``SENSOR_FAULT`` of a probe the PID closes its loop
   on (``feedback_channels``) ends the episode and starts a new calibration window, the
   channel masked; the thresholds become the larger of the old and the new
   (:attr:`FaultMonitor.calibrations`). The bearing now turns the probe's noise or offset into
   force, so the rotor really moves more than in the first window: with the old thresholds
   alone, 3 um of noise on the plane-3 y probe at 67 Hz drove the masked rotor's other
   channels across them, and db2 reported a contact 1.2 s later (issue 19). No class is
   reported until the window is accepted (``calibration_revs``; the node's status says
   ``calibrating``).

Sensor channels found faulty (decided sensor faults and stuck channels) are masked (their
plane feature uses the partner channel only) until :meth:`FaultMonitor.reset`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from amb_common.faults import FaultEvent
from amb_common.names import N_SENSORS
from amb_fault_monitor.calibration import Calibration, CalibrationWindow
from amb_fault_monitor.coil_check import CoilCheck
from amb_fault_monitor.config import MonitorConfig
from amb_fault_monitor.control_transients import ControlSteps
from amb_fault_monitor.dead_channels import DeadChannels
from amb_fault_monitor.episode_flow import EpisodeFlow
from amb_fault_monitor.episodes import Episode
from amb_fault_monitor.errors import RecordError
from amb_fault_monitor.features import ChangeFeatures, normalise
from amb_fault_monitor.loop_bias import LoopBias
from amb_fault_monitor.onset import AtomCentres
from amb_fault_monitor.phasor import SynchronousLevel
from amb_fault_monitor.provisional import ProvisionalClass
from amb_fault_monitor.records import SampleCoefficients
from amb_fault_monitor.trips import clearance_levels
from amb_wavelet.analysis import DETAIL
from amb_wavelet.levels import revolution_level

if TYPE_CHECKING:
    from amb_common.rig import Rig

__all__ = ["FaultMonitor"]


class FaultMonitor(EpisodeFlow):
    """
    Streaming fault detector and classifier (ROS-free core of the ``fault_monitor`` node).

    Parameters
    ----------
    config : MonitorConfig
    ki : float, optional
        The rig's current gain, N/A: with it :meth:`currents` checks the coils (step 6).
    feedback_channels : sequence of int, optional
        The sensor channel each bearing axis ``[b1x, b1y, b2x, b2y]`` is fed back from
        (:attr:`amb_common.rig.Rig.feedback_channels`): with it and ``ki`` the commanded forces
        given to :meth:`currents` also check for a biased probe inside the loop (step 7), and a
        sensor fault on one of them starts a new calibration (step 8).
    plane_bearings : sequence of int, optional
        Per sensor plane, the clearance bearing nearest it
        (:attr:`amb_common.rig.Rig.plane_clearance_bearings`): a contact event names the one of
        the plane its change was largest at (without it, ``bearing`` 0: not known).
    force_limit : float, optional
        The actuator's force limit per axis, N (:attr:`amb_common.rig.AmbData.force_limit`):
        with it, a sample at which the bearing force given to :meth:`currents` reaches or leaves
        the limit is a bend of the force, and a rotating-frame finest-level rise at it is not a
        contact (step 5, :mod:`~amb_fault_monitor.control_transients` "Limits").
    clearances : sequence of float, optional
        Per sensor plane, the radial clearance of its nearest auxiliary bearing, m
        (:func:`amb_fault_monitor.trips.clearance_levels`): with it, the displacements given
        to :meth:`displacements` show a rotor that landed on its bearing after a coil failure
        (step 6).

    Attributes
    ----------
    config : MonitorConfig
        May be replaced while running (the node changes ``control_step``); the levels used
        and the 1 x level stay those of the first configuration.
    trace : list or None
        ``None`` (default, no cost) or a list the caller sets: every monitored feature after
        calibration is then appended as ``(sample_index, level, frame, first, last, ratio)``,
        ``ratio`` the (4,) plane ratios feature / threshold (dimensionless) of the coefficient
        completed at ``sample_index`` whose support is samples ``first..last``. Kept across
        :meth:`reset`.
    unconfirmed : int
        Episodes dropped unconfirmed (isolated noise crossings).
    samples : int
        Records processed since the reset.
    calibrations : list of int
        Sample indices at which thresholds were set: the first calibration, then each
        recalibration (step 8).
    recalibrations : int
        Recalibrations begun after a sensor fault on a feedback probe (step 8).

    Notes
    -----
    Feed one :class:`~amb_fault_monitor.records.SampleCoefficients` per sample with
    :meth:`step`, in increasing ``sample_index``, the control force applied in each sample
    with :meth:`control_force` (module notes, step 5; without it no transient is attributed to
    control) and, given the rig's current gain ``ki`` (N/A), its currents with
    :meth:`currents` (step 6; without ``ki`` no coil check). The first ``calibration_revs``
    revolutions of settled coefficients calibrate the thresholds (they must be healthy); events
    are emitted afterwards. :meth:`reset` starts again (new calibration).
    """

    def __init__(
        self,
        config: MonitorConfig,
        ki: float | None = None,
        feedback_channels: Sequence[int] | None = None,
        plane_bearings: Sequence[int] | None = None,
        force_limit: float | None = None,
        clearances: Sequence[float] | None = None,
    ) -> None:
        self._config = config
        self._clearances = None if clearances is None else np.asarray(clearances, dtype=float)
        # N: a bearing force this close to the limit is at it (the plant clips to it exactly)
        self._at_limit = None if force_limit is None else float(force_limit) * (1.0 - 1e-9)
        self._plane_bearings = tuple(int(b) for b in plane_bearings or ())
        self._coils = CoilCheck(config, ki) if ki is not None else None
        self._bias = None
        if ki is not None and feedback_channels is not None:
            self._bias = LoopBias(config, feedback_channels)
        self._R = revolution_level(config.samples_per_rev)
        self._finest = min(config.levels) if config.levels else 1
        self._centres = AtomCentres()
        self._early = ProvisionalClass(config)
        self.trace: list[tuple[int, int, str, int, int, np.ndarray]] | None = None
        self.reset()

    @classmethod
    def from_rig(cls, config: MonitorConfig, rig: Rig) -> FaultMonitor:
        """
        The monitor of ``rig``: every check that needs the rig's data switched on.

        The one place the monitor's rig fields are read, for the node, ``amb-fault-eval`` and
        the in-process loop alike: ``ki`` (:attr:`~amb_common.rig.AmbData.Ki`, A to N),
        ``feedback_channels``, ``plane_bearings`` (the clearance bearing of each sensor
        plane), ``force_limit`` (:attr:`~amb_common.rig.AmbData.force_limit`, N) and
        ``clearances`` (that bearing's radial clearance, m; none for a rig without clearance
        bearings).

        Parameters
        ----------
        config : MonitorConfig
        rig : amb_common.rig.Rig

        Returns
        -------
        FaultMonitor
        """
        return cls(
            config,
            ki=rig.amb.Ki,
            feedback_channels=rig.feedback_channels,
            plane_bearings=rig.plane_clearance_bearings,
            force_limit=rig.amb.force_limit,
            clearances=clearance_levels(rig, 1.0) if rig.clearance_bearings else None,
        )

    # ------------------------------------------------------------------ public
    @property
    def config(self) -> MonitorConfig:
        """The parameters (shared with the parts of the monitor)."""
        return self._config

    @config.setter
    def config(self, config: MonitorConfig) -> None:
        self._config = config
        parts = (
            self._calibration, self._sync, self._dead, self._control, self._coils, self._bias,
            self._early,
        )  # fmt: skip
        for part in parts:
            if part is not None:
                part.config = config

    def reset(self) -> None:
        """Forget all state, thresholds and masked channels; calibrate again."""
        cfg = self._config
        self._features = ChangeFeatures(self._R)
        self._calibration = CalibrationWindow(cfg)
        self._thr: dict[tuple[int, str], np.ndarray] = {}
        self._old_thr: dict[tuple[int, str], np.ndarray] = {}
        self._old_sync: np.ndarray | None = None
        self._sync = SynchronousLevel(cfg, self._R)
        self._dead = DeadChannels(cfg)
        self._control = ControlSteps(cfg)
        self._mask = np.ones(N_SENSORS, dtype=bool)
        self._last_index: int | None = None
        self._episode: Episode | None = None
        self._rearm_until = -(2**62)
        self._omega = 0.0
        self.unconfirmed = 0
        self.samples = 0
        self.calibrations: list[int] = []
        if self._coils is not None:
            self._coils.reset()
        if self._bias is not None:
            self._bias.reset()
        self._early.reset()
        self._coil_onsets: list[int] = []
        self.coil_explained = 0
        self.recalibrations = 0

    @property
    def calibration_end(self) -> int | None:
        """Sample index at which the thresholds were last set (None while calibrating first)."""
        return self.calibrations[-1] if self.calibrations else None

    @property
    def calibrated(self) -> bool:
        """True once thresholds are set."""
        return bool(self._thr)

    @property
    def calibration_retries(self) -> int:
        """Times the calibration window was refused (not yet stationary or healthy)."""
        return self._calibration.retries

    @property
    def thresholds(self) -> dict[tuple[int, str], np.ndarray]:
        """Per (level, frame): plane thresholds (4,), m. Empty while calibrating."""
        return {k: v.copy() for k, v in self._thr.items()}

    @property
    def sync_threshold(self) -> np.ndarray | None:
        """Per plane threshold of the synchronous phasor change (4,), m."""
        return None if self._sync.threshold is None else self._sync.threshold.copy()

    def set_thresholds(
        self, thresholds: dict[tuple[int, str], np.ndarray], sync_threshold: np.ndarray
    ) -> None:
        """
        Replace the calibrated thresholds (e.g. with those of another run).

        Parameters
        ----------
        thresholds : dict
            Per (level, frame): plane thresholds (4,), m (copied).
        sync_threshold : numpy.ndarray
            Per plane threshold of the synchronous phasor change (4,), m.
        """
        self._thr = {k: np.array(v, dtype=float) for k, v in thresholds.items()}
        self._sync.threshold = sync_threshold

    @property
    def masked_channels(self) -> list[int]:
        """Channels excluded after a sensor fault."""
        return [int(c) for c in np.flatnonzero(~self._mask)]

    @property
    def channel_mask(self) -> np.ndarray:
        """Channels in use (8,), bool: False for those masked after a sensor fault (a copy)."""
        return self._mask.copy()

    @property
    def in_episode(self) -> bool:
        """True while a disturbance is being tracked (alarm raised or pending)."""
        return self._episode is not None

    @property
    def alarm(self) -> bool:
        """True from a confirmed detection until the episode ends."""
        return self._episode is not None and self._episode.alarm is not None

    @property
    def control_transients(self) -> int:
        """Episodes decided as control transients (module notes, step 5)."""
        return self._control.transients

    @property
    def last_control_transient(self) -> dict | None:
        """The latest control transient (``ControlSteps.last_transient``), or None."""
        return self._control.last_transient

    def atom_centre(self, s) -> float:
        """
        Time centre (sample index) of the atom of coefficient set ``s`` in the current stream.

        From the wavelet of the latest record (:class:`~amb_fault_monitor.onset.AtomCentres`).
        """
        return self._centres.centre(s)

    def control_force(self, sample_index: int, force: np.ndarray) -> None:
        """
        Record the control (wavelet) force applied during one sample (module notes, step 5).

        Parameters
        ----------
        sample_index : int
            The sample during which ``force`` was applied (the measurement's index).
        force : numpy.ndarray
            Shape ``(4,)``, N per axis ``[b1x, b1y, b2x, b2y]``.

        Notes
        -----
        Compared with the force of ``sample_index - samples_per_rev`` (if recorded): a change
        of more than ``control_step`` on an axis extends the current step run, or starts one.
        Samples may come in any order relative to :meth:`step` (an episode is attributed at
        its decision, revolutions later; a contact burst when it is found, so the force of a
        sample should come before the coefficients it completes, as the measurement comes
        before the filterbank's message); a missing sample only leaves a gap in the
        comparison.
        """
        self._control.record(sample_index, force)

    def currents(
        self, sample_index: int, commanded_force: np.ndarray, current: np.ndarray, omega: float
    ) -> list[FaultEvent]:
        """
        Check one sample's currents for a coil or amplifier failure (module notes, step 6).

        Parameters
        ----------
        sample_index : int
            The measurement's index.
        commanded_force : numpy.ndarray
            Its ``bearing_force`` (4,), N: ``K_i`` times the demanded current.
        current : numpy.ndarray
            Its measured control current (4,), A.
        omega : float
            Its running speed, rad/s.

        Returns
        -------
        list of FaultEvent
            ``COIL_FAILURE`` events confirmed at this sample (:mod:`amb_fault_monitor.coil_check`);
            empty without ``ki``. The commanded force also feeds the loop-bias check (step 7)
            and, given ``force_limit``, the bends of the force at the limit (step 5).
        """
        if self._at_limit is not None:
            self._control.clipped(sample_index, np.abs(commanded_force) >= self._at_limit)
        if self._bias is not None:
            self._bias.add(sample_index, commanded_force)
        if self._coils is None:
            return []
        events = self._coils.step(sample_index, commanded_force, current, omega)
        self._coil_onsets += [e.onset_sample_index for e in events]
        return events

    def displacements(self, sample_index: int, displacement: np.ndarray) -> None:
        """
        Record one sample's probe readings (8,), m: the provisional class and landings.

        From the measurement, for the jump test and the change's shape
        (:mod:`amb_fault_monitor.provisional`; without them the provisional class comes from
        the coefficients alone, and nothing is done for it while ``provisional_revs`` is 0),
        and, given the clearances, for a landing on an auxiliary bearing in an open episode
        (step 6: :attr:`Episode.landing`).
        """
        if self._config.provisional_revs > 0:
            self._early.add(sample_index, displacement)
        ep = self._episode
        if self._clearances is None or ep is None or ep.decided is not None:
            return
        d = np.asarray(displacement, dtype=float)
        planes = self._mask[0::2] & self._mask[1::2]
        shares = np.hypot(d[0::2], d[1::2]) * planes / self._clearances
        if ep.landing is not None:
            ep.landing = (ep.landing[0], np.maximum(ep.landing[1], shares))
        elif shares.max() >= self._config.landing_fraction:
            ep.landing = (int(sample_index), shares)

    def step(self, record: SampleCoefficients) -> list[FaultEvent]:
        """
        Process the coefficients completed by one sample.

        Parameters
        ----------
        record : SampleCoefficients

        Returns
        -------
        list of FaultEvent
            Events decided at this sample (usually empty).

        Raises
        ------
        RecordError
            If the sample index does not increase or a set has the wrong length.
        """
        n = int(record.sample_index)
        if self._last_index is not None and n <= self._last_index:
            raise RecordError(
                f"sample_index must increase: got {n} after {self._last_index}; "
                "call reset() after a restart of the stream"
            )
        self._last_index = n
        self.samples += 1
        self._omega = float(record.omega)
        self._centres.wavelet = record.wavelet
        events: list[FaultEvent] = []
        if not record.sets:
            self._advance(n, events)
            return events
        cfg = self._config
        by_key = {}
        for s in record.sets:
            if s.frame not in cfg.frames:
                continue
            if s.kind != DETAIL:  # deepest approximation: the band below the last detail
                s = s._replace(level=s.level + 1)
            if cfg.levels and s.level not in cfg.levels:
                continue
            if len(s.values) != N_SENSORS:
                raise RecordError(f"coefficient set has {len(s.values)} values, expected 8")
            by_key[(s.level, s.frame, s.quadrature)] = s
        for (level, frame, quad), s in by_key.items():
            if quad != "even" or not s.settled:
                continue
            self._feature(n, level, frame, s)
            if level == self._R and frame == "fixed":
                odd = by_key.get((level, frame, "odd"))
                self._phasor(s, odd if odd is not None and odd.settled else None)
            if level == 1 and frame == "fixed":
                self._dead_channels(n, s, events)
        self._advance(n, events)
        return events

    # ------------------------------------------------------------------ features
    def _feature(self, n: int, level: int, frame: str, s) -> None:
        delta = self._features.change(level, frame, s.values, self._mask)
        if delta is None:
            return
        planes = np.hypot(delta[0::2], delta[1::2])
        key = (level, frame)
        if not self._thr:
            done = self._calibration.add_feature(n, key, planes)
            if done is not None:
                self._calibrated(done)
            return
        thr = self._thr.get(key)
        if thr is None:
            return  # a feature that appeared after calibration: not monitored
        ratio = planes / thr
        if self.trace is not None:
            self.trace.append(
                (n, level, frame, s.first_sample_index, s.last_sample_index, ratio.copy())
            )
        self._evidence(n, level, frame, s, ratio, delta, thr)

    def _calibrated(self, calibration: Calibration) -> None:
        self._thr = calibration.thresholds
        self._sync.threshold = calibration.sync_threshold
        old = self._old_thr
        if old:  # step 8: the loop adds motion, never removes it
            self._thr = {k: np.maximum(v, old[k]) if k in old else v for k, v in self._thr.items()}
            self._sync.threshold = np.maximum(self._sync.threshold, self._old_sync)
        if calibration.dead_reference is not None:
            self._dead.reference = calibration.dead_reference
        self.calibrations.append(calibration.end)
        if self._bias is not None:
            self._bias.calibrate(calibration.end)
        self._early.calibrate(calibration.end)

    def _recalibrate(self, ev: FaultEvent) -> None:
        """
        Learn the thresholds again after a sensor fault on a feedback probe (step 8).

        The episode ends with its decision (its tail is the loop's new motion) and the features
        calibrate a new window, the faulty channel masked; ``ev`` says so. The old thresholds
        are kept as a floor (:meth:`_calibrated`): the loop adds motion, it removes none, and
        the coarse levels' thresholds rest on few coefficients per window.
        """
        revs = self._config.calibration_revs
        ev.evidence["recalibrating_revs"] = revs
        ev.description += f"; in the loop: thresholds learnt again over {revs:g} revolutions"
        self._episode = None
        retries = self._calibration.retries
        self._calibration = CalibrationWindow(self._config)
        self._calibration.retries = retries
        self._old_thr, self._old_sync = self._thr, self._sync.threshold
        self._thr = {}
        self.recalibrations += 1

    def _phasor(self, even, odd) -> None:
        calibrating = not self._thr
        change = self._sync.add(even, odd, self._mask, calibrating)
        if change is not None:
            self._calibration.add_sync(int(even.last_sample_index), change)

    def _dead_channels(self, n: int, s, events: list[FaultEvent]) -> None:
        v = np.abs(normalise(1, s.values))
        if not self._thr:
            self._calibration.add_dead(n, v)
            return
        spr = self._config.samples_per_rev
        for ev, start in self._dead.check(n, v, self._mask, self._omega):
            self._mask[ev.channel] = False
            events.append(ev)
            ep = self._episode
            if ep is not None and ep.decided is None and ep.start >= start - spr:
                self._episode = None  # the crossings came from the failing channel
                events += ep.withdrawal("SENSOR_FAULT")
