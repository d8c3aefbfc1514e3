"""How long after a new reader has matched its writer the writer sends to it.

A reader's move to a participant of its own (:class:`amb_tools.reader_participant.DeafReaders`)
may switch over only once the writers send to the new readers. The reader's publisher count
shows its own side of the match; the writer's side (the writer has matched the reader in turn
and sends to it) shows only as a first message in the new reader's queue
(:meth:`amb_tools.reader_participant.MovableReader.ready`). This measures both, from the moment
the new reader is made, for ``--trials`` moves of a reader fed by a writer process publishing
``std_msgs/String`` every ``--period`` s: each trial makes a new participant (as a move does),
subscribes there, spins until the new reader holds a message, and closes the participant.

Printed: per trial the reader-side match and the first message (ms after the subscription),
then the median and maximum of their difference, and how many trials had it longer than one
publish period (a switch made at the reader-side match would have lost messages there, unless
the writer's history covers the lag).

    python bench/reader_match_lag.py [--trials 20] [--period 0.002]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time

TOPIC = "/amb_bench/match_lag"

WRITER = """
import sys, time
from amb_tools.transport_profile import use_project_profile
use_project_profile()
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("amb_bench_match_lag_writer")
pub = node.create_publisher(
    String, "{topic}", QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
)
k = 0
while True:
    pub.publish(String(data=str(k)))
    k += 1
    time.sleep({period})
"""


def main() -> int:
    """Measure ``--trials`` moves and print the lags; 1 if the stream or every match failed."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=20, help="moves measured")
    parser.add_argument("--period", type=float, default=0.002, help="s between publishes")
    args = parser.parse_args()
    if args.trials < 1 or args.period <= 0:
        parser.error("--trials must be >= 1 and --period > 0")

    from amb_tools.transport_profile import use_project_profile

    use_project_profile()
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile
    from std_msgs.msg import String

    from amb_tools.reader_participant import MovableSubscription, ReaderParticipant, has_queued

    rclpy.init()
    node = rclpy.create_node("amb_bench_match_lag_reader")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    got: list[int] = []
    reader = MovableSubscription(
        node, String, TOPIC, lambda msg: got.append(int(msg.data)), QoSProfile(depth=100)
    )
    writer = subprocess.Popen(
        [sys.executable, "-c", WRITER.format(topic=TOPIC, period=args.period)],
        env=dict(os.environ),
    )
    lags: list[float] = []
    try:
        deadline = time.monotonic() + 60.0
        while len(got) < 50 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.01)
        if len(got) < 50:
            print("the writer's stream did not arrive in 60 s", file=sys.stderr)
            return 1
        print(f"writer every {args.period * 1e3:.1f} ms; ms after the new subscription:")
        for trial in range(args.trials):
            participant = ReaderParticipant(node)
            successor = reader.subscribe_on(participant.node)
            t0 = time.monotonic()
            matched = first = None
            while time.monotonic() - t0 < 10.0 and first is None:
                executor.spin_once(timeout_sec=0.0005)
                now = time.monotonic()
                if matched is None and successor.get_publisher_count() > 0:
                    matched = now
                if has_queued(successor, participant.node.context):
                    first = now
            reader.cancel()
            participant.close()
            if matched is None or first is None:
                print(f"trial {trial}: no match in 10 s")
                continue
            lags.append(first - matched)
            print(
                f"trial {trial:2d}: reader-side match {1e3 * (matched - t0):7.1f}, "
                f"first message {1e3 * (first - t0):7.1f}, lag {1e3 * (first - matched):6.1f}"
            )
    finally:
        writer.kill()
        writer.wait()
        node.destroy_node()
        rclpy.try_shutdown()
    if not lags:
        return 1
    longer = sum(lag > args.period for lag in lags)
    print(
        f"lag over {len(lags)} trials: median {1e3 * statistics.median(lags):.1f} ms, "
        f"max {1e3 * max(lags):.1f} ms; longer than one publish period in {longer}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
