"""pyroomacoustics' own binaural simulation of a scene: the reference the renderer is
tested and benchmarked against.

pyroomacoustics renders a head as two microphones whose directivities are the HRIRs of a
SOFA file (``MeasuredDirectivityFile``). Its behaviour, as measured for this project:

- both microphones go at the head centre: the HRIRs already carry the interaural delay;
- ``Rotation3D([yaw], "z")`` is an upright head facing +x (yaw 0) with +y to the left;
- a response starts after a fixed offset (half of its 81-tap fractional-delay filter) and
  carries the HRIR's own onset; the direct path falls as 1/r;
- its simulation re-runs the whole image-source model and directivity lookup per call,
  which is why it is the baseline for the renderer's speed-up.
"""

from __future__ import annotations

from pathlib import Path

import warnings

import numpy as np
import pyroomacoustics as pra
from pyroomacoustics.directivities import MeasuredDirectivityFile, Rotation3D

from acoustic_sim.acoustics.hrtf import sofa_left_receiver
from acoustic_sim.acoustics.room import Room
from acoustic_sim.frames import SAMPLE_RATE

PRA_OFFSET = pra.constants.get("frac_delay_length") // 2
"""Fixed delay (samples) pyroomacoustics adds to every response."""


class PraBinaural:
    """pyroomacoustics simulating a binaural head in a room, one pose per call.

    Parameters
    ----------
    sofa_path : path
        SimpleFreeFieldHRIR SOFA file; its left ear is the receiver that ``HRTF.load``
        takes for it (:func:`~acoustic_sim.acoustics.hrtf.sofa_left_receiver`).
    room : Room
        The room (its ``ism_order`` unless ``max_order`` is given).
    """

    def __init__(self, sofa_path, room: Room, *, max_order: int | None = None, sample_rate: int = SAMPLE_RATE) -> None:
        self.room = room
        self.max_order = room.ism_order if max_order is None else max_order
        self.sample_rate = sample_rate
        # Building a directivity object takes about a second; pyroomacoustics lets a
        # built one be re-oriented, which is what a fair per-pose baseline does.
        with warnings.catch_warnings():  # it warns that it resamples with scipy (it need not resample at all)
            warnings.simplefilter("ignore", UserWarning)
            self.file = MeasuredDirectivityFile(Path(sofa_path), fs=sample_rate)
        front = Rotation3D([0.0], "z", degrees=True)
        left = sofa_left_receiver(Path(sofa_path))
        self.ears = [self.file.get_mic_directivity(left, front), self.file.get_mic_directivity(1 - left, front)]

    def brir(self, source_position, head_position, head_yaw_deg: float = 0.0) -> np.ndarray:
        """Binaural response (2, n) for one pose, exactly as pyroomacoustics computes it."""
        orientation = Rotation3D([head_yaw_deg], "z", degrees=True)
        for ear in self.ears:
            ear.set_orientation(orientation)
        shoebox = self.room.pra_room(max_order=self.max_order, fs=self.sample_rate)
        shoebox.add_source(list(np.asarray(source_position, float)))
        head = np.asarray(head_position, float)
        mics = pra.MicrophoneArray(
            np.stack([head, head], axis=1),
            fs=self.sample_rate,
            directivity=self.ears,
        )
        shoebox.add_microphone_array(mics)
        shoebox.compute_rir()
        rirs = [np.asarray(shoebox.rir[m][0], float) for m in range(2)]
        n = max(len(r) for r in rirs)
        return np.stack([np.pad(r, (0, n - len(r))) for r in rirs])
