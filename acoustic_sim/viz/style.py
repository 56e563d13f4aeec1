"""Colours of a recording: one per sound class, and the colour map of the direction maps
and spectrograms.

Pure functions of their arguments (no randomness), so two recordings of the same episode
look the same.
"""

from __future__ import annotations

import numpy as np

# The six classes of acoustics.sounds.SOUND_CLASSES, plus the distractor-only names that
# tasks may label sources with; anything else falls back to PALETTE by position.
CLASS_COLORS: dict[str, tuple[int, int, int]] = {
    "car_horn": (255, 127, 14),
    "reverse_alarm": (214, 39, 40),
    "ratchet": (31, 119, 180),
    "gearshift": (148, 103, 189),
    "key_turning": (188, 189, 34),
    "human_voice": (44, 160, 44),
    "white_noise": (127, 127, 127),
}

PALETTE: tuple[tuple[int, int, int], ...] = (
    (23, 190, 207), (227, 119, 194), (140, 86, 75), (255, 187, 120), (152, 223, 138), (174, 199, 232),
)

TRUE_COLOR = (255, 255, 255)
"""Colour of the ground-truth direction arrows (the estimate takes its class colour)."""

# Viridis sampled at 9 points; interpolated to 256 entries.
_VIRIDIS_ANCHORS = np.array([
    (68, 1, 84), (72, 40, 120), (62, 74, 137), (49, 104, 142), (38, 130, 142),
    (31, 158, 137), (53, 183, 121), (109, 205, 89), (253, 231, 37),
], dtype=np.float64)


def class_color(name: str, classes: tuple[str, ...] = ()) -> tuple[int, int, int]:
    """RGB (0..255) of a sound class: a fixed colour for known classes, else by position."""
    if name in CLASS_COLORS:
        return CLASS_COLORS[name]
    idx = classes.index(name) if name in classes else sum(map(ord, name))
    return PALETTE[idx % len(PALETTE)]


def colormap_lut(n: int = 256) -> np.ndarray:
    """uint8 (n, 3): a viridis-like colour map, dark (low) to yellow (high)."""
    x = np.linspace(0.0, 1.0, len(_VIRIDIS_ANCHORS))
    t = np.linspace(0.0, 1.0, n)
    return np.stack([np.interp(t, x, _VIRIDIS_ANCHORS[:, c]) for c in range(3)], axis=1).round().astype(np.uint8)
