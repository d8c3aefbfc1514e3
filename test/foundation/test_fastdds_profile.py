"""The node set's Fast DDS profile (config/fastdds_profile.xml): set by tools/env.sh, and valid.

Fast DDS reports a profile it cannot parse (``XMLPARSER Error``) and falls back to its
defaults, silently for the nodes: so the profile is loaded here in a fresh process, with a
broken copy as the control that the check sees such an error.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PROFILE = ROOT / "config" / "fastdds_profile.xml"
NODE = (
    "import rclpy\n"
    "from std_msgs.msg import String\n"
    "rclpy.init()\n"
    "node = rclpy.create_node('amb_profile_check')\n"
    "node.create_publisher(String, 'amb_profile_check', 10)\n"
    "rclpy.shutdown()\n"
    "print('participant made')\n"
)


def _participant(profile: Path) -> str:
    env = dict(os.environ, FASTRTPS_DEFAULT_PROFILES_FILE=str(profile))
    out = subprocess.run(
        [sys.executable, "-c", NODE], env=env, capture_output=True, text=True, timeout=60
    )
    assert out.returncode == 0, out.stdout + out.stderr
    return out.stdout + out.stderr


def test_env_sh_points_fast_dds_at_the_profile_unless_one_is_set() -> None:
    script = 'source tools/env.sh && printf "%s" "$FASTRTPS_DEFAULT_PROFILES_FILE"'
    env = {k: v for k, v in os.environ.items() if k != "FASTRTPS_DEFAULT_PROFILES_FILE"}
    out = subprocess.run(["bash", "-c", script], cwd=ROOT, env=env, capture_output=True, text=True)
    assert out.stdout == str(PROFILE), out.stderr
    env["FASTRTPS_DEFAULT_PROFILES_FILE"] = "/elsewhere/mine.xml"
    out = subprocess.run(["bash", "-c", script], cwd=ROOT, env=env, capture_output=True, text=True)
    assert out.stdout == "/elsewhere/mine.xml"


def test_the_profile_parses_and_a_participant_is_made_with_it(tmp_path) -> None:
    text = _participant(PROFILE)
    assert "participant made" in text and "XMLPARSER" not in text, text
    assert "<healthy_check_timeout_ms>60000</healthy_check_timeout_ms>" in PROFILE.read_text()
    broken = tmp_path / "broken.xml"
    broken.write_text(PROFILE.read_text().replace("<type>SHM</type>", "<type>SHMX</type>"))
    assert "XMLPARSER" in _participant(broken)  # the control: a bad profile is reported
