"""LocalVisionModel: the export signatures it knows, labels, boxes in input pixels, and typed errors."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from agents_core.engines.local_vision import LocalVisionModel, coco90_labels, nms, read_labels_file
from agents_core.errors import ConfigError, InferenceError
from agents_core.testing.pairs import skip_unless_installed

from .models_dir import TINY
from .vision_recipe import KNOWN, found_on, needs_ssd, photo

pytestmark = pytest.mark.local_models


def _onnx() -> object:
    skip_unless_installed("", "onnxruntime", reason="onnxruntime is not installed (pip install 'agents-core[local]')")
    skip_unless_installed("", "onnx", reason="the onnx package is not installed (pip install 'agents-core[dev]'): it "
                                             "builds the tiny models")
    import onnx  # noqa: PLC0415

    return onnx


def _tiny_yolo(path: Path) -> Path:
    """An Ultralytics-style export: images [1,3,640,640] -> output0 [1,4+2,8], names in the metadata.

    The output is constant (plus 0 x the image mean, so the graph uses its input): box 0 is a 'robot'
    at cx,cy,w,h = 320,320,200,100 of the letterboxed input, box 1 a near-duplicate with a lower score
    (NMS drops it), box 2 a 'ball' below the threshold.
    """
    onnx = _onnx()
    from onnx import TensorProto, helper, numpy_helper  # noqa: PLC0415

    rows = np.zeros((1, 6, 8), np.float32)  # 8 candidates (as the real ones, more than 4 + classes)
    rows[0, :, :3] = [[320, 330, 100], [320, 322, 100], [200, 200, 20], [100, 100, 20], [0.9, 0.8, 0.05],
                      [0.1, 0.1, 0.3]]
    nodes = [helper.make_node("ReduceMean", ["images"], ["m"], keepdims=1),  # [1,1,1,1]
             helper.make_node("Reshape", ["m", "shape"], ["m3"]),
             helper.make_node("Mul", ["m3", "zero"], ["z"]),
             helper.make_node("Add", ["rows", "z"], ["output0"])]
    inits = [numpy_helper.from_array(rows, "rows"), numpy_helper.from_array(np.zeros(1, np.float32), "zero"),
             numpy_helper.from_array(np.array([1, 1, 1], np.int64), "shape")]
    graph = helper.make_graph(nodes, "tiny_yolo", [helper.make_tensor_value_info("images", TensorProto.FLOAT,
                                                                                  [1, 3, 640, 640])],
                              [helper.make_tensor_value_info("output0", TensorProto.FLOAT, [1, 6, 8])], inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    helper.set_model_props(model, {"names": "{0: 'robot', 1: 'ball'}", "imgsz": "[640, 640]"})
    onnx.checker.check_model(model)  # type: ignore[attr-defined]
    onnx.save(model, str(path))  # type: ignore[attr-defined]
    return path


def test_the_real_ssd_on_the_photos() -> None:
    model = LocalVisionModel(needs_ssd(), threshold=0.5)
    assert model.signature == "ssd" and model.labels[1] == "person" and model.labels[90] == "toothbrush"
    for name in KNOWN:
        found = model.detect(photo(name))
        assert found_on(name, found["labels"], found["scores"], found["bboxes"]), (name, found)
    blank = model({"images": [np.zeros((480, 640, 3), np.uint8)]})["output"][0]
    assert blank["labels"] == [] and blank["bboxes"].shape == (0, 4)
    ids = model.detect(photo("chelsea.png"), dataset_labels=False)
    assert ids["labels"][0] == "17"  # COCO id of 'cat'


def test_deim_signature_gives_boxes_in_the_input_images_pixels() -> None:
    stub = TINY / "deim_stub.onnx"
    if importlib.util.find_spec("onnxruntime") is None or not stub.is_file():
        pytest.skip(f"onnxruntime or {stub} is missing")
    model = LocalVisionModel(str(stub), threshold=0.3)
    assert model.signature == "deim" and (model.input_height, model.input_width) == (640, 640)
    found = model.detect(np.full((100, 200, 3), 200, np.uint8))
    # The stub's first box is (0.1, 0.1, 0.4, 0.5) of the image it was given, labelled COCO class 0.
    first = found["labels"].index("person")
    assert found["bboxes"][first].tolist() == pytest.approx([20, 10, 80, 50], abs=0.01)
    assert set(found["labels"]) <= {"person", "car", "bottle", "chair"}


def test_ultralytics_yolo_signature_letterbox_nms_and_metadata_names(tmp_path: Path) -> None:
    model = LocalVisionModel(str(_tiny_yolo(tmp_path / "tiny_yolo.onnx")), threshold=0.5)
    assert model.signature == "yolo" and model.labels == {0: "robot", 1: "ball"}
    # 320x160: scaled x2 to 640x320 and padded 160 above and below.
    found = model.detect(np.zeros((160, 320, 3), np.uint8))
    assert found["labels"] == ["robot"]
    assert found["scores"].tolist() == pytest.approx([0.9])
    # cx, cy, w, h = 320, 320, 200, 100 -> x 220..420, y 270..370 -> minus the pad, halved.
    assert found["bboxes"][0].tolist() == pytest.approx([110, 55, 210, 105], abs=0.01)
    labels_file = tmp_path / "names.txt"
    labels_file.write_text("droid\nsphere\n")
    renamed = LocalVisionModel(str(tmp_path / "tiny_yolo.onnx"), labels_path=str(labels_file))
    assert renamed.detect(np.zeros((64, 64, 3), np.uint8))["labels"] == ["droid"]


def test_an_unknown_signature_is_a_config_error_listing_what_was_found(tmp_path: Path) -> None:
    onnx = _onnx()
    from onnx import TensorProto, helper  # noqa: PLC0415

    graph = helper.make_graph([helper.make_node("Relu", ["features"], ["activations"])], "not_a_detector",
                              [helper.make_tensor_value_info("features", TensorProto.FLOAT, [1, 10])],
                              [helper.make_tensor_value_info("activations", TensorProto.FLOAT, [1, 10])])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    path = tmp_path / "relu.onnx"
    onnx.save(model, str(path))  # type: ignore[attr-defined]
    with pytest.raises(ConfigError, match=r"inputs \[features \[1, 10\] tensor\(float\)\]; outputs \[activations"):
        LocalVisionModel(str(path))


def test_files_that_are_not_models_and_missing_files(tmp_path: Path) -> None:
    skip_unless_installed("", "onnxruntime", reason="onnxruntime is not installed")
    bogus = tmp_path / "model.onnx"
    bogus.write_bytes(b"\x00\x01 not a protobuf")
    with pytest.raises(ConfigError, match="not a loadable ONNX model"):
        LocalVisionModel(str(bogus))
    with pytest.raises(ConfigError, match="no such file"):
        LocalVisionModel(str(tmp_path / "missing.onnx"))
    with pytest.raises(ConfigError, match="device"):
        LocalVisionModel(str(bogus), device="tpu")


def test_bad_arrays_are_typed_errors_and_the_next_good_one_works() -> None:
    model = LocalVisionModel(needs_ssd())
    for bad, match in ((np.zeros((48, 64, 3), np.float32), "uint8"), (np.zeros((0, 0, 3), np.uint8), "empty"),
                       (np.zeros((48, 64), np.uint8), "HxWx3"), (np.zeros((5000, 10, 3), np.uint8), "larger"),
                       ([[1, 2, 3]], "numpy")):
        with pytest.raises(InferenceError, match=match):
            model.detect(bad)  # type: ignore[arg-type]
    with pytest.raises(InferenceError, match="images"):
        model({"images": []})
    assert "cat" in model.detect(photo("chelsea.png"))["labels"]


def test_helpers() -> None:
    assert len(coco90_labels()) == 80 and coco90_labels()[44] == "bottle" and 12 not in coco90_labels()
    boxes = np.array([[0, 0, 10, 10], [1, 1, 10, 10], [0, 0, 10, 10], [50, 50, 60, 60]], np.float32)
    kept = nms(boxes, np.array([0.9, 0.8, 0.7, 0.6], np.float32), np.array([0, 0, 1, 0]), 0.5)
    assert kept.tolist() == [0, 2, 3], "same-class overlaps go, other classes stay"


def test_labels_files(tmp_path: Path) -> None:
    numbered = tmp_path / "labels.txt"
    numbered.write_text("1 person\n3 car\n")
    assert read_labels_file(numbered) == {1: "person", 3: "car"}
    as_json = tmp_path / "labels.json"
    as_json.write_text('{"0": "robot"}')
    assert read_labels_file(as_json) == {0: "robot"}
    with pytest.raises(ConfigError):
        read_labels_file(tmp_path / "none.txt")
