"""Goal round trip: send a goal, receive N feedbacks and the result, framework vs the raw library.

One child per transport measures, in one process with two independent endpoints (two Zenoh
sessions on loopback; two ROS 2 contexts, so DDS discovers them as two processes would):

- framework: ``send_goal`` on one transport to a ``create_action_server`` on the other; the
  execute callback publishes N feedbacks and returns the result; the clock stops when the result
  and all N feedbacks have arrived;
- raw zenoh: what an application would write by hand for the same exchange: the client
  subscribes to a feedback key, queries a goal key; the queryable's handler (on a thread of its
  own) puts N feedback samples and replies with the result;
- raw ROS 2: ``rclpy.action.ActionServer`` (execute callback publishing N feedbacks) and
  ``ActionClient`` (send_goal_async, get_result_async), each node spun by its own
  single-threaded executor;
- rmw_zenoh: the framework's goal as a ROS 2 action in rmw_zenoh's format (three services and two topics
  under ``_action/``, CDR, attachments) between two rmw_zenoh peers of a router in the child, against raw
  zenoh's exchange above between two plain peers of such a router (the same topology);
- memory: the framework only (there is no raw library to compare with).

The framework is measured twice: with the feedback callback on a thread of the goal's own (the
default, payload ``goal_<n>_feedbacks``) and with ``send_goal(..., feedback_inline=True)`` (on the
thread that receives the goal's events, no hand-off: payload ``goal_<n>_feedbacks_inline``, with the
same raw measurement as its baseline). On Zenoh also with the server in a child process and the client
here, raw and framework alike (payload ``goal_<n>_feedbacks_processes``): as deployments run them, with
no GIL shared between the two sides.

The time of a goal is from sending it to holding its result; the feedback is then collected
(bounded) and what never came is recorded as ``feedback_lost`` (ROS 2 drops feedback that arrives
after the result, in raw rclpy as in the framework). Records carry ``rtt`` (median / p99 in µs,
from :func:`~benchmarks.common.summarize_ns`).
``python -m benchmarks.goals --transport zenoh --goals 50 --feedbacks 10`` is the child;
:func:`run_suite` runs it.
"""

from __future__ import annotations

import argparse
import logging
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

from .common import ChildFailed, Children, available, child_env, emit, free_tcp_port, log, summarize_ns

VLA = "VisionLanguageAction"
WARMUP = 5
#: After the result, how long a goal waits for feedback still on its way (not counted in the time).
FEEDBACK_GRACE_S = 0.5


class Lost:
    """Feedback that never arrived (ROS 2 drops feedback that arrives after the result, raw or not)."""

    count = 0


def _drain(got: threading.Semaphore, feedbacks: int) -> None:
    """Collect the goal's feedback (bounded); what does not come is counted in :class:`Lost`."""
    deadline = time.monotonic() + FEEDBACK_GRACE_S
    for received in range(feedbacks):
        if not got.acquire(timeout=max(0.0, deadline - time.monotonic())):
            Lost.count += feedbacks - received
            return


def _measure(one: Callable[[], threading.Semaphore], goals: int, feedbacks: int) -> list[int]:
    """Time ``goals`` goal round trips: ``one()`` returns once the result is in, with the feedback semaphore."""
    for _ in range(WARMUP):
        _drain(one(), feedbacks)
    Lost.count = 0
    samples = []
    for _ in range(goals):
        start = time.perf_counter_ns()
        got = one()
        samples.append(time.perf_counter_ns() - start)
        _drain(got, feedbacks)
    return samples


def _router() -> tuple[str, Any]:
    """A Zenoh router in this process on a free loopback port: (its endpoint, its session)."""
    from agents_zenoh.router import open_router  # noqa: PLC0415

    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    return endpoint, open_router([endpoint])


def _pair(transport: str, domain: int | None, closers: list[Callable[[], Any]]) -> tuple[Any, Any]:
    if transport == "memory":
        from agents_core.transport import MemoryTransport  # noqa: PLC0415

        t = MemoryTransport()
        return t, t
    if transport == "rmw_zenoh":
        from agents_zenoh.rmw.transport import RmwZenohTransport  # noqa: PLC0415

        endpoint, router = _router()
        closers.append(router.close)
        return (RmwZenohTransport(connect=[endpoint], listen=["tcp/127.0.0.1:0"]),
                RmwZenohTransport(connect=[endpoint], listen=["tcp/127.0.0.1:0"]))
    if transport == "zenoh":
        from agents_zenoh.transport import ZenohTransport  # noqa: PLC0415

        port = free_tcp_port()
        a = ZenohTransport(mode="peer", listen=[f"tcp/127.0.0.1:{port}"], connect=[], multicast_scouting=False)
        b = ZenohTransport(mode="peer", listen=[f"tcp/127.0.0.1:{free_tcp_port()}"],
                           connect=[f"tcp/127.0.0.1:{port}"], multicast_scouting=False)
        return a, b
    from agents_ros2.transport import Ros2Transport  # noqa: PLC0415

    return Ros2Transport(domain_id=domain), Ros2Transport(domain_id=domain)


def _framework_server(transport: Any, feedbacks: int) -> None:
    def execute(handle: Any) -> dict[str, Any]:
        for step in range(feedbacks):
            handle.publish_feedback({"step": step, "action": [0.1, 0.2, 0.3], "status": "moving"})
        return {"success": True, "steps": feedbacks}

    transport.create_action_server("bench_goal", VLA, execute)


def framework(transport: str, goals: int, feedbacks: int, domain: int | None, inline: bool = False,
              server_port: int | None = None) -> list[int]:
    """The framework's goals; ``server_port``: the server runs in another process (see :func:`serve`)."""
    closers: list[Callable[[], Any]] = []
    if server_port is None:
        a, b = _pair(transport, domain, closers)
        _framework_server(a, feedbacks)
    else:
        from agents_zenoh.transport import ZenohTransport  # noqa: PLC0415

        a = b = ZenohTransport(mode="peer", listen=[f"tcp/127.0.0.1:{free_tcp_port()}"],
                               connect=[f"tcp/127.0.0.1:{server_port}"], multicast_scouting=False)
    try:
        deadline = time.monotonic() + 20
        while True:  # discovery on networked transports
            try:
                b.send_goal("bench_goal", VLA, {"task": "warm"}, timeout=2.0).result(10.0)
                break
            except Exception:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.1)

        def one() -> threading.Semaphore:
            got = threading.Semaphore(0)
            goal = b.send_goal("bench_goal", VLA, {"task": "t", "max_steps": feedbacks},
                               feedback=lambda fb: got.release(), feedback_inline=inline)
            goal.result(30.0)
            return got

        return _measure(one, goals, feedbacks)
    finally:
        b.close()
        if a is not b:
            a.close()
        for close in closers:
            close()


def _raw_server(server: Any, feedbacks: int) -> Any:
    import msgpack  # noqa: PLC0415
    import zenoh  # noqa: PLC0415

    def serve(query: zenoh.Query) -> None:
        def run() -> None:
            with query:
                goal_id = msgpack.unpackb(query.payload.to_bytes())["goal_id"]
                for step in range(feedbacks):
                    server.put(f"raw_goal/feedback/{goal_id}",
                               msgpack.packb({"step": step, "action": [0.1, 0.2, 0.3], "status": "moving"}))
                query.reply(query.key_expr, msgpack.packb({"status": 4, "result": {"success": True}}))

        threading.Thread(target=run, daemon=True).start()

    return server.declare_queryable("raw_goal/goal", serve)


def raw_zenoh(goals: int, feedbacks: int, server_port: int | None = None, via_router: bool = False) -> list[int]:
    """Raw zenoh goals; ``server_port``: the queryable runs in another process (see :func:`serve`);
    ``via_router``: between two peers of a router (rmw_zenoh's topology)."""
    import msgpack  # noqa: PLC0415
    import zenoh  # noqa: PLC0415

    from .common import zenoh_raw_config  # noqa: PLC0415

    router = None
    if via_router:
        endpoint, router = _router()
        server: Any = zenoh.open(zenoh_raw_config(["tcp/127.0.0.1:0"], [endpoint]))
        client = zenoh.open(zenoh_raw_config(["tcp/127.0.0.1:0"], [endpoint]))
    else:
        port = server_port or free_tcp_port()
        server = zenoh.open(zenoh_raw_config([f"tcp/127.0.0.1:{port}"], [])) if server_port is None else None
        client = zenoh.open(zenoh_raw_config([], [f"tcp/127.0.0.1:{port}"]))
    queryable = _raw_server(server, feedbacks) if server is not None else None
    counter = iter(range(10**9))
    try:
        time.sleep(0.5)

        subscribers: list[Any] = []

        def one() -> threading.Semaphore:
            goal_id = f"g{next(counter)}"
            got = threading.Semaphore(0)
            subscribers.append(client.declare_subscriber(f"raw_goal/feedback/{goal_id}", lambda s: got.release()))
            replies = list(client.get("raw_goal/goal", payload=msgpack.packb({"goal_id": goal_id}), timeout=30.0))
            if not replies or replies[0].ok is None:
                raise RuntimeError("no result")
            return got

        samples = _measure(one, goals, feedbacks)
        for sub in subscribers:
            sub.undeclare()
        return samples
    finally:
        if queryable is not None:
            queryable.undeclare()
        client.close()
        if server is not None:
            server.close()
        if router is not None:
            router.close()


def serve(kind: str, port: int, feedbacks: int) -> None:
    """The server side alone (``--serve raw|framework``), listening on ``port``; prints ``ready``, ends when
    stdin closes (or after 600 s)."""
    import zenoh  # noqa: PLC0415

    from .common import zenoh_raw_config  # noqa: PLC0415

    closing: list[Callable[[], Any]] = []
    if kind == "raw":
        session = zenoh.open(zenoh_raw_config([f"tcp/127.0.0.1:{port}"], []))
        closing += [_raw_server(session, feedbacks).undeclare, session.close]
    else:
        from agents_zenoh.transport import ZenohTransport  # noqa: PLC0415

        transport = ZenohTransport(mode="peer", listen=[f"tcp/127.0.0.1:{port}"], connect=[],
                                   multicast_scouting=False)
        _framework_server(transport, feedbacks)
        closing.append(transport.close)
    print("ready", flush=True)
    done = threading.Event()

    def until_stdin_closes() -> None:
        sys.stdin.read()
        done.set()

    threading.Thread(target=until_stdin_closes, daemon=True).start()
    done.wait(600)
    for close in closing:
        close()


def _in_another_process(kind: str, goals: int, feedbacks: int) -> list[int]:
    """Goals to a server in a child process (``serve``), as deployments run them: no GIL shared."""
    import subprocess  # noqa: PLC0415

    port = free_tcp_port()
    child = subprocess.Popen([sys.executable, "-m", "benchmarks.goals", "--transport", "zenoh", "--serve", kind,
                              "--port", str(port), "--feedbacks", str(feedbacks)],
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=child_env())
    try:
        ready = threading.Event()
        stdout = child.stdout

        def until_ready() -> None:
            if stdout is not None and stdout.readline():
                ready.set()

        threading.Thread(target=until_ready, daemon=True).start()
        if not ready.wait(60):
            raise RuntimeError(f"the {kind} goal server did not start")
        if kind == "raw":
            time.sleep(0.5)
            return raw_zenoh(goals, feedbacks, server_port=port)
        return framework("zenoh", goals, feedbacks, None, server_port=port)
    finally:
        if child.stdin is not None:
            child.stdin.close()
        try:
            child.wait(10)
        except subprocess.TimeoutExpired:
            child.kill()
            child.wait(5)


def raw_ros2(goals: int, feedbacks: int, domain: int | None) -> list[int]:
    import rclpy  # noqa: PLC0415
    from agents_interfaces.action import VisionLanguageAction  # noqa: PLC0415
    from rclpy.action import ActionClient, ActionServer  # noqa: PLC0415
    from rclpy.context import Context  # noqa: PLC0415
    from rclpy.executors import SingleThreadedExecutor  # noqa: PLC0415

    contexts, nodes, executors, threads = [], [], [], []
    stop = threading.Event()
    for name in ("raw_goal_server", "raw_goal_client"):
        context = Context()
        rclpy.init(context=context, domain_id=domain)
        node = rclpy.create_node(name, context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        contexts.append(context)
        nodes.append(node)
        executors.append(executor)

    def execute(handle: Any) -> Any:
        for step in range(feedbacks):
            handle.publish_feedback(VisionLanguageAction.Feedback(step=step, action=[0.1, 0.2, 0.3], status="moving"))
        handle.succeed()
        return VisionLanguageAction.Result(success=True, steps=feedbacks)

    server = ActionServer(nodes[0], VisionLanguageAction, "raw_goal", execute)
    client = ActionClient(nodes[1], VisionLanguageAction, "raw_goal")
    for executor in executors:
        def spin(executor: Any = executor) -> None:
            while not stop.is_set():
                executor.spin_once(timeout_sec=0.05)

        thread = threading.Thread(target=spin, daemon=True)
        thread.start()
        threads.append(thread)

    def wait(future: Any) -> Any:
        done = threading.Event()
        future.add_done_callback(lambda _f: done.set())
        if not done.wait(30.0):
            raise RuntimeError("no answer")
        return future.result()

    try:
        if not client.wait_for_server(timeout_sec=20.0):
            raise RuntimeError("raw action server not discovered")

        def one() -> threading.Semaphore:
            got = threading.Semaphore(0)
            handle = wait(client.send_goal_async(VisionLanguageAction.Goal(task="t", max_steps=feedbacks),
                                                 feedback_callback=lambda _m: got.release()))
            wait(handle.get_result_async())
            return got

        return _measure(one, goals, feedbacks)
    finally:
        stop.set()
        for thread in threads:
            thread.join(5.0)
        server.destroy()
        client.destroy()
        for executor, node, context in zip(executors, nodes, contexts, strict=True):
            executor.shutdown(timeout_sec=2.0)
            node.destroy_node()
            context.try_shutdown()


def run_child(transport: str, goals: int, feedbacks: int, domain: int | None) -> None:
    payload = f"goal_{feedbacks}_feedbacks"
    modes: list[tuple[str, str, Callable[[], list[int]]]] = [
        ("framework", payload, lambda: framework(transport, goals, feedbacks, domain)),
        ("framework", f"{payload}_inline", lambda: framework(transport, goals, feedbacks, domain, inline=True))]
    if transport == "zenoh":
        modes.insert(0, ("raw", payload, lambda: raw_zenoh(goals, feedbacks)))
        # Client and server in two processes (each side's own GIL), raw then framework.
        modes += [("raw", f"{payload}_processes", lambda: _in_another_process("raw", goals, feedbacks)),
                  ("framework", f"{payload}_processes", lambda: _in_another_process("framework", goals, feedbacks))]
    elif transport == "ros2":
        modes.insert(0, ("raw", payload, lambda: raw_ros2(goals, feedbacks, domain)))
    elif transport == "rmw_zenoh":
        modes.insert(0, ("raw", payload, lambda: raw_zenoh(goals, feedbacks, via_router=True)))
    for mode, name, measure in modes:
        samples = measure()
        record = {"suite": "goals", "transport": transport, "payload": name, "mode": mode,
                  "rtt": summarize_ns(samples), "goals": goals, "feedbacks": feedbacks, "feedback_lost": Lost.count}
        emit(record)
        if mode == "raw" and name == payload:  # the baseline of the inline figure too (the same measurement)
            emit({**record, "payload": f"{payload}_inline"})
        log(f"goals {transport} {mode} {name} done")


def run_suite(transports: list[str], settings: dict[str, Any], children: Children, ros_domain: int,
              progress: Callable[[str], None]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """One child per transport (raw then framework in each); (records, skipped)."""
    records: list[dict[str, Any]] = []
    skipped: list[dict[str, str]] = []
    for transport in transports:
        if transport == "ros2" and not available("rclpy"):
            continue
        try:
            child = children.start(f"goals-{transport}", [
                "-m", "benchmarks.goals", "--transport", transport, "--goals", str(settings.get("goal_count", 50)),
                "--feedbacks", str(settings.get("goal_feedbacks", 10)), "--ros-domain", str(ros_domain)],
                child_env(ros_domain))
            got = list(child.records(timeout=300))
            children.stop(child)
            records += got
            for r in got:
                progress(f"{'goals':<10} {transport:<6} {r['mode']:<9} {r['payload']:<26} "
                         f"{r['rtt']['median_us']:10.1f} us median")
        except ChildFailed as exc:
            progress(f"goals {transport}: FAILED: {str(exc).splitlines()[0]}")
            skipped.append({"suite": "goals", "transport": transport, "mode": "both", "reason": str(exc)[-1500:]})
    return records, skipped


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--transport", choices=("memory", "zenoh", "ros2", "rmw_zenoh"), required=True)
    parser.add_argument("--goals", type=int, default=50)
    parser.add_argument("--feedbacks", type=int, default=10)
    parser.add_argument("--ros-domain", type=int, default=None)
    parser.add_argument("--serve", choices=("raw", "framework"), help="the server side alone, in this process")
    parser.add_argument("--port", type=int, default=0)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr)
    if args.serve:
        serve(args.serve, args.port, args.feedbacks)
        return 0
    run_child(args.transport, args.goals, args.feedbacks, args.ros_domain)
    return 0


if __name__ == "__main__":
    sys.exit(main())
