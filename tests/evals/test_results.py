"""Reading results directories back: the format of docs/evaluate.md, bounded reads, and clear errors for bad lines."""

from __future__ import annotations

import json
import os
import tracemalloc
from pathlib import Path
from typing import Any

import pytest

from agents_core.evals.results import ResultsError, ResultsLimits, load_results

from .results_dirs import episode, info, make_run, png, write_dir


def test_a_complete_run_reads_back_field_by_field(tmp_path: Path) -> None:
    out = make_run(tmp_path / "run", [True, False, True], seeds=[10, 11, 12])
    results = load_results(out)
    assert results.info.name == "reacher-expert" and results.info.world == "Reacher-v5"
    assert results.info.seeds == (10, 11, 12) and results.info.max_steps == 50 and results.info.max_wall_s == 60.0
    assert results.info.clock == "lockstep" and results.info.interrupted is False
    assert (results.n, results.successes, results.failed_seeds) == (3, 2, (11,))
    assert results.success_rate == pytest.approx(2 / 3)
    assert results.complete
    first = results.episodes[0]
    line = json.loads((out / "results.jsonl").read_text().splitlines()[0])
    assert (first.seed, first.success, first.steps, first.ended) == (10, True, 50, "success")
    assert first.reward_sum == line["reward_sum"] and list(first.rewards) == line["rewards"]
    assert first.time_to_success_s == line["time_to_success_s"] and first.steps_to_success == 30
    assert len(first.frames) == 4 and results.frame_file(first.frames[0]) == (out / first.frames[0]).resolve()


def test_episodes_come_back_in_episode_order_whatever_the_order_they_finished(tmp_path: Path) -> None:
    # Parallel episodes finish out of order.
    out = write_dir(tmp_path / "run", info(episodes=3), [episode(2, True), episode(0, False), episode(1, True)])
    assert [e.episode for e in load_results(out).episodes] == [0, 1, 2]


def test_an_interrupted_run_keeps_what_finished_and_drops_a_half_written_last_line(tmp_path: Path) -> None:
    whole = json.dumps(episode(2, True))
    out = write_dir(tmp_path / "run", info(episodes=5, finished=None, interrupted=True),
                    [episode(0, True), episode(1, False), whole[: len(whole) // 2]], newline_at_end=False)
    results = load_results(out)
    assert results.n == 2 and results.partial_last_line and not results.complete


def test_a_last_line_without_newline_that_is_whole_counts(tmp_path: Path) -> None:
    out = write_dir(tmp_path / "run", info(episodes=2), [episode(0, True), episode(1, True)], newline_at_end=False)
    results = load_results(out)
    assert results.n == 2 and not results.partial_last_line


def test_no_results_file_yet_is_no_episodes_and_blank_lines_are_skipped(tmp_path: Path) -> None:
    out = tmp_path / "run"
    out.mkdir()
    (out / "evaluation.json").write_text(json.dumps(info(finished=None)))
    assert load_results(out).n == 0
    write_dir(out, None, [episode(0, True), "", "   ", episode(1, False)])
    assert load_results(out).n == 2


def test_a_bad_line_in_the_middle_is_an_error_naming_file_and_line(tmp_path: Path) -> None:
    out = write_dir(tmp_path / "run", info(), [episode(0, True), '{"episode": 1, "seed": 1,', episode(2, True)])
    with pytest.raises(ResultsError, match=r"results\.jsonl, line 2: invalid JSON"):
        load_results(out)


def test_a_cut_line_in_the_middle_is_not_taken_for_an_interruption(tmp_path: Path) -> None:
    # Only the very last line may be cut short: one with a newline after it was written whole, then damaged.
    out = write_dir(tmp_path / "run", info(), [episode(0, True), '{"episode": 1', episode(2, True)],
                    newline_at_end=False)
    with pytest.raises(ResultsError, match=r"line 2"):
        load_results(out)


@pytest.mark.parametrize(("change", "message"), [
    ({"success": "yes"}, "field 'success' must be true or false, got str"),
    ({"success": 1}, "field 'success' must be true or false, got int"),
    ({"episode": -1}, "field 'episode' must be >= 0"),
    ({"episode": 1.5}, "field 'episode' must be an integer, got float"),
    ({"seed": True}, "field 'seed' must be an integer, got bool"),
    ({"steps": None}, "field 'steps' must be an integer, got null"),
    ({"reward_sum": "high"}, "field 'reward_sum' must be a number, got str"),
    ({"rewards": [0.1, "x"]}, r"field 'rewards\[1\]' must be a number, got str"),
    ({"rewards": {"a": 1}}, "field 'rewards' must be a list"),
    ({"frames": [3]}, r"field 'frames\[0\]' must be a string"),
    ({"ended": ""}, "field 'ended' must be a word"),
    ({"ended": "x" * 500}, "field 'ended' must be a word"),
    ({"reason": 42}, "field 'reason' must be a string or null, got int"),
    ({"time_to_success_s": "soon"}, "field 'time_to_success_s' must be a number"),
])
def test_a_field_of_the_wrong_type_is_an_error_naming_line_and_field(tmp_path: Path, change: dict[str, Any],
                                                                      message: str) -> None:
    out = write_dir(tmp_path / "run", info(), [episode(0, True), {**episode(1, True), **change}])
    with pytest.raises(ResultsError, match=r"results\.jsonl, line 2: " + message):
        load_results(out)


@pytest.mark.parametrize("field", ["episode", "seed", "success", "steps", "ended"])
def test_a_missing_field_is_named(tmp_path: Path, field: str) -> None:
    line = episode(0, True)
    del line[field]
    out = write_dir(tmp_path / "run", info(), [line])
    with pytest.raises(ResultsError, match=f"line 1: field '{field}' is missing"):
        load_results(out)


@pytest.mark.parametrize("line", ["[1, 2]", "42", '"text"', "null"])
def test_a_line_that_is_not_an_object(tmp_path: Path, line: str) -> None:
    out = write_dir(tmp_path / "run", info(), [line, episode(1, True)])
    with pytest.raises(ResultsError, match=r"line 1: expected a JSON object"):
        load_results(out)


def test_two_lines_of_one_episode_are_an_error(tmp_path: Path) -> None:
    out = write_dir(tmp_path / "run", info(), [episode(0, True), episode(1, True), episode(0, False)])
    with pytest.raises(ResultsError, match=r"line 3: episode 0 is already on line 1"):
        load_results(out)


def test_hostile_lines_are_refused_with_a_message(tmp_path: Path) -> None:
    nested = "[" * 100_000 + "]" * 100_000
    for bad in [nested.encode(), b'{"episode": 0, "seed": \xff\xfe}', b'{"episode": 1e999999}',
                b'{"episode": ' + b"9" * 400 + b"}"]:
        out = write_dir(tmp_path / "run", info(), [bad, episode(1, True)])
        with pytest.raises(ResultsError, match=r"line 1"):
            load_results(out)


def test_non_finite_rewards_are_accepted_as_what_the_env_returned(tmp_path: Path) -> None:
    out = write_dir(tmp_path / "run", info(), [
        '{"episode": 0, "seed": 0, "success": false, "reward_sum": NaN, "steps": 3, "time_to_success_s": null, '
        '"steps_to_success": null, "wall_s": 0.1, "ended": "error", "reason": "NaN observation", '
        '"rewards": [0.5, NaN, Infinity], "frames": []}'])
    first = load_results(out).episodes[0]
    assert first.reward_sum != first.reward_sum and first.rewards[2] == float("inf")
    assert first.reason == "NaN observation"


def test_a_line_too_long_is_refused_without_reading_it_whole(tmp_path: Path) -> None:
    out = write_dir(tmp_path / "run", info(), [])
    line_cap = 64 * 1024
    with (out / "results.jsonl").open("wb") as stream:  # 32 MiB and no newline at all
        stream.write(b'{"episode": 0, "reason": "' + b"x" * (32 * 1024 * 1024) + b'"}')
    tracemalloc.start()
    try:
        with pytest.raises(ResultsError, match=r"line 1 is longer than 65536 bytes \(ResultsLimits.max_line_bytes\)"):
            load_results(out, ResultsLimits(max_line_bytes=line_cap))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 16 * line_cap, peak


def test_too_many_lines_and_too_many_bytes_are_refused(tmp_path: Path) -> None:
    out = write_dir(tmp_path / "run", info(episodes=10), [episode(i, True) for i in range(10)])
    with pytest.raises(ResultsError, match=r"more than 5 lines \(ResultsLimits.max_lines\)"):
        load_results(out, ResultsLimits(max_lines=5))
    size = (out / "results.jsonl").stat().st_size
    with pytest.raises(ResultsError, match=r"larger than .* bytes \(ResultsLimits.max_total_bytes\)"):
        load_results(out, ResultsLimits(max_total_bytes=size // 2))
    assert load_results(out, ResultsLimits(max_lines=10, max_total_bytes=size)).n == 10


def test_evaluation_json_errors_name_the_file(tmp_path: Path) -> None:
    out = tmp_path / "run"
    out.mkdir()
    with pytest.raises(ResultsError, match=r"evaluation\.json does not exist"):
        load_results(out)
    with pytest.raises(ResultsError, match=r"is not a directory"):
        load_results(out / "nothing")
    (out / "evaluation.json").write_text("[1, 2]")
    with pytest.raises(ResultsError, match=r"evaluation\.json: expected a JSON object"):
        load_results(out)
    (out / "evaluation.json").write_text(json.dumps(info(interrupted="no")))
    with pytest.raises(ResultsError, match=r"evaluation\.json: field 'interrupted' must be true or false"):
        load_results(out)
    (out / "evaluation.json").write_text(json.dumps(info(seeds=[1, 2]) | {"seeds": [1, "two"]}))
    with pytest.raises(ResultsError, match=r"field 'seeds\[1\]' must be an integer"):
        load_results(out)
    (out / "evaluation.json").write_text(json.dumps(info(limits={"max_steps": "many"})))
    with pytest.raises(ResultsError, match=r"field 'limits\.max_steps' must be an integer"):
        load_results(out)
    (out / "evaluation.json").write_text(json.dumps(info(name="x" * 2000)))
    with pytest.raises(ResultsError, match=r"ResultsLimits.max_info_bytes"):
        load_results(out, ResultsLimits(max_info_bytes=1000))


def test_frame_paths_must_stay_inside_the_output_directory(tmp_path: Path) -> None:
    out = make_run(tmp_path / "run", [True])
    results = load_results(out)
    secret = tmp_path / "secret.png"
    secret.write_bytes(png(2, 2, lambda x, y: (1, 2, 3)))
    (out / "frames" / "link.png").symlink_to(secret)
    (out / "frames" / "loop.png").symlink_to(out / "frames" / "loop.png")
    for relative in ["../secret.png", str(secret), "frames/link.png", "frames/loop.png", "frames", "",
                     "frames/none.png", "frames/\x00.png"]:
        assert results.frame_file(relative) is None, relative
    assert results.frame_file("frames/../frames/ep0000_00.png") == (out / "frames" / "ep0000_00.png").resolve()
    assert os.path.isfile(out / "frames" / "link.png")  # the link itself works: it is refused for where it leads
