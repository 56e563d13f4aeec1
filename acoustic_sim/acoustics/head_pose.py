"""The head pose the renderer is given: a position in the room and a proper rotation."""

from __future__ import annotations

import numpy as np

from acoustic_sim.errors import ConfigError


def rotation_tuple(rotation) -> tuple[np.ndarray, tuple]:
    """Check a head-to-room rotation and return it as an array and as a row-major tuple.

    Parameters
    ----------
    rotation : array_like, shape (3, 3)
        A proper rotation: orthonormal (each row's squared norm within 1.1e-5 of 1, rows
        orthogonal within 1e-6) with determinant +1. A reflection (determinant -1, e.g.
        ``diag(1, -1, 1)``) is refused: it would render a mirrored world, left and right
        ears swapped.

    Returns
    -------
    matrix : numpy.ndarray, shape (3, 3), float64
    entries : tuple of 9 float
        The same, row-major (the renderer's per-block arithmetic is scalar).

    Raises
    ------
    ConfigError
        ``rotation`` is not a proper rotation.
    """
    r = np.asarray(rotation, float)
    rot = tuple(r.ravel().tolist()) if r.shape == (3, 3) else (np.nan,) * 9
    # R R^T = I within numpy.allclose(atol=1e-6) tolerances, in scalar arithmetic:
    # this runs every control step (NaN fails every comparison). Orthonormal rows
    # make the determinant +-1 within ~2e-5, so its sign tells rotation from reflection.
    a, b, c, d, e, f, g, h, i = rot
    if not (
        abs(a * a + b * b + c * c - 1.0) <= 1.1e-5
        and abs(d * d + e * e + f * f - 1.0) <= 1.1e-5
        and abs(g * g + h * h + i * i - 1.0) <= 1.1e-5
        and abs(a * d + b * e + c * f) <= 1e-6
        and abs(a * g + b * h + c * i) <= 1e-6
        and abs(d * g + e * h + f * i) <= 1e-6
    ):
        raise ConfigError(f"head rotation must be a 3x3 rotation matrix, got {r.tolist()}")
    if a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g) <= 0.0:
        raise ConfigError(f"head rotation must be a proper rotation (determinant +1), got a reflection {r.tolist()}")
    return r, rot
