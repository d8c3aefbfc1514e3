"""
Exceptions of the plant core.

All subclass :class:`ValueError` so that callers can catch configuration problems with the
standard type; messages state the expected and the actual value and how to recover.
"""


class RigError(ValueError):
    """An invalid or inconsistent rig description (``config/rig.yaml``)."""


class ScenarioError(ValueError):
    """An invalid scenario file or event."""


class SimulationError(ValueError):
    """An invalid call to the simulator (wrong shapes, wrong state)."""
