"""``agentsctl topics hz`` against the publisher's own rate, and against a raw Zenoh subscriber.

A child process publishes ``String`` samples through the framework's Zenoh transport at a set
rate (deadline-paced) and reports how many it sent over how long: the publisher's rate. While it
runs, ``python -m agents_core.cli topics hz`` (a separate process, a client of the publisher's
endpoint) measures the rate over a window, and so does a raw ``zenoh`` subscriber in this process
counting samples on the same key over the same time. Reported per target rate: the three rates
and the ratios ``cli / publisher`` and ``cli / raw`` (1.0: the CLI sees every message).

``python -m benchmarks.cli_hz [--rates 10,100,1000] [--window 3] [--out DIR]`` prints a markdown
table and writes ``<out>/<stamp>-cli-hz.json``. Not yet one of ``benchmarks.run``'s suites.
"""

from __future__ import annotations

import argparse
import datetime
import json
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .common import REPO, child_env, free_tcp_port, zenoh_raw_config

TOPIC = "bench/hz"

PUBLISHER = """
import json, sys, time
from agents_core.topics import Topic
from agents_zenoh.transport import ZenohTransport
endpoint, rate, seconds = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
with ZenohTransport(mode="peer", listen=[endpoint], connect=[], match_timeout=0.0) as t:
    pub = t.create_publisher(Topic("bench/hz", "String"))
    print("READY", flush=True)
    time.sleep(1.0)
    period, sent = 1.0 / rate, 0
    start = time.monotonic()
    next_at = start
    while time.monotonic() - start < seconds:
        pub.publish(f"sample {sent}")
        sent += 1
        next_at += period
        time.sleep(max(0.0, next_at - time.monotonic()))
    elapsed = time.monotonic() - start
print(json.dumps({"sent": sent, "elapsed_s": elapsed}), flush=True)
"""


def _raw_rate(endpoint: str, window: float, start_after: float) -> dict[str, float]:
    import zenoh  # noqa: PLC0415 - the zenoh extra

    stamps: list[float] = []
    lock = threading.Lock()

    def on_sample(_sample: Any) -> None:
        with lock:
            stamps.append(time.monotonic())

    with zenoh.open(zenoh_raw_config([], [endpoint])) as session:
        session.declare_subscriber(TOPIC, on_sample)
        time.sleep(start_after)
        with lock:
            stamps.clear()
        time.sleep(window)
        with lock:
            got = list(stamps)
    rate = (len(got) - 1) / (got[-1] - got[0]) if len(got) > 1 else 0.0
    return {"messages": len(got), "rate_hz": rate}


def measure(rate: float, window: float) -> dict[str, Any]:
    """One target rate: publisher, CLI and raw subscriber rates."""
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    seconds = window + 6.0  # the CLI's start-up and discovery come first
    publisher = subprocess.Popen([sys.executable, "-c", PUBLISHER, endpoint, str(rate), str(seconds)], cwd=REPO,
                                 env=child_env(), stdout=subprocess.PIPE, text=True)
    try:
        assert publisher.stdout is not None
        if publisher.stdout.readline().strip() != "READY":
            raise RuntimeError("the publisher did not start")
        cli = subprocess.Popen([sys.executable, "-m", "agents_core.cli", "topics", "hz", TOPIC, "--connect", endpoint,
                                "--window", str(window), "--json"], cwd=REPO, env=child_env(),
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        raw = _raw_rate(endpoint, window, start_after=2.0)
        out, err = cli.communicate(timeout=window + 60)
        if cli.returncode != 0:
            raise RuntimeError(f"agentsctl topics hz failed: {err.strip()}")
        cli_doc = json.loads(out)
        published = json.loads(publisher.communicate(timeout=seconds + 30)[0].strip().splitlines()[-1])
    finally:
        if publisher.poll() is None:
            publisher.kill()
            publisher.wait(timeout=10)
    publisher_rate = published["sent"] / published["elapsed_s"]
    return {"target_hz": rate, "publisher_hz": publisher_rate, "cli_hz": cli_doc["rate_hz"],
            "raw_hz": raw["rate_hz"], "cli_vs_publisher": cli_doc["rate_hz"] / publisher_rate,
            "cli_vs_raw": cli_doc["rate_hz"] / raw["rate_hz"] if raw["rate_hz"] else None,
            "cli_messages": cli_doc["messages"], "raw_messages": raw["messages"]}


def run_suite(settings: dict[str, Any],
              progress: Callable[[str], None]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """The ``cli`` suite of ``benchmarks.run``: ``topics hz`` vs a raw subscriber's rate; (records, skipped)."""
    records: list[dict[str, Any]] = []
    skipped: list[dict[str, str]] = []
    window = float(settings.get("cli_window", 3.0))
    for rate in settings.get("cli_rates", (100.0,)):
        payload = f"String_at_{rate:g}_Hz"
        try:
            result = measure(float(rate), window)
        except (RuntimeError, OSError, subprocess.SubprocessError, ValueError) as exc:
            progress(f"cli: FAILED at {rate:g} Hz: {exc}")
            skipped.append({"suite": "cli", "transport": "zenoh", "mode": "both", "reason": str(exc)[-1500:]})
            continue
        for mode, key in (("framework", "cli_hz"), ("raw", "raw_hz")):
            records.append({"suite": "cli", "transport": "zenoh", "payload": payload, "mode": mode,
                            "rate_hz": result[key], "publisher_hz": result["publisher_hz"]})
        progress(f"{'cli':<10} {'zenoh':<6} {rate:g} Hz: agentsctl hz {result['cli_hz']:.1f}, "
                 f"raw {result['raw_hz']:.1f}")
    return records, skipped


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", default="10,100,1000", help="comma-separated target rates (Hz)")
    parser.add_argument("--window", type=float, default=3.0, help="seconds the CLI and raw side measure over")
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks" / "results")
    args = parser.parse_args(argv)
    rows = [measure(float(r), args.window) for r in args.rates.split(",")]
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"{stamp}-cli-hz.json").write_text(json.dumps({"suite": "cli_hz", "window_s": args.window,
                                                               "results": rows}, indent=2))
    print("| target Hz | publisher Hz | agentsctl hz | raw zenoh sub | cli/publisher | cli/raw |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        ratio = f"{r['cli_vs_raw']:.3f}" if r["cli_vs_raw"] is not None else "-"
        print(f"| {r['target_hz']:g} | {r['publisher_hz']:.1f} | {r['cli_hz']:.1f} | {r['raw_hz']:.1f} | "
              f"{r['cli_vs_publisher']:.3f} | {ratio} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
