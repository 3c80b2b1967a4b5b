"""Multi-object tracking by detection: a constant-velocity Kalman filter per object and optimal assignment.

:class:`ObjectTracker` takes each frame's detections (boxes, labels, scores, the frame's time) and
returns the tracked objects seen in that frame, each with an id that persists across frames
(``int64``), its box, centroid and estimated velocity in pixels per second. It is SORT-like:

1. every track's Kalman filter predicts where its box is at the new frame's time;
2. detections and predictions of the same label are matched by IoU with an optimal assignment
   (``scipy.optimize.linear_sum_assignment`` when scipy is installed, else a greedy match);
3. detections still unmatched are matched to tracks that were not seen in the last frame by
   the distance from where that track was last seen or is predicted to be (gated by its size): an
   object that left the view or was hidden for up to ``max_age`` seconds gets its id back;
4. matched tracks are corrected with their detection, the others are new tracks, and tracks
   unseen for longer than ``max_age`` are forgotten.

Time comes from the frames' stamps, so velocities are right whatever the frame rate.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from attrs import define, field

__all__ = ["ObjectTracker", "TrackedObject", "iou_matrix"]

FloatArray = npt.NDArray[np.float64]
# Cost of a forbidden pairing (different labels, or too little overlap): never chosen.
_FORBIDDEN = 1e6


def iou_matrix(a: npt.NDArray[Any], b: npt.NDArray[Any]) -> FloatArray:
    """IoU of every box of ``a`` (Nx4, x1 y1 x2 y2) with every box of ``b`` (Mx4): an NxM array."""
    a = np.asarray(a, np.float64).reshape(-1, 4)
    b = np.asarray(b, np.float64).reshape(-1, 4)
    w = np.clip(np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0]), 0, None)
    h = np.clip(np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1]), 0, None)
    inter = w * h
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    result: FloatArray = inter / np.maximum(area_a[:, None] + area_b[None, :] - inter, 1e-9)
    return result


def _assign(cost: FloatArray) -> list[tuple[int, int]]:
    """Pairs (row, column) of least total cost, leaving out forbidden pairings."""
    if cost.size == 0:
        return []
    try:
        from scipy.optimize import linear_sum_assignment  # type: ignore[import-untyped,import-not-found,unused-ignore]  # noqa: PLC0415
    except ImportError:
        pairs, used_r, used_c = [], set(), set()
        for flat in np.argsort(cost, axis=None, kind="stable"):
            r, c = divmod(int(flat), cost.shape[1])
            if r not in used_r and c not in used_c and cost[r, c] < _FORBIDDEN:
                pairs.append((r, c))
                used_r.add(r)
                used_c.add(c)
        return pairs
    rows, cols = linear_sum_assignment(cost)
    return [(int(r), int(c)) for r, c in zip(rows, cols, strict=True) if cost[r, c] < _FORBIDDEN]


def _to_state(box: npt.NDArray[Any]) -> FloatArray:
    x1, y1, x2, y2 = (float(v) for v in box)
    return np.array([(x1 + x2) / 2, (y1 + y2) / 2, max(x2 - x1, 1e-3), max(y2 - y1, 1e-3)])


class _Track:
    """One object's Kalman filter: state (cx, cy, w, h, vx, vy), velocities in pixels per second."""

    # Process noise: how much (px/s) the velocity may change in a second; the size drifts slowly.
    ACCEL = 200.0
    SIZE_DRIFT = 20.0

    def __init__(self, track_id: int, label: str, box: npt.NDArray[Any], score: float, stamp: float) -> None:
        self.id = track_id
        self.label = label
        self.score = score
        self.x = np.zeros(6)
        self.x[:4] = _to_state(box)
        # Position is known to the detector's noise; the velocity is unknown until the second sighting.
        self.P = np.diag([*(self._meas_sigma() ** 2), 1e6, 1e6])
        self.stamp = stamp  # time of the state
        self.last_seen = stamp
        self.last_box = np.asarray(box, np.float64)
        self.hits = 1

    def _meas_sigma(self) -> FloatArray:
        return np.full(4, 0.05 * max(self.x[2], self.x[3]) + 1.0)

    def predict(self, stamp: float) -> None:
        dt = stamp - self.stamp
        if dt <= 0:
            return
        f = np.eye(6)
        f[0, 4] = f[1, 5] = dt
        q = np.diag([0.25 * dt**4 * self.ACCEL**2] * 2 + [(self.SIZE_DRIFT * dt) ** 2] * 2
                    + [(self.ACCEL * dt) ** 2] * 2)
        q[0, 4] = q[4, 0] = q[1, 5] = q[5, 1] = 0.5 * dt**3 * self.ACCEL**2
        self.x = f @ self.x
        self.P = f @ self.P @ f.T + q
        self.stamp = stamp

    def update(self, box: npt.NDArray[Any], score: float) -> None:
        h = np.zeros((4, 6))
        h[:, :4] = np.eye(4)
        r = np.diag(self._meas_sigma() ** 2)
        y = _to_state(box) - h @ self.x
        s = h @ self.P @ h.T + r
        k = self.P @ h.T @ np.linalg.inv(s)
        self.x = self.x + k @ y
        self.P = (np.eye(6) - k @ h) @ self.P
        self.last_seen = self.stamp
        self.last_box = np.asarray(box, np.float64)
        self.score = score
        self.hits += 1

    def box(self) -> FloatArray:
        cx, cy, w, h = self.x[:4]
        return np.array([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2])


@define(eq=False)
class TrackedObject:
    """One tracked object in one frame: ``box`` x1 y1 x2 y2 and ``centroid`` in pixels, ``velocity`` in px/s."""

    id: int
    label: str
    box: FloatArray
    centroid: FloatArray
    velocity: FloatArray
    score: float = field(default=1.0)


class ObjectTracker:
    """Keeps ids of detected objects across frames (see the module docs).

    :param max_age: seconds an unseen object keeps its id.
    :param iou_threshold: minimum IoU of a detection with a track's predicted box to continue it.
    :param reentry_distance: in step 3, how far (in multiples of the track's box diagonal) a
        detection may be from where the track was last seen or is predicted to be.
    """

    def __init__(self, max_age: float = 1.0, iou_threshold: float = 0.2, reentry_distance: float = 1.0) -> None:
        self.max_age = max_age
        self.iou_threshold = iou_threshold
        self.reentry_distance = reentry_distance
        self._tracks: list[_Track] = []
        self._ids = itertools.count(1)

    def reset(self) -> None:
        """Forget every track (ids keep increasing: an id is never reused)."""
        self._tracks.clear()

    @property
    def track_count(self) -> int:
        """How many objects are remembered (seen, or unseen for less than ``max_age``)."""
        return len(self._tracks)

    def update(self, boxes: npt.NDArray[Any], labels: Sequence[str], stamp: float,
               scores: npt.NDArray[Any] | None = None) -> list[TrackedObject]:
        """Feed one frame's detections (taken at ``stamp`` seconds); the tracked objects seen in it."""
        boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
        score_list = [1.0] * len(labels) if scores is None else [float(s) for s in scores]
        for track in self._tracks:
            track.predict(stamp)
        unmatched = set(range(len(labels)))
        matched: dict[int, _Track] = {}
        self._match_by_overlap(boxes, labels, stamp, unmatched, matched)
        self._match_lost(boxes, labels, stamp, unmatched, matched)
        for d, track in matched.items():
            track.update(boxes[d], score_list[d])
        for d in sorted(unmatched):
            track = _Track(next(self._ids), labels[d], boxes[d], score_list[d], stamp)
            self._tracks.append(track)
            matched[d] = track
        self._tracks = [t for t in self._tracks if stamp - t.last_seen <= self.max_age]
        return [self._report(matched[d], boxes[d]) for d in sorted(matched)]

    def _match_by_overlap(self, boxes: FloatArray, labels: Sequence[str], stamp: float, unmatched: set[int],
                          matched: dict[int, _Track]) -> None:
        if not self._tracks or not len(labels):
            return
        predicted = np.stack([t.box() for t in self._tracks])
        iou = iou_matrix(predicted, boxes)
        cost = 1.0 - iou
        for i, track in enumerate(self._tracks):
            for d, label in enumerate(labels):
                if label != track.label or iou[i, d] < self.iou_threshold:
                    cost[i, d] = _FORBIDDEN
        for i, d in _assign(cost):
            matched[d] = self._tracks[i]
            unmatched.discard(d)

    def _match_lost(self, boxes: FloatArray, labels: Sequence[str], stamp: float, unmatched: set[int],
                    matched: dict[int, _Track]) -> None:
        taken = {id(t) for t in matched.values()}
        lost = [t for t in self._tracks if id(t) not in taken]
        dets = sorted(unmatched)
        if not lost or not dets:
            return
        cost = np.full((len(lost), len(dets)), _FORBIDDEN)
        for i, track in enumerate(lost):
            diagonal = float(np.hypot(*(track.last_box[2:] - track.last_box[:2])))
            gate = self.reentry_distance * max(diagonal, 1.0)
            seen_at = (track.last_box[:2] + track.last_box[2:]) / 2
            for j, d in enumerate(dets):
                if labels[d] != track.label:
                    continue
                centre = (boxes[d, :2] + boxes[d, 2:]) / 2
                distance = min(float(np.hypot(*(centre - seen_at))), float(np.hypot(*(centre - track.x[:2]))))
                if distance <= gate:
                    cost[i, j] = distance / gate
        for i, j in _assign(cost):
            track = lost[i]
            # It was out of sight: its old velocity says nothing about where it went; restart from here.
            track.x[:4] = _to_state(boxes[dets[j]])
            track.x[4:] = 0.0
            track.P = np.diag([*(track._meas_sigma() ** 2), 1e6, 1e6])
            matched[dets[j]] = track
            unmatched.discard(dets[j])

    @staticmethod
    def _report(track: _Track, detected: FloatArray) -> TrackedObject:
        # The published box is the detection's (what was seen); the velocity is the filter's estimate.
        centroid = (detected[:2] + detected[2:]) / 2
        velocity = track.x[4:].copy() if track.hits > 1 else np.zeros(2)
        return TrackedObject(id=track.id, label=track.label, box=detected.copy(), centroid=centroid,
                             velocity=velocity, score=track.score)
