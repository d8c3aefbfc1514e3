"""
Exceptions of the plant core.

All subclass :class:`ValueError` so that callers can catch configuration problems with the
standard type; messages state the expected and the actual value and how to recover. The rig's
:class:`~amb_common.errors.RigError` lives with the rig loader in ``amb_common``.
"""


class ScenarioError(ValueError):
    """An invalid scenario file or event."""


class SimulationError(ValueError):
    """An invalid call to the simulator (wrong shapes, wrong state)."""


class BoundExceededError(SimulationError):
    """
    No added force keeps a constrained output within its bound.

    The output leaves it before any force can act, or no force within the force limits can hold
    it: a physical verdict on the case, not a failure (``amb-bound`` and ``amb-compare`` report
    it in place of the limit).
    """
