"""Coordinate frames and the sample clock, written down once.

World frame: MuJoCo's, z up. Head frame: x forward (nose), y toward the left ear, z up.
Azimuth is measured counter-clockwise from +x toward +y (left is positive), elevation up
from the horizontal plane (the SOFA convention). Degrees at every API boundary and in
files; unit vectors inside the math, so that nothing wraps around.

The sample counter is the master clock: ear frame ``k`` ends at sample
``round(k * SAMPLE_RATE / FRAME_RATE)``, so control blocks are 705 or 706 samples long and
never drift.
"""

from __future__ import annotations

import math

import numpy as np

from acoustic_sim.errors import ConfigError

SAMPLE_RATE = 44100
"""Project sample rate in Hz; every other rate is resampled on load."""

FRAME_RATE = 62.5
"""Ear frame (and control step) rate in Hz: the ear unit's 16 ms spectrum cycle."""

SPEED_OF_SOUND = 343.0
"""Speed of sound in m/s (dry air at 20 deg C)."""

P_REF = 20e-6
"""Reference sound pressure for dB SPL, in pascal."""


def sph_to_vec(azimuth_deg, elevation_deg) -> np.ndarray:
    """Unit vectors from azimuth and elevation in degrees.

    Parameters
    ----------
    azimuth_deg, elevation_deg : array_like
        Azimuth (deg, counter-clockwise from +x, left positive) and elevation
        (deg, -90..90, up positive); broadcast against each other.

    Returns
    -------
    numpy.ndarray, shape (..., 3)
        Unit vectors (x forward, y left, z up).
    """
    az = np.deg2rad(np.asarray(azimuth_deg, dtype=float))
    el = np.deg2rad(np.asarray(elevation_deg, dtype=float))
    az, el = np.broadcast_arrays(az, el)
    return np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1)


def vec_to_sph(vectors) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth in (-180, 180] and elevation in [-90, 90], degrees, of vectors (..., 3).

    Vectors need not be unit length; a zero vector is an error (it has no direction).
    """
    v = np.asarray(vectors, dtype=float)
    if v.shape[-1] != 3:
        raise ConfigError(f"direction vectors must have shape (..., 3), got {v.shape}")
    norm = np.linalg.norm(v, axis=-1)
    if np.any(norm == 0) or not np.all(np.isfinite(norm)):
        raise ConfigError("a direction vector is zero or not finite: it has no direction")
    az = np.rad2deg(np.arctan2(v[..., 1], v[..., 0]))
    el = np.rad2deg(np.arcsin(np.clip(v[..., 2] / norm, -1.0, 1.0)))
    # arctan2 gives -180 for (-1, -0.0); fold it to +180 so the range is (-180, 180].
    az = np.where(az <= -180.0, az + 360.0, az)
    return az, el


def unit_vectors(vectors, what: str = "direction vectors") -> np.ndarray:
    """Validated unit vectors (..., 3) from any non-zero finite vectors.

    Raises :class:`ConfigError` naming ``what`` for a wrong shape or a zero or non-finite
    vector (it has no direction).
    """
    v = np.asarray(vectors, dtype=float)
    if v.ndim == 0 or v.shape[-1] != 3:
        raise ConfigError(f"{what} must have shape (..., 3), got {v.shape}")
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    if not np.all(np.isfinite(norm)) or np.any(norm == 0):
        raise ConfigError(f"{what} contain a zero or non-finite vector (no direction)")
    return v / norm


def angle_between_deg(a, b) -> np.ndarray:
    """Angle in degrees between direction vectors ``a`` and ``b`` (broadcast, (..., 3)).

    Uses atan2(|a x b|, a . b), which stays accurate for small and near-180 deg angles.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    dot = np.sum(a * b, axis=-1)
    return np.rad2deg(np.arctan2(cross, dot))


def rotation_zyx(yaw_deg: float = 0.0, pitch_deg: float = 0.0, roll_deg: float = 0.0) -> np.ndarray:
    """Rotation matrix (3, 3) of a frame turned by yaw (about z, left positive), then pitch
    (about the new y; positive pitches the nose *down*, the right-hand rule about +y), then
    roll (about the new x).

    The matrix maps head-frame coordinates to world coordinates: ``v_world = R @ v_head``.
    """
    y, p, r = np.deg2rad([yaw_deg, pitch_deg, roll_deg])
    cz, sz, cy, sy, cx, sx = np.cos(y), np.sin(y), np.cos(p), np.sin(p), np.cos(r), np.sin(r)
    rz = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]])
    return rz @ ry @ rx


def head_to_body_azimuth(v_head, yaw: float = 0.0, pitch: float = 0.0, *, heading: float = 0.0,
                         mirror: bool = False) -> float:
    """Azimuth (rad, + left, -pi..pi) in the body's frame of a head-frame direction, the head
    turned on the body by ``yaw`` then ``pitch`` (rad, the neck's proprioception):
    ``v = Rz(yaw) Ry(pitch) v_head`` (:func:`rotation_zyx`'s convention); ``heading`` (rad)
    turns the body itself (a wheelchair's odometry).

    ``mirror``: of the direction's front-back mirror image through the head's interaural
    axis, ``(-x, y, z)``, which interaural cues cannot tell from the direction itself.
    Scalar math: the policies call it every control step.
    """
    x, y, z = (float(c) for c in v_head)
    if mirror:
        x = -x
    x = x * math.cos(pitch) + z * math.sin(pitch)
    return (math.atan2(y, x) + yaw + heading + math.pi) % (2.0 * math.pi) - math.pi


def head_to_body_elevation(v_head, pitch: float = 0.0, *, mirror: bool = False) -> float:
    """Elevation (rad, + up, -pi/2..pi/2) in the body's frame of a head-frame direction, the
    head pitched by ``pitch`` (rad, + nose down) on the body: the companion of
    :func:`head_to_body_azimuth` (the yaw and the heading turn about the vertical and leave
    it unchanged); ``mirror`` as there. Scalar math, as there.
    """
    x, y, z = (float(c) for c in v_head)
    if mirror:
        x = -x
    n = math.sqrt(x * x + y * y + z * z)
    if not (n > 0.0 and math.isfinite(n)):
        raise ConfigError("a direction vector is zero or not finite: it has no elevation")
    return math.asin(max(-1.0, min(1.0, (z * math.cos(pitch) - x * math.sin(pitch)) / n)))


def lateral_deg(v_head) -> float:
    """Lateral angle (deg, + left, -90..90) of a head-frame vector: its angle to the head's
    median plane, the one angle that interaural cues give (every direction on the cone of
    confusion around the interaural axis has the same). The scripted ReverseAlarm and
    ParkingBrake policies' test of where a sound is, and the demo's narration of it. Scalar
    math: the policies call it every control step."""
    x, y, z = (float(c) for c in v_head)
    n = math.sqrt(x * x + y * y + z * z)
    return math.degrees(math.asin(max(-1.0, min(1.0, y / max(n, 1e-12)))))


def in_lateral_region(v_head, pitch: float = 0.0, *, lateral_range_deg: tuple,
                      elevation_deg: tuple = (-90.0, 90.0)) -> bool:
    """Whether a head-frame direction has a lateral angle (:func:`lateral_deg`) within
    ``lateral_range_deg`` and an elevation in the body's frame (the head pitched by ``pitch``,
    rad, + nose down; :func:`head_to_body_elevation`) within ``elevation_deg`` (lowest,
    highest; deg). The scripted ReverseAlarm policy's test of "the alarm's region" (the
    dashboard speaker and its front-back mirror image), and the demo's narration of it.
    """
    lo, hi = lateral_range_deg
    if not lo <= lateral_deg(v_head) <= hi:
        return False
    return elevation_deg[0] <= math.degrees(head_to_body_elevation(v_head, pitch)) <= elevation_deg[1]


def world_to_head(points_world, head_position, head_rotation) -> np.ndarray:
    """Express world points (..., 3) in the head frame given the head pose.

    ``head_rotation`` maps head to world (as from :func:`rotation_zyx`), so the inverse is
    its transpose.
    """
    p = np.asarray(points_world, dtype=float) - np.asarray(head_position, dtype=float)
    return p @ np.asarray(head_rotation, dtype=float)


def frame_end_sample(k, sample_rate: int = SAMPLE_RATE, frame_rate: float = FRAME_RATE):
    """Sample index at which ear frame ``k`` ends (exclusive): ``round(k * fs / frame_rate)``.

    Integer arithmetic (fs * 2 / 125 for 62.5 Hz) is used where the ratio allows, so the
    clock is exact over any number of frames; ties round half to even like ``round``.
    """
    k = np.asarray(k, dtype=np.int64)
    # frame_rate 62.5 = 125/2: compute fs*k*2/125 with integers to avoid float drift.
    num, den = (2 * sample_rate, 125) if frame_rate == 62.5 else (None, None)
    if num is None:
        return np.rint(k * (sample_rate / frame_rate)).astype(np.int64)
    q, rem = np.divmod(k * num, den)
    twice = 2 * rem
    up = (twice > den) | ((twice == den) & (q % 2 == 1))
    out = q + up
    return out if out.ndim else int(out)



class FrameEnds:
    """:func:`frame_end_sample` as a lookup for a stepping clock: the ends are computed 1024
    frames at a time, which keeps numpy's per-call overhead out of the control step (the
    coupling and the renderer each hold one)."""

    def __init__(self, sample_rate: int = SAMPLE_RATE, chunk: int = 1024) -> None:
        self.sample_rate = int(sample_rate)
        self._chunk = int(chunk)
        self._first, self._ends = 0, []

    def __call__(self, k: int) -> int:
        """The sample at which frame ``k`` ends (exclusive)."""
        i = k - self._first
        if not 0 <= i < len(self._ends):
            self._first, i = k, 0
            self._ends = frame_end_sample(np.arange(k, k + self._chunk), self.sample_rate).tolist()
        return self._ends[i]

def block_length(k, sample_rate: int = SAMPLE_RATE, frame_rate: float = FRAME_RATE) -> int:
    """Number of samples in control block ``k`` (from the end of frame k-1 to the end of frame k)."""
    return int(frame_end_sample(k, sample_rate, frame_rate) - frame_end_sample(k - 1, sample_rate, frame_rate))


def db_spl_to_pa(level_db: float) -> float:
    """RMS sound pressure in pascal of a level in dB SPL re 20 uPa."""
    return P_REF * 10.0 ** (np.asarray(level_db, dtype=float) / 20.0)


def pa_to_db_spl(pressure_rms) -> np.ndarray:
    """Level in dB SPL of an RMS pressure in pascal (silence gives -inf, never NaN)."""
    p = np.asarray(pressure_rms, dtype=float)
    with np.errstate(divide="ignore"):
        return 20.0 * np.log10(p / P_REF)
