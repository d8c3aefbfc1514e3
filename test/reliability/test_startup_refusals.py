"""rclpy's own parameter refusals at start-up end every node with exit code 2 and a reason.

A value that violates a node's ``ParameterDescriptor`` (range) or its declared type is refused
by rclpy before the node's own checks run; :func:`amb_tools.node_main.run_node` turns that
exception into the configuration-error exit (2) with one ``[ERROR] configuration`` line naming
the parameter and the value (issue 8: "refuses invalid values with a message naming the
parameter, the value and the allowed range, at start-up (exit code != 0)"). Before, the
traceback ended the process with exit code 1.
"""

from __future__ import annotations

import pytest
from ros_harness import configuration_refusals

CASES = [
    # (node, parameters, words the error line must contain)
    ("wavelet_filterbank", {"levels": 99}, ("levels", "99", "Max: 16")),
    ("wavelet_filterbank", {"samples_per_rev": "abc"}, ("samples_per_rev", "abc", "INTEGER")),
    ("plant_sim", {"samples_per_rev": "abc"}, ("samples_per_rev", "abc", "INTEGER")),
    ("wavelet_controller", {"samples_per_rev": "abc"}, ("samples_per_rev", "abc", "INTEGER")),
    ("plant_sim", {"command_timeout": 1000.0}, ("command_timeout", "1000.0", "600")),
]


@pytest.mark.slow
def test_descriptor_and_type_refusals_exit_2_with_the_parameter_and_value(node_process) -> None:
    """All cases start at once (start-up dominates the wall time), then are checked."""
    cases = [(f"{n} {p}", node_process(n, params=p), w) for n, p, w in CASES]
    failures = configuration_refusals(cases)
    assert not failures, "\n".join(failures)
