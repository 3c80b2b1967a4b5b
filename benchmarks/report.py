"""Turning measurement records into figures (framework, raw, ratio), a markdown table and a plot."""

from __future__ import annotations

import importlib.metadata
import os
import platform
import statistics
import subprocess
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from .common import REPO

#: suite -> [(metric, unit, better, how to read it from a record)]
METRICS: dict[str, list[tuple[str, str, str, str]]] = {
    "hop": [("rtt_median", "us", "lower", "rtt.median_us"), ("rtt_p99", "us", "lower", "rtt.p99_us")],
    "throughput": [("msgs_per_s", "msg/s", "higher", "msgs_per_s"), ("mb_per_s", "MB/s", "higher", "mb_per_s")],
    # benchmarks.telemetry: the framework hop with telemetry on ("framework") against off ("raw").
    "telemetry_hop": [("rtt_median", "us", "lower", "rtt.median_us"), ("rtt_p99", "us", "lower", "rtt.p99_us")],
    "telemetry_throughput": [("msgs_per_s", "msg/s", "higher", "msgs_per_s")],
    "telemetry_sampled_hop": [("rtt_median", "us", "lower", "rtt.median_us"), ("rtt_p99", "us", "lower", "rtt.p99_us")],
    "telemetry_sampled_throughput": [("msgs_per_s", "msg/s", "higher", "msgs_per_s")],
    "startup": [("start_to_active", "ms", "lower", "median_ms"),
                ("threads_3_inputs", "threads", "lower", "threads_3_inputs")],
    "model": [("ttft", "ms", "lower", "ttft_ms"), ("tokens_per_s", "tokens/s", "higher", "tokens_per_s")],
    "imports": [("wall", "ms", "lower", "wall_ms"), ("import", "ms", "lower", "import_ms")],
    # framework: camera -> Vision component (Zenoh) -> Detections; raw: a direct onnxruntime loop.
    "vision": [("fps", "frames/s", "higher", "fps"), ("latency_p50", "ms", "lower", "latency_ms.p50"),
               ("latency_p99", "ms", "lower", "latency_ms.p99")],
    # stt: x real time through SpeechToText vs a direct sherpa-onnx loop; tts: first audio of a streamed
    # answer through TextToSpeech vs synthesizing the whole answer at once.
    "voice": [("stt_speed", "x realtime", "higher", "speed"), ("first_audio", "ms", "lower", "first_audio_ms")],
    # layer values written into a local Chroma through MapEncoding vs direct ChromaClient.add calls.
    "map": [("writes_per_s", "writes/s", "higher", "writes_per_s")],
    # Memory component fed a burst (values on its trigger topic) vs emem's add with the same embeddings; search via
    # execute_method (string) and the component's method called directly (method_call), vs emem's direct call.
    "memory": [("stored_per_s", "obs/s", "higher", "writes_per_s"),
               ("semantic_search", "us", "lower", "search_median_us")],
    # Cortex's own cost per step: the plan -> the first dispatched action, model time excluded (no raw side).
    "cortex": [("overhead_p50", "ms", "lower", "latency_ms.p50"), ("overhead_p99", "ms", "lower", "latency_ms.p99")],
    "mcp": [("call_p50", "ms", "lower", "latency_ms.p50"), ("call_p99", "ms", "lower", "latency_ms.p99")],
    # framework: the five-stage recipe with multiprocessing=True; raw: the same recipe in one process.
    # respawn: SIGKILL of a component process -> its new process active (multiprocessing only).
    # uss_per_process: memory only one component process holds (multiprocessing only; target <= 40 MB).
    "processes": [("start_to_active", "ms", "lower", "median_ms"),
                  ("respawn_to_active", "ms", "lower", "respawn_median_ms"),
                  ("uss_per_process", "MB", "lower", "uss_median_mb")],
    # framework: a topic value -> the web UI's WebSocket client; raw: a plain subscription's callback.
    "ui": [("latency_p50", "ms", "lower", "latency_ms.p50"), ("latency_p99", "ms", "lower", "latency_ms.p99")],
    # a goal with N feedbacks, sent to its result: send_goal / create_action_server vs raw zenoh queryables
    # or raw rclpy ActionServer / ActionClient.
    "goals": [("rtt_median", "us", "lower", "rtt.median_us"), ("rtt_p99", "us", "lower", "rtt.p99_us")],
    # 640x480 rgb8 and 1 MiB PointCloud2 through a relay between two processes (benchmarks/shm.py): the framework's
    # default / pool / no-shared-memory config vs raw zenoh with shared memory off, its default, its own SHM buffers.
    "shm": [("rtt_median", "us", "lower", "rtt_median_us"), ("mb_per_s", "MB/s", "higher", "mb_per_s")],
    # one observation -> action chunk round trip: LeRobotClient.inference vs the raw gRPC stubs, one server.
    "vla": [("latency_p50", "ms", "lower", "latency_ms.p50"), ("latency_p99", "ms", "lower", "latency_ms.p99")],
    # the rate `agentsctl topics hz` reports vs a raw zenoh subscriber counting the same publisher.
    "cli": [("hz_rate", "Hz", "higher", "rate_hz")],
    # a relay hop's throughput with a Recorder writing MCAP (framework) vs without one (raw); playback lateness.
    "recording": [("msgs_per_s", "msg/s", "higher", "msgs_per_s"), ("playback_p99", "ms", "lower", "lateness_ms.p99")],
    # a whole loop (voice: speech file -> STT -> LLM -> TTS -> first audio; perception: image -> Vision ->
    # VLM answer) through the recipe vs the sum of its stages run directly; ratio - 1 = framework overhead.
    "e2e": [("loop", "ms", "lower", "loop_ms")],
    # Reacher-v5 with the scripted expert in lock-step: GymWorld + the expert component (run_evaluation) vs the
    # same expert stepping the environment directly; steps inside episodes, and whole evaluations.
    # N robot processes (namespaced recipes) through one Zenoh router vs raw zenoh clients doing the same: time from
    # spawning them to an observer seeing all N components, each robot's delivered rate (of 100 Hz), router CPU.
    "fleet": [("discover_all", "s", "lower", "discover_s"),
              ("rate_per_robot", "msg/s", "higher", "msgs_per_s_per_robot"),
              ("router_cpu", "cores", "lower", "router_cpu")],
    "sim": [("steps_per_s", "steps/s", "higher", "steps_per_s"), ("episodes_per_s", "episodes/s", "higher",
                                                                   "episodes_per_s")],
}

#: Above this slowdown (framework cost / raw cost) a latency figure needs a profile note.
NOTE_THRESHOLD = 1.3


def _read(record: dict[str, Any], path: str) -> float | None:
    value: Any = record
    for key in path.split("."):
        if not isinstance(value, dict) or key not in value:
            return None  # a figure one mode has and the other has not (threads: framework only)
        value = value[key]
    return float(value)


def build_figures(records: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """One figure per (suite, transport, payload, metric), with the framework, raw and their ratio.

    A value is the median over rounds (a run may measure each pair several times). ``ratio`` is
    framework / raw as measured; ``slowdown`` is how many times costlier the framework is
    whichever way the metric points (the ratio for times, raw / framework for rates).
    """
    by_key: dict[tuple[str, str, str], dict[str, list[dict[str, Any]]]] = {}
    for r in records:
        by_key.setdefault((r["suite"], r["transport"], r["payload"]), {}).setdefault(r["mode"], []).append(r)
    figures = []
    for (suite, transport, payload), modes in by_key.items():
        for metric, unit, better, path in METRICS[suite]:
            fw_values = [v for r in modes.get("framework", []) if (v := _read(r, path)) is not None]
            raw_values = [v for r in modes.get("raw", []) if (v := _read(r, path)) is not None]
            if not fw_values and not raw_values:
                continue
            fw = statistics.median(fw_values) if fw_values else None
            raw = statistics.median(raw_values) if raw_values else None
            ratio = fw / raw if fw is not None and raw else None
            slowdown = None
            if ratio is not None and ratio > 0:
                slowdown = ratio if better == "lower" else 1.0 / ratio
            figures.append({"id": f"{suite}/{transport}/{payload}/{metric}", "suite": suite, "transport": transport,
                            "payload": payload, "metric": metric, "unit": unit, "better": better,
                            "framework": fw, "raw": raw, "ratio": ratio, "slowdown": slowdown,
                            "rounds": {mode: len(rs) for mode, rs in modes.items()}})
    return figures


def _fmt(value: float | None) -> str:
    if value is None:
        return "n/a"
    if value >= 100:
        return f"{value:,.0f}"
    if value >= 10:
        return f"{value:.1f}"
    return f"{value:.2f}"


def markdown_table(figures: list[dict[str, Any]], skipped: list[dict[str, str]]) -> str:
    """The summary: one row per figure; ratios over the threshold on latencies are starred."""
    lines = ["| figure | unit | framework | raw | framework / raw |", "|---|---|---:|---:|---:|"]
    for f in figures:
        ratio = "n/a" if f["ratio"] is None else f"{f['ratio']:.2f}"
        if f["suite"] == "hop" and f["slowdown"] is not None and f["slowdown"] > NOTE_THRESHOLD:
            ratio += " *"
        arrow = "lower is better" if f["better"] == "lower" else "higher is better"
        lines.append(f"| {f['id']} | {f['unit']} ({arrow}) | {_fmt(f['framework'])} | {_fmt(f['raw'])} | {ratio} |")
    lines.append("")
    lines.append(f"\\* latency ratio above {NOTE_THRESHOLD}: see the profile notes in benchmarks/README.md.")
    for s in skipped:
        lines.append(f"- skipped {s['suite']} on {s['transport']} ({s.get('mode', '')}): "
                     f"{s['reason'].strip().splitlines()[0] if s['reason'].strip() else 'no reason given'}")
    return "\n".join(lines)


# -- machine and versions -------------------------------------------------------------------------


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _memory_gib() -> float | None:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                return round(int(line.split()[1]) / 1024 / 1024, 1)
    except OSError:
        pass
    return None


def machine_info() -> dict[str, Any]:
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    return {"platform": platform.platform(), "machine": platform.machine(), "cpu": _cpu_model(),
            "cpu_count": os.cpu_count(), "memory_gib": _memory_gib(), "python": platform.python_version(),
            "loadavg_at_start": list(load) if load else None}


def versions() -> dict[str, str | None]:
    out: dict[str, str | None] = {}
    for dist in ("agents-core", "eclipse-zenoh", "msgpack", "numpy", "ros-jazzy-rclpy", "llama-cpp-python",
                 "sherpa-onnx", "matplotlib"):
        try:
            out[dist] = importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            out[dist] = None
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True,
                                timeout=10, check=False).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=REPO,
                               capture_output=True, text=True, timeout=10, check=False).stdout.strip()
        out["git_commit"] = (commit + ("+dirty" if dirty else "")) or None
    except (OSError, subprocess.SubprocessError):
        out["git_commit"] = None
    return out


# -- plot -----------------------------------------------------------------------------------------


def plot(figures: list[dict[str, Any]], records: list[dict[str, Any]], path: Path, title: str) -> None:
    """Left: the framework's slowdown per figure. Right: hop RTT medians, framework and raw (log scale)."""
    import matplotlib  # noqa: PLC0415  (optional: only for the plot)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    shown = [f for f in figures if f["slowdown"] is not None and f["metric"] not in ("mb_per_s",)]
    fig, (left, right) = plt.subplots(1, 2, figsize=(15, max(5.0, 0.32 * len(shown) + 1.5)),
                                      gridspec_kw={"width_ratios": [3, 2]})
    colors = {"hop": "tab:blue", "throughput": "tab:orange", "startup": "tab:green", "model": "tab:purple",
              "imports": "tab:brown", "vision": "tab:red", "voice": "tab:olive",
              "map": "tab:cyan", "processes": "tab:pink", "ui": "tab:gray", "goals": "tab:olive",
              "vla": "tab:brown", "cli": "tab:red", "memory": "tab:purple", "cortex": "tab:green",
              "e2e": "tab:orange"}
    labels = [f["id"] for f in shown]
    values = [f["slowdown"] for f in shown]
    y = list(range(len(shown)))
    # A suite without a colour of its own (a new one) is drawn in black rather than failing the run.
    left.barh(y, values, color=[colors.get(f["suite"], "black") for f in shown])
    left.set_yticks(y, labels, fontsize=8)
    left.invert_yaxis()
    left.set_xscale("log")
    left.axvline(1.0, color="black", linewidth=1)
    left.axvline(NOTE_THRESHOLD, color="grey", linestyle="--", linewidth=1)
    left.set_xlabel("framework cost / raw cost (x, log scale); 1 = as fast as the raw library")
    for yi, v in zip(y, values, strict=True):
        left.text(v, yi, f" {v:.2f}", va="center", fontsize=7)
    left.set_title("slowdown against the raw library (lower is better)")

    hops = [r for r in records if r["suite"] == "hop"]
    keys = sorted({(r["transport"], r["payload"]) for r in hops})
    width = 0.38
    for i, mode in enumerate(("raw", "framework")):
        medians = []
        for transport, payload in keys:
            match = [r["rtt"]["median_us"] for r in hops
                     if r["transport"] == transport and r["payload"] == payload and r["mode"] == mode]
            medians.append(statistics.median(match) if match else 0.0)
        right.bar([k + (i - 0.5) * width for k in range(len(keys))], medians, width, label=mode,
                  color="tab:grey" if mode == "raw" else "tab:blue")
    right.set_xticks(range(len(keys)), [f"{t}\n{p}" for t, p in keys], fontsize=8)
    right.set_yscale("log")
    right.set_ylabel("round trip, median (us, log scale)")
    right.set_title("hop latency: ping -> relay -> pong")
    right.legend()
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
