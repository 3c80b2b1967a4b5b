"""The object tracker on synthetic moving boxes: stable ids through crossings and exits, right velocities."""

from __future__ import annotations

import builtins

import numpy as np
import pytest

from agents_core.components.vision.tracking import ObjectTracker, iou_matrix

FPS = 10.0
SIZE = 40.0


def _box(cx: float, cy: float, size: float = SIZE) -> list[float]:
    return [cx - size / 2, cy - size / 2, cx + size / 2, cy + size / 2]


def test_iou_matrix() -> None:
    iou = iou_matrix(np.array([[0, 0, 10, 10]]), np.array([[0, 0, 10, 10], [5, 0, 15, 10], [20, 20, 30, 30]]))
    assert iou.shape == (1, 3)
    assert iou[0, 0] == pytest.approx(1.0)
    assert iou[0, 1] == pytest.approx(50 / 150)
    assert iou[0, 2] == 0.0


def test_two_people_crossing_keep_their_ids_and_velocities() -> None:
    """A moves right at 80 px/s, B left at 120 px/s on nearly the same line; they cross around frame 12."""
    tracker = ObjectTracker(max_age=1.0)
    ids_a, ids_b = set(), set()
    last: dict[str, np.ndarray] = {}
    for n in range(30):
        t = n / FPS
        a = _box(100 + 80 * t, 200)
        b = _box(340 - 120 * t, 210)
        out = tracker.update(np.array([a, b]), ["person", "person"], stamp=t, scores=np.array([0.9, 0.8]))
        assert len(out) == 2
        by_box = {(round(o.box[0]), round(o.box[1])): o for o in out}
        seen_a, seen_b = by_box[round(a[0]), round(a[1])], by_box[round(b[0]), round(b[1])]
        ids_a.add(seen_a.id)
        ids_b.add(seen_b.id)
        last = {"a": seen_a.velocity, "b": seen_b.velocity}
        assert all(isinstance(o.id, int) for o in out)
    assert len(ids_a) == 1 and len(ids_b) == 1 and ids_a != ids_b, (ids_a, ids_b)
    assert last["a"][0] == pytest.approx(80, rel=0.15) and abs(last["a"][1]) < 10
    assert last["b"][0] == pytest.approx(-120, rel=0.15) and abs(last["b"][1]) < 10


def test_an_object_leaving_and_coming_back_keeps_its_id_and_others_do_not_steal_it() -> None:
    """A cup moves down at 50 px/s, is unseen for 0.5 s (left the view), reappears; a bottle is steady."""
    tracker = ObjectTracker(max_age=1.0)
    cup_ids, bottle_ids = set(), set()
    velocity = np.zeros(2)
    for n in range(40):
        t = n / FPS
        boxes, labels = [_box(500, 300)], ["bottle"]
        cup_visible = not 10 <= n < 15
        if cup_visible:
            boxes.append(_box(200, 100 + 50 * t))
            labels.append("cup")
        out = tracker.update(np.array(boxes), labels, stamp=t)
        for o in out:
            (cup_ids if o.label == "cup" else bottle_ids).add(o.id)
            if o.label == "cup":
                velocity = o.velocity
        assert ("cup" in {o.label for o in out}) == cup_visible
    assert len(cup_ids) == 1 and len(bottle_ids) == 1 and cup_ids != bottle_ids
    assert velocity[1] == pytest.approx(50, rel=0.2) and abs(velocity[0]) < 5


def test_an_object_gone_longer_than_max_age_gets_a_new_id() -> None:
    tracker = ObjectTracker(max_age=0.3)
    first = tracker.update(np.array([_box(100, 100)]), ["cat"], stamp=0.0)[0].id
    assert tracker.update(np.zeros((0, 4)), [], stamp=0.2) == []
    assert tracker.update(np.zeros((0, 4)), [], stamp=0.6) == []
    assert tracker.track_count == 0
    again = tracker.update(np.array([_box(100, 100)]), ["cat"], stamp=0.7)[0].id
    assert again != first and again > first


def test_labels_are_never_mixed_and_ids_are_int64_ready() -> None:
    tracker = ObjectTracker()
    tracker.update(np.array([_box(100, 100)]), ["dog"], stamp=0.0)
    out = tracker.update(np.array([_box(102, 100)]), ["cat"], stamp=0.1)
    assert out[0].label == "cat" and out[0].id == 2
    assert np.array([o.id for o in out], np.int64).dtype == np.int64


def test_without_scipy_the_greedy_match_still_tracks(monkeypatch: pytest.MonkeyPatch) -> None:
    real_import = builtins.__import__

    def no_scipy(name: str, *args: object, **kwargs: object) -> object:
        if name.startswith("scipy"):
            raise ImportError("no scipy here")
        return real_import(name, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(builtins, "__import__", no_scipy)
    tracker = ObjectTracker()
    ids = set()
    for n in range(10):
        out = tracker.update(np.array([_box(100 + 5 * n, 100), _box(300, 100 + 5 * n)]), ["a", "a"], stamp=n / FPS)
        ids.add(tuple(o.id for o in out))
    assert ids == {(1, 2)}
