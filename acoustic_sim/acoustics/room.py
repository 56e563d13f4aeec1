"""Rooms: shoebox geometry, pyroomacoustics materials, image sources and the late tail.

A :class:`Room` is a shoebox (x from 0 to L, y from 0 to W, z from 0 to H, metres, in the
room's own frame, z up) with one material per wall (energy absorption per octave band,
from pyroomacoustics' material database), a background noise level and the image-source
order up to which reflections are rendered through the HRTF of their direction.

The binaural room impulse response (BRIR) is split, as in hybrid room simulators, into

- an **early part**: pyroomacoustics' image sources up to ``ism_order``, each rendered by
  the renderer through the HRTF of its direction relative to the *current* head pose;
- a **late part**: a diffuse tail (:func:`late_tail`) whose energy envelope follows the
  statistical-acoustics decay of the room, band by band, with the interaural coherence and
  the direction-averaged spectrum of a diffuse field computed from the HRTF set itself.
  It fades in where the truncated image-source model stops filling the echo density, so
  early plus late has the room's decay without a gap or a double count. Being diffuse, it
  does not depend on the head's orientation, which is what makes streaming cheap.

Image sources come from pyroomacoustics (``ShoeBox.image_source_model``); nothing here
re-implements the ISM. Because a shoebox's image positions are affine in the source
position (each image mirrors every axis an even or odd number of times), the images of a
moving source are updated from one pyroomacoustics run by :class:`ImageSources.at`, which
is exact for a shoebox and costs microseconds instead of a new room.

Presets (``room_preset``): ``anechoic``, ``car_cabin``, ``lab``, ``conference`` and
``shoebox:LxWxH`` (with ``rt60``). ``lab`` and ``conference`` are the paper's test room
(RT60 0.27-0.32 s, 58 dB SPL) and HRTF measurement room (RT60 0.55-0.60 s, 35 dB SPL);
their uniform absorption is set by inverting Eyring's formula, the decay that an image
source model with that absorption actually has (pyroomacoustics only inverts Sabine's,
which for these rooms disagrees with the ISM decay by about 20%).
"""

from __future__ import annotations

import dataclasses
import re
from functools import cached_property

import numpy as np
import pyroomacoustics as pra

from acoustic_sim.errors import RoomError
from acoustic_sim.frames import SAMPLE_RATE, SPEED_OF_SOUND

WALLS = ("west", "east", "south", "north", "floor", "ceiling")
"""Wall names in pyroomacoustics' order: x=0, x=L, y=0, y=W, z=0, z=H."""

BAND_CENTERS_HZ = (125.0, 250.0, 500.0, 1000.0, 2000.0, 4000.0, 8000.0)
"""Octave-band centre frequencies (Hz) of the absorption coefficients."""


@dataclasses.dataclass(frozen=True, kw_only=True)
class Room:
    """A shoebox room (or free field) for the acoustic world.

    Parameters
    ----------
    name : str
        Preset or user name, used in file names and reports.
    dimensions : tuple of 3 float
        Interior size (L, W, H) in metres along the room's x, y, z; each 0.5-100 m.
        Ignored when ``anechoic``.
    absorption : dict of str to tuple of float
        Energy absorption coefficient (0 <= a < 1) per wall in :data:`WALLS`, one value per
        octave band of :data:`BAND_CENTERS_HZ` (or a single value for all bands).
    background_db_spl : float
        Background noise level at the ears in dB SPL (unweighted), 0-120.
    ism_order : int
        Highest image-source order rendered through the HRTF (0-12); later reflections are
        in the diffuse tail.
    anechoic : bool
        Free field: no reflections and no tail.
    listener : tuple of 3 float
        Default head-centre position (m, room frame) used by the CLI.
    target_rt60_s : float or None
        The RT60 (s) the preset was designed for, for reporting and tests.
    """

    name: str
    dimensions: tuple[float, float, float] = (1.0, 1.0, 1.0)
    absorption: dict = dataclasses.field(default_factory=dict)
    background_db_spl: float = 0.0
    ism_order: int = 3
    anechoic: bool = False
    listener: tuple[float, float, float] = (0.5, 0.5, 0.5)
    target_rt60_s: float | None = None

    def __post_init__(self) -> None:
        if not 0.0 <= self.background_db_spl <= 120.0:
            raise RoomError(f"room {self.name!r}: background_db_spl must be 0..120 dB, got {self.background_db_spl}")
        if not isinstance(self.ism_order, (int, np.integer)) or not 0 <= self.ism_order <= 12:
            raise RoomError(f"room {self.name!r}: ism_order must be an integer 0..12, got {self.ism_order!r}")
        if self.anechoic:
            return
        dims = np.asarray(self.dimensions, dtype=float)
        if dims.shape != (3,) or not np.all(np.isfinite(dims)) or np.any(dims < 0.5) or np.any(dims > 100):
            raise RoomError(f"room {self.name!r}: dimensions must be 3 lengths of 0.5-100 m, got {self.dimensions}")
        if set(self.absorption) != set(WALLS):
            raise RoomError(f"room {self.name!r}: absorption needs exactly the walls {WALLS}, got {sorted(self.absorption)}")
        for wall, coeffs in self.absorption.items():
            a = np.atleast_1d(np.asarray(coeffs, dtype=float))
            if a.size not in (1, len(BAND_CENTERS_HZ)) or np.any(~np.isfinite(a)) or np.any(a < 0) or np.any(a >= 1):
                raise RoomError(
                    f"room {self.name!r}: wall {wall!r} absorption must be 1 or {len(BAND_CENTERS_HZ)} values in [0, 1), got {coeffs}"
                )
        self.check_inside(self.listener, what="listener")

    # -- geometry -------------------------------------------------------------------------
    @property
    def volume_m3(self) -> float:
        """Interior volume in m^3 (inf for free field)."""
        return float(np.prod(self.dimensions)) if not self.anechoic else float("inf")

    @property
    def surface_m2(self) -> float:
        """Interior surface in m^2."""
        lx, ly, lz = self.dimensions
        return 2.0 * (lx * ly + lx * lz + ly * lz)

    def wall_areas(self) -> np.ndarray:
        """Areas (m^2) of the walls in :data:`WALLS` order."""
        lx, ly, lz = self.dimensions
        return np.array([ly * lz, ly * lz, lx * lz, lx * lz, lx * ly, lx * ly])

    def check_inside(self, position, *, what: str = "position", margin: float = 0.05) -> np.ndarray:
        """Return ``position`` as an array, or raise :class:`RoomError` if it is outside the room.

        ``margin`` (m) keeps points off the walls, where image sources would coincide.
        """
        p = np.asarray(position, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise RoomError(f"{what} must be 3 finite coordinates in metres, got {position}")
        if not self.anechoic and (np.any(p < margin) or np.any(p > np.asarray(self.dimensions) - margin)):
            raise RoomError(
                f"{what} {tuple(round(float(v), 3) for v in p)} is not inside room {self.name!r} of size {self.dimensions} m "
                f"(at least {margin} m from every wall)"
            )
        return p

    # -- acoustics ------------------------------------------------------------------------
    def absorption_bands(self) -> np.ndarray:
        """Energy absorption per wall and octave band, shape (6, 7)."""
        n = len(BAND_CENTERS_HZ)
        return np.stack([np.broadcast_to(np.atleast_1d(np.asarray(self.absorption[w], float)), (n,)) for w in WALLS])

    def rt60_bands(self) -> np.ndarray:
        """Eyring reverberation time (s) per octave band, shape (7,): the decay of this
        room's image sources, which the late tail continues. Free field gives zeros."""
        if self.anechoic:
            return np.zeros(len(BAND_CENTERS_HZ))
        mean_a = (self.wall_areas()[:, None] * self.absorption_bands()).sum(0) / self.surface_m2
        return 24.0 * np.log(10.0) * self.volume_m3 / (SPEED_OF_SOUND * -self.surface_m2 * np.log1p(-mean_a))

    @property
    def rt60_s(self) -> float:
        """Mean of the 500 Hz and 1 kHz Eyring RT60 in seconds (the usual single figure)."""
        t = self.rt60_bands()
        return float(0.5 * (t[2] + t[3]))

    def pra_room(self, *, max_order: int | None = None, fs: int = SAMPLE_RATE) -> pra.ShoeBox:
        """A pyroomacoustics ShoeBox with this room's geometry and materials (no air absorption)."""
        if self.anechoic:
            raise RoomError(f"room {self.name!r} is anechoic: it has no pyroomacoustics shoebox")
        bands = self.absorption_bands()
        materials = {
            wall: pra.Material({"coeffs": [float(a) for a in bands[i]], "center_freqs": list(BAND_CENTERS_HZ)})
            for i, wall in enumerate(WALLS)
        }
        return pra.ShoeBox(
            list(self.dimensions), fs=fs, materials=materials,
            max_order=self.ism_order if max_order is None else max_order, air_absorption=False,
        )

    @cached_property
    def is_frequency_flat(self) -> bool:
        """True when every wall absorbs all bands equally (one gain per image suffices)."""
        a = self.absorption_bands()
        return bool(np.allclose(a, a[:, :1]))

    def image_sources(self, source_position, *, max_order: int | None = None) -> "ImageSources":
        """Image sources of a source at ``source_position`` (m, room frame), from pyroomacoustics."""
        return ImageSources.compute(self, source_position, max_order=max_order)


@dataclasses.dataclass(frozen=True)
class ImageSources:
    """Image sources of one source in a shoebox, movable with the source.

    Attributes
    ----------
    positions : numpy.ndarray, shape (M, 3)
        Image positions in metres (room frame) for ``source_position``; row 0 is the source.
    parity : numpy.ndarray, shape (M, 3)
        +1 or -1 per axis: how an image moves when the source moves.
    damping : numpy.ndarray, shape (B, M)
        Product of the wall pressure reflection coefficients per octave band (B = 1 for a
        frequency-flat room), as pyroomacoustics computes it.
    orders : numpy.ndarray, shape (M,)
        Reflection order of each image.
    source_position : numpy.ndarray, shape (3,)
    """

    positions: np.ndarray
    parity: np.ndarray
    damping: np.ndarray
    orders: np.ndarray
    source_position: np.ndarray

    @classmethod
    def compute(cls, room: Room, source_position, *, max_order: int | None = None) -> "ImageSources":
        s = room.check_inside(source_position, what="source position")
        if room.anechoic:
            return cls(s[None, :].copy(), np.ones((1, 3)), np.ones((1, 1)), np.zeros(1, int), s)
        order = room.ism_order if max_order is None else max_order

        def run(pos):
            r = room.pra_room(max_order=order)
            r.add_source(list(pos))
            # pyroomacoustics needs a microphone to run its visibility test (all images of
            # a shoebox are visible from anywhere inside it).
            r.add_microphone(list(np.asarray(room.dimensions) / 2.0))
            r.image_source_model()
            src = r.sources[0]
            return src.images.T.copy(), src.damping.copy(), src.orders.copy()

        images, damping, orders = run(s)
        # A second run with the source nudged tells each image's mirror parity per axis;
        # pyroomacoustics enumerates images in the same order for any position in the box.
        delta = 1e-3
        nudged = s + delta * np.where(s + delta < np.asarray(room.dimensions) - 0.01, 1.0, -1.0)
        images2, _, _ = run(nudged)
        parity = np.sign(np.round((images2 - images) / (nudged - s)))
        if images.shape[0] != images2.shape[0] or np.any(parity == 0):
            raise RoomError("pyroomacoustics returned inconsistent image sources for a nudged source")
        if room.is_frequency_flat:
            damping = damping[:1]
        # Row 0 must be the direct path (order 0).
        first = int(np.argmin(orders))
        perm = np.r_[first, np.delete(np.arange(len(orders)), first)]
        return cls(images[perm], parity[perm], damping[:, perm], orders[perm], s)

    def at(self, source_position) -> np.ndarray:
        """Image positions (M, 3) for the source moved to ``source_position`` (exact for a shoebox)."""
        return self.positions + self.parity * (np.asarray(source_position, float) - self.source_position)


# -- the diffuse late tail ---------------------------------------------------------------------------


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


# -- presets ---------------------------------------------------------------------------------------


def eyring_absorption(rt60_s: float, dimensions) -> float:
    """Uniform energy absorption for which Eyring's formula gives ``rt60_s`` in a shoebox."""
    lx, ly, lz = dimensions
    volume, surface = lx * ly * lz, 2 * (lx * ly + lx * lz + ly * lz)
    if not np.isfinite(rt60_s) or rt60_s <= 0:
        raise RoomError(f"rt60 must be a positive number of seconds, got {rt60_s}")
    a = 1.0 - np.exp(-24.0 * np.log(10.0) * volume / (SPEED_OF_SOUND * surface * rt60_s))
    if not 0.005 <= a < 0.99:
        raise RoomError(
            f"rt60 {rt60_s} s is not reachable in a {lx}x{ly}x{lz} m room with realistic walls "
            f"(needs absorption {a:.3f}; valid 0.005-0.99)"
        )
    return float(a)


def _uniform(a: float) -> dict:
    return {w: (a,) for w in WALLS}


PRESETS = ("anechoic", "car_cabin", "lab", "conference", "shoebox:LxWxH")
"""Room names accepted by :func:`room_preset`."""


def room_preset(name: str, *, rt60: float | None = None, ism_order: int | None = None) -> Room:
    """Build a room by name.

    Parameters
    ----------
    name : str
        One of :data:`PRESETS`; ``shoebox:LxWxH`` takes the size in metres, e.g.
        ``shoebox:4x3x2.5``.
    rt60 : float, optional
        Target RT60 in seconds (0.05-5): required for ``shoebox``, optional for ``lab`` and
        ``conference`` (overrides the paper's value), refused for the others.
    ism_order : int, optional
        Image-source order rendered through the HRTF (default per preset).
    """
    if name == "anechoic":
        if rt60 is not None:
            raise RoomError("the anechoic room has no reverberation: do not give rt60")
        return Room(name="anechoic", anechoic=True, ism_order=0, background_db_spl=0.0, listener=(0.0, 0.0, 0.0))
    if name == "car_cabin":
        if rt60 is not None:
            raise RoomError("car_cabin's reverberation follows from its materials: do not give rt60")
        # Interior of a compact car: x forward, y to the left, z up. Windows and windscreen
        # are glass; seats (the rear wall and the floor side as seen from the front) are
        # upholstered cloth; the roof lining is a felt-backed headliner; the floor carpeted.
        absorption = {
            "west": pra.materials_data["absorption"]["Seating (2 seats per m2)"]["chairs_upholstered_cloth"]["coeffs"],
            "east": pra.materials_data["absorption"]["Glazing"]["glass_window"]["coeffs"],
            "south": pra.materials_data["absorption"]["Glazing"]["glass_window"]["coeffs"],
            "north": pra.materials_data["absorption"]["Glazing"]["glass_window"]["coeffs"],
            "floor": pra.materials_data["absorption"]["Floor coverings"]["carpet_cotton"]["coeffs"],
            "ceiling": pra.materials_data["absorption"]["Floor coverings"]["felt_5mm"]["coeffs"],
        }
        absorption = {w: tuple(_seven(c)) for w, c in absorption.items()}
        return Room(
            name="car_cabin", dimensions=(2.0, 1.5, 1.2), absorption=absorption, background_db_spl=40.0,
            ism_order=3 if ism_order is None else ism_order, listener=(0.75, 1.05, 0.85),
        )
    if name in ("lab", "conference"):
        dims, target, noise, listener = (
            ((6.0, 5.0, 3.0), 0.30, 58.0, (3.0, 2.5, 1.2)) if name == "lab"
            else ((8.0, 6.0, 3.0), 0.575, 35.0, (4.0, 3.0, 1.2))
        )
        t = target if rt60 is None else rt60
        return Room(
            name=name, dimensions=dims, absorption=_uniform(eyring_absorption(t, dims)), background_db_spl=noise,
            ism_order=3 if ism_order is None else ism_order, listener=listener, target_rt60_s=t,
        )
    m = re.fullmatch(r"shoebox:([0-9.]+)x([0-9.]+)x([0-9.]+)", name)
    if m:
        try:
            dims = tuple(float(v) for v in m.groups())
        except ValueError:
            raise RoomError(f"room {name!r}: dimensions must be numbers, e.g. shoebox:4x3x2.5") from None
        if rt60 is None:
            raise RoomError(f"room {name!r} needs --rt60 (seconds)")
        if any(not 0.5 <= d <= 100 for d in dims):
            raise RoomError(f"room {name!r}: each dimension must be 0.5-100 m")
        return Room(
            name=name, dimensions=dims, absorption=_uniform(eyring_absorption(rt60, dims)), background_db_spl=35.0,
            ism_order=3 if ism_order is None else ism_order, listener=tuple(d / 2 for d in dims), target_rt60_s=rt60,
        )
    raise RoomError(f"unknown room {name!r}; valid: {', '.join(PRESETS)}")


def _seven(coeffs) -> list[float]:
    """Pad a material's coefficient list to the 7 bands (repeat the last band)."""
    c = list(coeffs)[: len(BAND_CENTERS_HZ)]
    return c + [c[-1]] * (len(BAND_CENTERS_HZ) - len(c))
