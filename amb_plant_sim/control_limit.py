"""
The physical limit of transient control: the best response any controller could give.

A controller with delay ``i`` computes its command for period ``m + i`` from the samples of
period ``m`` (``ARCHITECTURE.md``, "Time"); whatever it knows, a fault in period ``m_f`` can
first be answered by a force from sample ``k0 = (m_f + i) N``. The limit is the added force
sequence from ``k0`` on, chosen with full knowledge of the disturbance (clairvoyant), that
minimises the peak inner-sensor displacement ``max |x|`` over the window from the fault's
revolution on (the ``peak`` of ``amb-compare``), with

* the total control force per axis (local PID + added) within the force limit at every sample,
* the added force per axis within the force limit,
* every journal inside its auxiliary or retainer bearing's clearance (inscribed octagon).

On the linear plant (no contact, no saturation, linear AMB law; the constraints keep the
solution there) superposition holds exactly, so the problem is the linear program of
:mod:`amb_plant_sim.peak_lp`. Its data come from the simulator itself, through its public
API only: the free response is the PID-only run of the scenario on the same rig with
unbounded clearances and force (linear by construction, noise-free); the Markov parameters are
the responses of the undisturbed loop at the scenario's speed to a 1 N force held over sample
0 on each bearing axis. The optimal sequence is then replayed on the real rig (contacts,
saturation) noise-free, and the replayed peak is reported with the linear program's.

How exact it is. The ``floor`` (the largest inner |x| from the fault's revolution until
``k0``) bounds every controller from below; a limit equal to it is the true limit. Above it,
the limit is the peak of a force that exists (it is replayed), found within a restricted
set (force free for ``revolutions``, then periodic; journals in the inscribed octagon; the
force limits checked at the sample instants, the simulator's internal steps between them
are checked by the replay): the true limit lies between the floor and it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from amb_common.rig import Rig
from amb_plant_sim.errors import BoundExceededError, SimulationError
from amb_plant_sim.peak_lp import OCTAGON, Family, PeakProgram, octagon_bound
from amb_plant_sim.scenario import Scenario
from amb_plant_sim.simulator import MeasurementBlock, PlantSimulator

#: m -> um: the linear program works in micrometres and newtons (well-scaled rows)
UM = 1e6
#: revolutions of free response after the window for PID-only's steady amplitude
STEADY_REVS = 20
#: the settling level: this fraction of PID-only's steady amplitude (issue 18's metric)
SETTLE_FRACTION = 0.1


@dataclass
class LimitResult:
    """
    The limit for one scenario, fault sample and delay.

    Attributes
    ----------
    peak : float
        Smallest peak inner |x| from the fault's revolution on (linear program), m.
    replay_peak : float
        The same peak when the optimal force is replayed on the real rig (noise-free), m.
    floor : float
        Largest inner |x| from the fault's revolution up to ``k0`` (no force can change it), m.
    pid_peak : float
        PID-only peak over the same window (the linear free response), m.
    pid_steady : float
        PID-only steady amplitude after the fault (largest inner |x| over a revolution, the
        linear free response ``STEADY_REVS`` revolutions after the window), m.
    revs_below_10pct_pid : int or None
        Fewest revolutions from the fault's revolution after which every inner |x| stays below
        ``SETTLE_FRACTION * pid_steady`` with the peak held at its optimum (the window's
        length in revolutions: never within it); ``None`` when not computed.
    fault_sample, k0, end : int
        Fault onset sample, first sample of the added force, end of the window.
    samples_per_rev : int
    delay : int
    force : ndarray (end - k0, 4)
        Optimal added force [b1x, b1y, b2x, b2y], N.
    peak_force : float
        Largest ``hypot(f_x, f_y)`` of the added force, N.
    replay_contacts : int
        Samples in contact in the replay (0 when the clearance rows hold).
    replay_step_by_step : int
        Replayed samples integrated step by step (contact or saturation).
    rows, iterations : dict, int
        Size of the last linear program and the cutting-plane rounds.
    displacement : ndarray (end, 4)
        Predicted inner displacements (linear program), m.
    replay_displacement : ndarray (end, 4)
        Replayed inner displacements, m.
    pid_displacement : ndarray (end, 4)
        PID-only inner displacements (the linear free response), m.
    """

    peak: float
    replay_peak: float
    floor: float
    pid_peak: float
    pid_steady: float
    revs_below_10pct_pid: int | None
    fault_sample: int
    k0: int
    end: int
    samples_per_rev: int
    delay: int
    force: NDArray[np.float64]
    peak_force: float
    replay_contacts: int
    replay_step_by_step: int
    rows: dict[str, int] = field(default_factory=dict)
    iterations: int = 0
    displacement: NDArray[np.float64] | None = None
    replay_displacement: NDArray[np.float64] | None = None
    pid_displacement: NDArray[np.float64] | None = None


def linear_rig(rig: Rig) -> Rig:
    """``rig`` with unbounded clearances and force and the linear AMB law (superposition)."""
    return replace(
        rig,
        amb=replace(rig.amb, law="linear", force_limit=math.inf),
        clearance_bearings=tuple(
            replace(c, radial_clearance=math.inf) for c in rig.clearance_bearings
        ),
    )


def fault_sample(scenario: Scenario, fault_time: float, samples_per_rev: int) -> int:
    """First sample at or after ``fault_time`` (events act from there), constant speed."""
    fs = scenario.speed_hz * samples_per_rev
    return math.ceil(fault_time * fs - 1e-9)


def _outputs(block: MeasurementBlock, inner: list[int]) -> tuple[NDArray, NDArray, NDArray]:
    """Inner displacement (um), total control force (N), journal projections (um)."""
    jd = block.truth["journal_displacement"]  # (n, k, 2)
    proj = np.einsum("nkc,qc->nkq", jd, OCTAGON).reshape(len(jd), -1)
    return block.displacement[:, inner] * UM, block.bearing_force, proj * UM


def free_and_markov(
    rig: Rig, scenario: Scenario, samples_per_rev: int, n: int
) -> tuple[list[NDArray], list[NDArray]]:
    """
    Free responses and Markov parameters of the three output families over ``n`` samples.

    Returns
    -------
    free : list of ndarray
        Inner displacement (n, 4) um, control force (n, 4) N, journal projections (n, 4k) um,
        of the PID-only scenario run on :func:`linear_rig`.
    markov : list of ndarray
        The same outputs' responses (n, p, 4) to 1 N held over sample 0 on each axis of the
        undisturbed loop at the scenario's speed.
    """
    lin = linear_rig(rig)
    inner = rig.feedback_channels
    quiet = replace(scenario, measurement_noise=0.0)
    free = _outputs(PlantSimulator(lin, quiet, samples_per_rev).advance(n), inner)
    still = PlantSimulator(lin, replace(quiet, events=()), samples_per_rev)  # one discretisation
    cols = [_outputs(block, inner) for block in still.pulse_responses(n)]
    markov = [np.stack([c[f] for c in cols], axis=2) for f in range(3)]
    return list(free), markov


def control_limit(
    rig: Rig,
    scenario: Scenario,
    samples_per_rev: int,
    fault_time: float,
    delay: int,
    revolutions: int = 2,
    tail_revolutions: int = 4,
    force_limit: float | None = None,
    settle: bool = True,
    added_limit: float | None = None,
) -> LimitResult:
    """
    The best peak any controller with ``delay`` could give after the fault at ``fault_time``.

    Parameters
    ----------
    rig : Rig
    scenario : Scenario
        Resolved, constant speed; its events (the fault at ``fault_time`` among them) are the
        disturbance, known in full to the optimal force.
    samples_per_rev : int
        ``N``; a controller period is one revolution.
    fault_time : float
        Onset of the fault, s (the first sample at or after it is the fault sample).
    delay : int
        ``i`` >= 1: the first force is at ``k0 = (m_f + i) N``.
    revolutions, tail_revolutions : int
        Free decisions and periodic tail (:mod:`amb_plant_sim.peak_lp`), revolutions.
    force_limit : float, optional
        Per-axis limit of the total control force (PID + added), N (default: the rig's
        ``amb.force_limit``).
    settle : bool
        Also find the fewest revolutions to ``SETTLE_FRACTION`` of PID-only's steady amplitude
        at the optimal peak (second objective; a bisection of a few more linear programs); the
        force reported is then that second optimum's.
    added_limit : float, optional
        Per-axis limit of the added force alone, N (default: ``force_limit``).

    Returns
    -------
    LimitResult

    Raises
    ------
    BoundExceededError
        A clearance is reached before any added force can act, or no added force within the
        limits keeps the rotor inside its clearances (the linear program is infeasible).
    """
    if scenario.speed_hz is None or scenario.profile_hz:
        raise SimulationError("control_limit needs a resolved constant-speed scenario")
    if delay < 1:
        raise SimulationError(f"delay must be >= 1 period, got {delay}")
    N = int(samples_per_rev)
    k_f = fault_sample(scenario, fault_time, N)
    n_a = (k_f // N) * N
    k0 = n_a + delay * N
    end = k0 + (revolutions + tail_revolutions) * N
    limit = float(force_limit if force_limit is not None else rig.amb.force_limit)
    free, markov = free_and_markov(rig, scenario, N, end + STEADY_REVS * N)
    pid_steady = float(np.abs(free[0][-N:]).max()) / UM
    radii = np.repeat([octagon_bound(c.radial_clearance) for c in rig.clearance_bearings], 4)
    families = [
        Family("objective", free[0], markov[0], None, n_a, 1e-4),
        Family("force", free[1], markov[1], np.full(4, limit), k0, 1e-3),
        Family("clearance", free[2], markov[2], radii * UM, n_a, 1e-4, cut=True),
    ]
    added = limit if added_limit is None else float(added_limit)
    program = PeakProgram(families, k0, revolutions, tail_revolutions, N, added)
    sol = program.solve()
    if sol is None:
        raise BoundExceededError(
            "no added force within the limits keeps the rotor inside its clearances and the "
            "control force within the force limit (linear program infeasible)"
        )
    settle_revs = None
    if settle:
        settle_revs, sol = program.settle(sol.peak, SETTLE_FRACTION * pid_steady * UM)
    else:
        sol = program.solve(cap=sol.peak * (1 + 1e-6), least_force=True) or sol
    replay = replay_force(rig, scenario, N, sol.force, k0)
    x_replay = replay.displacement[:, rig.feedback_channels]
    hyp = np.hypot(sol.force[:, 0::2], sol.force[:, 1::2])
    return LimitResult(
        peak=sol.peak / UM,
        replay_peak=float(np.abs(x_replay[n_a:end]).max()),
        floor=program.floor / UM,
        pid_peak=float(np.abs(free[0][n_a:end]).max()) / UM,
        pid_steady=pid_steady,
        revs_below_10pct_pid=settle_revs,
        fault_sample=k_f,
        k0=k0,
        end=end,
        samples_per_rev=N,
        delay=int(delay),
        force=sol.force,
        peak_force=float(hyp.max()),
        replay_contacts=int(np.count_nonzero(replay.truth["contact"].any(axis=1))),
        replay_step_by_step=int(np.count_nonzero(replay.truth["step_by_step"])),
        rows=sol.rows,
        iterations=sol.iterations,
        displacement=sol.outputs["objective"] / UM,
        replay_displacement=x_replay,
        pid_displacement=free[0][:end] / UM,
    )


def replay_force(
    rig: Rig, scenario: Scenario, samples_per_rev: int, force: NDArray, k0: int
) -> MeasurementBlock:
    """Run the scenario noise-free on ``rig`` with ``force`` added from sample ``k0``."""
    n = k0 + len(force)
    added = np.zeros((n, 4))
    added[k0:] = force
    sim = PlantSimulator(rig, replace(scenario, measurement_noise=0.0), samples_per_rev)
    return sim.advance(n, added)
