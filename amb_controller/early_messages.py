"""What the early action (:mod:`amb_controller.early_action`) tells the operator, as text.

ROS-free: the ``wavelet_controller`` node logs these lines; ``amb-sim`` could print them.
"""

from __future__ import annotations

import math

from amb_controller.early_action import Detection
from amb_controller.early_stage import EarlyStage

__all__ = ["decision_message", "model_change_message"]


def model_change_message(stage: EarlyStage, omega: float) -> tuple[bool, str]:
    """
    The line for a change of the model in use (a bank holds one per speed).

    Parameters
    ----------
    stage : EarlyStage
        After the change.
    omega : float
        The measured speed, rad/s.

    Returns
    -------
    ok : bool
        False if no model is near the speed (the action tests nothing: a warning).
    text : str
    """
    hz = omega / (2 * math.pi)
    now = stage.model_omega
    if now is None:
        tol = stage.config.speed_tolerance
        return False, f"early action: no model within {tol:.1%} of the measured {hz:.3f} Hz: " + (
            "testing nothing"
        )
    if now == 0.0:
        return True, "early action: one model, its speed not recorded: used at every speed"
    text = f"early action: model of {now / (2 * math.pi):.3f} Hz (measured {hz:.3f} Hz)"
    limit = stage.early.step_limit
    if math.isfinite(limit):  # (E4) of amb_controller.early_action
        text += f", its plans stepping at most {limit:.0f} N per sample (amplifier slew)"
    else:
        text += ", its plans not slew-bounded (no slew rate in the model file)"
    return True, text


def decision_message(d: Detection, active: bool) -> str:
    """The line for a decision: what was found and what the action does (``active``: ACTIVE)."""
    if not d.acted:
        what = (
            f"left to the feedback law (predicted {d.predicted_peak * 1e6:.0f} um, "
            f"{d.clearance_share:.2f} x what the clearances allow with the model's error: too "
            "near them for the linear model)"
        )
    elif active:
        what = (
            f"cancelling it from period {d.first_period} (largest step {d.largest_step:.0f} N "
            f"per sample, smoothing {d.smoothing:g})"
        )
    else:
        what = "the controller is not active: no force"
    return (
        f"early action: sudden unbalance {d.me * 1e5:.0f} g cm at {d.plane}, onset sample "
        f"{d.onset_sample} (period {d.period}), {what}"
    )
