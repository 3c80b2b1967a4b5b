"""Run the benchmarks: ``python -m benchmarks.run [--quick] [--transports memory,zenoh,ros2] [--out DIR]``.

Runs the suites (hop latency and throughput, start-up, model path, import cost, vision, voice, map,
processes, ui, goals, vla, shm, cli, sim, e2e) for every transport this environment has, framework and raw library
side by side, then writes
``<out>/<stamp>-<quick|full>.json`` and ``.png`` and prints a markdown table. A transport or suite
that cannot run here (its extra is not installed) is skipped, and the reason is recorded in the
JSON. Child logs go to ``<out>/<stamp>-logs/``. See ``benchmarks/README.md``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import random
import signal
import sys
import time
from pathlib import Path
from types import FrameType
from typing import Any

from . import cli_hz, cortex, e2e, goals, hop, imports, model, processes, report, startup, ui, vision, vla, voice
from . import fleet as fleet_suite
from . import map as map_suite  # the module name is the suite name; "map" alone would hide the builtin
from . import mcp as mcp_suite
from . import memory as memory_suite
from . import recording as recording_suite
from . import rmw_zenoh as rmw_zenoh_suite
from . import shm as shm_suite
from . import sim as sim_suite
from . import telemetry as telemetry_suite
from .common import IMAGE_SHAPE, REPO, STRING_BYTES, Children, available
from .throughput import WINDOW

SCHEMA = "agents-core-bench/1"

SETTINGS: dict[str, dict[str, Any]] = {
    "quick": {"string_warmup": 50, "string_count": 200, "image_warmup": 10, "image_count": 50,
              "throughput_seconds": 1.5, "latency_max_seconds": 30.0, "startup_reps": 2,
              "model_reps": 2, "model_max_tokens": 64, "model_threads": 1, "rounds": 1, "import_reps": 5,
              "vision_frames": 20, "vision_seconds": 3.0, "voice_reps": 1, "map_values": 100, "map_reps": 1,
              "processes_reps": 2, "processes_respawns": 3, "ui_count": 100, "ui_warmup": 10,
              "goal_count": 20, "goal_feedbacks": 10, "vla_reps": 30, "vla_warmup": 5,
              "cli_rates": (100.0,), "cli_window": 2.0, "e2e_reps": 1, "e2e_max_tokens": 16,
              "e2e_transports": ("memory",), "mcp_reps": 50, "mcp_warmup": 10, "sim_episodes": 5,
              "fleet_sizes": (1, 5), "fleet_window": 2.0},
    "full": {"string_warmup": 200, "string_count": 2000, "image_warmup": 30, "image_count": 300,
             "throughput_seconds": 5.0, "latency_max_seconds": 120.0, "startup_reps": 5,
             "model_reps": 8, "model_max_tokens": 64, "model_threads": 1, "rounds": 3, "import_reps": 15,
             "vision_frames": 100, "vision_seconds": 10.0, "voice_reps": 5, "map_values": 300,
             "map_reps": 3, "processes_reps": 5, "processes_respawns": 10, "ui_count": 1000, "ui_warmup": 50,
             "goal_count": 200, "goal_feedbacks": 10, "vla_reps": 200, "vla_warmup": 10,
             "cli_rates": (10.0, 100.0, 1000.0), "cli_window": 3.0, "e2e_reps": 5, "e2e_max_tokens": 24,
             "e2e_transports": ("memory", "zenoh"), "mcp_reps": 300, "mcp_warmup": 30, "sim_episodes": 20,
             "fleet_sizes": (1, 5, 20), "fleet_window": 5.0},
}

SUITES = ("hop", "startup", "model", "imports", "vision", "voice", "map", "processes", "ui", "goals", "vla",
          "cortex", "cli", "memory", "recording", "sim", "e2e", "mcp", "rmw_zenoh", "telemetry", "fleet", "shm")


def transport_unavailable(name: str) -> str | None:
    """Why ``name`` cannot be measured in this environment, or None."""
    if name == "zenoh" and not (available("zenoh") and available("msgpack")):
        return "the zenoh extra is not installed (pip install 'agents-core[zenoh]')"
    if name == "ros2":
        if not available("rclpy"):
            return "the ros2 extra is not installed (pip install 'agents-core[ros2]')"
        if not available("agents_interfaces"):
            return "agents_interfaces is not built here (pip install --no-build-isolation ./interfaces)"
    return None


def _progress(start: float) -> Any:
    def progress(line: str) -> None:
        print(f"[{time.monotonic() - start:6.1f}s] {line}", flush=True)

    return progress


def _terminate(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt(f"signal {signum}")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="small counts, for CI (a couple of minutes)")
    parser.add_argument("--transports", default="memory,zenoh,ros2", help="comma-separated (default: all)")
    parser.add_argument("--suites", default=",".join(SUITES), help=f"comma-separated of {', '.join(SUITES)} "
                        "(hop includes throughput)")
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks" / "results", help="output folder")
    parser.add_argument("--ros-domain", type=int, default=None, help="ROS_DOMAIN_ID (default: random 1..101)")
    parser.add_argument("--no-plot", action="store_true", help="skip the PNG")
    args = parser.parse_args(argv)
    args.transports = [t.strip() for t in args.transports.split(",") if t.strip()]
    args.suites = [s.strip() for s in args.suites.split(",") if s.strip()]
    for name in args.transports:
        if name not in ("memory", "zenoh", "ros2"):
            parser.error(f"unknown transport {name!r}")
    for name in args.suites:
        if name not in SUITES:
            parser.error(f"unknown suite {name!r}")
    return args


def run_suites(transports: list[str], suites: list[str], settings: dict[str, Any], ros_domain: int,
               children: Children, progress: Any) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """Every selected suite, in order; all children are stopped by PID before this returns."""
    t, c, d, p = transports, children, ros_domain, progress
    # Each suite with the transport it needs in the selection (None: it picks its own), and how to run it.
    runners: list[tuple[str, str | None, Any]] = [
        ("hop", None, lambda: hop.run_suite(t, settings, c, d, p)),
        ("telemetry", None, lambda: telemetry_suite.run_suite(t, settings, c, d, p)),
        ("startup", None, lambda: startup.run_suite(t, settings, c, d, p)),
        ("model", None, lambda: model.run_suite(settings, c, p)),
        ("imports", None, lambda: imports.run_suite(settings, p)),
        ("vision", "zenoh", lambda: vision.run_suite(settings, c, p)),
        ("voice", "memory", lambda: voice.run_suite(settings, c, p)),
        ("map", "memory", lambda: map_suite.run_suite(settings, c, p)),
        ("processes", None, lambda: processes.run_suite(t, settings, c, d, p)),
        ("ui", "memory", lambda: ui.run_suite(settings, p)),
        ("goals", None, lambda: goals.run_suite(t, settings, c, d, p)),
        ("vla", None, lambda: vla.run_suite(settings, c, p)),
        ("shm", "zenoh", lambda: shm_suite.run_suite(settings, c, p)),
        ("cortex", None, lambda: cortex.run_suite(settings, c, p)),
        ("mcp", None, lambda: mcp_suite.run_suite(settings, c, p)),
        ("cli", "zenoh", lambda: cli_hz.run_suite(settings, p)),
        ("rmw_zenoh", "zenoh", lambda: rmw_zenoh_suite.run_suite(settings, c, d, p)),
        ("fleet", "zenoh", lambda: fleet_suite.run_suite(settings, c, p)),
        ("memory", "memory", lambda: memory_suite.run_suite(settings, p)),
        ("recording", "memory", lambda: recording_suite.run_suite(settings, p)),
        ("sim", None, lambda: sim_suite.run_suite(settings, t, c, d, p)),
        ("e2e", "memory", lambda: e2e.run_suite({**settings, "e2e_transports": [
            x for x in settings["e2e_transports"] if x in t]}, c, p)),
    ]
    records: list[dict[str, Any]] = []
    skipped: list[dict[str, str]] = []
    previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        for name, needs, run in runners:
            if name in suites and (needs is None or needs in transports):
                got, lost = run()
                records += got
                skipped += lost
    finally:
        children.stop_all()
        signal.signal(signal.SIGTERM, previous)
    return records, skipped


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    kind = "quick" if args.quick else "full"
    settings = dict(SETTINGS[kind])
    ros_domain = args.ros_domain if args.ros_domain is not None else random.randint(1, 101)
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    log_dir = args.out / f"{stamp}-logs"
    log_dir.mkdir(parents=True, exist_ok=True)

    started = time.monotonic()
    machine = report.machine_info()  # before the run: the load average says how busy the machine was
    progress = _progress(started)
    skipped: list[dict[str, str]] = []
    runnable = []
    for name in args.transports:
        reason = transport_unavailable(name)
        if reason is None:
            runnable.append(name)
        else:
            progress(f"{name}: skipped: {reason}")
            skipped.append({"suite": "all", "transport": name, "mode": "both", "reason": reason})
    progress(f"{kind} run: transports {', '.join(runnable) or 'none'}; suites {', '.join(args.suites)}; "
             f"ROS_DOMAIN_ID {ros_domain}; logs in {log_dir}")
    records, lost = run_suites(runnable, args.suites, settings, ros_domain, Children(log_dir), progress)
    skipped += lost

    figures = report.build_figures(records)
    duration = time.monotonic() - started
    result = {
        "schema": SCHEMA, "kind": kind, "started": stamp, "duration_s": round(duration, 1),
        "argv": sys.argv[1:] if argv is None else argv,
        "machine": {**machine, "loadavg_at_end": list(os.getloadavg())},
        "versions": report.versions(),
        "settings": {**settings, "transports": runnable, "suites": args.suites, "ros_domain_id": ros_domain,
                     "string_bytes": STRING_BYTES, "image_shape": list(IMAGE_SHAPE), "throughput_window": WINDOW},
        "figures": figures, "skipped": skipped, "records": records,
    }
    json_path = args.out / f"{stamp}-{kind}.json"
    json_path.write_text(json.dumps(result, indent=2))
    png_path = args.out / f"{stamp}-{kind}.png"
    if not args.no_plot and records:
        if available("matplotlib"):
            report.plot(figures, records, png_path, f"agents-core benchmarks, {kind} run {stamp} "
                        f"({result['machine']['cpu']}, {result['machine']['cpu_count']} cores)")
        else:
            progress("plot: skipped (matplotlib is not installed)")
    print(f"\n## Benchmarks ({kind}, {duration:.0f} s): framework vs the raw library\n")
    print(report.markdown_table(figures, skipped))
    print(f"\nJSON: {json_path}")
    if png_path.exists():
        print(f"plot: {png_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
