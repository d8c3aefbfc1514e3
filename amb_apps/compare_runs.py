"""Running the ``amb-compare`` matrix and the metrics of each run.

:func:`comparison` runs every row of :mod:`amb_apps.compare_cases` on every scenario,
:func:`robustness` the rows with perturbed models, :func:`command_timing` times one command.

Metrics (per run; inner sensors x2, y2, x3, y3 unless said)
-----------------------------------------------------------
* ``peak``: largest |x| after the fault (m).
* ``revs_to_10``: revolutions after the fault period until the per-revolution peak |x|
  stays below 10 % of ``peak`` (``None``: not within the run).
* ``revs_to_10_1x``: the same on the per-revolution 1 x amplitude (one-revolution DFT bin 1
  of each inner sensor, the largest), i.e. the settling of the synchronous vibration the
  controllers act on, without the harmonics a control waveform may add.
* ``revs_below_10pct_pid``: revolutions after the fault period until the per-revolution peak
  |x| stays below 10 % of PID-only's steady 1 x amplitude (``pid_steady``; ``None``: not
  within the run, or no PID-only run to compare with), issue 18's settling metric.
* ``attenuation_db``: ``20 log10`` of the steady 1 x amplitude (last 10 revolutions,
  largest inner sensor) over the PID-only one (negative = reduction).
* ``peak_force`` / ``rms_force``: largest ``hypot(f_x, f_y)`` of the added force over the
  run, and its RMS over all axes after the fault (N).
* ``contacts``: contact onsets (simulator truth).
* ``non1x_um`` / ``harmonics_um``: over the last 10 revolutions, the largest |x| without
  each revolution's own mean and 1 x, and the largest 2 x, 3 x, 5 x, 7 x amplitudes (um)
  (:func:`harmonic_content`; ``residual_um``, a 1 x fit over all 10 revolutions, also
  counts a 1 x still decaying in a short ``--quick`` run).
* ``model_radius``: exact closed-loop spectral radius of the row's controller on its own
  model, as the run's pipeline checked it before going ACTIVE
  (:func:`amb_controller.stability.own_model_radius`; :func:`model_radius` without a run):
  >= 1 predicts divergence; at or above ``max_model_radius`` (0.98) the row is PID only
  (``refused`` says why). ``None`` for PID, the limit rows and the synchronous baseline (no
  dynamic model).
* ``peak_to_limit``: ``peak`` over the ``limit_i<delay>`` row's peak of the same scenario
  at the row's own delay (``None`` where no limit exists).

Rows ``limit_i1`` / ``limit_i2`` (:func:`run_limit`): the best response any controller with
that delay could give (:mod:`amb_plant_sim.control_limit`, ``amb-bound``), replayed on the
simulated rig noise-free for the whole run (its periodic tail continued) and measured with
the same metrics. Where the rotor reaches a clearance before any force can act (the contact
case), there is no such row and the reason is kept in ``limits_unavailable``.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from amb_apps.closed_loop import RunResult, first_fault, run_closed_loop
from amb_apps.compare_cases import (
    CONTROLLERS,
    HOLD_RAMP_PERIODS,
    MASS_LOSS,
    ML_LEVELS,
    MULTILEVEL,
    ROBUSTNESS_SCENARIO,
    SPECS,
    Matrix,
)
from amb_apps.parallel import run_jobs
from amb_common.rig import load_rig
from amb_controller.baselines import perturb_model
from amb_controller.basis import control_basis
from amb_controller.early_model import EarlyModelBank
from amb_controller.influence_coefficient import InfluenceCoefficientController
from amb_controller.metrics import (
    INNER,
    inner_revolution_peaks,
    revolutions_below,
    steady_sync_amplitude,
)
from amb_controller.multilevel import LevelResponse, MultiLevelController, block_diagonal_model
from amb_controller.response import PrescribedResponse
from amb_controller.selection import prescribed_response, selected_measurement_basis
from amb_controller.stability import own_model_radius
from amb_controller.supervisor import Mode
from amb_controller.synthesis import ForceLimiter
from amb_controller.transient import TransientController
from amb_plant_sim.control_limit import control_limit, replay_force
from amb_plant_sim.errors import BoundExceededError


def run_metrics(result, speed_hz: float, pid_steady: float | None = None) -> dict:
    """
    Return the comparison metrics of one :class:`~amb_apps.closed_loop.RunResult`.

    Parameters
    ----------
    result : RunResult
    speed_hz : float
        Running speed in Hz.
    pid_steady : float, optional
        PID-only steady 1 x amplitude (m) for ``attenuation_db``.

    Returns
    -------
    dict
        Module docstring, "Metrics".

    """
    spr = result.samples_per_rev
    x = result.displacement[:, list(INNER)]
    k_f = min(math.floor(result.fault_time * speed_hz + 1e-9), len(x) // spr - 1)
    after = inner_revolution_peaks(result.displacement, spr, k_f)
    peak = float(after.max())
    revs_to_10 = revolutions_below(after, 0.1 * peak)
    n_rev = len(x) // spr
    amp_1x = np.abs(np.fft.rfft(x[: n_rev * spr].reshape(n_rev, spr, -1), axis=1)[:, 1])
    after_1x = amp_1x[k_f:].max(axis=1) * 2 / spr  # per-revolution 1 x amplitude (m)
    above_1x = np.flatnonzero(after_1x > 0.1 * after_1x.max())
    revs_1x = int(above_1x[-1]) + 1 if above_1x.size else 0
    steady = float(steady_sync_amplitude(x, spr).max())
    wf = result.wavelet_force
    hyp = np.hypot(wf[:, 0::2], wf[:, 1::2])
    post = wf[k_f * spr :]
    contact_any = result.contact.any(axis=1) if result.contact.size else np.zeros(0, bool)
    contacts = int(np.count_nonzero(np.diff(contact_any.astype(int), prepend=0) == 1))
    below_pid = None
    if pid_steady is not None and pid_steady > 0:
        below_pid = revolutions_below(after, 0.1 * pid_steady)
    att = None
    if pid_steady is not None and pid_steady > 0 and steady > 0:
        att = 20 * math.log10(steady / pid_steady)
    return {
        "peak": peak,
        "peak_all_sensors": float(np.abs(result.displacement[k_f * spr :]).max()),
        "revs_to_10": revs_to_10,
        "revs_to_10_1x": None if revs_1x >= len(after_1x) else revs_1x,
        "revs_below_10pct_pid": below_pid,
        "peak_1x": float(after_1x.max()),
        "steady_1x": steady,
        "attenuation_db": att,
        "peak_force": float(hyp.max()),
        "rms_force": float(np.sqrt(np.mean(post**2))) if post.size else 0.0,
        "contacts": contacts,
    }


def residual_after_1x(result, revs: int = 10) -> float:
    """Peak inner displacement (m) of the last ``revs`` revolutions minus its 1 x fit."""
    spr = result.samples_per_rev
    x = result.displacement[-revs * spr :, list(INNER)]
    theta = 2 * np.pi * np.arange(x.shape[0]) / spr
    basis = np.column_stack([np.ones(theta.size), np.cos(theta), np.sin(theta)])
    coef, *_ = np.linalg.lstsq(basis, x, rcond=None)
    return float(np.abs(x - basis @ coef).max())


def model_radius(matrix: Matrix, name: str, key: str) -> float | None:
    """
    Exact closed-loop spectral radius of controller ``name`` on its own model at ``key``.

    The eq.-8.10 controller (wavelet or harmonic, delay and ``alpha`` of the run) closed
    around the FIR realisation of the model's Markov parameters
    (:func:`~amb_controller.stability.own_model_radius`, as the pipeline checks it): >= 1
    predicts divergence on the FE
    model itself, before any run. ``None`` for PID, the synchronous baseline (no dynamic
    model) and the multi-level rows (their runs' pipelines report theirs).
    """
    scenario = matrix.scenarios[key]
    if name == "wavelet_i1_8sensors":
        spec = SPECS["wavelet_i1"]
        config = replace(matrix.config(spec, scenario), sensors=tuple(range(8)))
    else:
        spec = SPECS.get("wavelet_i1" if name.startswith("wavelet_reconf") else name)
        if spec is None or spec.model not in ("fe", "harmonic"):
            return None
        config = matrix.config(spec, scenario)
    model = matrix.model(spec, scenario, config)
    controller = TransientController(
        model.inverse, prescribed_response(config), config.delay_periods
    )
    return own_model_radius(model.markov, controller)


def harmonic_content(result, revs: int = 10) -> dict:
    """
    What is left besides 1 x over the last ``revs`` revolutions, revolution by revolution.

    Each revolution of each inner sensor is split by its own DFT (so a 1 x still decaying
    from revolution to revolution is removed too, unlike a 1 x fit over all ``revs``).

    Returns
    -------
    dict
        ``non1x_um``: largest |x| without the revolution's mean and 1 x (um);
        ``harmonics_um``: ``{"2x": .., "3x": .., "5x": .., "7x": ..}`` largest amplitude (um).

    """
    spr = result.samples_per_rev
    x = result.displacement[-revs * spr :, list(INNER)].reshape(revs, spr, len(INNER))
    spectrum = np.fft.rfft(x, axis=1)
    rest = spectrum.copy()
    rest[:, :2] = 0.0
    non1x = np.fft.irfft(rest, n=spr, axis=1)
    amplitude = np.abs(spectrum) * 2 / spr
    return {
        "non1x_um": float(np.abs(non1x).max() * 1e6),
        "harmonics_um": {f"{h}x": float(amplitude[:, h].max() * 1e6) for h in (2, 3, 5, 7)},
    }


def run_multilevel(matrix: Matrix, name: str, key: str):
    """Run ``wavelet_124_coupled`` or ``wavelet_124_perlevel`` on scenario ``key``."""
    scenario = matrix.scenarios[key]
    config = replace(matrix.config(SPECS["wavelet_i1"], scenario), levels=ML_LEVELS)
    coupled = matrix.model(SPECS["wavelet_i1"], scenario, config)
    # plain least-squares inverse of fe_model for the coupled model (not the truncated SVD
    # the pipeline uses at p >= 2 when it recomputes the inverse): the truncated one made the
    # coupled loop less stable (docs/controller_notes.md, "Truncated-SVD inverse at p >= 2")
    controller = None
    if name == "wavelet_124_perlevel":
        controller = MultiLevelController.from_models(
            block_diagonal_model(coupled, config.inverse_order),
            {p: LevelResponse(p, config.w, config.v) for p in ML_LEVELS},
            config.delay_periods,
            selected_measurement_basis(config).labels,
            control_basis(config.wavelet, config.period_samples, ML_LEVELS).labels,
        )
    return run_closed_loop(matrix.rig, scenario, config, coupled, controller=controller)


def _engage_at_alarm(loop) -> bool:
    """``stop`` hook of run_closed_loop: set ACTIVE once the fault monitor's alarm is raised."""
    if loop.monitor.core.alarm and loop.pipeline.supervisor.mode == Mode.OFF:
        loop.pipeline.set_mode(Mode.ACTIVE)
    return False


def _engage_at_alarm_ramp(loop) -> bool:
    """As :func:`_engage_at_alarm`, HOLD ramping to zero over ``HOLD_RAMP_PERIODS``."""
    loop.pipeline.supervisor.hold_ramp_periods = HOLD_RAMP_PERIODS
    return _engage_at_alarm(loop)


#: delays of the limit rows (``limit_i1``, ``limit_i2``)
LIMIT_DELAYS = (1, 2)


#: A limit row's metrics that are the limit's only with its settling objective: ``--quick``
#: leaves that out (:func:`run_row`) and sets these to None (``settle_skipped``).
SETTLE_SKIPPED = (
    "revs_to_10", "revs_to_10_1x", "revs_below_10pct_pid", "peak_1x", "steady_1x",
    "attenuation_db", "residual_um", "non1x_um", "harmonics_um",
)  # fmt: skip


def run_limit(matrix: Matrix, key: str, delay: int, settle: bool = True) -> RunResult:
    """
    The control limit of scenario ``key`` at ``delay``, replayed over the whole run.

    The optimal force (:func:`amb_plant_sim.control_limit.control_limit` at the scenario's
    own fault instant and samples per revolution, with the settling objective unless
    ``settle`` is false) is continued periodically to the run's end and replayed noise-free on
    the rig.

    Raises
    ------
    BoundExceededError
        The rotor reaches a clearance before any force can act.
    """
    scenario = matrix.scenarios[key]
    spr = matrix.config(SPECS["pid"], scenario).samples_per_rev
    t_f = first_fault(scenario).time
    lim = control_limit(
        matrix.rig, scenario, spr, t_f, delay, force_limit=matrix.force_limit, settle=settle
    )
    n = max(1, round(scenario.duration * scenario.speed_hz)) * spr
    n_force = max(n - lim.k0, len(lim.force))
    reps = -(-(n_force - len(lim.force)) // spr)
    force = np.vstack([lim.force, np.tile(lim.force[-spr:], (reps, 1))])[:n_force]
    block = replay_force(matrix.rig, scenario, spr, force, lim.k0)
    added = np.zeros_like(block.bearing_force)
    added[lim.k0 :] = force
    return RunResult(
        time=block.time[:n],
        displacement=block.displacement[:n],
        wavelet_force=added[:n],
        bearing_force=block.bearing_force[:n],
        contact=block.truth["contact"][:n],
        phasor=np.zeros((0, 8), complex),
        commands=[],
        fault_time=t_f,
        samples_per_rev=spr,
        omega=float(block.omega[-1]),
    )


def _row_delay(name: str) -> int:
    """The delay a row's peak is compared at (its spec's; i = 1 for PID and the others)."""
    if name.startswith("limit_i"):
        return int(name.removeprefix("limit_i"))
    spec = SPECS.get(name)
    return spec.delay if spec is not None and spec.controller != "none" else 1


def _row_names(key: str, controllers, multilevel: bool, limits: bool) -> list[str]:
    """The rows run on scenario ``key`` (the matrix's own extras added)."""
    names = list(controllers)
    if key == "contact_case2":
        names += ["wavelet_reconf", "wavelet_reconf_alarm", "wavelet_reconf_alarm_ramp"]
    if multilevel and key.startswith("mass_loss"):
        names += list(MULTILEVEL)
    if key == "sync_150N_3rd":
        names += ["wavelet_i1_8sensors"]
    if limits:
        names += [f"limit_i{d}" for d in LIMIT_DELAYS]
    return names


def run_row(matrix: Matrix, key: str, name: str) -> RunResult:
    """
    Run row ``name`` of scenario ``key``.

    Raises
    ------
    BoundExceededError
        A ``limit_i*`` row where the rotor reaches a clearance before any force can act.
    """
    scenario = matrix.scenarios[key]
    if name.startswith("limit_i"):
        # quick: the least force of the optimal peak, without the settling objective's
        # bisection (most of a limit row's linear programs; the rows' steady columns are then
        # not the limit's: SETTLE_SKIPPED)
        delay = int(name.removeprefix("limit_i"))
        return run_limit(matrix, key, delay, settle=not matrix.quick)
    if name == "wavelet_reconf":
        return matrix.run(SPECS["wavelet_i1"], key, fault_monitor=True, engage_on=(MASS_LOSS,))
    if name == "wavelet_reconf_alarm":
        return matrix.run(
            SPECS["wavelet_i1"], key, fault_monitor=True, engage_on=(MASS_LOSS,),
            stop=_engage_at_alarm,
        )  # fmt: skip
    if name == "wavelet_reconf_alarm_ramp":
        return matrix.run(
            SPECS["wavelet_i1"], key, fault_monitor=True, engage_on=(MASS_LOSS,),
            stop=_engage_at_alarm_ramp,
        )  # fmt: skip
    if name in MULTILEVEL:
        return run_multilevel(matrix, name, key)
    if name == "wavelet_i1_8sensors":
        spec = SPECS["wavelet_i1"]
        config = replace(matrix.config(spec, scenario), sensors=tuple(range(8)))
        model = matrix.model(spec, scenario, config)
        return run_closed_loop(matrix.rig, scenario, config, model)
    return matrix.run(SPECS[name], key)


def _row_cost(key: str, name: str) -> int:
    """
    A row's cost relative to the others, to start the longest first (a scheduling hint only).

    From the wall times of ``amb-compare --quick``: the limit rows (linear programs) and the
    rows of the contact, first- and third-critical step-force scenarios (contact integrated
    step by step) take 15-45 s each, a run clear of the auxiliary bearings under a second.
    """
    if name.startswith("limit_i") or key in ("contact_case2", "sync_150N_1st", "sync_150N_3rd"):
        return 2 if name != "pid" else 1
    return 0


def _row_task(task: tuple) -> tuple:
    """
    Run one row of :func:`comparison` (in a worker process).

    ``(matrix args, key, name)`` -> ``(result, model radius, wall time, error)``; ``result``
    is ``None`` and ``error`` the reason where no limit exists.
    """
    args, key, name = task
    matrix = Matrix.shared(*args)
    t0 = time.perf_counter()
    try:
        result = run_row(matrix, key, name)
    except BoundExceededError as exc:
        return None, None, time.perf_counter() - t0, str(exc)
    # the radius the run's pipeline checked (every row with a realisable controller, the
    # multi-level ones included); model_radius() computes the same without a run
    return result, result.model_radius, time.perf_counter() - t0, None


def comparison(
    matrix: Matrix,
    controllers=CONTROLLERS,
    progress=None,
    multilevel: bool = False,
    limits: bool = True,
    jobs: int | None = 1,
) -> dict:
    """
    Run every controller on every scenario; return ``{scenario: {controller: metrics}}``.

    With ``limits`` the ``limit_i1`` and ``limit_i2`` rows are added (module docstring) and
    every row gets ``peak_to_limit``. The runs are independent: ``jobs`` processes run them
    (:func:`amb_apps.parallel.run_jobs`; ``None``: the machine's cores), the table is the
    same for any ``jobs``.
    """
    rows = [
        (key, name)
        for key in matrix.scenarios
        for name in _row_names(key, controllers, multilevel, limits)
    ]
    order = sorted(range(len(rows)), key=lambda i: -_row_cost(*rows[i]))
    tasks = [(matrix.args, *rows[i]) for i in order]

    def done(i: int, out: tuple) -> None:
        if progress is None:
            return
        key, name = rows[order[i]]
        result, _, wall, error = out
        if result is None:
            progress(f"{key} {name}: no limit: {error}")
        else:
            peak = run_metrics(result, matrix.scenarios[key].speed_hz)["peak"]
            progress(f"{key} {name}: peak {peak * 1e6:.1f} um ({wall:.0f} s)")

    Matrix.adopt(matrix)  # rows run here (one job) use it and its cached models
    outs = run_jobs(_row_task, tasks, jobs, done)
    by_row = {rows[order[i]]: out for i, out in enumerate(outs)}
    table: dict = {}
    traces: dict = {}
    unavailable: dict = {}
    for key, scenario in matrix.scenarios.items():
        table[key] = {}
        traces[key] = {}
        pid_steady = None
        for name in _row_names(key, controllers, multilevel, limits):
            result, radius, wall, error = by_row[(key, name)]
            if result is None:
                unavailable.setdefault(key, {})[name] = error
                continue
            m = run_metrics(result, scenario.speed_hz, pid_steady)
            if name == "pid":
                pid_steady = m["steady_1x"]
            m["wall_time"] = wall
            m["residual_um"] = residual_after_1x(result) * 1e6
            m.update(harmonic_content(result))
            m["model_radius"] = radius
            m["refused"] = result.refused
            if name.startswith("limit_i") and matrix.quick:
                m.update(dict.fromkeys(SETTLE_SKIPPED), settle_skipped=True)
            if name.startswith("wavelet_reconf"):
                spr = result.samples_per_rev
                m["fault_events"] = [
                    [e["fault_type"], e["detection_sample_index"] / spr / scenario.speed_hz]
                    for e in result.fault_events
                ]
            table[key][name] = m
            traces[key][name] = (result.time, result.displacement[:, 2], result.fault_time)
        for name, m in table[key].items():
            lim = table[key].get(f"limit_i{_row_delay(name)}")
            m["peak_to_limit"] = None if lim is None else m["peak"] / lim["peak"]
    return {"table": table, "traces": traces, "limits_unavailable": unavailable}


#: the robustness matrix's cases: model gain and phase errors, and speed off the model's
ROBUSTNESS_CASES = {
    "nominal": {},
    "gain +30%": {"gain": 1.3},
    "gain -30%": {"gain": 0.7},
    "phase +30deg": {"phase": math.radians(30)},
    "phase -30deg": {"phase": math.radians(-30)},
    "speed +10%": {"speed": 1.1},
    "speed -10%": {"speed": 0.9},
}
ROBUSTNESS_ROWS = tuple(name for name in CONTROLLERS if name != "pid")


def perturb_early_model(model, gain: float, phase: float):
    """
    The early action's model with its force path off by ``gain`` and ``phase`` (rad at 1 x).

    The bearing Markov parameters (the controller's model of its own force) are scaled by
    ``gain`` and delayed by ``phase / (2 pi) N`` samples (rounded; negative: advanced), the
    1 x phase error of a pure delay; the planes' responses (the unbalance model) are kept. A
    bank: each of its models.
    """
    if isinstance(model, EarlyModelBank):
        return EarlyModelBank(tuple(perturb_early_model(m, gain, phase) for m in model.models))
    h = model.bearing_markov * gain
    shift = round(phase / (2 * math.pi) * model.samples_per_rev)
    if shift > 0:
        h = np.concatenate([np.zeros_like(h[:shift]), h[:-shift]])
    elif shift < 0:
        h = np.concatenate([h[-shift:], np.zeros_like(h[:-shift])])
    return replace(model, bearing_markov=h)


def _robustness_task(task: tuple) -> dict:
    """Worker of :func:`robustness`: ``(matrix args, row, case)`` -> the run's metrics."""
    args, name, case = task
    matrix = Matrix.shared(*args)
    key = ROBUSTNESS_SCENARIO
    scenario = matrix.scenarios[key]
    p = ROBUSTNESS_CASES[case]
    spec = SPECS[name]
    config = matrix.config(spec, scenario)
    nominal = matrix.model(spec, scenario, config)
    model = perturb_model(nominal, p.get("gain", 1.0), p.get("phase", 0.0), config.inverse_order)
    hz = scenario.speed_hz * p.get("speed", 1.0)
    kw = {}
    if spec.early:
        early = matrix.early_model(scenario, config)
        kw["early_model"] = perturb_early_model(early, p.get("gain", 1.0), p.get("phase", 0.0))
    result = matrix.run(spec, key, model=model, speed_hz=hz, **kw)
    pid = matrix.run(SPECS["pid"], key, speed_hz=hz) if "speed" in p else None
    pid_steady = None if pid is None else run_metrics(pid, hz)["steady_1x"]
    m = run_metrics(result, hz, pid_steady)
    if pid is not None:
        m["pid_peak"] = run_metrics(pid, hz)["peak"]
    return m


def robustness(matrix: Matrix, progress=None, jobs: int | None = 1) -> dict:
    """
    Every controller with its model off by +-30 % gain, +-30 deg phase, and at +-10 % speed.

    On the first-critical mass loss; the coefficient model stays the one of the nominal speed
    (the early action's bank, :meth:`Matrix.early_model`, spans +-12 % of it), and at another
    speed the fault falls at the same sample of the same revolution
    (:func:`~amb_apps.compare_cases.at_speed`). ``jobs`` as in :func:`comparison`.
    """
    runs = [(name, case) for name in ROBUSTNESS_ROWS for case in ROBUSTNESS_CASES]

    def done(i: int, m: dict) -> None:
        if progress is not None:
            progress(f"robustness {runs[i][0]} {runs[i][1]}: peak {m['peak'] * 1e6:.1f} um")

    Matrix.adopt(matrix)
    outs = run_jobs(_robustness_task, [(matrix.args, *r) for r in runs], jobs, done)
    out: dict = {name: {} for name in ROBUSTNESS_ROWS}
    for (name, case), m in zip(runs, outs, strict=True):
        out[name][case] = m
    return out


def command_timing(
    samples_per_rev: int = 64, repeats: int = 2000, force_limit: float | None = None
) -> dict:
    """
    Median time of one command (controller step + synthesis + force limit), s.

    The work done at the end of a period, after its last sample, before the command for
    the next period can be sent: what must fit in a small fraction of a period for i = 1.
    ``force_limit`` (N per axis, also the capacity) defaults to the rig's bearing capacity
    (``amb.force_limit`` of config/rig.yaml).
    """
    if force_limit is None:
        force_limit = load_rig().amb.force_limit
    rng = np.random.default_rng(0)
    cb = control_basis("haar", samples_per_rev, (1,), 4)
    limiter = ForceLimiter(cb, force_limit, force_limit)
    ctl = {
        "transient": TransientController(
            rng.normal(size=(6, 8, 8)), PrescribedResponse.exponential(0.75, 0.75), 1
        ),
        "synchronous": InfluenceCoefficientController(
            rng.normal(size=(4, 4)) + 1j * rng.normal(size=(4, 4)), 0.5, 1
        ),
    }
    out = {}
    q = rng.normal(size=(repeats, 8)) * 1e-9
    for name, c in ctl.items():
        times = np.empty(repeats)
        for k in range(repeats):
            t0 = time.perf_counter()
            limiter.apply(c.step(k, q[k]).coefficients)
            times[k] = time.perf_counter() - t0
        out[name] = {"median_s": float(np.median(times)), "p99_s": float(np.quantile(times, 0.99))}
    return out
