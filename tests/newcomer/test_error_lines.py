"""Items 7 and 8 of issue 38: a recipe that cannot start says so in one line, with the traceback only when asked
for (``AGENTS_DEBUG=1``, ``agentsctl run --debug``); a missing relative model path is "no such file", not a hub
id; with a process per component, a missing model file "failed to configure" (not "its process crashed ...
on_process_fail respawns crashed components")."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from agents_core.testing.helpers import free_tcp_port

RECIPE = Path(__file__).with_name("bad_model_recipe.py")
REPO = Path(__file__).resolve().parents[2]


def _run(tmp_path: Path, *args: str, **env: str) -> subprocess.CompletedProcess[str]:
    clean = {k: v for k, v in os.environ.items() if not k.startswith(("AGENTS_", "HF_"))}
    clean["PYTHONPATH"] = os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")])
    return subprocess.run([sys.executable, str(RECIPE), *args], cwd=tmp_path, capture_output=True, text=True,
                          timeout=120, check=False, env={**clean, "HF_HUB_OFFLINE": "1", **env})


def test_one_line_and_no_such_file(tmp_path: Path) -> None:
    done = _run(tmp_path, "memory")
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    assert f"no such file 'models/x.gguf' (relative to the current directory {tmp_path})" in done.stderr
    assert "hub" not in done.stderr.lower(), done.stderr
    said = [line for line in done.stderr.splitlines() if "no such file" in line]
    assert len(said) == 1, done.stderr  # the status line says it, the exit line does not repeat it
    assert done.stderr.rstrip().splitlines()[-1].startswith("agents: could not start (the reason is above; "
                                                           "AGENTS_DEBUG=1"), done.stderr


def test_a_with_block_says_one_line_too(tmp_path: Path) -> None:
    """The tutorial's ``with launcher:`` form: the error leaves the script uncaught; one line, not the traceback."""
    done = _run(tmp_path, "memory", "--with")
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr and "started" not in done.stdout, done.stderr
    assert len([line for line in done.stderr.splitlines() if "no such file 'models/x.gguf'" in line]) == 1
    assert done.stderr.rstrip().splitlines()[-1].startswith("agents: could not start (the reason is above; "
                                                           "AGENTS_DEBUG=1"), done.stderr
    loud = _run(tmp_path, "memory", "--with", AGENTS_DEBUG="1")
    assert loud.returncode == 1 and "Traceback (most recent call last)" in loud.stderr, loud.stderr
    assert "ConfigError: LocalLLM model: no such file" in loud.stderr


def test_only_a_reported_framework_error_is_shortened(monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """The uncaught-error hook: the one line for the error the status line showed; any other error (a bug, a
    framework error nobody reported) goes to the handler before it, with its traceback."""
    import sys  # noqa: PLC0415

    from agents_core.errors import ConfigError  # noqa: PLC0415
    from agents_core.launch import report, short_errors  # noqa: PLC0415

    passed_on: list[BaseException] = []
    interpreters = lambda kind, value, tb: passed_on.append(value)  # noqa: E731 - stands in for Python's handler
    monkeypatch.setattr(sys, "excepthook", interpreters)
    monkeypatch.setattr(sys, "__excepthook__", interpreters)  # it is the interpreter's: the one line in front of it
    monkeypatch.setattr(report, "_last_failure", ["✗ llm failed to configure: LocalLLM model: no such file 'x'"])
    monkeypatch.delenv("AGENTS_DEBUG", raising=False)
    short_errors.one_line_if_uncaught()
    installed = sys.excepthook
    short_errors.one_line_if_uncaught()
    assert sys.excepthook is installed  # once: not a hook in front of a hook
    reported, other, bug = ConfigError("LocalLLM model: no such file 'x'"), ConfigError("else"), KeyError("k")
    for exc in (reported, other, bug):
        sys.excepthook(type(exc), exc, None)
    assert passed_on == [other, bug]
    assert capsys.readouterr().err.startswith("agents: could not start (the reason is above; AGENTS_DEBUG=1")
    monkeypatch.setenv("AGENTS_DEBUG", "1")
    sys.excepthook(type(reported), reported, None)
    assert passed_on == [other, bug, reported]


def test_a_hook_of_the_users_gets_the_error_and_a_bug_keeps_its_traceback(tmp_path: Path) -> None:
    """Review s9 #4: a crash reporter's hook installed before the launch still sees the uncaught error; a bug in
    a component's own code (a KeyError wrapped in LifecycleError) keeps its file and line, in both forms."""
    hooked = _run(tmp_path, "memory", "--with", "--hook")
    assert hooked.returncode == 1, hooked.stderr
    assert "USER HOOK got ConfigError" in hooked.stderr, hooked.stderr
    for form in (("--with",), ()):
        bug = _run(tmp_path, "memory", "--bug", *form)
        assert bug.returncode == 1, bug.stderr
        assert "failed to configure: component 'buggy': configure failed: 'user_bug_key'" in bug.stderr
        assert 'print(settings["user_bug_key"])' in bug.stderr and "KeyError: 'user_bug_key'" in bug.stderr, form
        assert "could not start" not in bug.stderr, bug.stderr


def test_the_reason_must_be_the_one_reported_by_this_launch(monkeypatch: pytest.MonkeyPatch) -> None:
    """Review s9 #4: the reported reason is compared whole, not as a substring, and a new launch forgets it."""
    from agents_core.errors import ConfigError, LifecycleError  # noqa: PLC0415
    from agents_core.launch import report, short_errors  # noqa: PLC0415

    monkeypatch.setattr(report, "_last_failure", ["✗ llm failed to configure: LocalLLM model: no such file 'x'"])
    assert report.already_reported("LocalLLM model:  no such file 'x'")
    assert not report.already_reported("no such file 'x'") and not report.already_reported("LocalLLM")
    report.LaunchReport(quiet=True)
    assert not report.already_reported("LocalLLM model: no such file 'x'")
    try:
        try:
            {}["k"]
        except KeyError as exc:
            raise LifecycleError("configure failed: 'k'") from exc
    except LifecycleError as exc:
        wrapped = exc
    assert short_errors.caused_by_a_bug(wrapped)
    assert not short_errors.caused_by_a_bug(LifecycleError("x"))
    with pytest.raises(LifecycleError), short_errors.short_errors():
        raise wrapped
    with pytest.raises(SystemExit), short_errors.short_errors():
        raise ConfigError("a reason")


def test_the_traceback_when_asked_for(tmp_path: Path) -> None:
    done = _run(tmp_path, "memory", AGENTS_DEBUG="1")
    assert done.returncode != 0
    assert "Traceback (most recent call last)" in done.stderr
    assert "ConfigError: LocalLLM model: no such file" in done.stderr


def test_agentsctl_run_debug_shows_the_traceback(tmp_path: Path) -> None:
    pytest.importorskip("typer")
    clean = {k: v for k, v in os.environ.items() if not k.startswith(("AGENTS_", "HF_"))}
    clean["PYTHONPATH"] = os.pathsep.join([str(REPO / "src"), os.environ.get("PYTHONPATH", "")])
    quiet = subprocess.run([sys.executable, "-m", "agents_core.cli", "run", str(RECIPE), "memory"], cwd=tmp_path,
                           capture_output=True, text=True, timeout=120, check=False, env=clean)
    loud = subprocess.run([sys.executable, "-m", "agents_core.cli", "run", "--debug", str(RECIPE), "memory"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120, check=False, env=clean)
    assert quiet.returncode == 1 and "Traceback" not in quiet.stderr, quiet.stderr
    assert loud.returncode != 0 and "Traceback" in loud.stderr, loud.stderr


@pytest.mark.zenoh
def test_a_component_process_that_cannot_load_its_model_failed_to_configure(tmp_path: Path) -> None:
    pytest.importorskip("zenoh")
    done = _run(tmp_path, "zenoh", "--processes", AGENTS_ZENOH_PORT=str(free_tcp_port()))
    assert done.returncode == 1, done.stderr
    assert "failed to configure: ConfigError: LocalLLM model: no such file 'models/x.gguf'" in done.stderr
    assert "crashed" not in done.stderr and "on_process_fail" not in done.stderr, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
