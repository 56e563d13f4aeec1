"""World-frame direction tracking: head movement resolves front and back (issue 33).

Interaural cues are the same for a direction and its mirror image through the interaural
axis, ``(x, y, z) -> (-x, y, z)`` in the head frame, so a still head confuses front and back
(the paper's open problem). When the head turns, the true source stays put in the world
while its mirror image moves twice as far as the head turned. :class:`DirectionTracker`
therefore keeps, per sound class, a log-likelihood over a *world-fixed* copy of the
direction grid and adds each frame's head-frame existence map to it through the head's pose
at that frame: evidence piles up on the true direction and spreads over the mirror's path.

A frame's map ``P(d)`` (the pipeline's fused existence map, >= 0) becomes a likelihood by
normalising it to a distribution and mixing in a uniform share ``outlier`` (a frame whose
cues are the room's, not the source's, then costs a bounded amount):
``q = (1 - outlier) P / sum P + outlier / D``. The world log-likelihood grows by
``weight * log q(R^T w)`` at every world direction ``w`` (``R`` the head-to-world rotation at
the frame's time; ``q`` interpolated between the three nearest grid directions). ``fold``
first mixes ``q(h)`` with ``q`` at the mirror image of ``h``: the spectral (pinna) cue that
tells front from back in one frame is the least reliable part of the map in a room
(docs/notes/active_hearing.md has the measurements), and with ``fold=1`` only the motion
decides.

The world grid is not the head's: it has rings every :data:`WORLD_STEP_DEG` over the head
grid's elevations, each with a multiple of four azimuths, so it holds the mirror image of
each of its directions through any vertical plane at a multiple of its azimuth step. The
paper's grid does not (10.8 deg steps), and on it a still head's evidence for a direction
and for its mirror image differed by the grid's sampling alone, a bias that grows with every
frame until it "decides". One frame costs a gather of three values per world direction (the
interpolation is cached per pose): constant time per frame, whatever the episode's length.

The front-back decision compares the world peak with the world position of its mirror
image at the current pose: the log-likelihood ratio of the two hypotheses
(:attr:`TrackedDirection.margin_nats`). It is decided at :data:`DECIDE_NATS` or more, or
when the two lie within :data:`SAME_CONE_DEG` of each other (a source on the interaural
axis has no front-back question).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from scipy.spatial import cKDTree

from acoustic_sim.directions import DirectionGrid
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import vec_to_sph

OUTLIER = 0.2
"""Default uniform share mixed into each frame's distribution (0..1)."""

FOLD = 1.0
"""Default share of each frame's map replaced by its mirror-symmetric part (0..1): all of it,
so that the head's motion alone tells front from back (in the rooms the single frame's pinna
cue was wrong as often as right; docs/notes/active_hearing.md)."""

DECIDE_NATS = 3.0
"""Log-likelihood ratio (nats, e^3 = 20:1) of the peak over its mirror at which front-back is decided."""

SAME_CONE_DEG = 25.0
"""A peak and its mirror closer than this (deg) need no front-back decision."""

WEIGHT = 0.1
"""Default scale of each frame's log-likelihood: about one independent look per 10 frames (0.16 s)."""

WORLD_STEP_DEG = 5.0
"""Spacing (deg) of the tracker's world grid, in elevation and along each ring."""

POSE_HISTORY = 128
"""Head poses kept (one per control step or frame): the frames' evidence may be up to the
MelCNN's 25 frames (0.4 s) old when a class is first detected."""


@dataclass(frozen=True, kw_only=True)
class TrackedDirection:
    """Where one sound is, in the world frame, from all frames heard so far.

    Attributes
    ----------
    world_vector : numpy.ndarray
        Unit vector (3,) of the peak in the world frame.
    azimuth_deg, elevation_deg : float
        The same in degrees, world frame (azimuth + left of the world's +x).
    head_vector : numpy.ndarray
        The peak in the head frame at the current pose (3,).
    head_azimuth_deg, head_elevation_deg : float
        The same in degrees.
    front : bool
        Whether the peak lies in front of the head (head-frame x >= 0) at the current pose.
    decided : bool
        Whether front/back is decided (``margin_nats >= decide_nats``, or the peak lies on
        the interaural axis).
    margin_nats : float
        log-likelihood of the peak minus that of its mirror image at the current pose.
    confidence : float
        0..1: the posterior mass within :data:`SAME_CONE_DEG` of the peak.
    frames : int
        Frames of evidence summed.
    """

    world_vector: np.ndarray
    azimuth_deg: float
    elevation_deg: float
    head_vector: np.ndarray
    head_azimuth_deg: float
    head_elevation_deg: float
    front: bool
    decided: bool
    margin_nats: float
    confidence: float
    frames: int

    def to_json(self) -> dict:
        return {
            "azimuth_deg": round(float(self.azimuth_deg), 2),
            "elevation_deg": round(float(self.elevation_deg), 2),
            "head_azimuth_deg": round(float(self.head_azimuth_deg), 2),
            "head_elevation_deg": round(float(self.head_elevation_deg), 2),
            "front": bool(self.front),
            "decided": bool(self.decided),
            "margin_nats": round(float(min(self.margin_nats, 1e6)), 3),
            "confidence": round(float(self.confidence), 4),
            "frames": int(self.frames),
        }


def world_grid(grid: DirectionGrid, step_deg: float = WORLD_STEP_DEG) -> DirectionGrid:
    """The tracker's world grid over ``grid``'s elevations (module docstring): rings every
    ``step_deg`` from the highest elevation down, each with a multiple of four azimuths
    (one direction at a pole)."""
    hi, lo = float(np.max(grid.elevation_deg)), float(np.min(grid.elevation_deg))
    az, el = [], []
    for e in np.arange(hi, lo - 1e-9, -step_deg):
        n = 1 if abs(abs(e) - 90.0) < 1e-9 else 4 * max(1, round(360.0 * np.cos(np.deg2rad(e)) / step_deg / 4))
        az.append(np.arange(n) * 360.0 / n)
        el.append(np.full(n, e))
    return DirectionGrid.from_angles(np.concatenate(az), np.concatenate(el), name=f"world_{step_deg:g}deg")


class DirectionTracker:
    """Per sound class, evidence over a world-fixed direction grid (module docstring).

    Parameters
    ----------
    grid : DirectionGrid
        The head-frame grid of the existence maps (the world grid is :func:`world_grid` of it).
    classes : sequence of str
        Names of the classes tracked (more with :meth:`track`).
    outlier : float
        Uniform share of each frame's distribution, in (0, 1] (default :data:`OUTLIER`).
    fold : float
        Share of each frame's map replaced by its mirror-symmetric part, 0..1 (default
        :data:`FOLD`; 0 keeps the map, 1 lets only the head's motion tell front from back).
    decide_nats : float
        Front-back decision threshold, > 0 (default :data:`DECIDE_NATS`).
    weight : float
        Each frame's log-likelihood is scaled by this, in (0, 1] (default :data:`WEIGHT`):
        successive frames overlap and share the room's reflections, so they are not
        independent looks, and counted as such they decide front-back from a bias too
        small to see in one frame.
    half_life_s : float or None
        Evidence older than this counts half (a moving source); None (default) keeps it all.
    """

    def __init__(self, grid: DirectionGrid, classes=(), *, outlier: float = OUTLIER, fold: float = FOLD,
                 decide_nats: float = DECIDE_NATS, weight: float = WEIGHT, half_life_s: float | None = None) -> None:
        if not (np.isfinite(outlier) and 0.0 < outlier <= 1.0):
            raise ConfigError(f"outlier must be in (0, 1], got {outlier}")
        if not (np.isfinite(fold) and 0.0 <= fold <= 1.0):
            raise ConfigError(f"fold must be in [0, 1], got {fold}")
        if not (np.isfinite(decide_nats) and decide_nats > 0.0):
            raise ConfigError(f"decide_nats must be > 0, got {decide_nats}")
        if not (np.isfinite(weight) and 0.0 < weight <= 1.0):
            raise ConfigError(f"weight must be in (0, 1], got {weight}")
        if half_life_s is not None and not (np.isfinite(half_life_s) and half_life_s > 0.0):
            raise ConfigError(f"half_life_s must be > 0 or None, got {half_life_s}")
        self.grid = grid
        self.classes: tuple[str, ...] = ()
        self.outlier = float(outlier)
        self.fold = float(fold)
        self.decide_nats = float(decide_nats)
        self.half_life_s = half_life_s
        self.weight = float(weight)
        self.world = world_grid(grid)
        self._tree = cKDTree(grid.vectors)
        self._loglik = np.zeros((0, len(self.world)))
        self._frames = np.zeros(0, np.int64)
        self._last_t = np.zeros(0)
        self._estimates: dict = {}  # class -> (its evidence count, pose key, estimate): until either changes
        for name in classes:
            self.track(name)
        self._poses: deque = deque(maxlen=POSE_HISTORY)  # (time_s, rotation), time ascending
        self._pull_cache: tuple | None = None  # (rotation bytes, head index of each world direction)

    # -- state ------------------------------------------------------------------------------
    def track(self, name: str) -> None:
        """Track one more class (no effect for a class already tracked)."""
        if not isinstance(name, str) or not name:
            raise ConfigError(f"a tracked class needs a name, got {name!r}")
        if name in self.classes:
            return
        self.classes += (name,)
        self._loglik = np.vstack([self._loglik, np.zeros((1, len(self.world)))])
        self._frames = np.append(self._frames, 0)
        self._last_t = np.append(self._last_t, -np.inf)

    def reset(self) -> None:
        """Forget all evidence and poses (a new episode)."""
        self._loglik[:] = 0.0
        self._frames[:] = 0
        self._last_t[:] = -np.inf
        self._poses.clear()
        self._pull_cache = None
        self._estimates.clear()

    def forget(self) -> None:
        """Forget the evidence, keep the poses (the listening warm-up before an episode)."""
        self._loglik[:] = 0.0
        self._frames[:] = 0
        self._last_t[:] = -np.inf
        self._estimates.clear()

    def note_pose(self, time_s: float, rotation) -> None:
        """The head's pose at ``time_s`` (s, the sample clock): ``rotation`` (3, 3) maps head
        to world coordinates. Times must not decrease."""
        r = np.asarray(rotation, float)
        if r.shape != (3, 3) or not np.all(np.isfinite(r)):
            raise ConfigError(f"rotation must be a finite (3, 3) matrix, got shape {r.shape}")
        if not np.allclose(r @ r.T, np.eye(3), atol=1e-6):
            raise ConfigError("rotation must be orthonormal (head to world)")
        t = float(time_s)
        if self._poses and t < self._poses[-1][0]:
            raise ConfigError(f"pose times must not decrease: {t} after {self._poses[-1][0]}")
        self._poses.append((t, r))

    def rotation_at(self, time_s: float) -> np.ndarray:
        """The head-to-world rotation in force at ``time_s``: the latest pose noted at or
        before it (the earliest kept when all are later; the identity before any, a still
        head whose frame is the world's, as for a recording)."""
        if not self._poses:
            return np.eye(3)
        best = self._poses[0][1]
        for t, r in reversed(self._poses):
            if t <= time_s:
                best = r
                break
        return best

    # -- evidence ---------------------------------------------------------------------------
    def _interpolation(self, head_vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The three nearest head-grid directions of each vector (n, 3) and their weights
        (inverse angular distance, summing to 1)."""
        dist, idx = self._tree.query(head_vectors, k=3)
        w = 1.0 / (dist + 1e-3)
        return idx, w / w.sum(axis=1, keepdims=True)

    def _pull(self, rotation: np.ndarray) -> tuple:
        """Interpolation, at ``rotation``, of each world direction's head-frame vector and of
        its mirror image: ``(idx, w, mirror_idx, mirror_w)``."""
        key = rotation.tobytes()
        if self._pull_cache is None or self._pull_cache[0] != key:
            h = self.world.vectors @ rotation  # rows: R^T w
            self._pull_cache = (key, *self._interpolation(h), *self._interpolation(h * np.array([-1.0, 1.0, 1.0])))
        return self._pull_cache[1:]

    def add(self, name: str, time_s: float, existence, *, rotation=None) -> None:
        """One frame's head-frame existence map (D,) of class ``name``, heard at ``time_s``;
        the pose is ``rotation`` or the one noted for that time. A map without a positive
        value is no evidence."""
        c = self._index(name)
        p = np.asarray(existence, float)
        if p.shape != (len(self.grid),):
            raise ConfigError(f"existence must have shape ({len(self.grid)},), got {p.shape}")
        total = float(p.sum())
        if not (np.isfinite(total) and total > 0.0) or np.any(p < 0):
            return
        q = (1.0 - self.outlier) * p / total + self.outlier / p.size
        r = self.rotation_at(time_s) if rotation is None else np.asarray(rotation, float)
        idx, w, m_idx, m_w = self._pull(r)
        at = (q[idx] * w).sum(axis=1)
        if self.fold > 0.0:
            at = (1.0 - 0.5 * self.fold) * at + 0.5 * self.fold * (q[m_idx] * m_w).sum(axis=1)
        if self.half_life_s is not None and np.isfinite(self._last_t[c]) and time_s > self._last_t[c]:
            self._loglik[c] *= 0.5 ** ((time_s - self._last_t[c]) / self.half_life_s)
        self._last_t[c] = max(self._last_t[c], float(time_s))
        self._loglik[c] += self.weight * np.log(at)
        self._frames[c] += 1

    def _index(self, name: str) -> int:
        try:
            return self.classes.index(name)
        except ValueError:
            raise ConfigError(f"unknown class {name!r}; tracked: {', '.join(self.classes)}") from None

    def frames(self, name: str) -> int:
        return int(self._frames[self._index(name)])

    def estimate(self, name: str, *, rotation=None) -> TrackedDirection | None:
        """The tracked direction of ``name`` (None before any evidence), its head-frame view
        and front-back decision at ``rotation`` (default: the latest pose noted)."""
        c = self._index(name)
        if self._frames[c] == 0:
            return None
        if rotation is None:
            rotation = self._poses[-1][1] if self._poses else np.eye(3)
        r = np.asarray(rotation, float)
        # Asked every frame by the pipeline: computed again only after new evidence (each
        # frame added counts one) or at another pose.
        key = (int(self._frames[c]), r.tobytes())
        kept = self._estimates.get(c)
        if kept is not None and kept[0] == key:
            return kept[1]
        self._estimates[c] = (key, self._estimate(c, r))
        return self._estimates[c][1]

    def _estimate(self, c: int, r: np.ndarray) -> TrackedDirection:
        ll = self._loglik[c]
        k = int(np.argmax(ll))
        w = self.world.vectors[k]
        h = r.T @ w
        mirror_world = r @ (h * np.array([-1.0, 1.0, 1.0]))
        cos_cone = np.cos(np.deg2rad(SAME_CONE_DEG))
        if float(w @ mirror_world) >= cos_cone:
            margin = np.inf
        else:  # the best world direction within half a step of the mirror image
            near_mirror = self.world.vectors @ mirror_world >= np.cos(np.deg2rad(0.75 * WORLD_STEP_DEG))
            near_mirror[int(self.world.nearest(mirror_world))] = True
            margin = float(ll[k] - ll[near_mirror].max())
        post = np.exp(ll - ll[k])
        near = self.world.vectors @ w >= cos_cone
        confidence = float(post[near].sum() / post.sum())
        az, el = vec_to_sph(w)
        haz, hel = vec_to_sph(h)
        return TrackedDirection(
            world_vector=w.copy(), azimuth_deg=float(az), elevation_deg=float(el), head_vector=h,
            head_azimuth_deg=float(haz), head_elevation_deg=float(hel), front=bool(h[0] >= 0.0),
            decided=bool(margin >= self.decide_nats), margin_nats=margin, confidence=confidence,
            frames=int(self._frames[c]),
        )
