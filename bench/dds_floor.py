"""The floor under the four-node loop: CPU per message and hop latency of rclpy over Fast DDS.

Two measurements with the stream types of the pipeline, each node in its own process, spinning
the executor the nodes use (``AMB_EXECUTOR``, default ``events``):

1. fan-out: one publisher sends ``--count`` ``Measurement`` messages at ``--rate`` Hz (the
   67 Hz x 32 sample rate by default) to ``--subscribers`` processes whose callbacks do nothing
   (``raw``: CDR bytes handed over; ``typed``: deserialised into the Python message). Printed:
   CPU microseconds per message of the publisher and of each subscriber (``os.times`` over the
   run), messages received.
2. ping-pong: two processes bounce one ``Measurement`` back and forth ``--pings`` times; the
   round trip (median, p99) is twice the one-hop latency, the floor of any chain of nodes.

Nothing of the project's nodes runs here: this is what any Python node pays per message before
it does its own work.

    python bench/dds_floor.py [--rate 2144] [--count 8000] [--subscribers 3] [--pings 2000]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

ROLE_TIMEOUT = 60.0


def _spin_until(executor, node, done, timeout: float = ROLE_TIMEOUT) -> None:
    deadline = time.monotonic() + timeout
    while not done() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)


def _executor():
    from amb_tools.node_main import make_executor

    return make_executor()


def role_publisher(args) -> dict:
    """Publish the fan-out stream at ``--rate``; return its publish cost per message."""
    import rclpy
    from amb_msgs.msg import Measurement
    from rclpy.serialization import serialize_message

    from amb_tools.streams import stream_qos

    rclpy.init()
    node = rclpy.create_node("floor_pub")
    pub = node.create_publisher(Measurement, "/floor/measurement", stream_qos(32))
    ex = _executor()
    ex.add_node(node)
    _spin_until(ex, node, lambda: pub.get_subscription_count() >= args.subscribers)
    time.sleep(1.0)
    msg = Measurement(samples_per_rev=32, rotor_speed=421.0)
    msg.header.frame_id = "amb_rig"
    raw = serialize_message(msg) if args.publish_raw else None
    cpu0, t0 = os.times(), time.monotonic()
    for i in range(args.count):
        wait = t0 + i / args.rate - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        if raw is None:
            msg.sample_index = i
            pub.publish(msg)
        else:
            pub.publish(raw)
    cpu1 = os.times()
    time.sleep(2.0)
    used = cpu1.user + cpu1.system - cpu0.user - cpu0.system
    node.destroy_node()
    rclpy.shutdown()
    return {"role": "publisher", "us_per_msg": used / args.count * 1e6}


def role_subscriber(args) -> dict:
    """Receive the fan-out stream; return this subscriber's receive cost per message."""
    import rclpy
    from amb_msgs.msg import Measurement

    from amb_tools.streams import stream_qos

    rclpy.init()
    node = rclpy.create_node(f"floor_sub_{os.getpid()}")
    got = []
    first = []

    def on_msg(msg) -> None:
        if not first:
            first.append(os.times())
        got.append(1)

    node.create_subscription(
        Measurement, "/floor/measurement", on_msg, stream_qos(32), raw=args.raw
    )
    ex = _executor()
    ex.add_node(node)
    _spin_until(
        ex, node, lambda: len(got) >= args.count, timeout=ROLE_TIMEOUT + args.count / args.rate
    )
    end = os.times()
    n = len(got)
    used = end.user + end.system - first[0].user - first[0].system if first else float("nan")
    node.destroy_node()
    rclpy.shutdown()
    return {"role": "subscriber", "received": n, "us_per_msg": used / max(n, 1) * 1e6}


def role_ping(args) -> dict:
    """One end of the ping-pong (``--role ping`` or ``pong``); ping returns the round trips."""
    import rclpy
    from amb_msgs.msg import Measurement

    from amb_tools.streams import stream_qos

    rclpy.init()
    node = rclpy.create_node(f"floor_{args.role}")
    ping = args.role == "ping"
    out_topic, in_topic = ("/floor/ping", "/floor/pong") if ping else ("/floor/pong", "/floor/ping")
    pub = node.create_publisher(Measurement, out_topic, stream_qos(32))
    rtt = []
    sent = [0.0]
    msg = Measurement(samples_per_rev=32, rotor_speed=421.0)

    def on_msg(m) -> None:
        if ping:
            rtt.append(time.monotonic() - sent[0])
            if len(rtt) < args.pings:
                sent[0] = time.monotonic()
                pub.publish(msg)
        else:
            pub.publish(m)

    sub = node.create_subscription(Measurement, in_topic, on_msg, stream_qos(32))
    ex = _executor()
    ex.add_node(node)
    _spin_until(
        ex, node, lambda: pub.get_subscription_count() >= 1 and sub.get_publisher_count() >= 1
    )
    if not ping:
        _spin_until(ex, node, lambda: False, timeout=args.pings * 0.01 + 20.0)
        node.destroy_node()
        rclpy.shutdown()
        return {"role": "pong"}
    time.sleep(0.5)
    sent[0] = time.monotonic()
    pub.publish(msg)
    _spin_until(ex, node, lambda: len(rtt) >= args.pings)
    r = np.asarray(rtt[len(rtt) // 10 :]) * 1e3  # the first tenth is warm-up
    node.destroy_node()
    rclpy.shutdown()
    return {
        "role": "ping",
        "n": int(r.size),
        "rtt_p50_ms": float(np.median(r)),
        "rtt_p99_ms": float(np.quantile(r, 0.99)),
    }


def _spawn(args, role: str, extra: list[str] = ()) -> subprocess.Popen:
    cmd = [sys.executable, __file__, "--role", role, "--rate", str(args.rate),
           "--count", str(args.count), "--subscribers", str(args.subscribers),
           "--pings", str(args.pings), *extra]  # fmt: skip
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)


def _result(p: subprocess.Popen) -> dict:
    out, _ = p.communicate(timeout=ROLE_TIMEOUT * 4)
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    """Run the fan-out and the ping-pong in subprocesses and print their costs."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rate", type=float, default=2144.0, help="Hz, fan-out publish rate")
    ap.add_argument("--count", type=int, default=8000, help="fan-out messages")
    ap.add_argument("--subscribers", type=int, default=3, help="fan-out subscriber processes")
    ap.add_argument("--pings", type=int, default=2000, help="ping-pong round trips")
    ap.add_argument("--role", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--raw", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--publish-raw", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.role is not None:
        fn = {"publisher": role_publisher, "subscriber": role_subscriber}.get(args.role, role_ping)
        print(json.dumps(fn(args)), flush=True)
        return
    print(f"executor {os.environ.get('AMB_EXECUTOR', 'events')}, {args.count} Measurement "
          f"messages at {args.rate:g} Hz to {args.subscribers} subscribers")  # fmt: skip
    for sub_kind, pub_raw in (("typed", False), ("raw", True)):
        subs = [_spawn(args, "subscriber", ["--raw"] if sub_kind == "raw" else [])
                for _ in range(args.subscribers)]  # fmt: skip
        pub = _spawn(args, "publisher", ["--publish-raw"] if pub_raw else [])
        p = _result(pub)
        s = [_result(x) for x in subs]
        print(
            f"  publish {'bytes' if pub_raw else 'message'}: {p['us_per_msg']:6.1f} us/msg; "
            f"subscribers ({sub_kind}): "
            + ", ".join(f"{r['us_per_msg']:.1f} us/msg ({r['received']} received)" for r in s)
        )
    pong = _spawn(args, "pong")
    ping = _spawn(args, "ping")
    r = _result(ping)
    pong.wait(timeout=ROLE_TIMEOUT * 4)
    print(f"  ping-pong Measurement round trip: p50 {r['rtt_p50_ms']:.3f} ms, "
          f"p99 {r['rtt_p99_ms']:.3f} ms over {r['n']} (one hop ~ half)")  # fmt: skip


if __name__ == "__main__":
    main()
