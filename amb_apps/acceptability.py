"""
Acceptable performance diagram of the wavelet transient controller (thesis section 8.5.1).

The thesis tested controllers with the exponential prescribed response
``alpha = w / (z - v)`` (eq. 8.6) on the rig at 11 Hz (its first critical speed), delay
``i = 2``, 5th-order inverse, and classified each (w, v) as unacceptable "if the vibration
exceeded a specified limit of 0.5 mm in any control plane" (figure 8.4); the same search gave
a maximum linear decay rate of 0.31 per time step. Here the rig is the FE simulator run
in-process (:func:`amb_apps.closed_loop.run_closed_loop`) on the mass-loss scenario at
the model's own first critical speed (``config/scenarios/mass_loss_first_critical.yaml``,
430 g cm at D1), with the chapter-6 FE-route model.

Classification of one run (decisions; the thesis judged by eye)
---------------------------------------------------------------
* **displacement** of a plane = orbit radius ``hypot(x_i, y_i)`` at sensor plane i (m); the
  peak is taken over the samples at or after the fault.
* **unstable** ("growth"): the divergence guard of the pipeline tripped, the rotor touched a
  clearance bearing (simulator truth; the run is stopped there), or the 1 x response
  is still growing at the end of the run (:func:`envelope_growth`). The guard is armed at
  ``RUNAWAY_FRACTION`` of the smallest auxiliary-bearing clearance of ``config/rig.yaml`` (a
  loop running towards the auxiliary bearings is stopped as the rig's operator would; it
  also keeps the simulator out of the slow contact model) with its default growth test.
* **unacceptable**: stable, but the peak plane displacement after the fault exceeds
  ``LIMIT`` = 0.5 mm.
* **acceptable**: neither.

Runs that trip the guard are counted unstable even when a transient might still have turned
back below the clearance: the thesis could not tell these apart either (the test is stopped).

The nominal stability boundary (figure 8.3, poles of ``(z - v) + w (z - 1)(z^i - 1)``,
:func:`amb_controller.stability.exponential_stability_map`) is drawn over the measured map.

Command: ``amb-acceptability --out DIR [--grid N] [--json] [--jobs N]`` writes
``acceptability.png`` and ``acceptability.json`` (the runs in N parallel processes, default the
machine's cores; the result is the same for any N).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from amb_apps.closed_loop import fe_model, run_closed_loop
from amb_apps.parallel import add_jobs_argument, run_jobs
from amb_common.paths import config_file
from amb_common.rig import load_rig
from amb_common.topics import DELAY_PERIODS
from amb_controller.config import ControllerConfig
from amb_controller.metrics import INNER, steady_sync_amplitude
from amb_controller.response import PrescribedResponse
from amb_controller.stability import exponential_stability_map, is_nominally_stable
from amb_plant_sim.scenario import load_scenario

__all__ = [
    "ACCEPTABLE",
    "LIMIT",
    "UNACCEPTABLE",
    "UNSTABLE",
    "RunClass",
    "SweepSetup",
    "classify_run",
    "envelope_growth",
    "exponential_sweep",
    "grid_values",
    "linear_rate_sweep",
    "main",
    "nominal_linear_rate_limit",
    "plot_acceptability",
    "run_until_runaway",
]

LIMIT = 0.5e-3  # m, thesis section 8.5.1 (also section 7.4.2)
THESIS_LINEAR_RATE = 0.31  # per time step, thesis section 8.5.1
RUNAWAY_FRACTION = 0.9  # of the smallest auxiliary-bearing clearance
WINDOW = 10  # periods
NOISE_FRACTION = 0.02
ACCEPTABLE, UNACCEPTABLE, UNSTABLE = "acceptable", "unacceptable", "unstable"
LABELS = (ACCEPTABLE, UNACCEPTABLE, UNSTABLE)


class AcceptabilityValueError(ValueError):
    """An argument of the acceptability sweep is out of range (the message says which)."""


@dataclass(frozen=True)
class RunClass:
    """
    Classification of one closed-loop run (module docstring).

    Attributes
    ----------
    label : str
        ``acceptable``, ``unacceptable`` or ``unstable``.
    peak_radius : float
        Largest plane orbit radius after the fault, m.
    steady_1x : float
        Largest steady 1 x amplitude of the inner sensors (planes 2, 3) over the last 10
        revolutions, m.
    guard_tripped : bool
        The divergence guard stopped the wavelet force.
    growth_per_period : float
        Envelope ratio per period of the late 1 x response (:func:`envelope_growth`;
        < 1 decaying, 0 when converged or too short).
    converged : bool
        The late second differences are below the noise fraction.

    """

    label: str
    peak_radius: float
    steady_1x: float
    guard_tripped: bool
    growth_per_period: float
    converged: bool


def envelope_growth(phasor: np.ndarray) -> tuple[float, bool]:
    """
    Estimate the per-period growth of the 1 x response after a fault.

    With ``s_k = max_c |P_k - 2 P_{k-1} + P_{k-2}|`` the second difference of the per-period
    1 x phasors (zero for a steady state and for a prescribed linear ramp, so a slow but
    intended decay is not taken for growth), the response has converged if the largest
    ``s`` of the last ``WINDOW`` periods is at most ``NOISE_FRACTION`` of the largest ``s``;
    otherwise ``log s_k`` is fitted by a straight line from the largest ``s`` before the last
    window to the end and
    ``exp(slope)`` is the envelope ratio per period (a pole modulus estimate).

    Parameters
    ----------
    phasor : numpy.ndarray of complex
        ``(K, c)`` 1 x phasors from the fault period on (m sqrt(samples)).

    Returns
    -------
    tuple of (float, bool)
        Growth per period (0 when converged or fewer than ``WINDOW`` points) and converged.

    """
    phasor = np.asarray(phasor)
    if phasor.shape[0] < 3:
        return 0.0, True
    s = np.abs(np.diff(phasor, n=2, axis=0)).max(axis=1)
    biggest = float(s.max())
    if biggest == 0.0 or s[-WINDOW:].max() <= NOISE_FRACTION * biggest:
        return 0.0, True
    tail = s[int(np.argmax(s[: max(1, s.size - WINDOW)])) :]
    if tail.size < WINDOW:
        return 0.0, False
    k = np.arange(tail.size)
    slope = np.polyfit(k, np.log(np.maximum(tail, 1e-12 * biggest)), 1)[0]
    return float(np.exp(slope)), False


def classify_run(result, speed_hz: float, limit: float = LIMIT) -> RunClass:
    """
    Classify a run as acceptable, unacceptable or unstable (module docstring).

    Parameters
    ----------
    result : amb_apps.closed_loop.RunResult
        The run (fault time, displacement, per-period 1 x phasors, commands).
    speed_hz : float
        Running speed in Hz.
    limit : float
        Acceptability limit on the plane orbit radius, m.

    Returns
    -------
    RunClass

    """
    x = np.asarray(result.displacement)
    after = result.time >= result.fault_time - 1e-12
    if not after.any():  # stopped before the fault
        after = np.ones_like(after)
    radius = np.hypot(x[after, 0::2], x[after, 1::2])
    peak = float(radius.max()) if radius.size else 0.0
    steady = steady_sync_amplitude(x, result.samples_per_rev)
    guard = any(c.guard_tripped for c in result.commands)
    contact = bool(np.any(result.contact))
    phasor = np.asarray(result.phasor)
    k_f = min(math.floor(result.fault_time * speed_hz + 1e-9), len(phasor) - 1)
    growth, converged = envelope_growth(phasor[k_f:])
    growing = (not converged) and growth >= 1.0
    if guard or contact or growing or not np.all(np.isfinite(x)):
        label = UNSTABLE
    elif peak > limit:
        label = UNACCEPTABLE
    else:
        label = ACCEPTABLE
    return RunClass(label, peak, float(steady[list(INNER)].max()), guard, growth, converged)


@dataclass
class SweepSetup:
    """
    What every run of a sweep shares: rig, scenario, FE model and base configuration.

    Build with :meth:`first_critical`.

    Attributes
    ----------
    rig : amb_common.rig.Rig
    scenario : amb_plant_sim.scenario.Scenario
    model : amb_controller.model_file.WaveletModel
    config : amb_controller.config.ControllerConfig
        Transient controller, Haar, 64 samples/rev, the delay given to :meth:`first_critical`,
        5th-order inverse, guard armed.

    """

    rig: object
    scenario: object
    model: object
    config: object

    @classmethod
    def first_critical(
        cls,
        delay: int = DELAY_PERIODS,
        samples_per_rev: int = 64,
        scenario_path: str | Path | None = None,
    ) -> SweepSetup:
        """
        Return the setup of figure 8.4: mass loss at the first critical speed, delay ``delay``.

        Parameters
        ----------
        delay : int
            Evaluation delay i in periods (default: the thesis's, section 8.5.1).
        samples_per_rev : int
            Samples per revolution (power of two).
        scenario_path : str or Path, optional
            Scenario file (default ``config/scenarios/mass_loss_first_critical.yaml``).

        Returns
        -------
        SweepSetup

        """
        rig = load_rig()
        path = scenario_path or config_file("scenarios/mass_loss_first_critical.yaml")
        scenario = load_scenario(path, rig)
        aux = [c.radial_clearance for c in rig.clearance_bearings if c.kind == "auxiliary"]
        bound = RUNAWAY_FRACTION * min(aux) if aux else math.inf
        config = ControllerConfig(
            samples_per_rev=samples_per_rev,
            delay_periods=delay,
            controller="transient",
            inverse_order=5,
            displacement_bound=bound,
            # the diagram maps what every (w, v) does on the rig, as the thesis tested them:
            # a controller its own model says diverges is run too (it is a point of the map)
            max_model_radius=math.inf,
        )
        model = fe_model(rig, 2 * math.pi * scenario.speed_hz, config)
        return cls(rig, scenario, model, config)

    def run(self, **overrides) -> RunClass:
        """
        Run the scenario with ``ControllerConfig`` fields overridden; classify it.

        The run is :func:`amb_apps.closed_loop.run_closed_loop` period by period
        (its lock-step loop), stopped at the first period after which the divergence guard
        has tripped or any clearance bearing is in contact: such a run is unstable
        (module docstring), and once the rotor rubs on an auxiliary bearing the contact can
        persist after the wavelet force is removed, which the simulator integrates step by step,
        far slower than contact-free samples (docs/results.md#plant-bench).
        """
        cfg = replace(self.config, **overrides)
        result = run_until_runaway(self.rig, self.scenario, cfg, self.model)
        return classify_run(result, self.scenario.speed_hz)


def run_until_runaway(rig, scenario, config, model):
    """
    Run one scenario as :func:`~amb_apps.closed_loop.run_closed_loop`, stopping early.

    Stops after the first period that ends with the divergence guard tripped or with contact
    at a clearance bearing (simulator truth).

    Parameters
    ----------
    rig : amb_common.rig.Rig
    scenario : amb_plant_sim.scenario.Scenario
        Resolved scenario (constant speed).
    config : amb_controller.config.ControllerConfig
    model : amb_controller.model_file.WaveletModel or None

    Returns
    -------
    amb_apps.closed_loop.RunResult
        Over the periods run.

    """
    return run_closed_loop(rig, scenario, config, model, 0, stop=_runaway)


def _runaway(loop) -> bool:
    """Return True once the divergence guard has tripped or a clearance bearing touches."""
    guard = loop.pipeline.supervisor.guard
    return bool((guard is not None and guard.tripped) or loop.blocks[-1].truth["contact"].any())


def grid_values(n: int) -> np.ndarray:
    """
    Return ``n`` cell-centred values in (0, 1): ``(k + 0.5) / n``, k = 0..n-1.

    Parameters
    ----------
    n : int
        Grid size (>= 2). ``n = 10`` contains 0.65 and 0.75 of section 8.5.3.

    Returns
    -------
    numpy.ndarray

    """
    if int(n) != n or n < 2:
        raise AcceptabilityValueError(f"grid must be an integer >= 2, got {n!r}")
    return (np.arange(int(n)) + 0.5) / int(n)


def _classify_task(task: tuple) -> RunClass:
    """Run one sweep point in a worker process: ``(setup, overrides)`` -> its class."""
    setup, overrides = task
    return setup.run(**overrides)


def _sweep(setup: SweepSetup, points: list[dict], labels: list[str], progress, jobs) -> list:
    """Classify every point (``ControllerConfig`` overrides) in ``jobs`` processes, in order."""
    done = [0]

    def report(i: int, c: RunClass) -> None:
        done[0] += 1
        if progress is not None:
            progress(done[0], len(points), f"{labels[i]}: {c.label}")

    return run_jobs(_classify_task, [(setup, p) for p in points], jobs, report)


def exponential_sweep(
    setup: SweepSetup, w: np.ndarray, v: np.ndarray, progress=None, jobs: int | None = 1
) -> dict:
    """
    Classify every (w, v) of a grid (figure 8.4).

    Parameters
    ----------
    setup : SweepSetup
        Shared run setup.
    w, v : numpy.ndarray
        1-D grids, ``0 < w < 1``, ``0 <= v < 1``.
    progress : callable, optional
        ``progress(done, total, text)`` after each run.
    jobs : int or None
        Parallel processes (:func:`amb_apps.parallel.run_jobs`; None: the cores).

    Returns
    -------
    dict
        ``w``, ``v`` (lists), ``label``, ``peak_radius`` (m), ``steady_1x`` (m),
        ``growth_per_period`` as nested lists indexed ``[iv][iw]``, and ``nominal_stable``
        (figure 8.3 at the grid points).

    """
    w = np.asarray(w, dtype=float)
    v = np.asarray(v, dtype=float)
    out = {k: [[None] * w.size for _ in range(v.size)] for k in
           ("label", "peak_radius", "steady_1x", "growth_per_period")}  # fmt: skip
    grid = [(iv, iw) for iv in range(v.size) for iw in range(w.size)]
    points = [dict(response="exponential", w=float(w[iw]), v=float(v[iv])) for iv, iw in grid]
    labels = [f"w={p['w']:.3f} v={p['v']:.3f}" for p in points]
    for (iv, iw), c in zip(grid, _sweep(setup, points, labels, progress, jobs), strict=True):
        for key in out:
            out[key][iv][iw] = getattr(c, key)
    nominal = exponential_stability_map(w, v, setup.config.delay_periods)
    return {"w": w.tolist(), "v": v.tolist(), **out, "nominal_stable": nominal.tolist()}


def linear_rate_sweep(
    setup: SweepSetup, rates: np.ndarray, progress=None, jobs: int | None = 1
) -> dict:
    """
    Classify the linear prescribed response ``c_k = max(0, 1 - rate k)`` over ``rates``.

    Parameters
    ----------
    setup : SweepSetup
        Shared run setup.
    rates : numpy.ndarray
        Decay rates per period, increasing, in (0, 1).
    progress : callable, optional
        ``progress(done, total, text)`` after each run.
    jobs : int or None
        Parallel processes, as in :func:`exponential_sweep`.

    Returns
    -------
    dict
        ``rate``, ``label``, ``peak_radius``, ``steady_1x``, ``nominal_stable`` (lists),
        ``max_acceptable_rate`` (the largest rate below which every swept rate is acceptable;
        None if the smallest is not) and ``largest_acceptable_rate`` (any).

    """
    rates = np.asarray(rates, dtype=float)
    delay = setup.config.delay_periods
    points = [dict(response="linear", rate=float(r)) for r in rates]
    rows = _sweep(setup, points, [f"linear rate={r:.3f}" for r in rates], progress, jobs)
    labels = [c.label for c in rows]
    ok = [lab == ACCEPTABLE for lab in labels]
    first_bad = ok.index(False) if False in ok else len(ok)
    return {
        "rate": rates.tolist(),
        "label": labels,
        "peak_radius": [c.peak_radius for c in rows],
        "steady_1x": [c.steady_1x for c in rows],
        "nominal_stable": [
            bool(is_nominally_stable(PrescribedResponse.linear_decay(float(r)), delay))
            for r in rates
        ],
        "max_acceptable_rate": float(rates[first_bad - 1]) if first_bad > 0 else None,
        "largest_acceptable_rate": float(max(r for r, g in zip(rates, ok, strict=True) if g))
        if any(ok)
        else None,
    }


def nominal_linear_rate_limit(delay: int, step: float = 1e-3) -> float:
    """
    Return the largest linear rate below which the nominal loop is stable for every rate.

    Scans ``rate = step, 2 step, ...`` (the number of non-zero ``c_k`` changes with the rate,
    so stability is not monotonic in general) with
    :func:`amb_controller.stability.is_nominally_stable`.

    Parameters
    ----------
    delay : int
        Evaluation delay i in periods.
    step : float
        Scan step.

    Returns
    -------
    float
        Rate per period (0 if the first is unstable).

    """
    last = 0.0
    for rate in np.arange(step, 1.0, step):
        if not is_nominally_stable(PrescribedResponse.linear_decay(float(rate)), delay):
            break
        last = float(rate)
    return last


def plot_acceptability(result: dict, path: str | Path) -> Path:
    """
    Draw figure 8.4 (w on x, v on y) with the nominal boundary of figure 8.3 and the rates.

    Parameters
    ----------
    result : dict
        As written by :func:`main` (keys ``exponential``, ``linear``, ``delay``).
    path : str or Path
        PNG to write.

    Returns
    -------
    pathlib.Path

    """
    # heavy, optional: matplotlib, only for the figure
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    exp = result["exponential"]
    w, v = np.asarray(exp["w"]), np.asarray(exp["v"])
    labels = np.asarray(exp["label"], dtype=object)
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.8), gridspec_kw={"width_ratios": [3, 2]})
    style = {
        ACCEPTABLE: {"marker": "o", "color": "tab:green"},
        UNACCEPTABLE: {"marker": "^", "color": "tab:orange"},
        UNSTABLE: {"marker": "x", "color": "tab:red"},
    }
    ww, vv = np.meshgrid(w, v)
    for name, st in style.items():
        sel = labels == name
        ax.scatter(ww[sel], vv[sel], label=name, s=40, **st)
    fw = np.linspace(0.005, 0.995, 300)
    fv = np.linspace(0.0, 0.995, 300)
    nominal = exponential_stability_map(fw, fv, result["delay"])
    ax.contour(fw, fv, nominal.astype(float), levels=[0.5], colors="k", linewidths=1.2)
    ax.plot([], [], "k-", label=f"nominal stability boundary (fig. 8.3, i = {result['delay']})")
    ax.set_xlabel("w (eq. 8.6)")
    ax.set_ylabel("v (eq. 8.6)")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    ax.set_title(
        f"Acceptable performance, {result['speed_hz']:.2f} Hz (first critical), "
        f"limit {LIMIT * 1e3:g} mm"
    )
    ax.legend(loc="lower left", fontsize=8)
    lin = result["linear"]
    rates = np.asarray(lin["rate"])
    peaks = np.asarray(lin["peak_radius"]) * 1e6
    for name, st in style.items():
        sel = np.asarray(lin["label"], dtype=object) == name
        bx.scatter(rates[sel], peaks[sel], s=25, **st)
    bx.axhline(LIMIT * 1e6, color="k", ls="--", lw=1)
    bx.axvline(THESIS_LINEAR_RATE, color="tab:blue", ls=":", lw=1, label="thesis 0.31")
    if lin["max_acceptable_rate"] is not None:
        bx.axvline(lin["max_acceptable_rate"], color="tab:green", lw=1, label="max acceptable")
    bx.axvline(result["nominal_linear_rate_limit"], color="k", lw=1, label="nominal limit")
    bx.set_xlabel("linear decay rate per period")
    bx.set_ylabel("peak plane displacement after fault (um)")
    bx.set_title("Linear prescribed decay")
    bx.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def _summary(exp: dict) -> dict:
    labels = [lab for row in exp["label"] for lab in row]
    return {name: labels.count(name) for name in LABELS}


def main(argv=None) -> int:
    """Command ``amb-acceptability``: sweep, write PNG and JSON, print progress."""
    ap = argparse.ArgumentParser(
        prog="amb-acceptability",
        description="Acceptable performance diagram (thesis figure 8.4) and the maximum "
        "linear decay rate from in-process closed-loop runs (mass loss, first critical).",
    )
    ap.add_argument("--out", required=True, type=Path, help="output folder (created)")
    ap.add_argument("--grid", type=int, default=10, help="points per axis in (0, 1) [10]")
    ap.add_argument("--delay", type=int, default=2, help="evaluation delay i [2]")
    ap.add_argument("--rate-step", type=float, default=0.01, help="linear rate step [0.01]")
    ap.add_argument("--json", action="store_true", help="print the JSON result to stdout")
    add_jobs_argument(ap)
    ap.add_argument("--quiet", action="store_true", help="no progress on stderr")
    args = ap.parse_args(argv)
    try:
        w = v = grid_values(args.grid)
        if not 0.0 < args.rate_step < 0.5:
            raise AcceptabilityValueError(f"--rate-step must lie in (0, 0.5), got {args.rate_step}")
        if not 1 <= args.delay <= 16:
            raise AcceptabilityValueError(f"--delay must lie in 1..16 periods, got {args.delay}")
    except AcceptabilityValueError as exc:
        ap.error(str(exc))
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()

    def progress(done: int, total: int, text: str) -> None:
        if not args.quiet:
            dt = time.perf_counter() - t0
            print(f"[{done}/{total}] {dt:6.1f} s  {text}", file=sys.stderr, flush=True)

    setup = SweepSetup.first_critical(delay=args.delay)
    pid = setup.run(controller="none")
    exp = exponential_sweep(setup, w, v, progress, args.jobs)
    rates = np.round(np.arange(args.rate_step, 1.0 - 1e-9, args.rate_step), 6)
    lin = linear_rate_sweep(setup, rates, progress, args.jobs)
    result = {
        "scenario": setup.scenario.name,
        "speed_hz": float(setup.scenario.speed_hz),
        "delay": int(args.delay),
        "limit": LIMIT,
        "classification": {
            "displacement": "plane orbit radius hypot(x_i, y_i) after the fault, m",
            "unstable": "guard tripped (runaway bound below the auxiliary clearance) or "
            "fitted 1x envelope growth per period >= 1 (second differences of the phasor)",
        },
        "pid_only": asdict(pid),
        "exponential": exp,
        "exponential_counts": _summary(exp),
        "linear": lin,
        "thesis_linear_rate": THESIS_LINEAR_RATE,
        "nominal_linear_rate_limit": nominal_linear_rate_limit(args.delay),
        "wall_time_s": round(time.perf_counter() - t0, 1),
    }
    (args.out / "acceptability.json").write_text(json.dumps(result, indent=1))
    plot_acceptability(result, args.out / "acceptability.png")
    if args.json:
        print(json.dumps(result, indent=1))
    else:
        print(
            f"wrote {args.out / 'acceptability.png'} and acceptability.json: "
            f"{result['exponential_counts']}; max linear rate {lin['max_acceptable_rate']} "
            f"(nominal {result['nominal_linear_rate_limit']:.3f}, thesis {THESIS_LINEAR_RATE})"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
