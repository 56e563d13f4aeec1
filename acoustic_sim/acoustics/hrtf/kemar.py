"""The bundled MIT KEMAR set: where its SOFA file lies and its measurement grid."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from acoustic_sim.frames import sph_to_vec

ASSET_DIR = Path(__file__).resolve().parents[3] / "assets" / "hrtf"
"""Folder of the bundled HRTF data (``assets/hrtf`` in the repository)."""

KEMAR_PATH = ASSET_DIR / "mit_kemar_normal_pinna.sofa"
"""The bundled MIT KEMAR normal-pinna set (see ``assets/hrtf/README.md``)."""

# Elevation rings of the MIT KEMAR measurement: (elevation deg, number of azimuths).
_KEMAR_RINGS = ((-40, 56), (-30, 60), (-20, 72), (-10, 72), (0, 72), (10, 72), (20, 72),
                (30, 60), (40, 56), (50, 45), (60, 36), (70, 24), (80, 12), (90, 1))


def kemar_directions() -> np.ndarray:
    """The 710 MIT KEMAR measurement directions.

    Elevation rings every 10 deg from -40 to 90 deg, azimuths equally spaced from 0 deg
    (counter-clockwise) with the ring's count; the same order as the bundled SOFA file.

    Returns
    -------
    numpy.ndarray, shape (710, 3)
        Unit vectors in the head frame.
    """
    az = np.concatenate([np.arange(n) * 360.0 / n for _, n in _KEMAR_RINGS])
    el = np.concatenate([np.full(n, float(e)) for e, n in _KEMAR_RINGS])
    return sph_to_vec(az, el)
