"""Stand-in detectors for the direction stage's tests (not test modules themselves)."""

import numpy as np


class AlwaysDetects:
    """A detector that declares every class in every frame, all bins characteristic:
    isolates the direction stage."""

    def __init__(self, real):
        self.classes = real.classes
        self.characteristic_bins = {}

    def predict(self, patch):
        return np.ones((2, len(self.classes)), np.float32)
