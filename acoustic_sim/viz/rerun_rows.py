"""Rows of a recording buffered in numpy and sent to rerun in columns.

``rr.log`` costs 70-250 us a call, so the recorder does not log per-frame data row by row:
each entity's rows wait in a :class:`Rows` (time stamps and component batches) and go out
in one ``send_columns`` call when the recorder flushes. :class:`RowBuffer` keeps one
:class:`Rows` per entity, sent in the order the entities were first logged. The helpers
below are shared by the world's and the hearing's loggers: the time columns of a batch,
the change test that skips rows whose value did not move, and JPEG encoding.
"""

from __future__ import annotations

import io

import numpy as np
import rerun as rr
from PIL import Image

from acoustic_sim.viz import blueprint as bp


class Rows:
    """Rows of one entity waiting to be sent: time stamps and per-row component batches."""

    __slots__ = ("archetype", "cols", "frames", "lengths", "times")

    def __init__(self, archetype) -> None:
        self.archetype = archetype
        self.frames: list[int] = []
        self.times: list[float] = []
        self.lengths: list[int] = []
        self.cols: dict[str, list] = {}

    def add(self, frame: int, t: float, n: int, **cols) -> None:
        self.frames.append(frame)
        self.times.append(t)
        self.lengths.append(n)
        for k, v in cols.items():
            self.cols.setdefault(k, []).append(v)

    def add_many(self, frame: int, times, n: int, **cols) -> None:
        """Rows of one frame at several times, each of ``n`` instances (arrays concatenated)."""
        m = len(times)
        self.frames.extend([frame] * m)
        self.times.extend(times)
        self.lengths.extend([n] * m)
        for k, v in cols.items():
            self.cols.setdefault(k, []).append(v)

    def send(self, rec: rr.RecordingStream, entity: str, episode: int | None = None) -> None:
        """Send the rows (one ``send_columns`` call); ``episode``: the value of the ``episode``
        timeline for all of them (the recorder flushes before the episode changes)."""
        if not self.frames:
            return
        cols = {}
        for k, v in self.cols.items():
            if isinstance(v[0], np.ndarray):
                cols[k] = np.concatenate(v)
            else:
                cols[k] = [x for part in v for x in part]
        columns = self.archetype.columns(**cols).partition(self.lengths)
        rec.send_columns(entity, indexes=time_indexes(self.frames, self.times, episode), columns=columns)
        self.frames, self.times, self.lengths, self.cols = [], [], [], {}


class RowBuffer:
    """The :class:`Rows` of every entity logged per frame, in the order first logged."""

    __slots__ = ("_rows",)

    def __init__(self) -> None:
        self._rows: dict[str, Rows] = {}

    def rows(self, entity: str, archetype) -> Rows:
        """The rows of ``entity`` (made on first use with ``archetype``)."""
        rows = self._rows.get(entity)
        if rows is None:
            rows = self._rows[entity] = Rows(archetype)
        return rows

    def send(self, rec: rr.RecordingStream, episode: int | None) -> None:
        """Send every entity's rows, one ``send_columns`` call each."""
        for entity, rows in self._rows.items():
            rows.send(rec, entity, episode)


def time_indexes(frames, times, episode: int | None) -> list[rr.TimeColumn]:
    """The time columns of a batch of rows: ``frame``, ``sim_time`` and, if set, ``episode``."""
    frames = np.asarray(frames, np.int64)
    cols = [rr.TimeColumn(bp.FRAME_TIMELINE, sequence=frames),
            rr.TimeColumn(bp.TIMELINE, duration=np.asarray(times, np.float64))]
    if episode is not None:
        cols.append(rr.TimeColumn(bp.EPISODE_TIMELINE, sequence=np.full(frames.size, episode, np.int64)))
    return cols


def unchanged(last, labels, vecs, tolerance: float) -> bool:
    """Whether labelled vectors equal the ``(labels, vecs)`` last logged (``None``: none yet)
    within ``tolerance`` per component."""
    return (last is not None and last[0] == labels and last[1].shape == vecs.shape
            and bool(np.all(np.abs(last[1] - vecs) <= tolerance)))


def jpeg(image: np.ndarray, quality: int) -> bytes:
    """``image`` (uint8) encoded as JPEG at ``quality`` (1..95)."""
    out = io.BytesIO()
    Image.fromarray(image).save(out, format="JPEG", quality=quality)
    return out.getvalue()
