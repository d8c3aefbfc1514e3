"""
Fault detection from wavelet coefficients in the fixed and rotating frames (thesis chapter 5).

Features (per completed detail coefficient, per level ``j``, frame and sensor plane ``p``)
-----------------------------------------------------------------------------------------
Coefficients are first normalised to metres, ``c = d / 2**(j / 2)`` (the orthonormal filters
of eq. 4.6 scale a level-``j`` coefficient by the square root of its support). The feature is
the change of the coefficient (figure 5.30 c-d: "the change in wavelet coefficients with each
sample"), taken between coefficients one revolution apart where a level has several
coefficients per revolution:

.. math::

    \\Delta_j[k] = c_j[k] - c_j[k - m_j], \\quad
    m_j = \\max(1, 2^{R - j}), \\qquad
    e_{j,p}[k] = \\sqrt{\\Delta_{j,x_p}^2 + \\Delta_{j,y_p}^2},

with ``R = log2(samples_per_rev)`` (level ``R`` is 1 x running speed). Decision (a
generalisation of the thesis): for ``j < R`` the thesis's coefficient-to-coefficient change
is periodic, not zero, under a steady orbit in the fixed frame (eq. 5.3-5.4 only make the
*rotating*-frame coefficients vanish); the one-revolution lag makes ``Delta`` vanish for any
steady response periodic in the revolution, in both frames (the steady orbit, its harmonics,
and the rotating-frame image of static offsets such as gravity sag), so that only transients
remain, as eq. 5.4 requires. At ``j = R`` and coarser, ``m_j = 1`` is the thesis's change
from one coefficient to the next.

Thresholds ``theta_{j,f,p}`` come from a healthy calibration window
(:mod:`amb_fault_monitor.calibration`); the ratio ``r = e / theta`` crosses when ``r > 1``.

The synchronous (1 x) phasor per channel is ``P = c_even + i c_odd`` at level ``R`` in the
fixed frame (the odd channel is delayed a quarter revolution, section 4.3, so ``|P|`` does not
depend on the phase of the orbit); it is compared before and after an episode to decide
whether the synchronous level changed for good (a new steady state, Table 5.1).

Episodes
--------
1. *Onset candidate*: the first crossing opens an episode.
2. *Detection (alarm)*: confirmed when a crossing has ``r >= confirm_ratio`` or crossings
   occurred in ``confirm_features`` different (level, frame) features; otherwise the episode
   is dropped after ``confirm_revs`` revolutions (an isolated noise crossing).
3. *Decision*: when the synchronous (1 x) level has either *settled* or *returned*, or at the
   latest ``decision_revs`` revolutions after the alarm, the evidence is classified
   (:mod:`amb_fault_monitor.classifier`) and one event emitted. With ``s_k`` the largest plane
   ratio of ``|P_k - P_ref|`` to its threshold for the k-th 1 x phasor wholly after the onset
   (``P_ref`` the last one wholly before): *returned* when the latest ``settle_revs`` values
   are all below ``sync_change`` (no lasting change: the ring-down of a contact or an
   impulse); *settled* when their spread is at most ``settle_spread`` of their mean and their
   mean is at least ``sustain`` times the mean of the ``settle_revs`` before (a new steady
   level, Table 5.1 "sudden mass loss"; a decaying ring-down fails the second test). Table
   5.1 asks for the new *steady state*: deciding at a fixed delay while the transient still
   rings confuses the two (the simulated contacts at 29 and 67 Hz move the 1 x level by
   10-20 thresholds for 5-20 revolutions, a 100 g cm loss settles at 40-50 thresholds).
   The wait is extended up to ``decision_max_revs`` while ``s_k >= sync_change`` on all of
   the latest ``2 settle_revs`` phasors (the level has not returned and still moves: a
   430 g cm loss at 67 Hz whose contacts keep it ringing settles 19-20 revolutions after
   the alarm; deciding at 16 called it a contact). If it is still that far from the
   reference when the wait ends, the change is lasting (settled): with db2 the same case
   still moved 34 revolutions after the alarm and the trend test alone called it a contact.
4. *Contacts inside an episode and tail*: the disturbance may ring on; no new episode starts
   until ``quiet_revs`` pass without a crossing (at most ``max_tail_revs``), and for
   ``rearm_revs`` after that a new episode needs a strong crossing (``confirm_ratio``) to be
   confirmed (the end of a long ring-down hovers at the threshold). From one revolution
   after the first crossing, each finest-level coefficient (either frame) is compared with
   the ring-down's own envelope, the largest finest-level ratio of the preceding revolution
   without its last quarter: ``r >= tail_rise * envelope`` and ``r >= confirm_ratio`` is a
   new impulse, a contact (a free ring-down decays smoothly; contacts that a mass loss leads
   to, figure 5.27 case 2, keep re-exciting it). Bursts closer than ``burst_gap_revs`` are
   one. If the episode is decided a contact, they add to its count; otherwise one
   ``AUX_BEARING_CONTACT`` event is emitted right after the decision (or at the first
   contact found in the tail), onset at the first burst, ``count`` the bursts found until
   then (later bursts of the same episode are not reported again). Bursts found before an
   episode is decided a sensor fault are dropped (the failing probe's own spikes; the
   channel is masked from then on). From a quarter
   revolution into the episode a second, robust envelope applies: ``r >= tail_rise_median``
   times the median fixed-frame finest-level ratio since the episode began (one revolution
   at most, its last eighth excluded), and the same on the change of the fixed-frame
   finest-level coefficient from one coefficient to the next (figure 5.30 c-d, "the change in
   wavelet coefficients with each sample"), which separates a contact in the first
   revolution with each wavelet (:meth:`FaultMonitor._contact_burst`).
5. *Control transients*: the controller's wavelet force moves the rotor too, and a change
   of it from one revolution to the next excites the same transient features as a fault: in
   a soak run a steady 65 N synchronous force answered by zero for one period (a late
   command) moved the inner sensors from 2 to 34 um and was called a contact. The node tells
   the monitor the force applied in each sample (:meth:`FaultMonitor.control_force`); it is
   compared with the force one revolution earlier (the lag of the features: a steady force
   periodic in the revolution changes nothing), and the samples where an axis changed by
   more than ``control_step`` (N) form step runs (joined across gaps under half a
   revolution; a one-revolution drop is a two-revolution run, the drop and the return). An
   episode is a *control transient* when a step run began before its first crossing
   completed and its estimated onset lies in the run or at most ``control_window_revs``
   after it (or before it by less than the shortest crossing support, the estimate's own
   back-dating). Its decision emits no event, whatever the class: it is counted
   (``control_transients``) and kept (``last_control_transient``: the step, the onset and
   the class it would have had). The step must come first: the controller's reaction to a
   disturbance begins at the earliest with the period after the one that measured it
   (``delay_periods`` >= 1, 2 by default: a period later still), so it begins after the
   disturbance's onset and does not excuse it (a 430 g cm loss at 67 Hz with a 50 N force
   stepped in 11 samples after it: still a loss). Only with ``delay_periods`` 1 and a
   disturbance in the last samples of a period (fewer than the shortest crossing support, 2
   with haar, up to 8 with db4 at 32 samples per revolution) can the two not be told
   apart. Within such an episode, the contact bursts of step 4 inside a step run or up to
   ``control_window_revs`` after it are the response to that step (a second late command
   a few revolutions on re-excites the finest level like an impulse: a contact with haar)
   and are not counted; bursts outside are contacts and reported as in any episode. Without
   a force step nothing changes. The price: a fault that begins while a control transient's
   episode is open (its decision wait and its ring-down) is decided with it and not
   reported unless its bursts rise above the ring-down envelope (simulated AB1 contact by a
   misalignment at 29 Hz, whose ramp starts 6 revolutions before the first touch, after a
   one-revolution drop of a 20 N force: drop 0-12 revolutions before the touch, missed with
   haar, db2 and db4; 16-20, found with haar and db2; 24, found with each). Before, that
   merged episode was reported only because the step itself was taken for a fault.

Sensor channels found faulty are masked (their plane feature uses the partner channel only)
until :meth:`FaultMonitor.reset`. A channel whose finest-level coefficient stays below
``dead_fraction`` of its healthy median for ``dead_revs`` revolutions is reported as stuck or
zero (a constant signal has zero detail coefficients at every level).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field, replace

import numpy as np

from amb_fault_monitor.calibration import robust_threshold
from amb_fault_monitor.classifier import EpisodeEvidence, bearing_of_plane, classify
from amb_fault_monitor.errors import FaultMonitorError, RecordError
from amb_fault_monitor.events import FaultEvent, FaultType
from amb_fault_monitor.records import N_SENSORS, SampleCoefficients
from amb_wavelet.analysis import DETAIL
from amb_wavelet.filters import get_filters
from amb_wavelet.levels import revolution_level, support_length
from amb_wavelet.synthesis import atom_time_centre

__all__ = ["Crossing", "FaultMonitor", "MonitorConfig", "estimate_onset"]

FRAMES = ("fixed", "rotating")


@dataclass(frozen=True)
class MonitorConfig:
    """
    Parameters of :class:`FaultMonitor` (all times in revolutions of the rotor).

    Attributes
    ----------
    samples_per_rev : int
        Samples per revolution (power of two >= 4).
    levels : tuple of int
        Detail levels used; empty = every level received.
    frames : tuple of str
        ``"fixed"`` and/or ``"rotating"``.
    calibration_revs : float
        Length of the healthy calibration window.
    settle_ratio : float
        Stationarity test of the calibration window: the median feature of its first half may
        exceed that of its second half by at most this factor (per level and frame, planes
        pooled), or the window slides on by one revolution (a start-up transient still decaying).
    k : float
        Robust standard deviations of the threshold (see ``calibration``).
    threshold_floor : float
        m, smallest threshold (noise-free signals).
    confirm_ratio, confirm_features, confirm_revs
        Detection confirmation (module notes).
    quiet_revs, decision_revs, max_tail_revs
        Episode timing (module notes).
    decision_max_revs : float
        Longest wait for the decision while the 1 x level is still moving far from its
        reference (module notes, step 3); at least ``decision_revs``.
    rearm_revs : float
        After an episode ends, a new one needs a strong crossing (``confirm_ratio``) for this
        many revolutions: the ring-down of a large transient hovers at the threshold and would
        otherwise confirm on two weak features (module notes, step 4).
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
        Revolutions of the synchronous-level settling test (module notes, step 3).
    settle_spread : float
        The synchronous change has settled when its spread (max - min) over the latest
        ``settle_revs`` revolutions is at most this fraction of its mean.
    burst_gap_revs : float
        Quiet gap separating two fine-level bursts (contacts).
    tail_rise : float
        A finest-level coefficient one revolution or more into an episode counts as a contact
        burst if its ratio is at least this many times the largest finest-level ratio of the
        preceding revolution (its last quarter excluded): a new impulse above the ringing's
        own envelope (module notes, step 4).
    tail_rise_median : float
        From a quarter revolution into an episode, a fixed-frame finest-level coefficient is also
        a contact burst if its ratio, or its change from the previous coefficient, is at least
        this many times the *median* of the same quantity since the episode began (at most one
        revolution back, its last eighth excluded): the robust envelope that an earlier contact
        spike does not inflate (module notes, step 4).
    dead_fraction, dead_revs
        Stuck/zero channel test (module notes).
    control_step : float
        N, change of the applied control force on an axis from one revolution to the next
        that makes a control step (module notes, step 5). Measured at 67 Hz (unbalance of
        the soak run, 1 kg mm on D1; the transient controller holds the inner sensors at 2 um
        with 65 N): in steady control the force changes by at most 0.4 N per revolution
        (median 0.23 N). With a synchronous force that nulls the inner sensors answered by
        zero for one revolution, a drop of 0.8 N made no event, 2.1-2.5 N an UNKNOWN event
        (haar, db2, db4), 4 N a contact with haar and db2, 8 N and more a contact with each.
        2 N lies between: 5 times the steady adjustments, below the smallest drop that made
        an event.
    control_window_revs : float
        How long after a step run an episode's estimated onset may lie to be its transient
        (module notes, step 5). Measured on the one-revolution drops above: onsets 0-66
        samples after the drop began, at most 3 samples after its two-revolution run; one
        revolution (one control period) leaves a margin and keeps short the time in which a
        real fault would be taken for the step.
    """

    samples_per_rev: int
    levels: tuple[int, ...] = ()
    frames: tuple[str, ...] = FRAMES
    calibration_revs: float = 16.0
    settle_ratio: float = 2.0
    k: float = 8.0
    threshold_floor: float = 2.0e-8
    confirm_ratio: float = 3.0
    confirm_features: int = 2
    confirm_revs: float = 1.0
    quiet_revs: float = 2.0
    decision_revs: float = 16.0
    max_tail_revs: float = 200.0
    decision_max_revs: float = 32.0
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
    tail_rise_median: float = 3.0
    dead_fraction: float = 0.02
    dead_revs: float = 1.0
    control_step: float = 2.0
    control_window_revs: float = 1.0

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
            "tail_rise", "tail_rise_median", "dead_revs", "base_coherence", "base_dominance",
            "rearm_revs", "control_step", "control_window_revs",
        )  # fmt: skip
        for name in positive:
            if not getattr(self, name) > 0:
                raise FaultMonitorError(f"{name} must be > 0, got {getattr(self, name)}")
        if self.settle_ratio < 1:
            raise FaultMonitorError(f"settle_ratio must be >= 1, got {self.settle_ratio}")
        if self.threshold_floor < 0 or self.sync_relative_floor < 0 or self.dead_fraction < 0:
            raise FaultMonitorError(
                "threshold_floor, sync_relative_floor and dead_fraction must be >= 0"
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


class Crossing(tuple):
    """
    ``(level, frame, plane, first, last, ratio, centre)`` of a threshold crossing.

    ``first`` and ``last`` are the sample indices of the coefficient's support, ``centre`` the
    time centre of its atom (sample index, :func:`amb_wavelet.synthesis.atom_time_centre`;
    ``first`` when the wavelet is not known).
    """

    __slots__ = ()

    def __new__(
        cls,
        level: int,
        frame: str,
        plane: int,
        first: int,
        last: int,
        ratio: float,
        centre: float | None = None,
    ):
        return super().__new__(
            cls, (level, frame, plane, first, last, ratio, first if centre is None else centre)
        )

    level = property(lambda s: s[0])
    frame = property(lambda s: s[1])
    plane = property(lambda s: s[2])
    first = property(lambda s: s[3])
    last = property(lambda s: s[4])
    ratio = property(lambda s: s[5])
    centre = property(lambda s: s[6])


def estimate_onset(crossings: list[Crossing]) -> int:
    """
    Onset sample from the crossings of an episode (back-dated within the wavelet support).

    The coefficients that crossed first (the earliest completion sample) bound the onset:
    the change that made them cross lies in their supports. Among them the strongest (largest
    ratio to its threshold) is the one whose support surely holds the change, and within that
    support the estimate is the time centre of its atom (the earlier sample when it falls
    between two), where the coefficient is most sensitive to a change of its input
    (:func:`amb_wavelet.synthesis.atom_time_centre`). Thesis section 5.2 back-dates by the
    support; the centre is its best single sample.

    Measured on the scenario suite (``amb-fault-eval``, 32 samples per revolution, 41 cases,
    haar / db2 / db4), largest onset error of the mass-loss cases in finest-level supports:
    1.0 / 0.75 / 0.88 with this rule, 1.0 / 1.5 / 1.75 with the support's first sample
    narrowed by overlapping later crossings (the earlier rule: a response that keeps growing
    makes later, finer coefficients cross whose supports begin after the onset), 1.0 / 1.25 /
    1.75 with the first crossing's first sample alone.

    Parameters
    ----------
    crossings : list of Crossing
        Of one episode, any order.

    Returns
    -------
    int
        Estimated onset sample index.
    """
    if not crossings:
        raise FaultMonitorError("estimate_onset needs at least one crossing")
    first = min(c.last for c in crossings)
    strongest = max((c for c in crossings if c.last == first), key=lambda c: c.ratio)
    return onset_sample(strongest.centre)


def onset_sample(centre: float) -> int:
    """The sample of an atom's time centre: the nearest, the earlier one when midway."""
    return math.ceil(centre - 0.5)


@dataclass
class _Episode:
    start: int
    crossings: list[Crossing] = field(default_factory=list)
    keys: set = field(default_factory=set)
    alarm: int | None = None
    last_crossing: int = 0
    max_ratio: dict = field(default_factory=dict)  # (level, frame) -> (4,) plane ratios
    channel_energy: np.ndarray = field(default_factory=lambda: np.zeros(N_SENSORS))
    bursts: list = field(default_factory=list)  # [start, end, max ratio fixed, max rotating]
    p_ref: np.ndarray | None = None
    decided: FaultEvent | None = None
    tail_contacts: int = 0
    tail_peak: float = 0.0
    tail_plane_peak: np.ndarray = field(default_factory=lambda: np.zeros(4))
    tail_first: int = -1
    tail_onset: int = -1
    tail_history: deque = field(default_factory=deque)
    fixed_history: deque = field(default_factory=deque)
    rise_at: deque = field(default_factory=lambda: deque(maxlen=64))
    step_history: deque = field(default_factory=deque)
    prev_fine: np.ndarray | None = None
    tail_detect: int = -1
    contact_reported: bool = False
    strong_only: bool = False
    control: list | bool | None = None  # step run explaining it (step 5); False: none
    low_coherent: float = 0.0
    low_energy: float = 0.0
    low_peak: float = 0.0
    high_peak: float = 0.0


class _Lag:
    """Ring buffer of the last ``m`` coefficient vectors of one (level, frame)."""

    def __init__(self, m: int) -> None:
        self.buf = np.zeros((m, N_SENSORS))
        self.m = m
        self.pos = 0
        self.count = 0

    def push(self, v: np.ndarray) -> np.ndarray | None:
        old = self.buf[self.pos].copy() if self.count >= self.m else None
        self.buf[self.pos] = v
        self.pos = (self.pos + 1) % self.m
        self.count += 1
        return old


class FaultMonitor:
    """
    Streaming fault detector and classifier (ROS-free core of the ``fault_monitor`` node).

    Parameters
    ----------
    config : MonitorConfig

    Attributes
    ----------
    trace : list or None
        ``None`` (default, no cost) or a list the caller sets: every monitored feature after
        calibration is then appended as ``(sample_index, level, frame, first, last, ratio)``,
        ``ratio`` the (4,) plane ratios feature / threshold (dimensionless) of the coefficient
        completed at ``sample_index`` whose support is samples ``first..last``. Kept across
        :meth:`reset`.

    Notes
    -----
    Feed one :class:`~amb_fault_monitor.records.SampleCoefficients` per sample with
    :meth:`step`, in increasing ``sample_index``, and the control force applied in each sample
    with :meth:`control_force` (module notes, step 5; without it no transient is attributed to
    control). The first ``calibration_revs`` revolutions of settled coefficients calibrate the
    thresholds (they must be healthy); events are emitted afterwards. :meth:`reset` starts
    again (new calibration).
    """

    def __init__(self, config: MonitorConfig) -> None:
        self.config = config
        self._R = revolution_level(config.samples_per_rev)
        self._finest = min(config.levels) if config.levels else 1
        self._wavelet = ""
        self._centres: dict[tuple[str, int, str, int], float] = {}
        self.trace: list[tuple[int, int, str, int, int, np.ndarray]] | None = None
        self.reset()

    # ------------------------------------------------------------------ public
    def reset(self) -> None:
        """Forget all state, thresholds and masked channels; calibrate again."""
        self._lags: dict[tuple[int, str], _Lag] = {}
        self._calib: dict[tuple[int, str], deque] = {}
        self._calib_tried = -(2**62)
        self._thr: dict[tuple[int, str], np.ndarray] = {}
        self._sync_calib: deque = deque()
        self._sync_thr: np.ndarray | None = None
        self._dead_calib: deque = deque()
        self._dead_ref: np.ndarray | None = None
        self._dead_run = np.zeros(N_SENSORS, dtype=int)
        self._phasors: deque[tuple[int, int, np.ndarray]] = deque(maxlen=64)
        self._support_R = self.config.samples_per_rev
        self._mask = np.ones(N_SENSORS, dtype=bool)
        self._calib_start: int | None = None
        self._last_index: int | None = None
        self._episode: _Episode | None = None
        self._rearm_until = -(2**62)
        self._omega = 0.0
        self.unconfirmed = 0
        self.samples = 0
        self.calibration_retries = 0
        self.calibration_end: int | None = None
        spr = self.config.samples_per_rev
        self._force = np.zeros((spr, 4))
        self._force_at = np.full(spr, -(2**62), dtype=np.int64)
        self._force_steps: deque[list] = deque(maxlen=32)  # [first, last, largest change N]
        self.control_transients = 0
        self.last_control_transient: dict | None = None

    @property
    def calibrated(self) -> bool:
        """True once thresholds are set."""
        return bool(self._thr)

    @property
    def thresholds(self) -> dict[tuple[int, str], np.ndarray]:
        """Per (level, frame): plane thresholds (4,), m. Empty while calibrating."""
        return {k: v.copy() for k, v in self._thr.items()}

    @property
    def sync_threshold(self) -> np.ndarray | None:
        """Per plane threshold of the synchronous phasor change (4,), m."""
        return None if self._sync_thr is None else self._sync_thr.copy()

    @property
    def masked_channels(self) -> list[int]:
        """Channels excluded after a sensor fault."""
        return [int(c) for c in np.flatnonzero(~self._mask)]

    @property
    def in_episode(self) -> bool:
        """True while a disturbance is being tracked (alarm raised or pending)."""
        return self._episode is not None

    @property
    def alarm(self) -> bool:
        """True from a confirmed detection until the episode ends."""
        return self._episode is not None and self._episode.alarm is not None

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
        n = int(sample_index)
        spr = self.config.samples_per_rev
        slot = n % spr
        f = np.asarray(force, dtype=float)
        if self._force_at[slot] == n - spr:
            change = float(np.abs(f - self._force[slot]).max())
            if change > self.config.control_step:
                steps = self._force_steps
                if steps and steps[-1][0] <= n <= steps[-1][1] + spr // 2:
                    run = steps[-1]
                    run[1], run[2] = n, max(run[2], change)
                else:
                    steps.append([n, n, change])
        self._force[slot] = f
        self._force_at[slot] = n

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
        self._wavelet = record.wavelet
        events: list[FaultEvent] = []
        if not record.sets:
            self._advance(n, events)
            return events
        by_key = {}
        for s in record.sets:
            if s.frame not in self.config.frames:
                continue
            if s.kind != DETAIL:  # deepest approximation: the band below the last detail
                s = s._replace(level=s.level + 1)
            if self.config.levels and s.level not in self.config.levels:
                continue
            if len(s.values) != N_SENSORS:
                raise RecordError(f"coefficient set has {len(s.values)} values, expected 8")
            by_key[(s.level, s.frame, s.quadrature)] = s
        for (level, frame, quad), s in by_key.items():
            if quad != "even" or not s.settled:
                continue
            self._feature(n, level, frame, s, events)
            if level == self._R and frame == "fixed":
                odd = by_key.get((level, frame, "odd"))
                self._phasor(s, odd if odd is not None and odd.settled else None)
            if level == 1 and frame == "fixed":
                self._dead_channels(n, s, events)
        self._advance(n, events)
        return events

    # ------------------------------------------------------------------ features
    def _norm(self, level: int, values: np.ndarray) -> np.ndarray:
        v = np.asarray(values, dtype=float) / 2.0 ** (level / 2)
        return v

    def _feature(self, n: int, level: int, frame: str, s, events: list[FaultEvent]) -> None:
        key = (level, frame)
        lag = self._lags.get(key)
        if lag is None:
            lag = self._lags[key] = _Lag(max(1, 2 ** (self._R - level)))
        old = lag.push(self._norm(level, s.values))
        if old is None:
            return
        delta = (lag.buf[(lag.pos - 1) % lag.m] - old) * self._frame_mask(frame)
        planes = np.hypot(delta[0::2], delta[1::2])
        if not self._thr:
            self._calibrate(n, key, planes)
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

    def _frame_mask(self, frame: str) -> np.ndarray:
        """Channels in use: in the rotating frame u and v both mix x and y of the plane."""
        if frame == "fixed":
            return self._mask
        return np.repeat(self._mask[0::2] & self._mask[1::2], 2)

    def _calibrate(self, n: int, key: tuple[int, str], planes: np.ndarray) -> None:
        """
        Collect a healthy feature; set the thresholds once the window is full and stationary.

        The window holds the last ``calibration_revs`` revolutions. It is accepted when, for
        every (level, frame) and for the synchronous phasor change, the median of the first half
        (planes pooled) is at most ``settle_ratio`` times the median of the second half: a
        start-up or run-up transient that still decays fails the test, and the window slides
        on (the rotor may be started, or the monitor restarted, in a transient; thresholds
        calibrated on it would be 10-100 times the noise-only ones). The window is refused too
        while a feature of its last revolution exceeds the thresholds it gives: a disturbance
        that began in the window's last revolutions moves neither half's median, and was
        then reported once calibrated, with an onset at the calibration's end (the
        first-critical mass loss 0.6-3.7 revolutions before calibration ended). The test
        runs once per revolution.
        """
        cfg = self.config
        spr = cfg.samples_per_rev
        if self._calib_start is None:
            self._calib_start = n
        self._calib.setdefault(key, deque()).append((n, planes))
        window = cfg.calibration_revs * spr
        if n - self._calib_start < window or n - self._calib_tried < spr:
            return
        self._calib_tried = n
        lo = n - window
        for q in (*self._calib.values(), self._sync_calib, self._dead_calib):
            while q and q[0][0] <= lo:
                q.popleft()
        if any(len(v) < 8 for v in self._calib.values()) or len(self._sync_calib) < 8:
            return  # coarse levels (few coefficients per revolution) still filling
        mid = n - window / 2
        for q in (*self._calib.values(), self._sync_calib):
            first = [v for m, v in q if m <= mid]
            second = [v for m, v in q if m > mid]
            if not first or not second:
                return
            if np.median(first) > cfg.settle_ratio * max(np.median(second), cfg.threshold_floor):
                self.calibration_retries += 1
                return  # still settling
        thr = {k: self._plane_thresholds(q) for k, q in self._calib.items()}
        last = n - spr
        if any(m > last and np.any(v > thr[k]) for k, q in self._calib.items() for m, v in q):
            self.calibration_retries += 1
            return  # a disturbance in the window's last revolution: not healthy yet
        self._thr = thr
        self._sync_thr = robust_threshold(
            np.array([v for _m, v in self._sync_calib]), cfg.k, cfg.threshold_floor
        )
        if self._dead_calib:
            self._dead_ref = np.median(np.abs(np.array([v for _m, v in self._dead_calib])), axis=0)
        self.calibration_end = n
        self._calib.clear()

    def _plane_thresholds(self, q: deque) -> np.ndarray:
        """
        Plane thresholds: the larger of the per-plane and the planes-pooled robust threshold.

        Coarse levels give few coefficients per window (one per two revolutions at the level
        below 1 x: 8 in 16 revolutions); the MAD of 8 values is too uncertain (a third of the
        time under 0.7 of its true value, the crossings of the simulated healthy runs at 29
        and 67 Hz before this floor). Pooling the four planes (sensor noise is common to the
        probes) gives 4 times the observations; the per-plane value is kept where a plane
        moves more.
        """
        cfg = self.config
        a = np.array([v for _m, v in q])
        per_plane = robust_threshold(a, cfg.k, cfg.threshold_floor)
        pooled = robust_threshold(a.ravel(), cfg.k, cfg.threshold_floor)
        return np.maximum(per_plane, pooled)

    def _phasor(self, even, odd) -> None:
        p = self._norm(self._R, even.values).astype(complex)
        if odd is not None:
            p = p + 1j * self._norm(self._R, odd.values)
        if not self._thr and self._phasors:
            d = (p - self._phasors[-1][2]) * self._mask
            self._sync_calib.append(
                (int(even.last_sample_index), np.sqrt(np.abs(d[0::2]) ** 2 + np.abs(d[1::2]) ** 2))
            )
        self._phasors.append((int(even.first_sample_index), int(even.last_sample_index), p))
        self._support_R = int(even.last_sample_index - even.first_sample_index + 1)

    def _dead_channels(self, n: int, s, events: list[FaultEvent]) -> None:
        v = np.abs(self._norm(1, s.values))
        if not self._thr:
            self._dead_calib.append((n, v))
            return
        ref = self._dead_ref
        if ref is None:
            return
        cfg = self.config
        low = (v < cfg.dead_fraction * ref) & (ref > 0) & self._mask
        self._dead_run = np.where(low, self._dead_run + 1, 0)
        need = max(2, math.ceil(cfg.dead_revs * cfg.samples_per_rev / 2))
        for ch in np.flatnonzero(self._dead_run >= need):
            start = n - 2 * int(self._dead_run[ch])
            self._mask[ch] = False
            self._dead_run[ch] = 0
            ev = FaultEvent(
                FaultType.SENSOR_FAULT,
                onset_sample_index=max(start, 0),
                detection_sample_index=n,
                decision_sample_index=n,
                samples_per_rev=cfg.samples_per_rev,
                omega=self._omega,
                plane=int(ch) // 2 + 1,
                channel=int(ch),
                severity=float(ref[ch]),
                confidence=float(1.0 - v[ch] / max(cfg.dead_fraction * ref[ch], 1e-300)),
                evidence={
                    "mode": "stuck_or_zero",
                    "level": 1,
                    "frame": "fixed",
                    "healthy_median_m": float(ref[ch]),
                    "now_m": float(v[ch]),
                },
                description=(
                    f"sensor channel {ch} stuck or zero: finest-level coefficient below "
                    f"{cfg.dead_fraction:g} x its healthy median for {self._dead_run_revs()} rev"
                ),
            )
            ev.confidence = float(min(max(ev.confidence, 0.0), 1.0))
            events.append(ev)
            ep = self._episode
            if ep is not None and ep.decided is None and ep.start >= start - cfg.samples_per_rev:
                self._episode = None  # the crossings came from the failing channel

    def _dead_run_revs(self) -> str:
        return f"{self.config.dead_revs:g}"

    # ------------------------------------------------------------------ episodes
    def _evidence(self, n, level, frame, s, ratio, delta, thr) -> None:
        cfg = self.config
        crossed = ratio > 1.0
        ep = self._episode
        if ep is None:
            if not crossed.any():
                return
            ep = self._episode = _Episode(start=n, last_crossing=n)
            ep.p_ref = self._reference_phasor(s.first_sample_index)
            ep.strong_only = n < self._rearm_until
        if level == self._finest:
            self._contact_burst(n, s, ratio, frame)
        if ep.decided is not None:  # tail
            if crossed.any():
                ep.last_crossing = n
            return
        key = (level, frame)
        prev = ep.max_ratio.get(key)
        ep.max_ratio[key] = ratio.copy() if prev is None else np.maximum(prev, ratio)
        if not crossed.any():
            return
        ep.last_crossing = n
        centre = self._centre(s)
        for p in np.flatnonzero(crossed):
            ep.crossings.append(
                Crossing(level, frame, int(p) + 1, s.first_sample_index, s.last_sample_index,
                         float(ratio[p]), centre)
            )  # fmt: skip
        ep.keys.add(key)
        if frame == "fixed":
            w = np.repeat(thr, 2)
            ep.channel_energy += (delta / w) ** 2
            if level > self._R:
                self._low_coherence(ep, delta)
            elif level < self._R:
                ep.high_peak = max(ep.high_peak, float(np.abs(delta).max()))
        if level < self._R:
            rmax = float(ratio.max())
            if ep.bursts and n - ep.bursts[-1][1] <= cfg.burst_gap_revs * cfg.samples_per_rev:
                b = ep.bursts[-1]
                b[1] = n
            else:
                b = [n, n, 0.0, 0.0]
                ep.bursts.append(b)
            b[2 if frame == "fixed" else 3] = max(b[2 if frame == "fixed" else 3], rmax)
        if ep.alarm is None and (
            float(ratio.max()) >= cfg.confirm_ratio
            or (len(ep.keys) >= cfg.confirm_features and not ep.strong_only)
        ):
            ep.alarm = n

    def _low_coherence(self, ep: _Episode, delta: np.ndarray) -> None:
        """Accumulate the plane coherence of a fixed-frame change below 1 x (classifier rule 2)."""
        for axis in (0, 1):
            used = self._mask[axis::2]
            d = delta[axis::2][used]
            if d.size < 2:
                continue
            ep.low_coherent += float(d.sum()) ** 2
            ep.low_energy += d.size * float(d @ d)
        ep.low_peak = max(ep.low_peak, float(np.abs(delta).max()))

    def _contact_burst(self, n: int, s, ratio: np.ndarray, frame: str) -> None:
        """
        Rise test for a contact inside an episode (module notes, step 4).

        ``ratio`` is the finest-level ratio of one coefficient (either frame). From one
        revolution after the episode's first crossing, it is compared with the largest
        finest-level ratio of the preceding revolution, its last quarter excluded (the
        coefficients overlapping this one): the ring-down of a transient decays smoothly, so
        a coefficient ``tail_rise`` times that envelope, and strong (``confirm_ratio``), is a
        new impulse. Measured on the simulated suite (haar, 32 samples per revolution): the
        largest rise in a mass-loss ring-down without contact is 1.54, with contacts 1.84-2.66
        (a 10-20 % margin each side of 1.7).

        That envelope fails where a contact comes within the first revolution (the 430 g cm
        losses at 67 Hz touch 0.5 revolution after the loss): the test has not started, and
        the first contact's spike then sits in the envelope and hides the next ones. So two
        robust envelopes apply from a quarter revolution into the episode, on the fixed-frame
        finest level: the *median* since the episode began (at most one revolution back, the
        last eighth excluded, which a single spike does not raise) of (a) the ratio ``r`` and
        (b) the change of the coefficient from the previous one (figure 5.30 c-d). A
        coefficient with ``r >= confirm_ratio`` and (a) or (b) at least ``tail_rise_median``
        times its median is a burst; (a) alone not if a burst was found one revolution before
        (the feature's one-revolution lag echoes every spike one revolution later). With db2
        and db4 (2 and 4 vanishing moments) the finest level of a smooth ring-down stays near
        the noise and a contact spikes it: (a). With haar the finest level follows the slope
        of the ring-down (one vanishing moment), so a contact, a sudden change of velocity, is
        a step of the coefficient: (b). Fixed frame only: an impulse is local in time in
        either frame, but slow motion (base motion, below 1 x) appears near 1 x in the rotating
        frame, where the haar finest level follows its slope (rises of 3 on the simulated base
        motion there, none in the fixed frame). Measured on the suite (32 samples per
        revolution), over the mass-loss and base-motion episodes without contact: largest
        rise (a) 2.36 haar, 2.44 db2, none with ``r >= confirm_ratio`` for db4; (b) 1.75 haar,
        1.48 db2; at the first contact of the 430 g cm losses at 67 Hz (a) 3.2-4.1 db2,
        10.8-15.8 db4 and (b) about 4 haar. Sensor-fault episodes rise up to 15 (a noisy or
        offset probe spikes its finest level): their bursts are dropped at the decision.
        """
        ep = self._episode
        cfg = self.config
        spr = cfg.samples_per_rev
        r = float(ratio.max())
        hist = ep.tail_history
        while hist and hist[0][0] < n - spr:
            hist.popleft()
        recent = max((h[1] for h in hist if h[0] <= n - spr // 4), default=0.0)
        hist.append((n, r))
        median = step_median = math.inf
        step = 0.0
        if frame == "fixed":
            median = _window_median(ep.fixed_history, n, spr, r)
            c = self._norm(self._finest, s.values) * self._mask
            if ep.prev_fine is not None:
                d = c - ep.prev_fine
                step = float(np.hypot(d[0::2], d[1::2]).max())
                step_median = _window_median(ep.step_history, n, spr, step)
            ep.prev_fine = c
        if r < cfg.confirm_ratio or n < ep.start + spr // 4:
            return
        envelope = n >= ep.start + spr and r >= cfg.tail_rise * recent
        if not envelope and step < cfg.tail_rise_median * step_median:
            if r < cfg.tail_rise_median * median:
                return
            if any(abs(m + spr - n) <= 2 for m in ep.rise_at):
                return  # the one-revolution lag of the feature echoes a burst 1 rev later
        ep.rise_at.append(n)
        if self._control_window(ep, n):
            return  # the response to a control step (module notes, step 5)
        if ep.decided is not None:
            ep.last_crossing = n
        gap = cfg.burst_gap_revs * spr
        if ep.tail_first < 0 or n - ep.tail_first > gap:
            ep.tail_contacts += 1
            if ep.tail_onset < 0:  # at the time centre of the coefficient (estimate_onset)
                ep.tail_onset, ep.tail_detect = onset_sample(self._centre(s)), n
        ep.tail_first = n
        ep.tail_peak = max(ep.tail_peak, r)
        ep.tail_plane_peak = np.maximum(ep.tail_plane_peak, ratio)

    def _centre(self, s) -> float:
        """
        Time centre (sample index) of the atom of coefficient set ``s`` (``estimate_onset``).

        The first sample of the support when the stream's wavelet is unknown or its atom does
        not span the support (a filterbank other than ``amb_wavelet``'s).
        """
        level = s.level if s.kind == DETAIL else s.level - 1  # approximations: see step()
        size = s.last_sample_index - s.first_sample_index + 1
        key = (self._wavelet, level, s.kind, size)
        offset = self._centres.get(key)
        if offset is None:
            offset = 0.0
            try:
                if support_length(level, get_filters(self._wavelet).length) == size:
                    offset = atom_time_centre(self._wavelet, level, s.kind)
            except ValueError:  # not a PyWavelets name (WaveletNameError)
                pass
            self._centres[key] = offset
        return s.first_sample_index + offset

    def _reference_phasor(self, before: int) -> np.ndarray | None:
        for _first, last, p in reversed(self._phasors):
            if last < before:
                return p
        return None

    def _advance(self, n: int, events: list[FaultEvent]) -> None:
        ep = self._episode
        if ep is None:
            return
        cfg = self.config
        spr = cfg.samples_per_rev
        quiet = n - ep.last_crossing >= cfg.quiet_revs * spr
        if ep.alarm is None:
            if n - ep.start > cfg.confirm_revs * spr:
                self.unconfirmed += 1
                self._episode = None
            return
        if ep.decided is None:
            status = self._sync_status(ep)
            extra = max(self._support_R - spr, 0)
            waited = n - ep.alarm
            due = waited >= cfg.decision_revs * spr + extra and not (
                self._sync_moving(ep) and waited < cfg.decision_max_revs * spr + extra
            )
            if status is not None or due:
                ev = self._decide(n, ep)
                ep.control = self._control_run(ep) or False
                ep.decided = ev
                if ep.control:
                    self._control_transient(ep, ev, n, events, quiet)
                    return
                events.append(ev)
                if ev.fault_type == FaultType.SENSOR_FAULT and ev.channel >= 0:
                    self._mask[ev.channel] = False
                if ev.fault_type == FaultType.SENSOR_FAULT:
                    # bursts so far came from the failing channel (a noisy or offset probe
                    # spikes its finest level), not from the rotor: step 4
                    ep.tail_contacts, ep.tail_onset, ep.tail_detect = 0, -1, -1
                    ep.tail_first, ep.tail_peak = -1, 0.0
                    ep.tail_plane_peak = np.zeros(4)
                if ev.fault_type == FaultType.AUX_BEARING_CONTACT:
                    ev.count = max(ev.count, ep.tail_contacts)
                    ep.contact_reported = True
                elif ep.tail_contacts:
                    self._report_contacts(n, events)
                if quiet:
                    self._end_tail(n, events)
            return
        if ep.tail_contacts and not ep.contact_reported:
            self._report_contacts(n, events)
        if quiet or n - ep.decided.decision_sample_index >= cfg.max_tail_revs * spr:
            self._end_tail(n, events)

    def _control_run(self, ep: _Episode) -> list | None:
        """
        The control step run that explains episode ``ep``, or None (module notes, step 5).

        The run began before the episode's first crossing completed (a step at sample ``s``
        moves the rotor from ``s + 1``), and the estimated onset lies in the run or at most
        ``control_window_revs`` after it, or before it by less than the shortest crossing
        support (the estimate is the earliest sample the change can be at).
        """
        if ep.control is not None or ep.decided is not None:
            return ep.control or None
        if not ep.crossings or not self._force_steps:
            return None
        window = self.config.control_window_revs * self.config.samples_per_rev
        onset = estimate_onset(ep.crossings)
        support = min(c.last - c.first + 1 for c in ep.crossings)
        for run in self._force_steps:
            if run[0] < ep.start and run[0] < onset + support and onset <= run[1] + window:
                return run
        return None

    def _control_window(self, ep: _Episode, n: int) -> bool:
        """True if ``ep`` is a control transient and sample ``n`` within a step's window."""
        if not self._control_run(ep):
            return False
        window = self.config.control_window_revs * self.config.samples_per_rev
        return any(run[0] < n <= run[1] + window for run in self._force_steps)

    def _control_transient(
        self, ep: _Episode, ev: FaultEvent, n: int, events: list[FaultEvent], quiet: bool
    ) -> None:
        """
        Count a decided episode explained by a control step instead of emitting ``ev``.

        Contact bursts found outside the step's window are reported as after any decision.
        """
        first, last, change = ep.control
        self.control_transients += 1
        self.last_control_transient = {
            "onset_sample_index": int(ev.onset_sample_index),
            "decision_sample_index": int(ev.decision_sample_index),
            "step_first_sample_index": int(first),
            "step_last_sample_index": int(last),
            "step_n": float(change),
            "classified_as": ev.fault_type.name,
        }
        if ep.tail_contacts:
            self._report_contacts(n, events)
        if quiet:
            self._end_tail(n, events)

    def _end_tail(self, n: int, events: list[FaultEvent]) -> None:
        ep = self._episode
        self._episode = None
        self._rearm_until = n + self.config.rearm_revs * self.config.samples_per_rev
        if ep is not None and ep.tail_contacts and not ep.contact_reported:
            self._episode = ep
            self._report_contacts(n, events)
            self._episode = None

    def _report_contacts(self, n: int, events: list[FaultEvent]) -> None:
        """One ``AUX_BEARING_CONTACT`` event for the contact bursts found so far (step 4)."""
        ep = self._episode
        ep.contact_reported = True
        plane = int(np.argmax(ep.tail_plane_peak)) + 1
        r = ep.tail_peak
        after = "CONTROL_TRANSIENT" if ep.control else ep.decided.fault_type.name
        events.append(
            FaultEvent(
                FaultType.AUX_BEARING_CONTACT,
                onset_sample_index=ep.tail_onset,
                detection_sample_index=ep.tail_detect,
                decision_sample_index=n,
                samples_per_rev=self.config.samples_per_rev,
                omega=self._omega,
                plane=plane,
                bearing=bearing_of_plane(plane),
                confidence=float(min(max(1.0 - math.exp(-(r - 1.0)), 0.0), 1.0)),
                count=ep.tail_contacts,
                evidence={
                    "after": after,
                    "bursts": ep.tail_contacts,
                    "peak_ratio_finest_level": r,
                    "rule": f"finest level >= {self.config.tail_rise:g} x its ring-down envelope",
                },
                description=(
                    f"{ep.tail_contacts} contact burst(s) at the finest level above the "
                    f"envelope of the {'control' if ep.control else after.lower()} transient"
                ),
            )
        )

    def _sync_series(
        self, ep: _Episode, onset: int, final: bool = False
    ) -> tuple[str | None, np.ndarray, np.ndarray]:
        """
        Synchronous-level status after ``onset`` (module notes, step 3).

        Returns
        -------
        status : str or None
            ``"settled"``, ``"returned"`` or None (still moving; at ``final`` the trend
            decides: sustained, or at least ``sync_change`` from the reference on each of the
            latest ``2 settle_revs`` phasors (a lasting change whose ring-down contacts keep
            it moving), -> settled, else returned).
        ratio : numpy.ndarray
            (4,) mean ratio per plane over the latest ``settle_revs`` revolutions.
        change : numpy.ndarray
            (4,) latest change per plane, m.
        """
        cfg = self.config
        w = cfg.settle_revs
        zero = np.zeros(4)
        if ep.p_ref is None or self._sync_thr is None:
            return ("returned" if final else None), zero, zero
        after = [p for first, _last, p in self._phasors if first >= onset]
        if len(after) < (2 * w if not final else 1):
            return ("returned" if final and len(after) == 0 else None), zero, zero
        ref_level = np.hypot(np.abs(ep.p_ref[0::2]), np.abs(ep.p_ref[1::2]))
        thr = np.maximum(self._sync_thr, cfg.sync_relative_floor * ref_level)
        dev = np.array([np.hypot(np.abs(d[0::2]), np.abs(d[1::2])) for d in
                        ((p - ep.p_ref) * self._mask for p in after)])  # fmt: skip
        change = dev[-1]
        ratio = dev / thr
        s = ratio.max(axis=1)
        last, prev = s[-w:], s[-2 * w : -w]
        mean_last = ratio[-w:].mean(axis=0)
        if np.all(last < cfg.sync_change):
            return "returned", mean_last, change
        sustained = prev.size == 0 or last.mean() >= cfg.sustain * prev.mean()
        if prev.size and sustained and np.ptp(last) <= cfg.settle_spread * last.mean():
            return "settled", mean_last, change
        if final:
            away = len(s) >= 2 * w and bool(np.all(s[-2 * w :] >= cfg.sync_change))
            return ("settled" if sustained or away else "returned"), mean_last, change
        return None, mean_last, change

    def _sync_status(self, ep: _Episode) -> str | None:
        if not ep.crossings:
            return None
        return self._sync_series(ep, estimate_onset(ep.crossings))[0]

    def _sync_moving(self, ep: _Episode) -> bool:
        """
        True while the 1 x level stayed at least ``sync_change`` from its reference over the
        latest ``2 settle_revs`` revolutions: it has not returned and is still settling (a
        large loss whose transient contacts keep ringing), so the decision waits on up to
        ``decision_max_revs`` for the new steady state of Table 5.1.
        """
        if ep.p_ref is None or self._sync_thr is None or not ep.crossings:
            return False
        w = 2 * self.config.settle_revs
        onset = estimate_onset(ep.crossings)
        after = [p for first, _last, p in self._phasors if first >= onset][-w:]
        if len(after) < w:
            return False
        ref_level = np.hypot(np.abs(ep.p_ref[0::2]), np.abs(ep.p_ref[1::2]))
        thr = np.maximum(self._sync_thr, self.config.sync_relative_floor * ref_level)
        d = (np.array(after) - ep.p_ref) * self._mask
        s = (np.hypot(np.abs(d[:, 0::2]), np.abs(d[:, 1::2])) / thr).max(axis=1)
        return bool(np.all(s >= self.config.sync_change))

    def _decide(self, n: int, ep: _Episode) -> FaultEvent:
        cfg = self.config
        onset = estimate_onset(ep.crossings)
        status, sync_ratio, sync_change = self._sync_series(ep, onset, final=True)
        if status != "settled":
            sync_ratio = np.zeros(4)
        evidence = EpisodeEvidence(
            revolution_level=self._R,
            max_ratio={k: v.copy() for k, v in ep.max_ratio.items()},
            channel_energy=ep.channel_energy.copy(),
            sync_ratio=sync_ratio,
            sync_change=sync_change,
            bursts=[tuple(b) for b in ep.bursts],
            mask=self._mask.copy(),
            low_coherence=ep.low_coherent / ep.low_energy if ep.low_energy > 0 else 0.0,
            low_peak=ep.low_peak,
            high_peak=ep.high_peak,
        )
        decision = classify(evidence, cfg)
        return FaultEvent(
            decision.fault_type,
            onset_sample_index=onset,
            detection_sample_index=int(ep.alarm),
            decision_sample_index=n,
            samples_per_rev=cfg.samples_per_rev,
            omega=self._omega,
            plane=decision.plane,
            channel=decision.channel,
            bearing=decision.bearing,
            severity=decision.severity,
            confidence=decision.confidence,
            count=decision.count,
            evidence=decision.evidence,
            description=decision.description,
        )


def _window_median(hist: deque, n: int, spr: int, value: float) -> float:
    """
    Median of ``hist`` values from one revolution to one eighth before ``n``, then append.

    ``inf`` with fewer than two values (the rise test cannot apply yet).
    """
    while hist and hist[0][0] < n - spr:
        hist.popleft()
    older = [h[1] for h in hist if h[0] <= n - spr // 8]
    hist.append((n, value))
    return float(np.median(older)) if len(older) >= 2 else math.inf


def with_levels(config: MonitorConfig, levels: tuple[int, ...]) -> MonitorConfig:
    """Copy of ``config`` using ``levels``."""
    return replace(config, levels=tuple(levels))
