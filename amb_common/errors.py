"""
Exceptions of the vocabulary layer.

Subclass :class:`ValueError` so that callers can catch configuration problems with the standard
type; messages state the expected and the actual value and how to recover.
"""


class RigError(ValueError):
    """An invalid or inconsistent rig description (``config/rig.yaml``)."""
