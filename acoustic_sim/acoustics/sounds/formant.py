"""The formant speech synthesizer: the voice of ``human_voice`` where espeak-ng is missing.

Spelling-based (no dictionary, so a rough English guess at the phones): glottal pulses
(Rosenberg) with jitter and a call intonation, cascaded Klatt formant resonators whose
targets glide between phones, and band-passed noise bursts for the consonants.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from acoustic_sim.acoustics.sounds.synth_blocks import bandpass_sos, mix_at, ramp_envelope
from acoustic_sim.errors import SoundError


@dataclass(frozen=True)
class FormantVoice:
    """A formant speaker's voice, drawn once and kept for every phrase it says."""

    f0: float             # Hz, mean pitch
    tract: float          # formant scale: short vocal tracts (children, women) > 1
    breath: float         # aspiration noise relative to the glottal pulses
    rate: float           # duration multiplier (> 1 speaks slower)
    open_quotient: float  # fraction of the period the glottis opens; lower = brighter


# Peterson & Barney (1952) adult male formants F1-F3 in Hz; sonorants are weaker, voiced.
_VOWELS = {"a": (730, 1090, 2440), "e": (530, 1840, 2480), "i": (300, 2250, 3000),
           "o": (570, 840, 2410), "u": (300, 870, 2240), "y": (300, 2250, 3000)}
_SONORANTS = {"m": ((250, 1100, 2300), 0.3), "n": ((250, 1400, 2500), 0.3),
              "l": ((360, 1300, 2700), 0.5), "r": ((420, 1300, 1600), 0.5),
              "w": ((300, 700, 2200), 0.5), "j": ((280, 2200, 3000), 0.5)}
# Noise band (Hz) and level of fricatives and stop bursts.
_FRICATIVES = {"s": ((4000, 8000), 0.25), "z": ((4000, 8000), 0.2), "c": ((4000, 8000), 0.25),
               "x": ((3500, 8000), 0.25), "sh": ((2200, 5000), 0.3), "f": ((1500, 7000), 0.1),
               "v": ((1500, 7000), 0.08), "th": ((1500, 7000), 0.08), "h": ((500, 3000), 0.12)}
_STOPS = {"p": (500, 2500), "b": (500, 2500), "t": (3000, 7000), "d": (3000, 7000),
          "k": (1500, 3500), "g": (1500, 3500), "q": (1500, 3500), "ch": (2200, 5000)}
_BANDWIDTHS = (70.0, 100.0, 160.0, 220.0)


def _phones(text: str) -> list[tuple[str, str]]:
    """Spell ``text`` into (kind, symbol) pairs; no dictionary, so a rough English guess."""
    s, out, i = text.lower(), [], 0
    while i < len(s):
        two, c = s[i:i + 2], s[i]
        end_of_word = i + 1 >= len(s) or not s[i + 1].isalpha()
        if two in ("sh", "ch", "th"):
            out.append(("fric" if two != "ch" else "stop", two))
            i += 2
            continue
        if c in _VOWELS:
            word_has_vowel = any(k == "vowel" for k, _ in out[_word_start(out):])
            if not (c == "e" and end_of_word and word_has_vowel):  # silent final e
                out.append(("vowel", c))
        elif c in _SONORANTS:
            out.append(("sonorant", c))
        elif c in _FRICATIVES:
            out.append(("fric", c))
        elif c in _STOPS:
            out.append(("stop", c))
        elif c in ",;:":
            out.append(("pause", c))
        elif c.isspace() or c in "-.!?":
            out.append(("gap", c))
        i += 1
    return out


def _word_start(phones: list[tuple[str, str]]) -> int:
    for k in range(len(phones) - 1, -1, -1):
        if phones[k][0] in ("gap", "pause"):
            return k + 1
    return 0


def formant_speech(text: str, v: FormantVoice, rng: np.random.Generator,
                   sr: int) -> np.ndarray:
    phones = _phones(text)
    if not any(k in ("vowel", "sonorant") for k, _ in phones):
        raise SoundError(f"the formant synthesizer cannot speak {text!r} (no Latin vowels)")
    last_vowel = max(i for i, (k, _) in enumerate(phones) if k == "vowel" or k == "sonorant")
    # Segment table: start sample, length, formants (for voiced), voicing level.
    segs, noise, t = [], [], round(0.03 * sr)
    for i, (kind, sym) in enumerate(phones):
        if kind == "vowel":
            dur = rng.uniform(0.09, 0.16) * (rng.uniform(1.6, 2.6) if i == last_vowel else 1.0)
            segs.append((t, round(dur * v.rate * sr), _VOWELS[sym], 1.0))
        elif kind == "sonorant":
            formants, level = _SONORANTS[sym]
            segs.append((t, round(rng.uniform(0.05, 0.09) * v.rate * sr), formants, level))
        elif kind == "fric":
            (lo, hi), level = _FRICATIVES[sym]
            k = round(rng.uniform(0.06, 0.11) * v.rate * sr)
            noise.append((t, k, lo, hi, level))
            segs.append((t, k, None, 0.0))
        elif kind == "stop":  # closure silence, then the release burst
            closure = round(rng.uniform(0.03, 0.06) * v.rate * sr)
            burst = round(rng.uniform(0.01, 0.025) * sr)
            noise.append((t + closure, burst, *_STOPS[sym], 0.35))
            segs.append((t, closure + burst, None, 0.0))
        else:
            k = rng.uniform(0.12, 0.25) if kind == "pause" else rng.uniform(0.0, 0.04)
            segs.append((t, round(k * sr), None, 0.0))
        t += segs[-1][1]
    n = t + round(0.05 * sr)

    # Per-sample voicing level and formant targets; unvoiced spans borrow the next voiced
    # formants (coarticulation), and smoothing turns the steps into transitions.
    level = np.zeros(n)
    tracks = np.zeros((3, n))
    nxt = next(f for _, _, f, _ in reversed(segs) if f is not None)
    for start, k, formants, lv in reversed(segs):
        nxt = formants if formants is not None else nxt
        level[start:start + k] = lv
        tracks[:, start:start + k] = np.asarray(nxt, float)[:, None]
    tracks[:, t:] = tracks[:, t - 1:t]
    tracks[:, :segs[0][0]] = tracks[:, segs[0][0]:segs[0][0] + 1]
    level = _smooth(level, round(0.015 * sr))
    tracks = np.stack([_smooth(tr, round(0.03 * sr)) for tr in tracks]) * v.tract

    # Call intonation: rise to a peak on the stressed syllable, then fall; plus jitter.
    u = np.linspace(0, 1, n)
    contour = np.interp(u, [0, rng.uniform(0.15, 0.45), 1],
                        [1.0, rng.uniform(1.15, 1.5), rng.uniform(0.7, 0.9)])
    drift = np.interp(u, np.linspace(0, 1, 12), rng.normal(0, 0.02, 12))
    jitter = _smooth(rng.normal(0, 0.01, n), round(0.005 * sr))
    f0 = v.f0 * contour * (1 + drift + jitter)
    frac = np.mod(np.cumsum(f0) / sr, 1.0)
    # Rosenberg glottal flow pulse; its derivative (lip radiation) carries the harmonics.
    tp, tn = v.open_quotient, 0.16
    flow = np.where(frac < tp, 0.5 * (1 - np.cos(np.pi * frac / tp)),
                    np.where(frac < tp + tn, np.cos(0.5 * np.pi * (frac - tp) / tn), 0.0))
    source = np.diff(flow, prepend=0.0) * (sr / v.f0 / 10)
    source = (source + v.breath * rng.standard_normal(n)) * level
    voiced = _formant_filter(source, tracks, sr)
    voiced /= max(float(np.sqrt(np.mean(voiced[level > 0.5] ** 2))) if np.any(level > 0.5)
                  else 1.0, 1e-12)

    for start, k, lo, hi, lv in noise:
        burst = signal.sosfilt(bandpass_sos(lo, hi, sr), rng.standard_normal(k))
        mix_at(voiced, lv * burst * ramp_envelope(k, sr, 0.01, 0.015), start)
    return voiced


def _smooth(x: np.ndarray, width: int) -> np.ndarray:
    w = np.hanning(max(width, 3))
    return np.convolve(np.pad(x, (len(w) // 2, len(w) - 1 - len(w) // 2), mode="edge"),
                       w / w.sum(), mode="valid")


def _formant_filter(x: np.ndarray, tracks: np.ndarray, sr: int, block: int = 128) -> np.ndarray:
    """Cascade of Klatt resonators (F1-F3 tracked, fixed F4) updated every ``block`` samples.

    The filter states carry over from block to block, which keeps the output continuous
    while the coefficients glide; unit gain at DC keeps the vowels' relative levels natural.
    """
    f4 = np.full(tracks.shape[1], 3500.0 * tracks[2].mean() / 2500.0)
    freqs = np.vstack([tracks, f4])
    y = x.copy()
    for j, bw in enumerate(_BANDWIDTHS):
        zi = np.zeros(2)
        r = np.exp(-np.pi * bw / sr)
        for s in range(0, len(y), block):
            f = min(freqs[j, min(s + block // 2, len(y) - 1)], 0.45 * sr)
            b1, b2 = 2 * r * np.cos(2 * np.pi * f / sr), -r * r
            y[s:s + block], zi = signal.lfilter([1 - b1 - b2], [1, -b1, -b2], y[s:s + block], zi=zi)
    return y
