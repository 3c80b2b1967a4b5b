"""``agentsctl record`` and ``agentsctl play``: MCAP recordings of a live graph on Zenoh or ROS 2."""

from __future__ import annotations

import signal
import sys
import threading
import time
from pathlib import Path
from typing import Annotated, Any

import typer

from ..errors import ConfigError
from ..transport.requests import MAX_TIMEOUT_S
from .connection import one_line_errors, open_transport
from .output import print_json, say
from .topics import ConnectOpt, JsonOpt, TransportOpt, _topic_name

__all__ = ["play", "record"]

#: ``record`` with no --duration stops by itself after this long (a forgotten recorder must end).
MAX_RECORD_S = 7 * 24 * 3600.0


def _stop_on_signals(stop: threading.Event) -> None:
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())


@one_line_errors
def record(output: Annotated[Path, typer.Argument(help="the MCAP file to write (split files get _1, _2, ...)")],
           topics: Annotated[list[str] | None, typer.Option(
               "--topic", "-T", help="a topic to record (repeatable; default: every topic discovered)")] = None,
           transport: TransportOpt = None, connect: ConnectOpt = None, json_out: JsonOpt = False,
           duration: Annotated[float | None, typer.Option("--duration", "-d", help="stop after this many seconds",
                                                          min=0.01, max=MAX_RECORD_S)] = None,
           max_file_mb: Annotated[float | None, typer.Option("--max-file-mb", help="start a new file past this size",
                                                             min=0.001)] = None,
           max_total_mb: Annotated[float | None, typer.Option("--max-total-mb", help="stop recording past this size",
                                                              min=0.001)] = None,
           no_status: Annotated[bool, typer.Option("--no-status", help="leave the components' status topics "
                                                                       "out")] = False,
           encoding: Annotated[str, typer.Option("--encoding", help="cdr (ROS 2 CDR where a type has a ROS form) "
                                                                    "or msgpack")] = "cdr",
           compression: Annotated[str, typer.Option("--compression", help="each chunk's compression: lz4, zstd "
                                                                          "(smaller, more CPU) or none")] = "lz4",
           ) -> None:
    """Record topics of a running recipe into MCAP until Ctrl-C, SIGTERM or --duration."""
    from ..recording import Recorder, RecordingLimits  # noqa: PLC0415 - needs the record extra only here

    if encoding not in ("cdr", "msgpack"):
        raise ConfigError(f"unknown encoding {encoding!r}; use cdr or msgpack")
    if compression not in ("lz4", "zstd", "none"):
        raise ConfigError(f"unknown compression {compression!r}; use lz4, zstd or none")
    limits = RecordingLimits(max_file_bytes=None if max_file_mb is None else int(max_file_mb * 2**20),
                             max_total_bytes=None if max_total_mb is None else int(max_total_mb * 2**20))
    names = [_topic_name(t) for t in topics] if topics else None
    stop = threading.Event()
    _stop_on_signals(stop)
    with open_transport(transport, connect) as t:
        recorder = Recorder(t, output, topics=names, include_status=not no_status, limits=limits,
                            encoding=encoding, compression=compression)  # type: ignore[arg-type]  # checked above
        recorder.start()
        if not json_out:
            say(f"recording to {output} (Ctrl-C to stop)")
        sys.stdout.flush()
        stop.wait(duration if duration is not None else MAX_RECORD_S)
        stats = recorder.stop()
    doc: dict[str, Any] = {"files": [str(f) for f in stats.files], "topics": stats.topics, "written": stats.written,
                           "dropped": stats.dropped, "oversize": stats.oversize, "over_limit": stats.over_limit,
                           "errors": stats.errors}
    if json_out:
        print_json(doc)
    else:
        say(f"wrote {stats.written} messages on {len(stats.topics)} topics to {', '.join(doc['files']) or '-'} "
            f"(dropped {stats.dropped}, oversize {stats.oversize}, over limit {stats.over_limit})")


@one_line_errors
def play(recording: Annotated[Path, typer.Argument(help="the MCAP file to play")],
         transport: TransportOpt = None, connect: ConnectOpt = None, json_out: JsonOpt = False,
         rate: Annotated[float, typer.Option("--rate", "-r", help="speed against the recording (0: as fast as "
                                                                  "possible)", min=0.0)] = 1.0,
         remap: Annotated[list[str] | None, typer.Option(
             "--remap", help="OLD:=NEW, publish recorded topic OLD on NEW (repeatable)")] = None,
         topics: Annotated[list[str] | None, typer.Option("--topic", "-T", help="play only this topic "
                                                                                "(repeatable)")] = None,
         loop: Annotated[bool, typer.Option("--loop", help="start again at the end, until Ctrl-C")] = False,
         step: Annotated[bool, typer.Option("--step", help="publish one message per line read on stdin")] = False,
         wait: Annotated[float, typer.Option("--wait", help="seconds to let discovery connect first", min=0.0,
                                             max=MAX_TIMEOUT_S)] = 1.0,
         ) -> None:
    """Publish a recording into a running recipe, at the recorded pace, faster, or one message at a time."""
    from ..recording import Player  # noqa: PLC0415

    mapping: dict[str, str] = {}
    for item in remap or []:
        old, sep, new = item.partition(":=")
        if not sep or not old or not new:
            raise ConfigError(f"--remap {item!r}: expected OLD:=NEW")
        mapping[_topic_name(old)] = _topic_name(new)
    chosen = [_topic_name(t) for t in topics] if topics else None
    with open_transport(transport, connect) as t, \
            Player(t, recording, rate=rate or None, remap=mapping, topics=chosen, loop=loop) as player:
        signal.signal(signal.SIGINT, lambda *_: player.stop())
        signal.signal(signal.SIGTERM, lambda *_: player.stop())
        time.sleep(wait)
        if step:
            while sys.stdin.readline() and (message := player.step()) is not None:
                say(f"{message.topic} ({message.msg_type.type_name()})")
            stats = player.stats
        else:
            stats = player.play()
        time.sleep(0.2)  # let a networked middleware flush before the session closes
    doc = {"published": stats.published, "per_topic": stats.per_topic, "truncated": stats.read.truncated,
           "decode_errors": stats.read.decode_errors, "skipped_channels": stats.read.skipped_channels,
           "skipped_channel_count": stats.read.skipped_channel_count,
           "p99_lateness_s": stats.p99_lateness_s}
    if json_out:
        print_json(doc)
    else:
        say(f"published {stats.published} messages" + (" (the file ends early: truncated)" if
                                                        stats.read.truncated else ""))
