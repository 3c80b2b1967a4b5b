"""URDF files that used to slip past the reader's guards: other encodings, endless files, duplicates, signs."""

from __future__ import annotations

import os
import sys
import threading
import time
from pathlib import Path

import pytest

from agents_core.components.vla import urdf
from agents_core.components.vla.urdf import JointLimits, read_urdf_joint_limits
from agents_core.errors import ConfigError

# An entity that would set the joint's velocity limit: expanded, it turns a typo-free file's limit into 1e9.
ENTITY_URDF = ('<?xml version="1.0" encoding="UTF-16"?>\n<!DOCTYPE robot [<!ENTITY v "1e9">]>\n'
               '<robot name="r"><joint name="a" type="revolute">'
               '<limit lower="-1" upper="1" velocity="&v;"/></joint></robot>')
PLAIN = '<robot name="r"><joint name="a" type="revolute"><limit lower="-1" upper="1" velocity="2"/></joint></robot>'


def write(tmp_path: Path, data: bytes) -> Path:
    path = tmp_path / "robot.urdf"
    path.write_bytes(data)
    return path


@pytest.mark.parametrize("encoding", ["utf-16", "utf-16-le", "utf-16-be", "utf-32"])
def test_a_doctype_in_utf16_or_utf32_is_refused(tmp_path: Path, encoding: str) -> None:
    with pytest.raises(ConfigError, match="not UTF-8"):
        read_urdf_joint_limits(write(tmp_path, ENTITY_URDF.encode(encoding)))


def test_a_doctype_behind_a_utf8_bom_is_refused(tmp_path: Path) -> None:
    text = ENTITY_URDF.replace("UTF-16", "UTF-8")
    with pytest.raises(ConfigError, match="DOCTYPE"):
        read_urdf_joint_limits(write(tmp_path, text.encode("utf-8-sig")))


@pytest.mark.parametrize("declared", ["ISO-8859-1", "UTF-16", "cp037"])
def test_an_encoding_other_than_utf8_is_refused_by_name(tmp_path: Path, declared: str) -> None:
    data = f'<?xml version="1.0" encoding="{declared}"?>\n{PLAIN}'.encode()
    with pytest.raises(ConfigError, match=f"declares encoding '{declared}'"):
        read_urdf_joint_limits(write(tmp_path, data))


def test_utf8_files_with_or_without_a_declaration_or_bom_still_read(tmp_path: Path) -> None:
    expected = {"a": JointLimits(-1.0, 1.0, 2.0)}
    for data in (PLAIN.encode(), ('<?xml version="1.0" encoding="utf-8"?>' + PLAIN).encode("utf-8-sig"),
                 ("<?xml version='1.0' encoding='US-ASCII'?>" + PLAIN).encode()):
        assert read_urdf_joint_limits(write(tmp_path, data)) == expected


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
def test_dev_zero_is_refused_at_once() -> None:
    started = time.monotonic()
    with pytest.raises(ConfigError, match="not a regular file"):
        read_urdf_joint_limits("/dev/zero")
    assert time.monotonic() - started < 1.0


@pytest.mark.skipif(sys.platform == "win32", reason="FIFOs are POSIX")
def test_a_fifo_is_refused_without_waiting_for_a_writer(tmp_path: Path) -> None:
    fifo = tmp_path / "robot.urdf"
    os.mkfifo(fifo)
    outcome: list[BaseException] = []
    reader = threading.Thread(target=lambda: _capture(outcome, fifo), daemon=True)
    reader.start()
    reader.join(2.0)
    if reader.is_alive():  # the old reader blocks in open() until a writer comes: give it one, then fail
        with open(fifo, "wb") as writer:
            writer.write(b"<robot/>")
        reader.join(2.0)
        pytest.fail("reading a FIFO blocked waiting for a writer")
    assert len(outcome) == 1 and isinstance(outcome[0], ConfigError) and "not a regular file" in str(outcome[0])


def _capture(outcome: list[BaseException], path: Path) -> None:
    try:
        read_urdf_joint_limits(path)
    except BaseException as exc:  # handed to the test thread
        outcome.append(exc)


def test_a_file_over_the_bound_is_refused_reading_only_one_byte_more(tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(urdf, "MAX_URDF_BYTES", len(PLAIN) - 1)
    with pytest.raises(ConfigError, match=f"more than the {len(PLAIN) - 1} bytes allowed"):
        read_urdf_joint_limits(write(tmp_path, PLAIN.encode()))
    monkeypatch.setattr(urdf, "MAX_URDF_BYTES", len(PLAIN))
    assert read_urdf_joint_limits(write(tmp_path, PLAIN.encode())) == {"a": JointLimits(-1.0, 1.0, 2.0)}


def test_a_directory_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"not a regular file|cannot read URDF"):
        read_urdf_joint_limits(tmp_path)


def test_a_joint_declared_twice_is_refused_naming_it(tmp_path: Path) -> None:
    twice = ('<robot name="r">'
             '<joint name="elbow" type="revolute"><limit lower="-0.5" upper="0.5" velocity="1"/></joint>'
             '<joint name="elbow" type="revolute"><limit lower="-3" upper="3" velocity="9"/></joint></robot>')
    with pytest.raises(ConfigError, match="joint 'elbow' is declared twice"):
        read_urdf_joint_limits(write(tmp_path, twice.encode()))
    fixed_then_moving = ('<robot name="r"><joint name="j" type="fixed"/>'
                         '<joint name="j" type="continuous"/></robot>')
    with pytest.raises(ConfigError, match="joint 'j' is declared twice"):
        read_urdf_joint_limits(write(tmp_path, fixed_then_moving.encode()))


@pytest.mark.parametrize("velocity", ["-1", "-0.001", "-1e300"])
def test_a_negative_velocity_is_refused_naming_the_joint_and_field(tmp_path: Path, velocity: str) -> None:
    text = PLAIN.replace('velocity="2"', f'velocity="{velocity}"')
    with pytest.raises(ConfigError, match=r"joint 'a'.*limit velocity .* is negative"):
        read_urdf_joint_limits(write(tmp_path, text.encode()))


def test_a_zero_velocity_still_means_not_given(tmp_path: Path) -> None:
    text = PLAIN.replace('velocity="2"', 'velocity="0"')
    assert read_urdf_joint_limits(write(tmp_path, text.encode())) == {"a": JointLimits(-1.0, 1.0, None)}
