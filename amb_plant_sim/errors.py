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
    """A constrained output leaves its bound before any added force can act on it."""
