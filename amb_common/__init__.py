"""
amb_common: the vocabulary every part shares (the bottom layer; imports no other project package).

Modules: ``names`` (sensor and axis names and orders), ``topics`` (topic names), ``paths``
(the package's config files), ``rig`` (``config/rig.yaml`` loaded into dataclasses), ``errors``
(:class:`~amb_common.errors.RigError`), ``faults`` (fault kinds and the fault event record),
``config_fields`` (configuration dataclass fields that carry their description, range and
run-time flag, from which the nodes declare their ROS parameters).
"""
