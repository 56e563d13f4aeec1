"""The paper's HRTF measurement, run in a simulated room.

As in the paper ("HRTF measurement"): a loudspeaker stands at a fixed distance in front of
a dummy head that turns (azimuth and elevation servos) to each direction of the grid; the
loudspeaker plays white noise, both ears record through the microphone board, and the
transfer function from the played signal to each ear is estimated. Because the recording is
made in a room, the result contains the room's reflections that arrive within ``taps``
samples (the paper measured in a conference room with RT60 0.55-0.60 s and 35 dB SPL
background): with the default 512 taps (11.6 ms) SSDENets trained on it see the room's
early reflections; ``acoustic-sim eval paper`` cuts at 128 taps, before the first one
(:data:`acoustic_sim.experiments.paper.MEASURED_TAPS`).

Estimator: H1 = S_xy / S_xx (Welch, Hann windows of :data:`SEGMENT` samples or ``2 * taps``
if longer, 50% overlap), robust to the background and microphone noise on the ear signals.
The impulse response is then aligned like a free-field HRIR: the propagation delay from the
loudspeaker to the head centre is removed and the 1/r spreading undone, so ``HRTF.load`` can
use it directly; it is cut at ``taps`` samples (a gate: reflections arriving later are not
in it).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy import signal
from acoustic_sim.progress import progress_bar

from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.acoustics.microphone import FULL_SCALE_PA, Microphone
from acoustic_sim.acoustics.renderer import BinauralRenderer
from acoustic_sim.acoustics.room import room_preset
from acoustic_sim.directions import DirectionGrid
from acoustic_sim.errors import ConfigError
from acoustic_sim.files import check_writable
from acoustic_sim.frames import SAMPLE_RATE, SPEED_OF_SOUND, rotation_zyx, vec_to_sph

PRE_DELAY = 32
"""Samples kept before the sound reaches the head centre in a measured response."""

NOISE_LEVEL_DB = 75.0
"""Level of the measurement noise at the head (dB SPL), as in the paper's room tests."""

SEGMENT = 8192
"""Shortest Welch segment of the estimate (samples, 186 ms). The first version used segments
of ``2 * taps``: a segment much shorter than the room's response smooths the estimate over
the room's reverberation instead of cutting the response at ``taps``. Measured against the
true ears (musashi, 40 directions in the conference room, mean |ILD error| over 0.5-12 kHz):
``taps=128`` 9.6 dB with segments of 256 samples, 1.5 dB with 8192; ``taps=512`` 3.2 dB
with 1024 and 5.4 dB with 8192 (the room's reflections in the first 11.6 ms, now kept at
their full level, are part of what is measured); in the anechoic room, ``taps=512``, 0.8 dB
with 1024 and 0.1 dB with 8192."""


def measure_hrtf(
    *, hrtf="kemar", room="conference", rt60=None, distance_m=1.5, seconds=1.0, taps=512, max_directions=None,
    seed=0, out, progress=True,
) -> dict:
    """Measure an HRTF set over the paper's direction grid in a room; write it as SOFA.

    Parameters
    ----------
    hrtf : str or HRTF
        The ears being measured.
    room : str
        Room preset name (see :func:`room_preset`).
    distance_m : float
        Loudspeaker distance from the head centre (m), 0.3-5.
    seconds : float
        White-noise length recorded per direction (s), 0.1-10.
    taps : int
        Length of the measured impulse responses (samples), 64-4096.
    max_directions : int, optional
        Measure an evenly spread subset of the grid (quick runs and tests).
    out : path
        Output ``.sofa`` file.
    """
    out = Path(out)
    if out.suffix.lower() != ".sofa":
        raise ConfigError(f"--out must be a .sofa path, got {out}")
    if not 0.3 <= distance_m <= 5.0:
        raise ConfigError(f"distance must be 0.3-5 m, got {distance_m}")
    if not 0.1 <= seconds <= 10.0:
        raise ConfigError(f"seconds must be 0.1-10, got {seconds}")
    if not 64 <= int(taps) <= 4096:
        raise ConfigError(f"taps must be 64-4096, got {taps}")
    if max_directions is not None and max_directions < 1:
        raise ConfigError(f"max-directions must be >= 1, got {max_directions}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError(f"seed must be an integer >= 0, got {seed!r}")
    check_writable(out, what="--out")
    rng = np.random.default_rng(seed)
    ears = hrtf if isinstance(hrtf, HRTF) else HRTF.load(hrtf)
    space = room_preset(room, rt60=rt60)
    grid = DirectionGrid.paper(ears)
    vectors = grid.vectors
    if max_directions is not None:
        vectors = vectors[np.linspace(0, len(vectors) - 1, min(max_directions, len(vectors))).round().astype(int)]

    head = np.asarray(space.listener, float)
    speaker = head + np.array([distance_m, 0.0, 0.0])
    space.check_inside(speaker, what=f"loudspeaker at {distance_m} m in front of the head")
    renderer = BinauralRenderer(ears, space, rng=rng)
    noise = rng.standard_normal(int(round((seconds + 0.5) * SAMPLE_RATE * len(vectors))) + SAMPLE_RATE)
    level_at_1m = NOISE_LEVEL_DB + 20 * np.log10(distance_m)
    source = renderer.add_source("loudspeaker", noise, speaker, level_db=level_at_1m, start=0)
    mic = Microphone(rng=rng)
    n_rec = int(round(seconds * SAMPLE_RATE))
    nperseg = min(max(SEGMENT, 2 * int(taps)), n_rec)
    # Keep PRE_DELAY samples before the arrival at the head centre: the nearer ear hears
    # the sound up to half an interaural delay (~0.35 ms, 15 samples) earlier.
    bulk = distance_m / SPEED_OF_SOUND * SAMPLE_RATE - PRE_DELAY
    shift = int(np.floor(bulk))
    frac = bulk - shift

    irs = np.zeros((len(vectors), 2, int(taps)))
    fade = np.ones(int(taps))
    n_fade = int(taps) // 8  # not fade[-taps // 8:]: that is (-taps) // 8, one too many
    fade[int(taps) - n_fade :] = np.hanning(2 * n_fade)[n_fade:]
    for i, d in enumerate(progress_bar(vectors, desc="measuring HRTF", unit="dir", disable=not progress)):
        az, el = vec_to_sph(d)
        # Turn the head so that the loudspeaker (+x in the room) is at direction d.
        renderer.set_head_pose(head, rotation_zyx(float(az), -float(el)).T)
        settle = renderer.early_response(source)[0].shape[1] + 2 * int(taps)
        renderer.render(settle / SAMPLE_RATE)  # let the old orientation's early sound pass
        start = renderer.sample
        recorded = mic(renderer.render(n_rec / SAMPLE_RATE)).astype(float) * FULL_SCALE_PA
        played = source.emitted(start, n_rec)
        _, sxx = signal.welch(played, nperseg=nperseg)
        for e in range(2):
            _, sxy = signal.csd(played, recorded[e], nperseg=nperseg)
            ir = np.fft.irfft(sxy / np.maximum(sxx, 1e-30), n=nperseg)
            # Remove the propagation delay (integer part by shifting, fraction by phase)
            # and undo 1/r, so the response is referenced to the free field at the head.
            spec = np.fft.rfft(np.roll(ir, -shift)) * np.exp(2j * np.pi * np.fft.rfftfreq(nperseg) * frac)
            irs[i, e] = np.fft.irfft(spec, n=nperseg)[: int(taps)] * fade * distance_m
    measured = HRTF(
        irs, vectors, SAMPLE_RATE, name=out.stem, distance_m=distance_m,
        source=f"acoustic-sim measure-hrtf: {ears.name} in {space.name} at {distance_m} m, seed {seed}",
    )
    measured.save_sofa(out)
    return {"out": str(out), "directions": len(vectors), "taps": int(taps), "hrtf": ears.name, "room": space.name,
            "rt60_s": round(space.rt60_s, 3), "distance_m": distance_m}
