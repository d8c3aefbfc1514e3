"""
Calibrate the rig layout so the PID closed loop has the thesis's first four modes.

The thesis gives no drawing of the axial positions; the shared layout is a fitted proposal.
This script moves the four disks, the two AMBs (with their cores and auxiliary bearings) and
the two inner sensor planes by at most ``--max-shift`` (default 60 mm) from the proposal,
keeping the thesis's arrangement (disk outboard of each AMB, the inner sensor next to its AMB
on the inner side, two disks inboard), and chooses the disk and core masses between the
stated values (10 kg, 5 kg; section 2.2.4) and the geometric values of Table 2.1
(12.95 kg, 8.25 kg) and the shaft's non-structural mass between 0 and
``--max-nonstructural-mass`` (default 0; the text's 50 kg shaft less the Table 2.1 section's
30.8 kg allows 19.17 kg), so that the zero-speed natural frequencies of the full model
with the real PID (inner sensors, integral, filtered derivative) approach 11, 18, 29 and
67 Hz (sections 5.2, 8.5: the critical speeds used in the experiments).

Run ``python -m amb_plant_sim.calibrate [--rig config/rig.yaml] [--write]``; with ``--write``
the positions, masses and a ``calibration`` record (targets, achieved, residual) are written
back into the rig file. The fit is a bounded least-squares problem on the relative frequency
errors plus a small pull towards the proposal (weight ``--regularisation``) that makes the
under-determined problem (11 parameters, 4 targets) well posed.

``--critical-speeds 11,18,29`` fits the first critical speeds (the crossings of the Campbell
diagram with the synchronous line, :func:`amb_plant_sim.modal.critical_speeds`) as well: the
experiments run at the rig's critical speeds, which the gyroscopic effect puts above the
zero-speed frequencies (the third by about 2.5 %). About 4 times the cost per trial.

The global stage is a differential evolution from ``--seed``. It does not converge to one
optimum: a minimax fit's worst error depends on the seed (``docs/history.md``, "One seed is not
the closest fit"), so run several and keep the best.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import scipy.optimize

from amb_common.rig import DEFAULT_RIG_PATH, Rig, load_rig
from amb_plant_sim.closed_loop import build_closed_loop
from amb_plant_sim.modal import critical_speeds, distinct_modes, is_stable, modes_from_matrix

TARGETS_HZ = (11.0, 18.0, 29.0, 67.0)
#: Fixed-point settings of the critical speeds during a fit: the gyroscopic shift is small, so
#: a few iterations to 1 mHz suffice (the final record is computed to the default tolerance).
FIT_CRITICAL_TOL_HZ = 1e-3
FIT_CRITICAL_ITERATIONS = 4
# Stated masses (section 2.2.4) as the lower bounds of the mass search.
STATED_DISK_MASS = 10.0
STATED_CORE_MASS = 5.0
# The shaft "weighing 50kg" (section 2.2.4): the upper bound of the shaft's geometric mass plus
# its non-structural mass (the Table 2.1 section gives 30.8 kg).
STATED_SHAFT_MASS = 50.0
# Original proposal of /work/shared/rig/bath_rig.yaml, in thesis order (non-driven end first).
PROPOSAL = {
    "disks": (1.94, 1.28, 0.72, 0.06),
    "bearings": (1.38, 0.62),
    "inner_planes": (1.32, 0.68),
}
MIN_GAP = 0.04  # m: minimum distance between an AMB centre and its sensor or a disk centre


def parameters_of(rig: Rig) -> np.ndarray:
    """Parameter vector: 4 disk z, 2 bearing z, 2 inner planes z (m), 3 masses (kg).

    The masses: disk, core, and the shaft's non-structural mass.
    """
    inner = [rig.sensor_planes[b.sensor_plane - 1].z for b in rig.bearings]
    return np.array(
        [d.z for d in rig.disks]
        + [b.z for b in rig.bearings]
        + inner
        + [rig.disks[0].mass, rig.amb_cores[0].mass, rig.shaft.nonstructural_mass]
    )


def apply_parameters(rig: Rig, p: np.ndarray) -> Rig:
    """Copy of ``rig`` with the layout and masses of parameter vector ``p``."""
    z_disk, z_brg, z_in = p[0:4], p[4:6], p[6:8]
    m_disk, m_core = float(p[8]), float(p[9])
    shaft = replace(rig.shaft, nonstructural_mass=float(p[10]))
    disks = tuple(
        replace(d, z=float(z), mass=m_disk) for d, z in zip(rig.disks, z_disk, strict=True)
    )
    cores = tuple(
        replace(c, z=float(z), mass=m_core) for c, z in zip(rig.amb_cores, z_brg, strict=True)
    )
    bearings = tuple(replace(b, z=float(z)) for b, z in zip(rig.bearings, z_brg, strict=True))
    planes = list(rig.sensor_planes)
    for b, z in zip(rig.bearings, z_in, strict=True):
        planes[b.sensor_plane - 1] = replace(planes[b.sensor_plane - 1], z=float(z))
    brg_old = [b.z for b in rig.bearings]
    clearance = tuple(
        replace(c, z=float(z_brg[brg_old.index(c.z)])) if c.z in brg_old else c
        for c in rig.clearance_bearings
    )
    return replace(
        rig,
        shaft=shaft,
        disks=disks,
        amb_cores=cores,
        bearings=bearings,
        sensor_planes=tuple(planes),
        clearance_bearings=clearance,
    )


def _arrangement_violation(p: np.ndarray) -> np.ndarray:
    """Non-negative violations of the ordering constraints, m (zero when the order is kept)."""
    d1, d2, d3, d4, b1, b2, s2, s3 = p[:8]
    # along z (drive end = 0): D4 < B2 < S3 < D3 < D2 < S2 < B1 < D1
    chain = [d4, b2, s3, d3, d2, s2, b1, d1]
    gaps = np.diff(chain)
    return np.maximum(0.0, MIN_GAP - gaps)


def frequencies(rig: Rig, count: int = 4) -> tuple[list[float], bool]:
    """First ``count`` distinct zero-speed closed-loop frequencies (Hz) and stability."""
    cl = build_closed_loop(rig, 0.0)
    modes = distinct_modes(modes_from_matrix(cl.A, cl.plant.rotor.n_dof))
    return [m.frequency_hz for m in modes[:count]], is_stable(cl.A)


def frequency_errors(
    rig: Rig,
    targets: tuple[float, ...],
    critical_targets: tuple[float, ...] = (),
    fit: bool = False,
) -> tuple[np.ndarray, list[float], bool]:
    """
    Relative errors of the zero-speed frequencies and the critical speeds against targets.

    Parameters
    ----------
    rig : Rig
    targets : tuple of float
        Zero-speed natural frequencies, Hz (the first ``len(targets)`` distinct modes).
    critical_targets : tuple of float
        Critical speeds, Hz (the first ``len(critical_targets)``); none by default.
    fit : bool
        Critical speeds to :data:`FIT_CRITICAL_TOL_HZ` (inside a fit) instead of the default
        tolerance of :func:`~amb_plant_sim.modal.critical_speeds`.

    Returns
    -------
    numpy.ndarray
        ``achieved / target - 1``: the natural frequencies, then the critical speeds.
    list of float
        The achieved values, Hz, in the same order (0 for a mode not found).
    bool
        Whether the closed loop is stable.
    """
    f, stable = frequencies(rig, len(targets))
    f = f + [0.0] * (len(targets) - len(f))
    if critical_targets and stable:
        opts = {"tol_hz": FIT_CRITICAL_TOL_HZ, "max_iter": FIT_CRITICAL_ITERATIONS} if fit else {}
        if len(f) >= len(critical_targets):  # the iterations start at the frequencies found
            opts["start_hz"] = f[: len(critical_targets)]
        f += critical_speeds(rig, len(critical_targets), **opts)
    f = f + [0.0] * (len(targets) + len(critical_targets) - len(f))
    achieved = np.asarray(f)
    return achieved / np.r_[targets, critical_targets] - 1.0, f, stable


def calibrate(
    rig: Rig,
    max_shift: float = 0.06,
    regularisation: float = 0.02,
    max_nonstructural_mass: float = 0.0,
    objective: str = "least_squares",
    targets: tuple[float, ...] = TARGETS_HZ,
    popsize: int = 8,
    maxiter: int = 30,
    seed: int = 0,
    critical_targets: tuple[float, ...] = (),
) -> tuple[Rig, dict]:
    """
    Fit the layout and masses to the target frequencies.

    Parameters
    ----------
    rig : Rig
        Starting rig (its geometry defines the geometric masses; positions are taken from
        :data:`PROPOSAL`).
    max_shift : float
        Largest move of any disk, bearing or sensor plane from the proposal, m.
    regularisation : float
        Weight of the pull towards the proposal (relative to one unit of relative frequency
        error per ``max_shift`` of displacement or full mass range).
    max_nonstructural_mass : float
        Largest non-structural shaft mass the fit may add, kg (0 to the text's 50 kg less the
        section's mass).
    objective : {"least_squares", "minimax"}
        ``least_squares``: the sum of the squared relative errors (and the pull), a global
        stage and a local least-squares polish. ``minimax``: the largest relative error,
        through its smooth stand-in the 8-norm of the errors plus the squared pull, global
        stage only (``popsize`` and ``maxiter`` at least 10 and 60); it trades a smaller
        worst mode for larger others.
    targets : tuple of float
        Target frequencies, Hz.
    popsize, maxiter, seed : int
        Settings of the global (differential evolution) stage; the seed makes it repeatable.
    critical_targets : tuple of float
        Critical speeds to fit as well, Hz (:func:`frequency_errors`); none by default.

    Returns
    -------
    Rig
        The calibrated rig.
    dict
        Record: targets, achieved frequencies (Hz), relative errors, RMS residual, parameters.
    """
    p0 = np.array(
        list(PROPOSAL["disks"])
        + list(PROPOSAL["bearings"])
        + list(PROPOSAL["inner_planes"])
        + [rig.disks[0].geometric_mass, rig.amb_cores[0].geometric_mass, 0.0]
    )
    lo = p0.copy()
    hi = p0.copy()
    lo[:8] -= max_shift
    hi[:8] += max_shift
    lo[:8] = np.maximum(lo[:8], 0.0)
    hi[:8] = np.minimum(hi[:8], rig.shaft.length)
    # an end disk may not leave the shaft with its half width
    lo[3] = max(lo[3], rig.disks[3].width / 2)
    hi[0] = min(hi[0], rig.shaft.length - rig.disks[0].width / 2)
    lo[8], hi[8] = STATED_DISK_MASS, rig.disks[0].geometric_mass
    lo[9], hi[9] = STATED_CORE_MASS, rig.amb_cores[0].geometric_mass
    stated_room = STATED_SHAFT_MASS - rig.shaft.geometric_mass
    if not 0.0 <= max_nonstructural_mass <= stated_room:
        room = math.floor(stated_room * 100) / 100
        raise ValueError(
            f"max_nonstructural_mass {max_nonstructural_mass} kg: expected 0 to {room:.2f}"
            f" kg (the text's {STATED_SHAFT_MASS:g} kg shaft less the section's"
            f" {rig.shaft.geometric_mass:.1f} kg)"
        )
    lo[10], hi[10] = 0.0, max_nonstructural_mass
    scale = np.r_[np.full(8, max_shift), hi[8:] - lo[8:]]
    scale[scale == 0.0] = 1.0
    tgt = np.r_[targets, critical_targets].astype(float)
    free = hi > lo  # a parameter whose bounds meet (no non-structural mass allowed) is fixed

    def full(xf: np.ndarray) -> np.ndarray:
        x = lo.copy()
        x[free] = xf
        return x

    def residual(x: np.ndarray) -> np.ndarray:
        trial = apply_parameters(rig, x)
        try:
            r, _f, stable = frequency_errors(trial, targets, critical_targets, fit=True)
        except ValueError:
            return np.full(len(tgt) + p0.size + 7, 10.0)
        if not stable:
            r = r + 10.0
        pull = regularisation * (x - p0) / scale
        order = 10.0 * _arrangement_violation(x) / max_shift
        return np.r_[r, pull, order]

    def worst(xf: np.ndarray) -> float:
        res = residual(full(xf))
        n = len(tgt)
        return float(np.sum(np.abs(res[:n]) ** 8) ** 0.125 + np.sum(res[n:] ** 2))

    if objective not in ("least_squares", "minimax"):
        raise ValueError(f"objective {objective!r}: expected 'least_squares' or 'minimax'")
    minimax = objective == "minimax"
    # Global stage (the problem has cliffs where the PID loses stability), then a local polish.
    glob = scipy.optimize.differential_evolution(
        worst if minimax else lambda xf: float(np.sum(residual(full(xf)) ** 2)),
        list(zip(lo[free], hi[free], strict=True)),
        popsize=max(popsize, 10) if minimax else popsize,
        maxiter=max(maxiter, 60) if minimax else maxiter,
        tol=1e-10 if minimax else 1e-8,
        seed=seed,
        polish=False,
        init="sobol",
    )
    if minimax:
        x_best = full(glob.x)
    else:
        sol = scipy.optimize.least_squares(
            lambda xf: residual(full(xf)),
            glob.x,
            bounds=(lo[free], hi[free]),
            x_scale=scale[free],
            diff_step=1e-3,
            max_nfev=200,
        )
        x_best = full(sol.x)
    best = np.round(x_best, 4)
    best[8:] = np.round(x_best[8:], 3)
    best = np.clip(best, lo, hi)
    out = apply_parameters(rig, best)
    rel, f, stable = frequency_errors(out, targets, critical_targets)
    n = len(targets)
    record = {
        "targets_hz": [float(t) for t in targets],
        "achieved_hz": [round(float(v), 3) for v in f[:n]],
        "relative_error": [round(float(v), 4) for v in rel[:n]],
    }
    if critical_targets:
        record |= {
            "critical_targets_hz": [float(t) for t in critical_targets],
            "critical_achieved_hz": [round(float(v), 3) for v in f[n:]],
            "critical_relative_error": [round(float(v), 4) for v in rel[n:]],
        }
    record |= {
        "rms_relative_error": round(float(math.sqrt(np.mean(rel**2))), 4),
        "max_relative_error": round(float(np.max(np.abs(rel))), 4),
        "stable": bool(stable),
        "max_shift_m": max_shift,
        "max_nonstructural_mass_kg": max_nonstructural_mass,
        "objective": objective,
        "regularisation": regularisation,
        "seed": seed,
        "disk_mass_kg": float(best[8]),
        "core_mass_kg": float(best[9]),
        "shaft_nonstructural_mass_kg": float(best[10]),
        "largest_move_m": round(float(np.max(np.abs(best[:8] - p0[:8]))), 4),
    }
    return out, record


def _number(value: float) -> str:
    """YAML float text: 6 significant digits, always with a point or an exponent."""
    txt = f"{value:.6g}"
    return txt + ".0" if "." not in txt and "e" not in txt else txt


def _set_on_tag_line(text: str, tag: str, key: str, value: float) -> str:
    pat = re.compile(
        r"^(\s*- \{tag: " + re.escape(tag) + r",.*?\b" + key + r": )([-0-9.eE+]+)", re.M
    )
    txt = _number(value)
    new, n = pat.subn(lambda m: m.group(1) + txt, text)
    if n != 1:
        raise ValueError(f"rig file: expected one line with tag {tag} and key {key}, found {n}")
    return new


def write_calibration(path: Path, rig: Rig, record: dict) -> None:
    """Write the calibrated positions, masses and the record into the rig file ``path``."""
    text = path.read_text(encoding="utf-8")
    for body in rig.disks + rig.amb_cores:
        text = _set_on_tag_line(text, body.tag, "z", body.z)
        text = _set_on_tag_line(text, body.tag, "mass", body.mass)
    for b in rig.bearings:
        text = _set_on_tag_line(text, b.tag, "z", b.z)
    for s in rig.sensor_planes:
        text = _set_on_tag_line(text, s.tag, "z", s.z)
    for c in rig.clearance_bearings:
        text = _set_on_tag_line(text, c.tag, "z", c.z)
    pat = re.compile(r"^(  nonstructural_mass: )([-0-9.eE+]+)", re.M)
    text, n = pat.subn(lambda m: m.group(1) + _number(rig.shaft.nonstructural_mass), text)
    if n != 1:
        raise ValueError(f"rig file: expected one shaft line 'nonstructural_mass:', found {n}")
    head = (
        "# Output of `python -m amb_plant_sim.calibrate --write` (do not edit by hand): zero-speed"
    )
    text = text.split("\ncalibration:")[0].split("\n" + head)[0].rstrip("\n") + "\n"
    lines = [
        "",
        head,
        "# natural frequencies of the full model (14 elements, real PID on the inner sensors,",
        "# integral, filtered derivative) against the thesis's 11, 18, 29, 67 Hz.",
        "calibration:",
    ]
    for k, v in record.items():
        lines.append(f"  {k}: {json.dumps(v)}")
    path.write_text(text + "\n".join(lines) + "\n", encoding="utf-8")


def _hz_list(text: str) -> tuple[float, ...]:
    """Frequencies given as ``11,18,29`` (Hz), each positive; a clear error otherwise."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected frequencies in Hz, comma separated (11,18,29)"
        ) from None
    if not all(v > 0 for v in values):
        raise argparse.ArgumentTypeError(f"{text!r}: every frequency must be > 0 Hz")
    return values


def main(argv: list[str] | None = None) -> int:
    """Command line: fit, print the record as JSON, optionally write it into the rig file."""
    ap = argparse.ArgumentParser(prog="python -m amb_plant_sim.calibrate", description=__doc__)
    ap.add_argument("--rig", type=Path, default=DEFAULT_RIG_PATH, help="rig YAML file")
    ap.add_argument("--max-shift", type=float, default=0.06, help="largest move, m")
    ap.add_argument(
        "--max-nonstructural-mass",
        type=float,
        default=0.0,
        help="largest non-structural shaft mass, kg (the text's 50 kg shaft allows 19.17)",
    )
    ap.add_argument(
        "--targets",
        type=_hz_list,
        default=TARGETS_HZ,
        help="zero-speed target frequencies, Hz, comma separated (default 11,18,29,67)",
    )
    ap.add_argument(
        "--objective",
        choices=("least_squares", "minimax"),
        default="least_squares",
        help="sum of squared relative errors, or the largest one",
    )
    ap.add_argument("--regularisation", type=float, default=0.02)
    ap.add_argument(
        "--critical-speeds",
        type=_hz_list,
        default=(),
        help="also fit these critical speeds, Hz, comma separated (the thesis's: 11,18,29)",
    )
    ap.add_argument(
        "--seed",
        type=int,
        default=0,
        help="seed of the global stage (a minimax fit's result depends on it: try several)",
    )
    ap.add_argument("--write", action="store_true", help="write the result into the rig file")
    args = ap.parse_args(argv)
    rig = load_rig(args.rig)
    out, record = calibrate(
        rig,
        args.max_shift,
        args.regularisation,
        args.max_nonstructural_mass,
        args.objective,
        args.targets,
        seed=args.seed,
        critical_targets=args.critical_speeds,
    )
    layout = {
        "disks_z": [d.z for d in out.disks],
        "bearings_z": [b.z for b in out.bearings],
        "sensor_planes_z": [s.z for s in out.sensor_planes],
    }
    print(json.dumps({"calibration": record, "layout": layout}, indent=2))
    if args.write:
        write_calibration(args.rig, out, record)
    return 0


if __name__ == "__main__":
    sys.exit(main())
