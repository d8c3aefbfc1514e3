"""
Multi-level transient control with one model and one prescribed response per level.

Issue 9 (beyond the thesis): levels 1 x, 2 x and 4 x running speed (thesis levels p = 1, 2,
3; ``x_{p,q}`` has ``2^(p-1)`` translations per revolution) controlled at once, each by its
own eq.-8.10 controller::

    U_p(z) = -z^-i (G_pp B_u,p)^*(z) beta_p(z) Q_p(z),
    beta_p(z) = 1 / (alpha_p(z)(z - 1)) - 1                       (eq. 8.10 per level p)

``Q_p`` are the measured coefficients of level p only, ``(G_pp B_u,p)^*`` the truncated
inverse (eq. 6.35) of the level's OWN model (the diagonal block ``G_pp`` of the wavelet-domain
plant: level-p control coefficients to level-p measured coefficients, identified or derived
from the FE model with that level alone) and ``alpha_p`` the level's prescribed response
(eq. 8.6). The per-level commands are written into one control vector (basis order of
:func:`amb_controller.basis.control_basis`); the synthesised force is the sum of the levels'
forces, since the force is linear in the coefficients (eq. 6.7), and the one
:class:`~amb_controller.synthesis.ForceLimiter` of the pipeline limits that sum: the forces
are summed BEFORE the limiter.

What is neglected (decision)
----------------------------
The off-diagonal blocks ``G_pr`` (p != r): a level-r force seen in the level-p coefficients.
For a linear time-invariant rotor at constant speed a 1 x sinusoid has no 2 x or 4 x
content, but the Haar square waves of the control basis do, and the Haar analysis of a
sinusoid leaks into the finer levels; the coupled controller
(:class:`~amb_controller.transient.TransientController` on the full model, all levels in
one pseudo-inverse) accounts for these terms. The block-diagonal version trades them for
(a) one small inverse per level, identifiable level by level with the controller of the
other levels running, and (b) a per-level ``alpha_p``. Whether the neglected coupling
matters is measured, not assumed: ``amb-compare --multilevel`` runs both versions
(``wavelet_124_coupled``, ``wavelet_124_perlevel``) beside ``wavelet_i1`` (1 x only) on the
two mass-loss scenarios; the current numbers are in docs/results.md#compare, the first
run's with its reading in ``docs/controller_notes.md`` ("Multi-level").

A level whose harmonic lies near a critical speed of the rig (docs/results.md#modal; e.g. 2 x
of the second critical speed beside the third) has a nearly singular ``G_pp(1)``, and its
loop may diverge. The pipeline checks the closed loop on the coupled model before the
controller may go ACTIVE (:func:`~amb_controller.stability.own_model_radius`; at the first
critical speed, 32 samples/rev, i = 1, the per-level 1 x + 2 x + 4 x controller's radius there is
1.001, so it stays OFF unless ``max_model_radius`` is raised).

The state is explicit (one :class:`~amb_controller.transient.TransientState` per level) so
that the supervisor's anti-windup hold and the pipeline's reset act on all levels at once.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from amb_controller.errors import ControllerValueError, ShapeError
from amb_controller.inverse import pseudo_inverse_series
from amb_controller.lti import DiscreteStateSpace, block_diagonal, series, static_gain
from amb_controller.model_file import WaveletModel
from amb_controller.response import PrescribedResponse
from amb_controller.transient import ControlStep, TransientController

__all__ = [
    "LevelResponse",
    "MultiLevelController",
    "block_diagonal_model",
    "level_indices",
]


@dataclass(frozen=True)
class LevelResponse:
    """
    Exponential prescribed response ``alpha_p = w / (z - v)`` (eq. 8.6) of one level.

    Attributes
    ----------
    level : int
        Thesis level p (1 = 1 x running speed).
    w, v : float
        ``0 < w < 1``, ``0 <= v < 1``.

    """

    level: int
    w: float = 0.75
    v: float = 0.75

    def response(self) -> PrescribedResponse:
        """Return ``alpha_p`` as a :class:`~amb_controller.response.PrescribedResponse`."""
        return PrescribedResponse.exponential(self.w, self.v)


def level_indices(labels, level: int) -> np.ndarray:
    """
    Return the positions of the coefficients of thesis level ``level`` in a basis.

    Parameters
    ----------
    labels : sequence of str
        Basis labels ``p{level}/q{q}/{quadrature}/c{channel}`` (measurement or control).
    level : int
        Thesis level p.

    Returns
    -------
    numpy.ndarray of int
        Increasing positions (empty if the level is absent).

    """
    prefix = f"p{int(level)}/"
    return np.array([i for i, lab in enumerate(labels) if lab.startswith(prefix)], dtype=int)


class MultiLevelController:
    """
    Block-diagonal eq.-8.10 controller: one :class:`TransientController` per level.

    Same interface as :class:`~amb_controller.transient.TransientController` (``step``,
    ``reset``, ``skip``, ``get_state``, ``set_state``, ``delay``, ``n_inputs``,
    ``n_outputs``, ``state_space``), so that
    :class:`~amb_controller.supervisor.WaveletControlSupervisor` runs it unchanged.

    Parameters
    ----------
    inverses : dict of int to numpy.ndarray
        Level p -> ``B_p^(0) .. B_p^(K)`` of the level's own model, shape
        ``(K+1, n_u,p, n_y,p)`` (:func:`amb_controller.inverse.pseudo_inverse_series`).
    responses : dict of int to PrescribedResponse
        Level p -> ``alpha_p``.
    delay : int
        Evaluation delay i >= 1 (common: one command per period).
    measured_labels, control_labels : sequence of str
        Labels of the full measured and control vectors (the pipeline's bases); the
        level-p entries of each are located by their ``p{level}/`` prefix.

    """

    def __init__(self, inverses: dict, responses: dict, delay: int, measured_labels,
                 control_labels) -> None:  # fmt: skip
        if set(inverses) != set(responses) or not inverses:
            raise ControllerValueError(
                f"one inverse and one prescribed response per level expected, got levels "
                f"{sorted(inverses)} (inverses) and {sorted(responses)} (responses)"
            )
        self.measured_labels = tuple(measured_labels)
        self.control_labels = tuple(control_labels)
        self.n_inputs = len(self.measured_labels)
        self.n_outputs = len(self.control_labels)
        self.levels = tuple(sorted(int(p) for p in inverses))
        self.delay = int(delay)
        self._parts: list[tuple[np.ndarray, np.ndarray, TransientController]] = []
        covered_y: list[int] = []
        covered_u: list[int] = []
        for p in self.levels:
            iy = level_indices(self.measured_labels, p)
            iu = level_indices(self.control_labels, p)
            inv = np.asarray(inverses[p], dtype=float)
            if inv.ndim != 3 or inv.shape[1:] != (iu.size, iy.size) or iy.size == 0:
                raise ShapeError(
                    f"level {p}: inverse of shape {inv.shape} expected (K+1, {iu.size}, "
                    f"{iy.size}) (control x measured coefficients of that level); build it "
                    "from the level's own model (plant_models.level_models)"
                )
            self._parts.append((iy, iu, TransientController(inv, responses[p], delay)))
            covered_y += iy.tolist()
            covered_u += iu.tolist()
        if sorted(covered_u) != list(range(self.n_outputs)):
            raise ControllerValueError(
                f"levels {self.levels} do not cover the {self.n_outputs} control "
                "coefficients: give one inverse per configured level"
            )
        if sorted(covered_y) != list(range(self.n_inputs)):
            raise ControllerValueError(
                f"levels {self.levels} do not cover the {self.n_inputs} measured "
                "coefficients: give one inverse per configured level"
            )

    @classmethod
    def from_models(cls, models: dict, responses: dict, delay: int, measured_labels,
                    control_labels) -> MultiLevelController:  # fmt: skip
        """
        Build from per-level :class:`WaveletModel` (their ``inverse``) and responses.

        Parameters
        ----------
        models : dict of int to WaveletModel
            Level p -> the level's own model (``levels == (p,)``).
        responses : dict of int to PrescribedResponse or LevelResponse
        delay : int
        measured_labels, control_labels : sequence of str

        Returns
        -------
        MultiLevelController

        """
        for p, m in models.items():
            if tuple(m.levels) != (int(p),):
                raise ControllerValueError(
                    f"model given for level {p} covers levels {tuple(m.levels)}: give each "
                    "level its own single-level model (plant_models.level_models)"
                )
        alphas = {
            p: (r.response() if isinstance(r, LevelResponse) else r) for p, r in responses.items()
        }
        return cls({p: m.inverse for p, m in models.items()}, alphas, delay, measured_labels,
                   control_labels)  # fmt: skip

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget all past measurements of every level."""
        for _, _, ctl in self._parts:
            ctl.reset()

    def get_state(self) -> tuple:
        """Return a copy of the explicit state (one TransientState per level)."""
        return tuple(ctl.get_state() for _, _, ctl in self._parts)

    def set_state(self, state: tuple) -> None:
        """Restore a state returned by :meth:`get_state`."""
        if len(state) != len(self._parts):
            raise ControllerValueError(
                f"state of {len(state)} levels given, the controller has {len(self._parts)}"
            )
        for (_, _, ctl), s in zip(self._parts, state, strict=True):
            ctl.set_state(s)

    def skip(self, period_index: int) -> None:
        """Mark ``period_index`` consumed without updating any level (hold / anti-windup)."""
        for _, _, ctl in self._parts:
            ctl.skip(period_index)

    # ------------------------------------------------------------------ step
    def step(self, period_index: int, measured: np.ndarray) -> ControlStep:
        """
        Consume the measured coefficients of period k; return the command for ``k + i``.

        Parameters
        ----------
        period_index : int
            Period k (consecutive; :meth:`reset` after a gap).
        measured : numpy.ndarray
            All measured coefficients of period k, shape ``(n_inputs,)`` (m sqrt(samples)).

        Returns
        -------
        ControlStep
            All levels' control coefficients for period ``k + delay`` (N sqrt(samples)).

        """
        q = np.asarray(measured, dtype=float)
        if q.shape != (self.n_inputs,):
            raise ShapeError(f"measured must have shape ({self.n_inputs},), got {q.shape}")
        u = np.zeros(self.n_outputs)
        for iy, iu, ctl in self._parts:
            u[iu] = ctl.step(period_index, q[iy]).coefficients
        return ControlStep(int(period_index) + self.delay, int(period_index), u)

    def state_space(self) -> DiscreteStateSpace:
        """
        Return the whole controller (delay included) from all measured to all control coefficients.

        The levels' realisations side by side, inputs and outputs permuted to the full
        bases' order (for the exact closed-loop pole check with the coupled plant).
        """
        blocks = block_diagonal([ctl.state_space() for _, _, ctl in self._parts])
        order_y = np.concatenate([iy for iy, _, _ in self._parts])
        order_u = np.concatenate([iu for _, iu, _ in self._parts])
        select = np.zeros((order_y.size, self.n_inputs))
        select[np.arange(order_y.size), order_y] = 1.0
        place = np.zeros((self.n_outputs, order_u.size))
        place[order_u, np.arange(order_u.size)] = 1.0
        return series(series(static_gain(select), blocks), static_gain(place))


def block_diagonal_model(model: WaveletModel, inverse_order: int, regularisation: float = 0.0,
                         rank_rtol: float = 0.0) -> dict[int, WaveletModel]:  # fmt: skip
    """
    Split a coupled multi-level model into per-level models (its diagonal blocks ``G_pp``).

    Parameters
    ----------
    model : WaveletModel
        Model over several levels (labels ``p{level}/...``).
    inverse_order : int
        Truncation order K of each level's inverse (eq. 6.35).
    regularisation : float
        Tikhonov weight of the inverses.
    rank_rtol : float
        Singular-value cutoff of a truncated-SVD inverse for levels p >= 2
        (:func:`~amb_controller.inverse.pseudo_inverse_series`; level 1 always keeps the
        plain least-squares inverse). At p >= 2 the odd Haar waveforms are the even ones
        shifted a quarter revolution and linearly dependent on them, so ``G_22(1)`` has rank
        12 of 16 and ``G_33(1)`` rank 16 of 32 (:mod:`amb_controller.inverse`). Default 0
        (plain inverse): on the coupled FE model the truncated-SVD inverse made the
        per-level loop less stable, not more (``docs/controller_notes.md``, "Truncated-SVD
        inverse at p >= 2").

    Returns
    -------
    dict of int to WaveletModel
        Level p -> model with ``levels == (p,)``, Markov parameters the diagonal block.

    """
    if not model.control_labels or not model.measured_labels:
        raise ControllerValueError(
            "the model has no coefficient labels: cannot locate its levels; rebuild it with "
            "fe_model or an identification of this version"
        )
    out = {}
    for p in model.levels:
        iy = level_indices(model.measured_labels, p)
        iu = level_indices(model.control_labels, p)
        markov = model.markov[:, iy][:, :, iu]
        out[int(p)] = replace(
            model,
            markov=markov,
            inverse=pseudo_inverse_series(
                markov,
                inverse_order,
                regularisation=regularisation,
                rank_rtol=rank_rtol if p > 1 else 0.0,
            ),
            levels=(int(p),),
            control_labels=tuple(model.control_labels[i] for i in iu),
            measured_labels=tuple(model.measured_labels[i] for i in iy),
        )
    return out
