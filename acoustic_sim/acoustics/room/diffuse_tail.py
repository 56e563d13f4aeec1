"""The diffuse late tail of a binaural room impulse response.

The BRIR is split, as in hybrid room simulators, into an **early part** (the image
sources up to the room's ``ism_order``, which the renderer renders through the HRTF of
their direction relative to the *current* head pose) and a **late part**: the diffuse tail
made here, whose energy envelope follows the statistical-acoustics decay of the room,
band by band, with the interaural coherence and the direction-averaged spectrum of a
diffuse field computed from the HRTF set itself. It fades in where the truncated
image-source model stops filling the echo density (:func:`tail_fill`), so early plus late
has the room's decay without a gap or a double count. Being diffuse, it does not depend on
the head's orientation, which is what makes streaming cheap.
"""

from __future__ import annotations

import numpy as np
import pyroomacoustics as pra

from acoustic_sim.acoustics.room.image_sources import ImageSources
from acoustic_sim.acoustics.room.shoebox import BAND_CENTERS_HZ, Room
from acoustic_sim.frames import SAMPLE_RATE, SPEED_OF_SOUND


def late_tail(
    room: Room,
    images: ImageSources | None,
    listener_position,
    *,
    diffuse_power: np.ndarray,
    coherence: np.ndarray,
    rng: np.random.Generator,
    sample_rate: int = SAMPLE_RATE,
    floor_db: float = -65.0,
    n_samples: int | None = None,
) -> np.ndarray:
    """Synthesize the diffuse late part of a BRIR, shape (2, n), in the renderer's units
    (the direct path at 1 m has amplitude 1).

    The expected energy per sample of an image-source response at time t (seconds after
    emission) in a room of volume V is ``4 pi c / (V fs) * exp(-13.8 t / T)``: the image
    density grows as ``4 pi c^3 t^2 / V`` while each image's energy falls as ``1/(ct)^2``.
    The tail carries that energy minus what the rendered images (order <= ism_order)
    already carry (:func:`tail_fill`), per octave band with the room's Eyring decay per
    band, so the full BRIR decays at the room's RT60 and the early part is not counted twice.

    Once the rendered images have all arrived the fill is complete, and from there on the
    tail depends on the room alone, not on where the source is: that is what lets the
    renderer share one late-reverb convolution among all its sources.

    Parameters
    ----------
    images : ImageSources or None
        The rendered image sources of the source; None gives the room's tail with a
        complete fill at every time (the part of any source's tail after
        :func:`tail_complete_sample`).
    diffuse_power : numpy.ndarray, shape (2, n_fft // 2 + 1)
        Direction-averaged HRTF power per ear (what a diffuse field sounds like at the ear).
    coherence : numpy.ndarray, shape (n_fft // 2 + 1,)
        Interaural coherence of a diffuse field, from the HRTF set.
    rng : numpy.random.Generator
        The only source of randomness.
    floor_db : float
        The tail ends where its envelope has fallen this far below its start (dB, < 0).
    n_samples : int, optional
        Synthesize only the first ``n_samples`` samples (default: the whole tail).
    """
    if room.anechoic:
        return np.zeros((2, 0))
    fs = sample_rate
    rt = room.rt60_bands()
    full = tail_length(room, sample_rate=fs, floor_db=floor_db)
    n = full if n_samples is None else int(min(max(n_samples, 1), full))
    t = np.arange(n) / fs
    expected = _expected_energy(room, fs)
    n_bands = len(BAND_CENTERS_HZ)
    weight = np.ones((n_bands, n)) if images is None else tail_fill(room, images, listener_position, full, sample_rate=fs)[:, :n]

    # Two noises with the diffuse-field coherence and spectrum (frequency domain, once).
    nfft = 2 * (diffuse_power.shape[1] - 1)
    spec_n = (n + nfft) // 2 + 1
    freqs_src = np.fft.rfftfreq(nfft, 1 / fs)
    freqs = np.fft.rfftfreq(n + nfft, 1 / fs)
    gamma = np.interp(freqs, freqs_src, np.clip(coherence, -1, 1))
    power = np.stack([np.interp(freqs, freqs_src, diffuse_power[e]) for e in range(2)])
    z = rng.standard_normal((2, spec_n)) + 1j * rng.standard_normal((2, spec_n))
    left = z[0]
    right = gamma * z[0] + np.sqrt(1.0 - gamma**2) * z[1]
    spec = np.stack([left, right]) * np.sqrt(power)
    noise = np.fft.irfft(spec, n=n + nfft, axis=-1)[:, :n]
    noise /= np.sqrt(np.mean(noise**2, axis=1, keepdims=True) / np.mean(power, axis=1, keepdims=True))

    bands = pra.acoustics.OctaveBandsFactory(fs=fs, n_fft=512, keep_dc=True, base_frequency=BAND_CENTERS_HZ[0])
    out = np.zeros((2, n))
    for b in range(min(bands.n_bands, n_bands)):
        env = np.sqrt(expected * np.exp(-13.8155 * t / rt[b]) * weight[b])
        for e in range(2):
            out[e] += bands.analysis(noise[e], band=b) * env
    # Bands above the last absorption band (pyroomacoustics adds one up to Nyquist) decay
    # like the last one.
    for b in range(n_bands, bands.n_bands):
        env = np.sqrt(expected * np.exp(-13.8155 * t / rt[-1]) * weight[-1])
        for e in range(2):
            out[e] += bands.analysis(noise[e], band=b) * env
    return out


def tail_length(room: Room, *, sample_rate: int = SAMPLE_RATE, floor_db: float = -65.0) -> int:
    """Length (samples) of :func:`late_tail`: until the slowest band has decayed by ``-floor_db``."""
    return int(np.ceil(room.rt60_bands().max() * (-floor_db / 60.0) * sample_rate)) + 1


def _expected_energy(room: Room, fs: int) -> float:
    """Statistical energy per sample of the response at emission time (before decay)."""
    return 4.0 * np.pi * SPEED_OF_SOUND / (room.volume_m3 * fs)


def tail_fill(room: Room, images: ImageSources, listener_position, n: int, *, sample_rate: int = SAMPLE_RATE) -> np.ndarray:
    """Fraction (B, n) of the statistical late energy that the tail must carry, per octave
    band and sample: one minus what the rendered images carry (smoothed over 2.5 ms bins),
    zero before the first missing image can arrive, and never decreasing."""
    fs = sample_rate
    c = SPEED_OF_SOUND
    rt = room.rt60_bands()
    expected = _expected_energy(room, fs)
    # Energy that the rendered images put in each 2.5 ms bin, per band, as the fraction of
    # the statistical expectation: the tail fills the rest.
    listener = np.asarray(listener_position, float)
    dist = np.linalg.norm(images.positions - listener, axis=1)
    arrival = np.round(dist / c * fs).astype(int)
    hop = int(0.0025 * fs)
    nbins = n // hop + 1
    n_bands = len(BAND_CENTERS_HZ)
    damping = np.broadcast_to(images.damping, (n_bands, dist.size)) if images.damping.shape[0] == 1 else images.damping
    energy = np.zeros((n_bands, nbins))
    keep = arrival < n
    for b in range(n_bands):
        np.add.at(energy[b], arrival[keep] // hop, (damping[b, keep] / dist[keep]) ** 2)
    centres = (np.arange(nbins) + 0.5) * hop / fs
    decay = np.exp(-13.8155 * centres[None, :] / rt[:, None])
    stat = expected * hop * decay
    # Smooth over 5 bins: image arrivals are discrete, the expectation is continuous.
    kernel = np.hanning(7)[1:-1]
    kernel /= kernel.sum()
    frac = np.array([np.convolve(energy[b] / stat[b], kernel, mode="same") for b in range(n_bands)])
    # Before the first missing image can arrive the ISM is complete: no tail there.
    first_missing = _first_missing_arrival(room, images, listener)
    fill = np.clip(1.0 - frac, 0.0, 1.0) * (centres[None, :] >= first_missing)
    # Monotone fade-in: once the ISM thins out, the tail stays.
    fill = np.maximum.accumulate(fill, axis=1)
    return np.repeat(fill, hop, axis=1)[:, :n]


def tail_complete_sample(room: Room, images: ImageSources, listener_position, *, sample_rate: int = SAMPLE_RATE) -> int:
    """First sample from which :func:`tail_fill` is complete (1) in every band: from there
    on a source's tail is the room's tail (``late_tail(room, None, ...)``)."""
    n = tail_length(room, sample_rate=sample_rate)
    fill = tail_fill(room, images, listener_position, n, sample_rate=sample_rate)
    done = np.all(fill >= 1.0, axis=0)
    return int(np.argmax(done)) if done.any() else n


def _first_missing_arrival(room: Room, images: ImageSources, listener: np.ndarray) -> float:
    """Time (s) at which the first image of order ``max order + 1`` arrives at the listener."""
    order = int(images.orders.max())
    nxt = ImageSources.compute(room, images.source_position, max_order=order + 1)
    missing = nxt.positions[nxt.orders == order + 1]
    return float(np.linalg.norm(missing - listener, axis=1).min() / SPEED_OF_SOUND)
