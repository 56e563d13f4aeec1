"""Speech from the espeak-ng library that pip installs (the ``espeakng-loader`` wheel).

The wheel bundles ``libespeak-ng`` and its data (espeak-ng 1.52.0), so every machine that
installs the project speaks with the same engine, and models trained on its voices are the
same everywhere; no Debian package is involved.

Each phrase is synthesized in a fresh interpreter (``python -I -S``, about 40 ms): the
library keeps state between phrases (measured: the same phrase and voice said twice in one
process differs in length and samples), so in-process synthesis would make a voice depend on
what was said before it. A new process per phrase is what the ``espeak-ng`` program gave too.
The worker also fixes the seed of the library's noise source (``espeak_ng_SetRandSeed``),
which ``espeak_Initialize`` takes from the clock: otherwise a phrase changes every second.
"""

from __future__ import annotations

import functools
import io
import subprocess
import sys
from pathlib import Path

import numpy as np
import soundfile as sf

from acoustic_sim.errors import SoundError

TIMEOUT_S = 20.0
"""Longest a phrase may take to synthesize, in s."""

# Run with -I -S: no site packages and no user environment, only ctypes and wave. Writes a
# 16-bit mono WAV at the library's rate to stdout.
_WORKER = r"""
import ctypes, io, sys, wave
lib_path, data_path, voice, pitch, rate = sys.argv[1:6]
text = sys.stdin.buffer.read() + b"\0"
lib = ctypes.CDLL(lib_path)
sr = lib.espeak_Initialize(2, 0, data_path.encode(), 0x8000)  # synchronous, no phoneme events
if sr <= 0:
    sys.exit("espeak_Initialize failed")
lib.espeak_ng_SetRandSeed(ctypes.c_long(1))  # Initialize seeds its noise from the clock (time(NULL))
chunks = []
CB = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.POINTER(ctypes.c_short), ctypes.c_int, ctypes.c_void_p)
def collect(wav, n, events):
    if n > 0:
        chunks.append(ctypes.string_at(wav, 2 * n))
    return 0
callback = CB(collect)
lib.espeak_SetSynthCallback(callback)
if lib.espeak_SetVoiceByName(voice.encode()) != 0:
    sys.exit(f"unknown voice {voice!r}")
lib.espeak_SetParameter(1, int(rate), 0)   # espeakRATE, words per minute
lib.espeak_SetParameter(3, int(pitch), 0)  # espeakPITCH, 0-99
if lib.espeak_Synth(text, len(text), 0, 1, 0, 1 | 0x1000, None, None) != 0:  # UTF-8, end pause
    sys.exit("espeak_Synth failed")
lib.espeak_Synchronize()
buf = io.BytesIO()
with wave.open(buf, "wb") as w:
    w.setnchannels(1); w.setsampwidth(2); w.setframerate(sr)
    w.writeframes(b"".join(chunks))
sys.stdout.buffer.write(buf.getvalue())
"""


@functools.lru_cache(maxsize=1)
def _paths() -> tuple[str, str] | None:
    try:
        import espeakng_loader

        lib, data = espeakng_loader.get_library_path(), espeakng_loader.get_data_path()
    except (ImportError, RuntimeError, OSError):
        return None
    return (lib, data) if Path(lib).is_file() else None


def available() -> bool:
    """Whether the bundled espeak-ng library is installed on this machine."""
    return _paths() is not None


VERSION = "espeak-ng 1.52.0 (espeakng-loader 0.2.4, noise seed 1)"
"""The engine :func:`synthesize` speaks with; models trained on its voices record it."""


def synthesize(text: str, voice: str, pitch: int, speed: int) -> tuple[np.ndarray, int]:
    """Say ``text`` with an espeak-ng voice.

    Parameters
    ----------
    text : str
        The phrase (UTF-8).
    voice : str
        An espeak-ng voice name with an optional variant, e.g. ``"en-us+f3"``.
    pitch : int
        Base pitch, 0-99 (espeak-ng's scale).
    speed : int
        Speaking rate in words per minute, 80-450.

    Returns
    -------
    samples : numpy.ndarray, shape (n,), float64
        In [-1, 1].
    sample_rate : int
        The library's output rate in Hz (22050).

    Raises
    ------
    SoundError
        The library is not installed, or synthesis failed or timed out.
    """
    paths = _paths()
    if paths is None:
        raise SoundError("espeak-ng is not installed (the espeakng-loader package is missing)")
    cmd = [sys.executable, "-I", "-S", "-c", _WORKER, *paths, voice, str(int(pitch)), str(int(speed))]
    try:
        done = subprocess.run(cmd, input=text.encode(), capture_output=True, timeout=TIMEOUT_S, check=False)
    except (OSError, subprocess.SubprocessError) as exc:
        raise SoundError(f"espeak-ng could not run ({exc})") from exc
    if done.returncode != 0:
        raise SoundError(f"espeak-ng exited with {done.returncode}: "
                         f"{done.stderr.decode(errors='replace').strip()[-200:]}")
    try:
        x, sr = sf.read(io.BytesIO(done.stdout), dtype="float64")
    except (sf.SoundFileError, RuntimeError, ValueError) as exc:
        raise SoundError(f"espeak-ng wrote no readable WAV ({exc})") from exc
    return x, int(sr)
