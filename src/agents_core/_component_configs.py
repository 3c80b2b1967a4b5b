"""The configs of the model, map and video components, defined on first use of their names.

Public under :mod:`agents_core.config` (``from agents_core.config import LLMConfig``), which reads
them from here lazily: generating these attrs classes is most of what importing the config
module cost, and a recipe that only relays topics (``from agents_core.ros import Topic,
Launcher, String``) needs none of them. Import them from :mod:`agents_core.config`.
"""

from __future__ import annotations

from typing import Any, Literal

import attrs
from attrs import define, field

from . import base_validators
from .config import AT_CONFIGURE, BaseComponentConfig, ModelComponentConfig
from .errors import ConfigError

__all__ = [
    "LLMConfig",
    "MLLMConfig",
    "MapConfig",
    "SemanticRouterConfig",
    "SpeechToTextConfig",
    "TextToSpeechConfig",
    "VLAConfig",
    "VLMConfig",
    "VideoMessageMakerConfig",
    "VisionConfig",
]


def _optional_str(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    if value is not None and not isinstance(value, str):
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must be a str or None, got {value!r}")


def _non_empty(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    if not isinstance(value, str) or not value:
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must be a non-empty str, got {value!r}")


def _mcp_servers(instance: Any, attribute: Any, value: Any) -> None:
    if not isinstance(value, list):
        raise ConfigError(f"{type(instance).__name__}.mcp_servers: expected a list of MCP servers, got {value!r}")
    if value:
        from .mcp.client import server_spec  # noqa: PLC0415  (checked where given: a bad entry fails early)

        for entry in value:
            server_spec(entry)


@define(kw_only=True)
class LLMConfig(ModelComponentConfig):
    """Settings of the :class:`~agents_core.components.llm.LLM` component.

    :param system_prompt: the first message of every conversation (None: none).
    :param chat_history: keep the conversation between steps.
    :param history_size: how many past messages (user and assistant) the history keeps.
    :param history_reset_phrase: a query equal to this (case-insensitive) clears the history; the
        system prompt stays.
    :param temperature: sampling temperature.
    :param max_new_tokens: the most tokens one answer may have.
    :param stream: publish the answer while it is generated: chunk by chunk on StreamingString
        outputs, sentence by sentence (split at ``break_character``) on String outputs.
    :param break_character: where a streamed answer is cut for String outputs.
    :param strip_think_tokens: remove ``<think>...</think>`` blocks (reasoning models) from answers.
    :param max_tool_rounds: the most model calls in one step when the model keeps calling tools.
    :param enable_rag: look up the query in the component's vector database and give the model
        the ``n_results`` closest documents as context.
    :param collection_name: the database collection used for RAG.
    :param distance_func: ``"l2"``, ``"cosine"`` or ``"ip"``: the metric of the RAG collection when
        ``add_documents`` creates it (an existing collection keeps its own).
    :param n_results: how many documents RAG adds.
    :param add_metadata: also give the model the documents' metadata.
    :param mcp_servers: MCP servers whose tools the model may call (the ``mcp`` extra): each a URL
        (Streamable HTTP), a command line as a list (stdio) or a mapping of
        :class:`agents_core.mcp.client.McpServerSpec` fields (``allow``, ``limits``, ``approval``, ...).
    """

    system_prompt: str | None = field(default=None, validator=_optional_str)
    chat_history: bool = field(default=False)
    history_size: int = field(default=10, validator=base_validators.in_range(2, 10_000))
    history_reset_phrase: str = field(default="chat reset", validator=_non_empty)
    temperature: float = field(default=0.8, validator=base_validators.in_range(0.0, 2.0))
    max_new_tokens: int = field(default=500, validator=base_validators.in_range(1, 1_000_000))
    mcp_servers: list[Any] = field(factory=list, validator=_mcp_servers)
    stream: bool = field(default=False)
    break_character: str = field(default=".", validator=_non_empty)
    strip_think_tokens: bool = field(default=True)
    max_tool_rounds: int = field(default=5, validator=base_validators.in_range(1, 100))
    enable_rag: bool = field(default=False)
    collection_name: str | None = field(default=None, validator=_optional_str)
    distance_func: str = field(default="l2", validator=base_validators.in_(["l2", "cosine", "ip"]))
    n_results: int = field(default=1, validator=base_validators.in_range(1, 1000))
    add_metadata: bool = field(default=False)

    def _get_inference_params(self) -> dict[str, Any]:
        return {"temperature": self.temperature, "max_new_tokens": self.max_new_tokens, "stream": self.stream}


@define(kw_only=True)
class MLLMConfig(LLMConfig):
    """Settings of the :class:`~agents_core.components.mllm.MLLM` (VLM) component.

    :param task: ``"general"`` (text answers), or a structured task whose answer is parsed into a
        typed output: ``"grounding"`` (boxes → Detections), ``"pointing"`` (points →
        PointsOfInterest), ``"affordance"`` (boxes of where to act → Detections), ``"trajectory"``
        (an ordered path of points → PointsOfInterest).
    :param local_mmproj_path: the local VLM's projector file, when it is not beside the model.
    """

    task: str = field(default="general", validator=base_validators.in_(
        ["general", "grounding", "pointing", "affordance", "trajectory"]))
    local_mmproj_path: str | None = field(default=None, validator=_optional_str, metadata=AT_CONFIGURE)


#: The upstream name of the same configuration.
VLMConfig = MLLMConfig


@define(kw_only=True)
class SemanticRouterConfig(ModelComponentConfig):
    """Settings of the :class:`~agents_core.components.semantic_router.SemanticRouter`.

    :param router_name: names the collection of route samples in the vector database.
    :param distance_func: the database's distance, ``"l2"``, ``"cosine"`` or ``"ip"``.
    :param maximum_distance: in vector mode, a query farther than this from every route's samples
        goes to the default route.
    :param enable_local_model: in LLM mode, choose routes with the built-in local LLM.
    """

    router_name: str = field(default="semantic_router", validator=_non_empty, metadata=AT_CONFIGURE)
    distance_func: str = field(default="l2", validator=base_validators.in_(["l2", "cosine", "ip"]),
                               metadata=AT_CONFIGURE)
    maximum_distance: float = field(default=0.4, validator=base_validators.gt(0.0))


def _optional_labels(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    if value is None:
        return
    ok = (isinstance(value, list) and all(isinstance(v, str) for v in value)) or (
        isinstance(value, dict) and all(isinstance(k, int) and not isinstance(k, bool) and isinstance(v, str)
                                        for k, v in value.items()))
    if not ok:
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must be None, a list of str or a dict "
                          f"int -> str, got {value!r:.200}")


def _optional_str_list(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    if value is not None and not (isinstance(value, list) and all(isinstance(v, str) and v for v in value)):
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must be None or a list of non-empty str, "
                          f"got {value!r:.200}")


@define(kw_only=True)
class MapConfig(BaseComponentConfig):
    """Settings of the :class:`~agents_core.components.map_encoding.MapEncoding` component.

    :param map_name: the vector database collection the map is written to.
    :param distance_func: the collection's distance, ``"l2"``, ``"cosine"`` or ``"ip"`` (for a new one).
    :param position_timeout: a layer value is only placed on the map when the robot's position arrived at
        most this many seconds before it; older (or no) position: the value is dropped and counted.
    :param map_wait_timeout: how long (s) configure waits for the first grid map (default 0: do not wait,
        as upstream, which reads the map at each step).
    :param require_map: without a map after that wait, configure fails (True) or the component starts
        and drops values (counted as ``no_map``) until a map arrives (False, the default).
    :param buffer_size: the most values kept while the database cannot be written to; when it is full
        the oldest value is dropped (counted).
    """

    map_name: str = field(default="map", validator=_non_empty, metadata=AT_CONFIGURE)
    distance_func: str = field(default="cosine", validator=base_validators.in_(["l2", "cosine", "ip"]),
                               metadata=AT_CONFIGURE)
    position_timeout: float = field(default=2.0, validator=base_validators.gt(0.0))
    map_wait_timeout: float = field(default=0.0, validator=base_validators.in_range(0.0, 3600.0))
    require_map: bool = field(default=False)
    buffer_size: int = field(default=1000, validator=base_validators.in_range(1, 10_000_000))


@define(kw_only=True)
class VisionConfig(ModelComponentConfig):
    """Settings of the :class:`~agents_core.components.vision.Vision` component.

    :param threshold: minimum score of a published detection.
    :param nms_threshold: the local model's non-maximum suppression IoU (same-class boxes overlapping more
        than this are merged into the best one).
    :param get_dataset_labels: publish class names (False: class ids as text).
    :param labels_to_track: the labels Trackings outputs follow (None: every label); the ``track``
        action changes it at run time.
    :param enable_visualization: publish each frame with its boxes and labels drawn on the Image output.
    :param include_image: put the input image into every Detections / Trackings message.
    :param max_image_side: frames larger than this (pixels, either side) are refused with an error.
    :param tracking_max_age: seconds a tracked object may go unseen and keep its id when it reappears.
    :param tracking_iou_threshold: minimum overlap of a detection with a track's predicted box to continue it.
    :param input_height, input_width: the local model's input size, when the model file does not fix it.
    :param dataset_labels: class names of the local model (a list in class order, or id -> name);
        None: from a labels file beside the model, the model's metadata, or COCO.
    :param dataset_labels_file: a labels file for the local model (see
        :func:`~agents_core.engines.local_vision.read_labels_file`).
    :param recordings_dir: the folder ``record_video`` and ``take_picture`` save into; a ``save_path``
        they are given must lie inside it (a relative one is taken inside it), else refused.
    :param max_recordings: ``record_video`` recordings running at once; one more is refused.
    :param max_recording_bytes: the pixel bytes one recording may keep before it stops early.
    :param enable_local_classifier: upstream's name of ``enable_local_model`` for Vision: True turns
        it on (and reads back whether the local detector is enabled).
    """

    threshold: float = field(default=0.5, validator=base_validators.in_range(0.0, 1.0))
    nms_threshold: float = field(default=0.5, validator=base_validators.in_range(0.0, 1.0), metadata=AT_CONFIGURE)
    get_dataset_labels: bool = field(default=True)
    labels_to_track: list[str] | None = field(default=None, validator=_optional_str_list)
    enable_visualization: bool = field(default=False, metadata=AT_CONFIGURE)
    include_image: bool = field(default=False)
    max_image_side: int = field(default=4096, validator=base_validators.in_range(1, 1 << 20))
    tracking_max_age: float = field(default=1.0, validator=base_validators.in_range(0.0, 3600.0))
    tracking_iou_threshold: float = field(default=0.2, validator=base_validators.in_range(0.0, 1.0))
    input_height: int = field(default=640, validator=base_validators.in_range(1, 8192), metadata=AT_CONFIGURE)
    input_width: int = field(default=640, validator=base_validators.in_range(1, 8192), metadata=AT_CONFIGURE)
    dataset_labels: list[str] | dict[int, str] | None = field(default=None, validator=_optional_labels,
                                                              metadata=AT_CONFIGURE)
    dataset_labels_file: str | None = field(default=None, validator=_optional_str, metadata=AT_CONFIGURE)
    enable_local_classifier: bool = field(default=False, metadata=AT_CONFIGURE)
    recordings_dir: str = field(default="~/emos/videos", validator=_non_empty)
    max_recordings: int = field(default=2, validator=base_validators.in_range(1, 64))
    max_recording_bytes: int = field(default=268_435_456, validator=base_validators.in_range(1, 1 << 40))  # 256 MiB

    def __attrs_post_init__(self) -> None:
        # One setting under two names: either turns the local detector on, both read the same afterwards.
        self.enable_local_model = self.enable_local_classifier = self.enable_local_model or self.enable_local_classifier

    def _get_inference_params(self) -> dict[str, Any]:
        params: dict[str, Any] = {"threshold": self.threshold, "get_dataset_labels": self.get_dataset_labels}
        if self.labels_to_track:
            params["labels_to_track"] = list(self.labels_to_track)
        return params


def _video_frames_order(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    low = value if attribute.name == "min_video_frames" else getattr(instance, "min_video_frames", 1)
    high = value if attribute.name == "max_video_frames" else getattr(instance, "max_video_frames", low)
    if low > high:
        raise ConfigError(f"{type(instance).__name__}: min_video_frames ({low}) must not exceed "
                          f"max_video_frames ({high})")


@define(kw_only=True)
class VideoMessageMakerConfig(BaseComponentConfig):
    """Settings of the :class:`~agents_core.components.video_maker.VideoMessageMaker` component.

    :param min_video_frames: a clip with fewer frames when the motion stops is dropped.
    :param max_video_frames: a clip is published when it reaches this many frames (a new one starts).
    :param motion_estimation_func: ``"frame_difference"`` (a frame moves when it differs enough from
        the previous one), or None (every frame counts as motion: clips of ``max_video_frames``).
    :param threshold: percent of the pixels that must change for a frame to count as motion.
    :param pixel_threshold: how much (grey levels, 0..255) a pixel must change to count as changed.
    :param max_still_frames: still frames a clip may contain before it ends (they stay in the clip).
    """

    min_video_frames: int = field(default=15, validator=[base_validators.in_range(1, 100_000), _video_frames_order])
    max_video_frames: int = field(default=600, validator=[base_validators.in_range(1, 100_000), _video_frames_order])
    motion_estimation_func: Literal["frame_difference"] | None = field(
        default="frame_difference", validator=base_validators.in_(["frame_difference", None]))
    threshold: float = field(default=0.5, validator=base_validators.in_range(0.0, 100.0))
    pixel_threshold: int = field(default=25, validator=base_validators.in_range(1, 255))
    max_still_frames: int = field(default=3, validator=base_validators.in_range(0, 100_000))


@define(kw_only=True)
class SpeechToTextConfig(ModelComponentConfig):
    """Settings of :class:`~agents_core.components.SpeechToText`.

    :param enable_vad: cut the incoming audio stream into utterances with Silero VAD (each becomes
        one transcript); off: every Audio message is one utterance. None (default): on when a
        ``vad_model_path`` is given, else off (upstream's default).
    :param vad_threshold: speech probability above which audio counts as speech.
    :param min_silence_duration_ms: the silence that ends an utterance.
    :param min_speech_duration_ms: shorter bursts (a click, a cough) are not utterances.
    :param max_speech_duration_s: an utterance is cut (and transcribed) when it gets this long.
    :param vad_model_path: the ``silero_vad.onnx`` file (None: the one shipped by the PyPI package
        ``silero-vad``, installed with ``--no-deps``).
    :param enable_wakeword: transcribe only the utterance that follows a wake word (needs enable_vad).
    :param wakeword_model: a built-in microWakeWord model (``"hey_jarvis"``, ``"alexa"``,
        ``"okay_nabu"``, ``"hey_mycroft"``) or a microWakeWord ``.json`` file.
    :param wakeword_threshold: detection probability (None: the model's own tuned cutoff).
    :param wakeword_timeout_s: how long after the wake word the command may start.
    :param max_buffer_s: audio waiting for the worker (while a transcription runs) is kept up to
        this many seconds; beyond it the oldest chunks are dropped and counted.
    :param max_chunk_s: a longer single Audio message is refused with an error.
    :param language: the language hint of multilingual Whisper models.
    :param stream: the upstream name for partial results; none are produced yet: StreamingString
        outputs get each transcript as one final chunk (``done=True``) either way.
    :param enable_microphone: also listen to a local microphone (the ``voice`` extra's sounddevice;
        without it, or without an input device, configure fails with a clear error).
    :param device_audio: the microphone (device index or name; None: the default input device).
    :param ncpu_local_model: CPU threads of the local recognizer (default 2).
    """

    enable_vad: bool | None = field(default=None, metadata=AT_CONFIGURE)
    vad_threshold: float = field(default=0.5, validator=base_validators.in_range(0.01, 0.99), metadata=AT_CONFIGURE)
    min_silence_duration_ms: int = field(default=500, validator=base_validators.in_range(50, 10_000),
                                         metadata=AT_CONFIGURE)
    min_speech_duration_ms: int = field(default=250, validator=base_validators.in_range(10, 10_000),
                                        metadata=AT_CONFIGURE)
    max_speech_duration_s: float = field(default=20.0, validator=base_validators.in_range(1.0, 30.0),
                                         metadata=AT_CONFIGURE)
    vad_model_path: str | None = field(default=None, validator=_optional_str, metadata=AT_CONFIGURE)
    enable_wakeword: bool = field(default=False, metadata=AT_CONFIGURE)
    wakeword_model: str = field(default="hey_jarvis", validator=_non_empty, metadata=AT_CONFIGURE)
    wakeword_threshold: float | None = field(default=None, metadata=AT_CONFIGURE)
    wakeword_timeout_s: float = field(default=8.0, validator=base_validators.in_range(0.5, 600.0))
    max_buffer_s: float = field(default=30.0, validator=base_validators.in_range(1.0, 3600.0))
    max_chunk_s: float = field(default=10.0, validator=base_validators.in_range(0.01, 600.0))
    language: str = field(default="en", validator=_non_empty, metadata=AT_CONFIGURE)
    stream: bool = field(default=False)
    enable_microphone: bool = field(default=False, metadata=AT_CONFIGURE)
    device_audio: int | str | None = field(default=None, metadata=AT_CONFIGURE)
    ncpu_local_model: int = field(default=2, validator=base_validators.gt(0), metadata=AT_CONFIGURE)

    @wakeword_threshold.validator
    def _check_wakeword_threshold(self, attribute: attrs.Attribute[Any], value: Any) -> None:
        if value is not None and (isinstance(value, bool) or not isinstance(value, int | float)
                                  or not 0.0 < value < 1.0):
            raise ConfigError(f"SpeechToTextConfig.wakeword_threshold must be None or in (0, 1), got {value!r}")

    def __attrs_post_init__(self) -> None:
        if self.enable_vad is None:
            self.enable_vad = self.vad_model_path is not None
        if self.enable_wakeword and not self.enable_vad:
            raise ConfigError("SpeechToTextConfig: enable_wakeword needs enable_vad (the command after the wake "
                              "word is the next utterance)")

    def _get_inference_params(self) -> dict[str, Any]:
        return {"language": self.language}


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
    data_dir: str | None = field(default=None, validator=_optional_str, metadata=AT_CONFIGURE)
    ncpu_local_model: int = field(default=2, validator=base_validators.gt(0), metadata=AT_CONFIGURE)


def _topic_names(value: Any) -> Any:
    """``{camera: Topic}`` (upstream's form) or ``{camera: {"name": ...}}`` as ``{camera: topic name}``."""
    if not isinstance(value, dict):
        return value
    return {k: (v.get("name", v) if isinstance(v, dict) else getattr(v, "name", v) if not isinstance(v, str) else v)
            for k, v in value.items()}


def _str_map(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    if not isinstance(value, dict) or not all(isinstance(k, str) and k and isinstance(v, str) and v
                                              for k, v in value.items()):
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must map non-empty str to non-empty str, "
                          f"got {value!r:.200}")


def _optional_limits(instance: Any, attribute: attrs.Attribute[Any], value: Any) -> None:
    if value is None:
        return
    from .components.vla.urdf import joint_limits_from_config  # noqa: PLC0415  # validates each joint's entry

    if not isinstance(value, dict):
        raise ConfigError(f"{type(instance).__name__}.{attribute.name} must be None or a dict joint -> limits")
    joint_limits_from_config(value, type(instance).__name__)


@define(kw_only=True)
class VLAConfig(ModelComponentConfig):
    """Settings of the :class:`~agents_core.components.vla.VLA` component.

    :param joint_names_map: the policy's joint (state / action feature) names -> the robot's joint names.
        Every joint the policy commands must be here: an action for any other joint is an error, never sent.
    :param camera_inputs_map: the policy's camera names -> the component's Image / RGBD inputs (their names,
        or the Topic objects, as upstream's recipes write it).
    :param state_input_type: what the policy's state is, from the JointState input: ``"positions"``,
        ``"velocities"`` or ``"efforts"``.
    :param action_output_type: what the policy's actions are: ``"positions"`` (joint targets) or
        ``"velocities"``.
    :param observation_sending_rate: how often (Hz) an observation is sent to the policy during a goal.
    :param action_sending_rate: how often (Hz) a queued action is sent to the robot.
    :param robot_urdf_file: a URDF whose joint limits (position, velocity) clip every command.
    :param joint_limits: limits by robot joint name (``{"lower": .., "upper": .., "velocity": ..}``);
        they override the URDF's for the joints they name.
    :param max_timesteps: a goal ends (succeeded) after this many commands, unless its ``max_steps`` says
        otherwise.
    :param state_timeout: a joint state older than this (s) is stale: the goal aborts with a hold command.
    :param action_wait_timeout: a goal aborts when no action is ready for this long (s).
    :param on_new_goal: a goal arriving while one runs is ``"reject"``-ed, or ``"preempt"``-s the running
        one (which ends canceled, with a hold command, before the new one starts).
    :param aggregation_function: how overlapping chunks combine: ``"latest_only"``, ``"average"``,
        ``"weighted_average"``, ``"conservative"``
        (see :mod:`agents_core.components.vla.action_chunks`); set a callable with ``VLA.set_aggregation_function``.
    """

    joint_names_map: dict[str, str] = field(factory=dict, validator=_str_map)
    camera_inputs_map: dict[str, str] = field(factory=dict, validator=_str_map, converter=_topic_names)
    state_input_type: str = field(default="positions",
                                  validator=base_validators.in_(["positions", "velocities", "efforts"]))
    action_output_type: str = field(default="positions", validator=base_validators.in_(["positions", "velocities"]))
    observation_sending_rate: float = field(default=10.0, validator=base_validators.in_range(0.01, 1000.0))
    action_sending_rate: float = field(default=10.0, validator=base_validators.in_range(0.01, 1000.0))
    robot_urdf_file: str | None = field(default=None, validator=_optional_str, metadata=AT_CONFIGURE)
    joint_limits: dict[str, dict[str, float]] | None = field(default=None, validator=_optional_limits,
                                                             metadata=AT_CONFIGURE)
    max_timesteps: int = field(default=100, validator=base_validators.in_range(1, 2**32 - 1))
    state_timeout: float = field(default=1.0, validator=base_validators.in_range(0.001, 3600.0))
    action_wait_timeout: float = field(default=5.0, validator=base_validators.in_range(0.01, 3600.0))
    on_new_goal: str = field(default="reject", validator=base_validators.in_(["reject", "preempt"]))
    aggregation_function: str = field(default="weighted_average", validator=base_validators.in_(
        ["latest_only", "average", "weighted_average", "conservative"]))
