"""The robot's ears: an HRTF set whose right pinna is turned about the interaural axis.

Why the robot's ears are not mirror images: with mirror-symmetric ears (MIT KEMAR's
normal-pinna set is the left ear mirrored), every direction in the median plane gives
ILD = 0 and IPD = 0 at every frequency, so interaural features (the paper's only input to
SSDENet) cannot tell front from back or up from down there, and no network can. The
paper's robot discriminates top and bottom in the median plane (its Fig. 12e), which needs
interaural spectral differences: hand-mounted ear units (and human ears) are not exact
mirror images.
"""

from __future__ import annotations

import math

import numpy as np

from acoustic_sim.errors import ConfigError

MUSASHI_RIGHT_PINNA_TILT_DEG = 10.0
"""Tilt (deg) of the robot's right pinna about the interaural axis, relative to the left.

10 deg moves the right ear's pinna notch by about one KEMAR elevation step, an asymmetry of
the order that human pinnae show in orientation (why the ears differ at all: the module
docstring). Measurements: docs/notes/hrtf.md."""


def tilted_right_pinna(base, tilt_deg: float, *, name: str):
    """``base`` with its right ear's pinna turned by ``tilt_deg`` about the interaural axis.

    The right ear hears direction ``d`` as ``base``'s right ear hears ``R_y(tilt) d``
    (``R_y`` a rotation about the head's y axis, the interaural axis: positive tilts the
    pinna's front edge down, so a source in front sounds to it as if higher, a source behind
    as if lower). A rotation about the interaural axis keeps each direction's lateral angle,
    and so the interaural time difference, while moving the pinna's spectral features along
    the cone of confusion. Right-ear responses come from
    :meth:`~acoustic_sim.acoustics.hrtf.HRTF.hrirs_for` with ``mode="interpolated"``
    (rotated directions below the base set's lowest elevation fall back to the nearest
    measured one); the left ear is unchanged. Directions are the base set's; the result is
    normalized like a loaded set.

    Parameters
    ----------
    base : acoustic_sim.acoustics.hrtf.HRTF
        The set whose right pinna is turned.
    tilt_deg : float
        Tilt in degrees, -45..45 (positive: the pinna's front edge down).
    name : str
        Name of the new set.

    Returns
    -------
    acoustic_sim.acoustics.hrtf.HRTF
        A set of ``base``'s class on ``base``'s D directions, HRIRs (D, 2, K').

    Raises
    ------
    ConfigError
        ``tilt_deg`` is not finite or outside +-45 deg.
    """
    if not np.isfinite(tilt_deg) or abs(tilt_deg) > 45.0:
        raise ConfigError(f"tilt_deg must be within +-45 deg, got {tilt_deg}")
    a = math.radians(float(tilt_deg))
    rot = np.array([[math.cos(a), 0.0, -math.sin(a)], [0.0, 1.0, 0.0], [math.sin(a), 0.0, math.cos(a)]])
    dirs = np.asarray(base.directions)
    right = base.hrirs_for(dirs @ rot.T, mode="interpolated")[:, 1]
    hrir = np.stack([np.asarray(base.hrir)[:, 0], right], axis=1)
    # The base set's own class builds the result (this module cannot import it: HRTF.load
    # makes the "musashi" set with this function).
    return type(base)._from_measurement(
        hrir, dirs, base.sample_rate, name=name, distance_m=base.distance_m,
        source=f"{base.source}; right pinna tilted {tilt_deg:g} deg about the interaural axis")
