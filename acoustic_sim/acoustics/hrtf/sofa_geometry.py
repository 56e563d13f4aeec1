"""A SOFA file's geometry in the head frame, for :mod:`acoustic_sim.acoustics.hrtf.sofa_read`:
source positions (:func:`positions_to_cartesian`), the listener's orientation
(:func:`listener_frame`) and which receiver is the left ear (:func:`left_receiver`:
``ReceiverPosition`` checked against the data, for the metadata is wrong in some public sets
and files of an old Matlab/Octave SOFA API store the ears' y mirrored).
"""

from __future__ import annotations

import re
import warnings

import numpy as np

from acoustic_sim.errors import HRTFError
from acoustic_sim.frames import sph_to_vec

# --------------------------------------------------------------------------------------
# Positions and orientation
# --------------------------------------------------------------------------------------


def positions_to_cartesian(pos, kind, units, path, name) -> np.ndarray:
    """Positions of the file's coordinate type as cartesian coordinates.

    Parameters
    ----------
    pos : numpy.ndarray, shape (M, 3)
        Cartesian (x, y, z in m) or spherical (azimuth, elevation, radius: degrees unless
        ``units`` mentions radians; radius in m) positions.
    kind : str or None
        ``"cartesian"`` or ``"spherical"`` (the default when None), case-insensitive.
    units : str or None
        The file's units string, e.g. ``"degree, degree, metre"``.
    path : str or os.PathLike
        The file, for the messages.
    name : str
        The variable, e.g. ``"SourcePosition"``, for the messages.

    Returns
    -------
    numpy.ndarray, shape (M, 3)
        x, y, z in m (a copy).

    Raises
    ------
    HRTFError
        ``kind`` is neither spherical nor cartesian.
    """
    kind = str(kind or "spherical").strip().lower()
    if kind == "cartesian":
        return pos.copy()
    if kind != "spherical":
        raise HRTFError(f"{path}: {name}_Type {kind!r} is not supported (spherical or cartesian)")
    ang = pos[:, :2]
    if "rad" in str(units or "").lower():
        ang = np.rad2deg(ang)
    return sph_to_vec(ang[:, 0], ang[:, 1]) * pos[:, 2:3]


def listener_frame(sofa, path) -> np.ndarray | None:
    """Rotation from the file's frame to the listener's head frame.

    Parameters
    ----------
    sofa : sofar.Sofa
        The file's content: ``ListenerView`` and ``ListenerUp`` (cartesian, or spherical in
        degrees), one each; ``ListenerUp`` defaults to +z.
    path : str or os.PathLike
        The file, for the messages.

    Returns
    -------
    numpy.ndarray, shape (3, 3), or None
        Rows: the head's x, y, z axes in the file's frame; None without ``ListenerView`` or
        when the frames agree.

    Raises
    ------
    HRTFError
        One view per measurement, a zero vector, or parallel view and up vectors.
    """
    view = getattr(sofa, "ListenerView", None)
    up = getattr(sofa, "ListenerUp", None)
    if view is None:
        return None
    view = np.atleast_2d(np.asarray(view, dtype=float))
    up = np.atleast_2d(np.asarray(up if up is not None else [0.0, 0.0, 1.0], dtype=float))
    if view.shape[0] != 1 or up.shape[0] != 1 or view.shape[1] != 3 or up.shape[1] != 3:
        raise HRTFError(f"{path}: a ListenerView/ListenerUp per measurement is not supported")
    vtype = str(getattr(sofa, "ListenerView_Type", "cartesian")).lower()
    if vtype == "spherical":
        view = sph_to_vec(view[0, 0], view[0, 1])[None]
        up = sph_to_vec(up[0, 0], up[0, 1])[None]
    x, z = view[0], up[0]
    if np.linalg.norm(x) == 0 or np.linalg.norm(z) == 0:
        raise HRTFError(f"{path}: ListenerView or ListenerUp is a zero vector")
    x = x / np.linalg.norm(x)
    z = z - x * (z @ x)
    if np.linalg.norm(z) < 1e-9:
        raise HRTFError(f"{path}: ListenerView and ListenerUp are parallel")
    z = z / np.linalg.norm(z)
    rot = np.stack([x, np.cross(z, x), z])
    return None if np.allclose(rot, np.eye(3)) else rot


# --------------------------------------------------------------------------------------
# Which receiver is the left ear
# --------------------------------------------------------------------------------------

ARI_API_NAME = "ARI SOFA API for Matlab/Octave"
"""``GLOBAL_APIName`` of the SOFA API whose versions up to :data:`ARI_MIRRORED_UP_TO` can
store ``ReceiverPosition`` with the ears' y mirrored while receiver 0 is still the left ear."""

ARI_MIRRORED_UP_TO = (1, 1, 0)
"""Last ``GLOBAL_APIVersion`` (major, minor, patch) of that API with the mirrored positions."""

EAR_LEVEL_MIN_DB = 3.0
"""Least broadband level difference (dB) between the ears, at a side's most lateral source
directions, for the data to say which ear faces that side."""

LATERAL_MIN = 0.5
"""Least |interaural component| (sine of the lateral angle: 30 deg off the median plane) of
a side's most lateral direction for the data check to use that side."""

LATERAL_SPREAD = 0.1
"""Directions within this of the most lateral interaural component on a side are its most
lateral directions (about the 26 deg cone around the interaural axis when it is measured)."""


def _parse_version(text) -> tuple[int, int, int] | None:
    """``(major, minor, patch)`` of a version string ``"a.b.c"``, or None if it is not one."""
    match = re.fullmatch(r"\s*(\d+)\.(\d+)\.(\d+)\s*", str(text or ""))
    return tuple(int(g) for g in match.groups()) if match else None


def ari_mirrored_receivers(sofa) -> bool:
    """Whether the file was written by the ARI SOFA API for Matlab/Octave up to 1.1.0.

    libmysofa (``src/hrtf/check.c``, ``mysofa_check``) accepts a file whose first receiver
    has a negative y only if ``APIName`` is :data:`ARI_API_NAME` and ``APIVersion``, read as
    three integers ``a.b.c``, is at most 1.1.0; it then logs a warning and keeps receiver 0
    as the left ear. A version that does not parse as three integers does not qualify.

    Parameters
    ----------
    sofa : sofar.Sofa
        The file's content (any object with ``GLOBAL_APIName`` / ``GLOBAL_APIVersion``
        attributes; missing ones count as empty).

    Returns
    -------
    bool
        True for :data:`ARI_API_NAME` at a version <= :data:`ARI_MIRRORED_UP_TO`.
    """
    if str(getattr(sofa, "GLOBAL_APIName", "") or "").strip() != ARI_API_NAME:
        return False
    version = _parse_version(getattr(sofa, "GLOBAL_APIVersion", None))
    return version is not None and version <= ARI_MIRRORED_UP_TO


def receiver_y(sofa) -> np.ndarray | None:
    """The interaural (y) coordinate of each of the two receivers.

    Per-measurement positions (``R, C, M``) count only when the two receivers keep their
    order in every measurement (the first measurement's are returned then).

    Parameters
    ----------
    sofa : sofar.Sofa
        The file's content: ``ReceiverPosition`` (2, 3) or (2, 3, M), cartesian in m or
        spherical (degrees unless the units say radians).

    Returns
    -------
    numpy.ndarray, shape (2,), or None
        y in m of receiver 0 and 1; None when ``ReceiverPosition`` is absent, not two finite
        positions, of another coordinate type, or the receivers swap sides between
        measurements.
    """
    rec = getattr(sofa, "ReceiverPosition", None)
    if rec is None or isinstance(rec, str):
        return None
    try:
        rec = np.asarray(np.ma.filled(np.ma.asarray(rec, dtype=float), np.nan))
    except (TypeError, ValueError):
        return None
    if rec.ndim == 2:
        rec = rec[:, :, None]
    if rec.ndim != 3 or rec.shape[:2] != (2, 3) or rec.shape[2] == 0 or not np.all(np.isfinite(rec)):
        return None
    rtype = str(getattr(sofa, "ReceiverPosition_Type", "cartesian") or "cartesian").strip().lower()
    if rtype == "spherical":
        ang = rec[:, :2]
        if "rad" in str(getattr(sofa, "ReceiverPosition_Units", "") or "").lower():
            ang = np.rad2deg(ang)
        y = np.sin(np.deg2rad(ang[:, 0])) * np.cos(np.deg2rad(ang[:, 1])) * rec[:, 2]  # (2, M)
    elif rtype == "cartesian":
        y = rec[:, 1]
    else:
        return None
    order = np.sign(y[0] - y[1])
    if not np.all(order == order[0]):
        return None
    return y[:, 0]


def _ears_by_data(ir: np.ndarray, directions: np.ndarray):
    """(left receiver 0 or 1, or None; why) from the levels at the most lateral directions."""
    energy = np.sum(np.asarray(ir, dtype=float) ** 2, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        level = 10 * np.log10(energy[:, 0] / energy[:, 1])  # receiver 0 over receiver 1, dB
    y = np.asarray(directions)[:, 1]
    sides = []
    for sign, name in ((1.0, "left"), (-1.0, "right")):
        lateral = sign * y
        if lateral.max() < LATERAL_MIN:
            continue
        near = lateral >= lateral.max() - LATERAL_SPREAD
        # For a source on the left, the left ear is the louder: receiver 0 is left if its
        # level is higher there (sign +1), and if it is lower for sources on the right.
        sides.append((name, float(sign * np.median(level[near])), int(near.sum())))
    if not sides:
        return None, (f"no source direction is {np.degrees(np.arcsin(LATERAL_MIN)):.0f} deg or more off "
                      "the median plane, so the levels cannot tell the ears apart")
    said = "; ".join(f"sources on the {n} ({k} directions): receiver 0 is {abs(d):.1f} dB "
                     f"{'louder' if d * (1 if n == 'left' else -1) > 0 else 'quieter'}" for n, d, k in sides)
    if any(abs(d) < EAR_LEVEL_MIN_DB for _, d, _ in sides):
        return None, f"the ears' levels differ by less than {EAR_LEVEL_MIN_DB:g} dB ({said})"
    votes = {0 if d > 0 else 1 for _, d, _ in sides}
    if len(votes) > 1:
        return None, f"the levels contradict each other: one receiver is louder for sources on both sides ({said})"
    return votes.pop(), said


def left_receiver(sofa, ir: np.ndarray, directions: np.ndarray, path) -> int:
    """Index (0 or 1) of the receiver that is the left ear, checked against the data.

    Parameters
    ----------
    sofa : sofar.Sofa
        The file's content (``ReceiverPosition``, ``GLOBAL_APIName``, ``GLOBAL_APIVersion``).
    ir : numpy.ndarray, shape (M, 2, N)
        ``Data.IR`` in the file's receiver order (dimensionless, finite); no response is all
        zeros.
    directions : numpy.ndarray, shape (M, 3)
        Unit source directions in the head frame (y toward the left ear).
    path : str or os.PathLike
        The file, for the messages.

    Returns
    -------
    int
        0 or 1: the receiver that is the left ear.

    Raises
    ------
    HRTFError
        Neither ``ReceiverPosition`` nor the data tell the ears apart.

    Two witnesses. The metadata: the receiver with the larger y in ``ReceiverPosition`` is
    the left ear, except in a file of the ARI SOFA API for Matlab/Octave <= 1.1.0
    (:func:`ari_mirrored_receivers`), whose positions may be mirrored: there receiver 0 is
    the left ear, as libmysofa reads it. The data: for the most lateral source directions on
    each side, the ear facing the source carries the more energy (by at least
    :data:`EAR_LEVEL_MIN_DB`, on every side measured).

    Agreeing witnesses, or data that cannot tell, leave the metadata's answer, silently
    (an ARI file whose data confirm receiver 0 = left needs no message: nothing is in
    doubt). Data that clearly contradict the metadata win, with a warning naming the file.
    An ARI file with mirrored positions whose data cannot tell keeps receiver 0 = left
    (libmysofa's reading) with a warning. Without a usable ``ReceiverPosition`` the data
    decide (a warning if they put the left ear second); if they cannot tell either:
    :class:`~acoustic_sim.errors.HRTFError`.
    """
    y = receiver_y(sofa)
    by_data, why = _ears_by_data(ir, directions)
    if y is None or abs(y[0] - y[1]) < 1e-9:
        meta, meta_says = None, "ReceiverPosition does not tell the ears apart"
    elif y[0] < y[1] and ari_mirrored_receivers(sofa):
        meta = 0
        meta_says = (f"written by the {ARI_API_NAME} {getattr(sofa, 'GLOBAL_APIVersion', '')}, whose "
                     "ReceiverPosition has the ears' y mirrored: receiver 0 is the left ear")
        if by_data is None:
            warnings.warn(f"{path}: {meta_says} (as libmysofa reads it); the data cannot confirm it: {why}",
                          stacklevel=4)
            return 0
    else:
        meta = 0 if y[0] > y[1] else 1
        meta_says = f"ReceiverPosition puts receiver {meta} on the left (larger y)"
    if by_data is None:
        if meta is None:
            raise HRTFError(f"{path}: cannot tell which receiver is the left ear: {meta_says}, and {why}")
        return meta
    if meta is not None and by_data != meta:
        warnings.warn(f"{path}: {meta_says}, but the data say receiver {by_data} is the left ear ({why}); "
                      f"using receiver {by_data} as the left ear", stacklevel=4)
    elif meta is None and by_data != 0:  # the usual order is left first: say why not here
        warnings.warn(f"{path}: {meta_says}; the data say receiver 1 is the left ear ({why})", stacklevel=4)
    return by_data
