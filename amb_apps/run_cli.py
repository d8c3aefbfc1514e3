"""``amb-run``: the nodes as separate processes over DDS, recorded, until the scenario ends.

What ``launch/amb_system.launch.py`` does on a full ROS 2 install, for environments without
``ros2 launch``: each node executable is started as its own process with
``--ros-args --params-file <params> --params-file OUT/run_params.yaml`` (the run's own
parameters and the ``--set`` overrides, each node's under its fully qualified name:
:func:`amb_apps.system.run_params_document`), the recorder writes ``OUT/bag``, progress
(simulated time, real-time factor) is printed from the plant's ``/diagnostics`` while it runs,
and when ``plant_sim`` exits at the end of its scenario the other nodes are stopped with SIGINT
(the recorder last, once it has written every message published). Logs of every node are in
``OUT/logs``. The exit status is 0 only if every node stopped cleanly.

Ending: when the plant has exited, the filterbank, the controller and the fault monitor are
waited for until they report the plant's last sample as processed, then the recorder until it
reports every published message as written (:mod:`amb_apps.run_end`), each at most
``--drain-timeout`` wall seconds (progress printed each second). A node or recorder still short
then is stopped anyway, named with how far it got, and the exit status is 1: what it had not
processed or written (events, commands, coefficients) is missing from the bag.

Stopping early: Ctrl-C (SIGINT), SIGTERM and SIGHUP stop the nodes at once (the recorder last,
so the bag is closed with what was recorded) and exit with 128 + the signal's number. An
``amb-run`` killed outright (SIGKILL) takes its nodes with it: each gets SIGINT from the kernel
when ``amb-run`` is gone (:mod:`amb_apps.lifetime`), where they used to run on through their
scenario on the run's ROS domain.

Namespace: ``--namespace /rig1`` starts every node in ``/rig1`` (``-r __ns:=/rig1``), so that
the system's topics are ``/rig1/amb/...`` and a second run in another namespace, on the same
machine and ROS domain, does not cross-talk with this one; the bag then holds
``/rig1/amb/...`` (``amb-report`` finds the namespace in it). ``/diagnostics`` is shared: the
nodes name their reports with their namespace (``rig1/plant_sim``), and the progress and the
drain read only this run's.

Scheduling: the recorder, off the control loop, runs in its own process with a higher nice
value (:data:`NICENESS`, ``--nice NODE=N`` to change, e.g. ``--nice fault_monitor=5`` as well:
it then lags, and the end of the run waits for it to drain; with ``--composed`` the recorder is
in ``wavelet_stack`` and a thread of it writes the bag), so that when the CPU is short the
plant, filterbank and controller, whose chain sets the lock-step pace and the command latency,
are served first; the others catch up from their queues (reliable, thousands of messages
deep). ``bench/pipeline.py`` measures that pace and latency. On a computer shared with other
work, ``--rt-priority PROCESS=P`` starts a process (``plant_sim``, ``wavelet_stack``, a node)
under the kernel's real-time ``SCHED_FIFO`` policy at priority P (1-99), as a rig's control
loop is run (ros2_control's controller manager does the same for its thread): it and every
thread it makes (its DDS transport's too) then run before any ordinary process whenever they are
ready, so that a CPU-bound job beside them takes only the time they leave. It needs the right
to (root, ``CAP_SYS_NICE``, or an ``rtprio`` limit of at least P in
``/etc/security/limits.conf``); amb-run checks it before it starts anything and refuses with the
reason. The nodes log the policy they run under.

Transport: the recorder runs off shared memory (``amb_apps.system.OFF_SHARED_MEMORY``): its
DDS participant is on UDPv4 only, on 127.0.0.1 with the localhost discovery range. On shared
memory a reader's listener, descheduled while it holds its port's mutex, holds every writer
that pushes to that port, and the niced recorder is the reader most often descheduled
(``amb_tools.transport_profile``). ``--udp PROCESS`` takes another process off shared memory,
``--shm recorder`` puts the recorder back on it.

Examples
--------
::

    amb-run --scenario config/scenarios/mass_loss_first_critical.yaml --out out/run1
    amb-run --scenario mass_loss_first_critical.yaml --controller none --out out/pid_only
    amb-run --scenario ... --set wavelet_controller.w:=0.65 --set wavelet_filterbank.wavelet:=db4
    amb-run --scenario mass_loss_first_critical.yaml --namespace /rig1 --out out/rig1
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import time
from pathlib import Path

import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import SingleThreadedExecutor

from amb_apps.lifetime import RunStopped, StopSignals
from amb_apps.run_end import DRAIN_TIMEOUT, drain, plant_samples, settle_recording
from amb_apps.run_processes import (
    NICENESS,
    NodeRun,
    available,
    executable,
    per_process,
    rt_priorities,
    transports,
)
from amb_apps.system import (
    COMPOSED,
    NODES,
    OFF_SHARED_MEMORY,
    PUBLISHERS,
    STACK,
    run_parameters,
    run_params_document,
    stream_readers,
)
from amb_common import topics
from amb_common.paths import config_file, scenario_file
from amb_plant_sim.errors import ScenarioError
from amb_tools.streams import MATCHED_KEY

#: Wall s the plant's simulated time may stand still before ``amb-run`` aborts the run: longer
#: than any wait of a healthy run (a lock-step writer held by a reader that died without leaving
#: waits for the reader's lease, 20 s by Fast DDS's default; a command timeout per period).
STALL_TIMEOUT = 120.0


def build_parser() -> argparse.ArgumentParser:
    """Command-line interface."""
    p = argparse.ArgumentParser(prog="amb-run", description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--scenario", required=True, help="scenario YAML (path or name in config/scenarios)"
    )
    p.add_argument(
        "--out", required=True, type=Path, help="output folder (bag, logs); must not exist"
    )
    p.add_argument(
        "--params", type=Path, default=None, help="ROS params file (default config/amb_params.yaml)"
    )
    p.add_argument(
        "--controller",
        default=None,
        help="wavelet_controller.controller (none | proportional | moderated | transient | "
        "predictive)",
    )
    p.add_argument(
        "--without",
        action="append",
        default=[],
        choices=["fault_monitor", "wavelet_controller"],
        help="do not start this node (plant then runs without commands: use --set "
        "plant_sim.mode:=realtime)",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NODE.PARAM:=VALUE",
        help="parameter override for one node (repeatable)",
    )
    p.add_argument(
        "--composed",
        action="store_true",
        help="run the filterbank, fault monitor, controller and recorder in one process "
        "(wavelet_stack: the streams handed over in process, not over DDS)",
    )
    p.add_argument(
        "--apart",
        action="append",
        default=[],
        choices=["fault_monitor", "wavelet_controller", "recorder"],
        help="with --composed: run this node in its own process (repeatable; e.g. the fault "
        "monitor apart leaves the stack's core to the control path)",
    )
    p.add_argument(
        "--namespace",
        default=topics.ROOT_NAMESPACE,
        help="namespace of every node (e.g. /rig1: topics /rig1/amb/...; default /)",
    )
    p.add_argument(
        "--nice",
        action="append",
        default=[],
        metavar="NODE=N",
        help=f"niceness added to a node's process (repeatable; default {NICENESS})",
    )
    p.add_argument(
        "--rt-priority",
        action="append",
        default=[],
        metavar="PROCESS=P",
        help="run a process (a node, or wavelet_stack) under SCHED_FIFO at priority P, 1-99 "
        "(repeatable; needs root, CAP_SYS_NICE or an rtprio limit: checked before the start)",
    )
    p.add_argument(
        "--udp",
        action="append",
        default=[],
        metavar="PROCESS",
        help="run a process (a node, or wavelet_stack) off shared memory: its DDS participant on "
        f"UDPv4 only (repeatable; default {' '.join(OFF_SHARED_MEMORY)}; --shm PROCESS undoes it)",
    )
    p.add_argument(
        "--shm",
        action="append",
        default=[],
        metavar="PROCESS",
        help="run a process with Fast DDS's shared memory (the default of every process not "
        "named by --udp or its default)",
    )
    p.add_argument("--timeout", type=float, default=3600.0, help="wall s before the run is aborted")
    p.add_argument(
        "--drain-timeout",
        type=float,
        default=DRAIN_TIMEOUT,
        help="wall s to wait, after the plant's end, for the other nodes to process the last "
        f"sample before they are stopped anyway (default {DRAIN_TIMEOUT:g})",
    )
    p.add_argument(
        "--stall-timeout",
        type=float,
        default=STALL_TIMEOUT,
        help="wall s the plant's simulated time may stand still, once it has started, before "
        f"the run is aborted with the plant's last log lines (0 = never; default "
        f"{STALL_TIMEOUT:g})",
    )
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    return p


def _set_overrides(args: argparse.Namespace) -> dict[str, dict[str, object]]:
    """The ``--set NODE.PARAM:=VALUE`` items as parameters per node.

    VALUE is read as YAML, as rcl reads a ``-p name:=value``: ``0.65`` is a double, ``db4`` a
    string, ``[fixed]`` a list, ``true`` a bool.
    """
    over: dict[str, dict[str, object]] = {n: {} for n in NODES}
    for item in args.set:
        node, _, rest = item.partition(".")
        name, sep, text = rest.partition(":=")
        if node not in over or not sep or not name:
            raise SystemExit(
                f"amb-run: --set {item!r}: expected NODE.PARAM:=VALUE with NODE in {NODES}"
            )
        try:
            value = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise SystemExit(f"amb-run: --set {item!r}: VALUE is not YAML: {exc}") from None
        over[node][name] = text if value is None else value
    return over


class _Progress:
    """Reads the nodes' /diagnostics in a node of this process (simulated time, counts).

    The node is in the run's namespace, so that the graph counts of the (relative) streams are
    the run's; of the reports on the ROS-wide ``/diagnostics`` it keeps the run's nodes' (their
    names carry the namespace: :func:`amb_common.topics.diagnostic_name`).
    """

    def __init__(self, namespace: str = topics.ROOT_NAMESPACE) -> None:
        self.namespace = namespace
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("amb_run_progress", namespace=namespace, context=self.context)
        self.statuses: dict[str, dict[str, str]] = {}  # status name -> its last key values
        self.node.create_subscription(DiagnosticArray, topics.DIAGNOSTICS, self._on_diag, 100)

        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        #: Stop signals checked between spins; set by :func:`run` once its handlers are in
        #: place (after ``rclpy.init``, which installs handlers of its own).
        self.stop: StopSignals | None = None

    def _on_diag(self, msg) -> None:
        for s in msg.status:
            self.statuses[s.name] = {kv.key: kv.value for kv in s.values}

    @property
    def values(self) -> dict[str, str]:
        """The plant's last report (empty before the first)."""
        return self.statuses.get(topics.diagnostic_name("plant_sim", self.namespace), {})

    def report(self, name: str) -> dict[str, str]:
        """Node ``name``'s last report, key -> value (empty before the first)."""
        return self.statuses.get(topics.diagnostic_name(name, self.namespace), {})

    def processed(self, name: str, key: str) -> int | None:
        """Sample index ``key`` last reported by node ``name`` (None if not reported yet)."""
        value = self.report(name).get(key)
        return int(value) if value is not None and value.lstrip("-").isdigit() else None

    def spin(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            if self.stop is not None:
                self.stop.check()
            self.executor.spin_once(timeout_sec=0.05)

    def graph(self, names: dict[str, int]) -> dict[str, int]:
        """Subscribers of each topic now, as this process's participant sees them."""
        return {t: self.node.count_subscribers(t) for t in names}

    def matched(self, names: dict[str, int], started: set[str]) -> dict[str, int | None]:
        """Subscriptions matched by the publisher of each topic, as it last reported them.

        The publisher's own count (:func:`amb_tools.streams.matched_subscribers`), for the
        topics whose publisher is in ``started``; None before its first report.
        """
        out: dict[str, int | None] = {}
        for t in names:
            if PUBLISHERS[t] in started:
                status = self.statuses.get(topics.diagnostic_name(PUBLISHERS[t], self.namespace))
                value = (status or {}).get(MATCHED_KEY + topics.absolute(t, self.namespace))
                out[t] = int(value) if value is not None else None
        return out

    def wait_for_graph(self, expected: dict[str, int], started: set[str], timeout: float) -> bool:
        """Spin until every topic has its expected subscribers; False on timeout.

        Seen by this process's participant and, for the topics published by a node in
        ``started``, matched by the publisher itself: only then does the first message reach
        every reader (the plant, started afterwards, waits for its own matches).
        """
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            counts = self.graph(expected)
            matched = self.matched(expected, started)
            if all(counts[t] >= n for t, n in expected.items()) and all(
                m is not None and m >= expected[t] for t, m in matched.items()
            ):
                return True
            self.spin(0.1)
        return False

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()


def run(args: argparse.Namespace) -> int:
    """Start the nodes, wait for the scenario to end, stop them; return the exit status."""
    # before anything is made: a refusal leaves no trace
    nice = NICENESS | per_process(
        "--nice", args.nice, NODES, f"NODE=N with NODE in {NODES}", signed=True
    )
    rt = rt_priorities(args.rt_priority)
    transport = transports(args.udp, args.shm)
    try:
        scenario = scenario_file(args.scenario)
    except FileNotFoundError as exc:
        print(f"amb-run: {exc}", file=sys.stderr)
        return 2
    params = args.params or config_file("amb_params.yaml")
    if not Path(params).is_file():
        print(f"amb-run: params file {params} not found", file=sys.stderr)
        return 2
    try:
        namespace = topics.namespace(args.namespace)
    except ValueError as exc:
        print(f"amb-run: --namespace: {exc}", file=sys.stderr)
        return 2
    out: Path = args.out
    if out.exists():
        print(f"amb-run: output folder {out} exists; choose a new one", file=sys.stderr)
        return 2
    names = [n for n in NODES if n not in args.without and available(n)]
    missing = [n for n in NODES if n not in names and n not in args.without]
    if "plant_sim" not in names:
        print("amb-run: plant_sim is not available", file=sys.stderr)
        return 2
    set_by_user = _set_overrides(args)
    if args.apart and not args.composed:
        print("amb-run: --apart needs --composed", file=sys.stderr)
        return 2
    hosted = [n for n in COMPOSED if n in names and n not in args.apart] if args.composed else []
    try:
        run_params = run_parameters(
            scenario,
            tuple(names),
            controller=args.controller or "",
            mode=str(set_by_user["plant_sim"].get("mode", "")),  # realtime: the catch-up bound
            bag=str((out / "bag").resolve()),
            hosted=tuple(hosted),
        )
    except ScenarioError as exc:
        print(f"amb-run: {exc}", file=sys.stderr)
        return 2
    (out / "logs").mkdir(parents=True)
    run_params_file = out / "run_params.yaml"
    run_params_file.write_text(
        "# amb-run: this run's parameters, given to every node after the params file\n"
        + yaml.safe_dump(
            run_params_document({n: {**run_params[n], **set_by_user[n]} for n in names}, namespace),
            default_flow_style=None,
            sort_keys=False,
        )
    )
    ros_args = ["--params-file", str(params), "--params-file", str(run_params_file)]
    if namespace != topics.ROOT_NAMESPACE:
        ros_args = ["-r", f"__ns:={namespace}", *ros_args]
    runs = [
        NodeRun(
            n,
            [*executable(n), "--ros-args", *ros_args],
            out / "logs" / f"{n}.log",
            nice=nice.get(n, 0),
            rt_priority=rt.get(n, 0),
            transport=transport.get(n, "shm"),
        )
        for n in names
        if n not in hosted
    ]
    if hosted:
        without = [a for n in COMPOSED if n not in hosted for a in ("--without", n)]
        runs.insert(
            1,
            NodeRun(
                STACK,
                [*executable(STACK), *without, "--ros-args", *ros_args],
                out / "logs" / f"{STACK}.log",
                hosts=tuple(hosted),
                rt_priority=rt.get(STACK, 0),
                transport=transport.get(STACK, "shm"),
            ),
        )
    env = dict(os.environ)
    env["PYTHONUNBUFFERED"] = "1"
    if not args.quiet:
        where = "" if namespace == topics.ROOT_NAMESPACE else f" in namespace {namespace}"
        print(f"[amb-run] {scenario.name}: starting {', '.join(names)}{where}", flush=True)
        if missing:
            print(f"[amb-run] not built yet, not started: {', '.join(missing)}", flush=True)
    progress = _Progress(namespace)
    status = 0
    t0 = time.monotonic()
    progress.stop = StopSignals(lambda m: print(f"[amb-run] {m}", file=sys.stderr))
    try:
        plant = next(r for r in runs if r.name == "plant_sim")
        for r in runs:
            if r is not plant:
                r.start(env)
        # the plant starts last, once every stream has all its subscribers (the recorder
        # subscribes to a topic only when it has seen its publisher): nothing is lost at start
        expected = stream_readers(names, hosted=tuple(hosted))
        started = set(names) - {"plant_sim"}
        if not progress.wait_for_graph(expected, started, timeout=120.0):
            print(
                f"[amb-run] not every subscription was up after 120 s: {progress.graph(expected)}"
                f" (matched by their publishers: {progress.matched(expected, started)}) of "
                f"{expected}; starting anyway",
                file=sys.stderr,
            )
        plant.start(env)
        last_print = 0.0
        first_sample_wall = None  # wall time of the first progress report (nodes are up)
        sim_seen, advanced = None, 0.0  # the plant's last simulated time, and when it moved
        while plant.proc.poll() is None:
            progress.spin(0.2)
            for r in runs:
                if r is not plant and r.proc.poll() is not None:
                    print(
                        f"[amb-run] {r.name} exited early ({r.proc.returncode}); see {r.log_path}",
                        file=sys.stderr,
                    )
                    status = 1
                    plant.proc.send_signal(signal.SIGINT)
            wall = time.monotonic() - t0
            if wall > args.timeout:
                print(f"[amb-run] timeout after {wall:.0f} s: stopping", file=sys.stderr)
                status = 1
                break
            if progress.values and first_sample_wall is None:
                first_sample_wall = wall
            sim_now = progress.values.get("time")
            if sim_now != sim_seen:
                sim_seen, advanced = sim_now, wall
            elif sim_now is not None and 0 < args.stall_timeout < wall - advanced:
                print(
                    f"[amb-run] the plant's simulated time has stood at {sim_now} s for "
                    f"{wall - advanced:.0f} s (--stall-timeout): stopping. The plant's last "
                    f"log lines ({plant.log_path}):\n{log_tail(plant.log_path)}",
                    file=sys.stderr,
                )
                status = 1
                break
            if not args.quiet and wall - last_print >= 1.0 and progress.values:
                last_print = wall
                sim_t = float(progress.values.get("time", "nan"))
                running = wall - first_sample_wall
                rtf = sim_t / running if running > 0 else math.nan
                print(
                    f"[amb-run] t_sim = {sim_t:8.3f} s  wall = {wall:7.1f} s  "
                    f"real-time factor = {rtf:5.2f}  "
                    f"commands missing {progress.values.get('missing', '?')}",
                    flush=True,
                )
        if status == 0 and plant.proc.returncode == 0:
            samples = plant_samples(progress, runs)
            status = drain(progress, runs, samples, args.drain_timeout, args.quiet)
            if status == 0:  # samples is known
                status = settle_recording(progress, runs, samples, args.drain_timeout, args.quiet)
    except (KeyboardInterrupt, RunStopped) as exc:  # Ctrl-C, SIGTERM, SIGHUP
        signum = getattr(exc, "signum", signal.SIGINT)
        name = signal.Signals(signum).name
        print(
            f"[amb-run] {name}: stopping the nodes; the bag keeps what was recorded",
            file=sys.stderr,
        )
        status = 128 + signum
    finally:
        progress.close()
        codes = {}

        def records(r: NodeRun) -> bool:
            return r.name == "recorder" or "recorder" in r.hosts

        for r in sorted(runs, key=records):  # the recorder (or the stack holding it) last
            codes[r.name] = r.stop()
        progress.stop.restore()
    wall = time.monotonic() - t0
    bad = {n: c for n, c in codes.items() if c != 0}
    if bad:
        status = status or 1
        print(
            f"[amb-run] nodes that did not stop cleanly: {bad} (logs in {out / 'logs'})",
            file=sys.stderr,
        )
    if not args.quiet:
        print(
            f"[amb-run] done in {wall:.1f} s wall; bag: {out / 'bag'}; logs: {out / 'logs'}",
            flush=True,
        )
    return status


def log_tail(path: Path, lines: int = 12) -> str:
    """The last ``lines`` lines of a node's log (empty if it cannot be read)."""
    try:
        return "\n".join(path.read_text(errors="replace").splitlines()[-lines:])
    except OSError:
        return ""


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``amb-run``."""
    return run(build_parser().parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
