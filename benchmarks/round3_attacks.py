"""The attacks of issue 36 beyond Memory (items 5-11), each repeated by its test in a fresh process.

``python -m benchmarks.round3_attacks [--only SUBSTRING]`` runs, one at a time, the test that performs
each attack (``python -m pytest NODE -s``) and prints a Markdown table: the attack, the peak RSS of
the largest process of its run (``wait4``: the pytest process or a child it started and reaped, such
as the Foxglove bridge or the recorder; a pytest process alone is ~100-150 MB), the wall time, the
outcome (passed: the attack is refused as the issue asks) and the figures the test printed.
The Memory attacks (items 1-4 and Memory's part of 11) are ``benchmarks.memory_attacks``.
Run from the repository root with the code under test on ``PYTHONPATH``. Not a speed figure.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_SEC = "tests/security/"
_FOX = "tests/foxglove/test_foxglove_guard.py::"

#: (issue item and attack, pytest node id)
ATTACKS: list[tuple[str, str]] = [
    ("5 Foxglove: 20 stalled clients on a 640x480 camera (memory)",
     _FOX + "test_twenty_clients_that_stop_reading_do_not_grow_the_recipe[memory]"),
    ("5 Foxglove: 20 stalled clients (Zenoh)",
     _FOX + "test_twenty_clients_that_stop_reading_do_not_grow_the_recipe[zenoh]"),
    ("5 Foxglove: WebSocket with Origin http://evil.example (Zenoh)",
     _FOX + "test_a_web_pages_origin_gets_no_frame[zenoh]"),
    ("5 Foxglove: 200 unfinished HTTP upgrades (Zenoh)",
     _FOX + "test_connections_that_never_finish_the_upgrade_are_closed[zenoh]"),
    ("5 Foxglove: clients past max_clients (Zenoh)", _FOX + "test_clients_past_max_clients_are_refused[zenoh]"),
    ("6 Vision: 8 record_video calls from a peer (Zenoh)",
     _SEC + "test_vision_recordings.py::test_recordings_past_the_bound_are_refused_with_a_clear_error[zenoh]"),
    ("6 Vision: save_path=/etc (Zenoh)",
     _SEC + "test_vision_recordings.py::test_a_save_path_outside_the_configured_folder_is_refused[zenoh-/etc]"),
    ("7 OpenAI-compatible client: 199 KB gzip -> 200 MiB",
     _SEC + "test_reply_bombs.py::test_openai_compatible_client_refuses_a_gzip_bomb[False]"),
    ("7 OpenAI-compatible client: the same as a stream",
     _SEC + "test_reply_bombs.py::test_openai_compatible_client_refuses_a_gzip_bomb[True]"),
    ("7 Ollama client: gzip bomb", _SEC + "test_reply_bombs.py::test_ollama_client_refuses_a_gzip_bomb[False]"),
    ("7 RoboML HTTP client: gzip bomb",
     _SEC + "test_reply_bombs.py::test_roboml_http_client_refuses_a_gzip_bomb[False]"),
    ("7 RoboML WebSocket: endless split reply",
     _SEC + "test_reply_bombs.py::test_roboml_ws_client_bounds_split_and_streamed_replies[split]"),
    ("8 Reader: 1,000,000 channels of an unknown type",
     _SEC + "test_recording_round3.py::test_a_million_unknown_channels_cost_little_to_read"),
    ("9 Recorder: file size limit hit, then lifted (EFBIG)",
     _SEC + "test_recording_round3.py::test_the_recorder_survives_a_failing_disk_and_resumes_when_it_recovers[efbig]"),
    ("9 Recorder: a full tmpfs, then freed (ENOSPC)",
     _SEC + "test_recording_round3.py::test_the_recorder_survives_a_failing_disk_and_resumes_when_it_recovers[enospc]"),
    ("10 Cortex: goal never ends, CONTINUE forever (task_timeout=2 s, Zenoh)",
     _SEC + "test_cortex_round3.py::test_a_task_that_never_ends_is_cut_at_task_timeout[zenoh]"),
    ("10 Cortex: CONTINUE forever (max_confirmation_rounds=5, Zenoh)",
     _SEC + "test_cortex_round3.py::test_confirmation_rounds_are_bounded[zenoh]"),
    ("11 Cortex: malformed describe reply from a peer (Zenoh)",
     _SEC + "test_cortex_round3.py::test_a_malformed_describe_reply_leaves_the_peer_out[zenoh-actions_str]"),
    ("11 Cortex: a stranger's actions not offered (Zenoh)",
     _SEC + "test_cortex_round3.py::test_only_the_recipes_components_are_offered_by_default[zenoh]"),
    ("11 Cortex: invented argument on an empty schema (Zenoh)",
     _SEC + "test_cortex_round3.py::test_an_empty_schema_refuses_invented_arguments[zenoh]"),
    ("11 Cortex: injection in a tool result (Zenoh)",
     _SEC + "test_cortex_round3.py::test_tool_results_reach_the_planner_as_data_from_a_named_source[zenoh]"),
    ("11 Cortex: injection in a goal result (Zenoh)",
     _SEC + "test_cortex_round3.py::test_a_goal_result_reaches_the_confirmation_model_as_data[zenoh]"),
    ("11 Player: a channel conflicting with the live recipe (Zenoh)",
     _SEC + "test_recording_round3.py::test_a_channel_conflicting_with_the_live_recipe_is_skipped_and_counted[zenoh]"),
    ("11 Player: timestamps past 2**63 ns and a 31-year jump",
     _SEC + "test_recording_round3.py::test_impossible_timestamps_are_refused_and_a_jump_is_not_waited_for"),
    ("11 Processes: component SIGSTOPped, launcher SIGKILLed",
     _SEC + "test_component_processes.py::test_a_stopped_component_process_ends_when_its_launcher_is_killed"),
    ("11 Processes: what a component starts, clean stop",
     _SEC + "test_component_processes.py::test_what_a_component_starts_ends_with_a_clean_stop"),
    ("11 Processes: what a component starts, component SIGKILLed",
     _SEC + "test_component_processes.py::test_what_a_component_starts_ends_when_the_component_is_killed_outright"),
    ("11 UI: login token with a lone surrogate",
     _SEC + "test_ui_tokens_forwarded.py::test_a_lone_surrogate_token_is_a_clean_401"),
    ("11 UI: X-Forwarded-For to dodge the throttle",
     _SEC + "test_ui_tokens_forwarded.py::test_x_forwarded_for_does_not_dodge_the_throttle"),
    ("11 UI: X-Forwarded-For to lock another address out",
     _SEC + "test_ui_tokens_forwarded.py::test_x_forwarded_for_cannot_lock_another_address_out"),
]

_NOISE = re.compile(r"^(=+|-+|\s*$|\d+ (passed|failed)|FAILED|PASSED|SKIPPED|ERROR|[.sFE]+$|rootdir|platform|plugins|"
                    r"collected|cachedir|configfile)")


def measure(node: str, limit_s: float = 300.0) -> tuple[float, float, str, list[str]]:
    """Run one test node in a fresh pytest process: (peak RSS MB, seconds, outcome, lines it printed)."""
    start = time.monotonic()
    proc = subprocess.Popen([sys.executable, "-m", "pytest", node, "-q", "-s", "-p", "no:cacheprovider"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    timer = threading.Timer(limit_s, proc.kill)  # a hung attack is ended, and says so
    timer.start()
    assert proc.stdout is not None
    out = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)  # reaped here: the peak of it and what it reaped
    timer.cancel()
    seconds = time.monotonic() - start
    code = os.waitstatus_to_exitcode(status)
    outcome = {0: "passed", 1: "FAILED", 5: "not collected"}.get(code, f"exit {code}")
    if " skipped" in out and code == 0 and " passed" not in out:
        outcome = "skipped"
    said = [line.lstrip(".") for line in out.splitlines() if not _NOISE.match(line.lstrip(".")) and line.strip(".")]
    return usage.ru_maxrss / 1024, seconds, outcome, said[:3]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--only", default="", help="run the attacks whose label holds this text")
    args = parser.parse_args()
    print("| attack | peak RSS MB | time s | outcome | what the test measured |\n|---|---|---|---|---|")
    for label, node in ATTACKS:
        if args.only not in label:
            continue
        rss, seconds, outcome, said = measure(node)
        print(f"| {label} | {rss:.0f} | {seconds:.1f} | {outcome} | {'; '.join(said)[:300]} |", flush=True)


if __name__ == "__main__":
    main()
