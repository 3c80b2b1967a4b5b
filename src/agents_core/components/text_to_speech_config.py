"""``TextToSpeechConfig``: the settings of ``TextToSpeech`` (:mod:`agents_core.components.text_to_speech`), beside it.

Public as ``agents_core.config.TextToSpeechConfig`` (re-exported there on first use); importing this module
does not import the component.
"""

from __future__ import annotations

from attrs import define, field

from .. import base_validators
from ..config import AT_CONFIGURE, ModelComponentConfig

__all__ = ["TextToSpeechConfig"]


@define(kw_only=True)
class TextToSpeechConfig(ModelComponentConfig):
    """Settings of :class:`~agents_core.components.TextToSpeech`.

    :param play_on_device: also play the speech on a local sound device (needs the ``voice``
        extra's ``sounddevice`` and a device; a clear error at configure otherwise).
    :param device: the output device (index or name) for playback (None: the default device).
    :param stream: speak StreamingString input sentence by sentence as it arrives (off: wait for
        the stream's last chunk and speak the whole text).
    :param interrupt: a new utterance stops the one being spoken (False: it is queued).
    :param max_text_chars: longer text is refused with an error (synthesis time grows with it).
    :param max_queue: the most sentences waiting to be spoken; beyond it the oldest are dropped, counted.
    :param speaker_id: the speaker of multi-speaker voices.
    :param speed: speaking rate (1.0: the voice's own).
    :param chunk_ms: the length of each published Audio message (ms).
    :param first_clause_words: speak an utterance's first clause on its own, as soon as it is complete
        (ends at , ; or :), when it has at least this many words, so speech starts before the first
        sentence ends; shorter first clauses wait for the sentence (0: whole sentences only).
    :param data_dir: the espeak-ng data directory the voice phonemizes with (None: found in the
        ``voice-gpl`` extra's ``espeakng-loader`` package when installed).
    """

    play_on_device: bool = field(default=False, metadata=AT_CONFIGURE)
    device: int | str | None = field(default=None, metadata=AT_CONFIGURE)
    stream: bool = field(default=True)
    interrupt: bool = field(default=True)
    max_text_chars: int = field(default=10_000, validator=base_validators.in_range(1, 10_000_000))
    max_queue: int = field(default=100, validator=base_validators.in_range(1, 100_000))
    speaker_id: int = field(default=0, validator=base_validators.in_range(0, 100_000))
    speed: float = field(default=1.0, validator=base_validators.in_range(0.25, 4.0))
    chunk_ms: int = field(default=100, validator=base_validators.in_range(10, 10_000))
    first_clause_words: int = field(default=4, validator=base_validators.in_range(0, 1000))
    data_dir: str | None = field(default=None, validator=base_validators.optional_str, metadata=AT_CONFIGURE)
    ncpu_local_model: int = field(default=2, validator=base_validators.gt(0), metadata=AT_CONFIGURE)

