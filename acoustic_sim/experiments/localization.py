"""The paper's sound source localization experiments (simulation and room).

Simulation ("Simulation" in the paper's experiments): a single virtual source at every
direction of the estimation grid, rendered straight through the HRTF (no room), playing
each of the paper's 13 test signals (sine, triangle, square and sawtooth at 500, 1000 and
2000 Hz, and white noise). Each method estimates one direction per source from the
recording; the table is the mean angular error per signal.

Room ("Sound source direction estimation in the real environment"): white noise at
73-76 dB SPL (drawn per trial) from 1.5 m in the ``lab`` room (RT60 about 0.3 s, 58 dB SPL
background), on the horizontal plane (every 30 deg of azimuth) and the median plane (front
and back, every 10 deg of elevation within the HRTF's coverage). The estimators were built
from the HRTF *measured* in the ``conference`` room (the paper's setting), while the
world's ears are the true HRTF.

Estimators are callables ``(spectra (K, 2, 1025), noise_power (2, 1025)) -> unit vector (3,)``
in the head frame, so every method is scored by the same code; ``noise_power`` is the
power per bin of the noise in the recording (what the paper's validity threshold refers to).
The room experiment also takes estimators of the recording itself, ``(audio (2, n),
noise_power) -> unit vector`` (:data:`AudioEstimator`): :func:`first_wavefront` is the
streaming pipeline's precedence rule (:mod:`~acoustic_sim.auditory.precedence`) applied to the
loudspeaker's onset, so the room table shows what it does against the paper's frames.

The frames lose the median plane in the room: at 1.5 m the lab's reverberant field is
stronger than the direct sound, so the frames' cues are mostly the room's, while the
loudspeaker's first wavefront still holds the direct sound. Measurements:
docs/notes/room_localization.md.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np
from scipy import signal as sp_signal

from acoustic_sim.acoustics import sounds
from acoustic_sim.acoustics.microphone import Microphone
from acoustic_sim.acoustics.renderer import BinauralRenderer
from acoustic_sim.acoustics.room import room_preset
from acoustic_sim.auditory.features import ild_ipd
from acoustic_sim.auditory.frontend import N_FFT, analyze, bin_frequencies, window
from acoustic_sim.auditory.precedence import FirstWavefront
from acoustic_sim.auditory.ssdenet import DEFAULT_FUSION, LEAKAGE, check_fusion, fuse, pool_looks, valid_bins
from acoustic_sim.directions import DirectionGrid, angular_error_deg, is_front, is_left, is_up
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE, frame_end_sample, rotation_zyx, sph_to_vec, vec_to_sph
from acoustic_sim.progress import progress_bar

Estimator = Callable[[np.ndarray, np.ndarray], np.ndarray]
AudioEstimator = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""``(audio (2, n), noise_power (2, 1025)) -> unit vector (3,)``: estimates from the recording."""

SIGNALS: tuple[tuple[str, float | None], ...] = tuple(
    (w, f) for w in ("sine", "triangle", "square", "sawtooth") for f in (500.0, 1000.0, 2000.0)
) + (("white_noise", None),)
"""The paper's 13 test signals: (waveform, fundamental in Hz or None)."""

SIM_SECONDS = 0.25
"""Length of each simulated recording (s): 10 ear frames after the first full window."""

SIM_SNR_DB = 40.0
"""Sensor noise added to the simulated ear signals, dB below the signal (both ears
independent, white): what keeps a sine's empty bins below the validity threshold."""


def _signal(waveform: str, f0: float | None, seconds: float, rng: np.random.Generator) -> np.ndarray:
    return sounds.test_signal(waveform, f0 or 0.0, seconds, rng=rng) if f0 else sounds.white_noise(seconds, rng)


def _frames_of(audio: np.ndarray, skip: int) -> np.ndarray:
    """Spectra of the frames after the first ``skip`` (which still see the start)."""
    return analyze(audio).spectra[skip:]


def simulate_source(hrtf, direction, x: np.ndarray, rng: np.random.Generator,
                    snr_db: float = SIM_SNR_DB) -> tuple[np.ndarray, np.ndarray]:
    """Ear signals (2, n) of ``x`` from a head-frame direction through the HRTF (interpolated),
    with independent white sensor noise ``snr_db`` below the signal; and the noise's
    expected power per bin (2, 1025) in the front end (sigma^2 times the window's energy)."""
    h = hrtf.hrirs_for(np.asarray(direction, float)[None, :], mode="interpolated")[0]  # (2, taps)
    y = sp_signal.oaconvolve(x[None, :], h, axes=-1)[:, : x.size]
    sigma = np.sqrt(np.mean(y**2)) * 10 ** (-snr_db / 20)
    noise_power = np.full((2, 1025), sigma**2 * float(np.sum(window() ** 2)))
    return y + rng.standard_normal(y.shape) * sigma, noise_power


def simulation(
    hrtf, grid: DirectionGrid, estimators: Mapping[str, Estimator], *, rng: np.random.Generator,
    directions: np.ndarray | None = None, signals=SIGNALS, seconds: float = SIM_SECONDS, progress: bool = True,
) -> list[dict]:
    """Mean angular error (deg) per signal and method over virtual sources.

    Parameters
    ----------
    hrtf : HRTF
        The ears (and the world): sources are rendered through it.
    grid : DirectionGrid
        Truth directions come from here (all of it unless ``directions`` is given).
    estimators : mapping of method name to Estimator
    directions : numpy.ndarray, optional
        (M, 3) subset of directions (quick runs).
    seconds : float
        Recording length per source (s).

    Returns
    -------
    list of dict
        One row per signal: ``{"signal", "f0_hz", "<method>_deg": mean error, ...}`` with
        method names made JSON keys by replacing ``-`` with ``_``.
    """
    dirs = grid.vectors if directions is None else np.asarray(directions, float)
    rows = []
    total = len(signals) * len(dirs)
    bar = progress_bar(total=total, desc="simulation", unit="src", disable=not progress)
    for waveform, f0 in signals:
        x = _signal(waveform, f0, seconds + 2048 / hrtf.sample_rate, rng)
        errors = {m: [] for m in estimators}
        for d in dirs:
            audio, noise = simulate_source(hrtf, d, x, rng)
            spectra = _frames_of(audio, skip=3)
            for m, est in estimators.items():
                errors[m].append(float(angular_error_deg(est(spectra, noise), d)))
            bar.update()
        row = {"signal": waveform, "f0_hz": f0}
        for m, e in errors.items():
            row[f"{m.replace('-', '_')}_deg"] = round(float(np.mean(e)), 2)
        rows.append(row)
    bar.close()
    return rows


def room_directions(hrtf, *, quick: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The room test's horizontal-plane and median-plane directions (head frame).

    Horizontal: azimuth every 30 deg (every 90 deg when quick). Median: elevation every 10 deg
    (30 when quick) within the HRTF's coverage, in front (azimuth 0) and behind (180), the
    zenith once.
    """
    az = np.arange(-150.0, 181.0, 90.0 if quick else 30.0)
    horizontal = sph_to_vec(az, np.zeros_like(az))
    step = 30.0 if quick else 10.0
    lo, hi = float(hrtf.min_elevation_deg), min(float(hrtf.max_elevation_deg), 80.0)
    els = np.arange(np.ceil(lo / step) * step, hi + 1e-9, step)
    median = np.concatenate([sph_to_vec(np.zeros_like(els), els), sph_to_vec(np.full_like(els, 180.0), els)])
    if hrtf.max_elevation_deg >= 90:
        median = np.concatenate([median, sph_to_vec(np.zeros(1), np.full(1, 90.0))])
    return horizontal, median


LEAD_S = 0.1
"""Background heard before the loudspeaker starts in a room trial (s): the source switches on
against the room's noise, so its onset is there to be heard (:func:`first_wavefront`)."""


def render_room_trial(hrtf, direction, *, rng: np.random.Generator, room: str = "lab", distance_m: float = 1.5,
                      seconds: float = 0.5, lead_s: float = LEAD_S) -> np.ndarray:
    """Digital ear signals (2, n) of the room's background for ``lead_s``, then white noise at
    73-76 dB SPL from ``direction`` (head frame, head facing the room's +x at its listener
    position) for ``seconds`` plus 0.1 s."""
    space = room_preset(room)
    head = np.asarray(space.listener, float)
    r = BinauralRenderer(hrtf, space, rng=rng)
    r.set_head_pose(head, rotation_zyx(0.0))
    level = float(rng.uniform(73.0, 76.0))
    start = int(round(lead_s * SAMPLE_RATE))
    r.add_source("noise", sounds.white_noise(seconds + 0.1, rng), head + distance_m * np.asarray(direction, float),
                 level_db=level + 20 * np.log10(distance_m), start=start)
    return Microphone(rng=rng)(r.render(lead_s + seconds + 0.1))


def frames_after(audio: np.ndarray, start: int) -> np.ndarray:
    """Spectra (K, 2, 1025) of the frames whose whole window lies at or after sample ``start``."""
    frames = analyze(audio)
    ends = np.asarray(frame_end_sample(frames.index), dtype=np.int64)
    return frames.spectra[ends - N_FFT >= start]


def straight_ahead(grid: DirectionGrid) -> np.ndarray:
    """The grid direction nearest to straight ahead: every method's answer when a recording
    gives it nothing to estimate from (silence, no valid bin, no onset)."""
    return grid.vectors[grid.nearest(np.array([1.0, 0.0, 0.0]))]


ROOM_ONSET_WINDOWS = 3
"""Windows the room experiment's first-wavefront estimator takes at a rising onset, 1 ms
apart (the cabin tasks' setting, :attr:`tasks.cabin.CabinLeverTask.onset_windows`). The
loudspeaker's noise reaches the head before any of the lab's reflections (the floor's about
4 ms later), so the later windows add looks at the direct sound (measurements:
docs/notes/room_localization.md)."""


def first_wavefront(bank, *, leakage: float = LEAKAGE, windows: int = 1, fusion: str = DEFAULT_FUSION) -> AudioEstimator:
    """SSDENet on the first wavefront of a recording's strongest onset: the streaming
    pipeline's precedence rule (``precedence="wavefront"``, :class:`FirstWavefront` with its
    defaults and ``windows``) for a whole recording.

    The cues of the bank's bins at or above the window's :attr:`FirstWavefront.min_hz` come
    from the onset's 1.75 ms window, those below from the first frame wholly after the onset,
    whose bins also decide validity (:func:`valid_bins` against ``noise_power``). The
    streaming pipeline tests validity on the frame the window completes in, which for a
    loudspeaker switched on holds only the first milliseconds of it, and so leaves few valid
    bins (measurements: docs/notes/room_localization.md). A recording with no onset, or no valid bin,
    gives straight ahead (no information, as for silence).

    ``windows``: the windows taken at a rising onset (``AuditoryPipeline(onset_windows=)``,
    1 ms apart), whose existence maps are pooled per bin (:func:`pool_looks`) and then
    fused over the valid bins (:func:`fuse`, ``fusion``), as the streaming pipeline does
    (the room experiment takes :data:`ROOM_ONSET_WINDOWS`).
    """
    check_fusion(fusion)
    short_ok = bin_frequencies()[bank.bins] >= FirstWavefront(windows=windows).min_hz  # checks windows too
    short = bank.bins[short_ok]
    ahead = straight_ahead(bank.grid)

    def estimate(audio, noise_power):
        fw = FirstWavefront(windows=windows)
        fw.push(audio)
        taken = fw.take_onset(audio.shape[1])
        after = frames_after(audio, taken[0]) if taken is not None else ()
        if len(after) == 0:
            return ahead
        frame = after[0]  # the first frame wholly after the onset
        looks = taken[1] if taken[1].ndim == 3 else taken[1][None]  # (k, 2, 1025): one per window
        x = np.repeat(frame[None], len(looks), axis=0)
        x[:, :, short] = looks[:, :, short]
        valid = valid_bins(frame, noise_power, class_bins=bank.bins, leakage=leakage)[bank.bins]
        if not valid.any():
            return ahead
        sel = x[:, :, bank.bins]
        maps = pool_looks(bank.existence(ild_ipd(sel[:, 0], sel[:, 1])), fusion)  # (n_bins, D)
        p = fuse(maps, valid[None], fusion)[0]
        return bank.grid.vectors[int(np.argmax(p))].copy()

    return estimate


def noise_floor(hrtf, *, rng: np.random.Generator, room: str = "lab", seconds: float = 1.0) -> np.ndarray:
    """Mean power per ear and bin (2, 1025) of the room's background through the microphone,
    with no source: the noise the validity threshold is measured against."""
    space = room_preset(room)
    r = BinauralRenderer(hrtf, space, rng=rng)
    r.set_head_pose(np.asarray(space.listener, float), rotation_zyx(0.0))
    spectra = analyze(Microphone(rng=rng)(r.render(seconds))).spectra[3:]
    return np.mean(np.abs(spectra) ** 2, axis=0)


ROOM_TRIALS = 4
"""Trials per angle of the room experiment (full run): each a new noise signal, level and
background. One trial per angle leaves the accuracies over the 24 top-bottom sources
uncertain by about +-0.1 (a binomial standard error); four halve that."""


def room(world_hrtf, estimators: Mapping[str, Estimator], *, rng: np.random.Generator, quick: bool = False,
         trials: int | None = None, progress: bool = True,
         audio_estimators: Mapping[str, AudioEstimator] | None = None) -> dict:
    """The room experiment's metrics per method (see the module docstring).

    Parameters
    ----------
    estimators : mapping of method name to Estimator
        Given the spectra of the frames wholly after the loudspeaker's start.
    trials : int, optional
        Trials per angle (default :data:`ROOM_TRIALS`, 1 when ``quick``).
    audio_estimators : mapping of method name to AudioEstimator, optional
        Given the whole recording (:data:`LEAD_S` of background, then the source).

    Returns
    -------
    dict
        ``horizontal_mean_deg``, ``median_mean_deg``: method -> mean error (deg, over every
        trial); ``horizontal_per_angle``, ``median_per_angle``: method -> list of
        ``{"azimuth_deg", "elevation_deg", "error_deg"}`` (the mean over the angle's
        trials); ``lr_accuracy``, ``tb_accuracy``, ``front_back_confusion``: method ->
        fraction of trials; ``trials_per_angle``.
    """
    trials = (1 if quick else ROOM_TRIALS) if trials is None else trials
    if not isinstance(trials, (int, np.integer)) or trials < 1:
        raise ConfigError(f"trials must be a positive integer, got {trials!r}")
    horizontal, median = room_directions(world_hrtf, quick=quick)
    horizontal, median = np.repeat(horizontal, trials, axis=0), np.repeat(median, trials, axis=0)
    out = {k: {} for k in ("horizontal_mean_deg", "median_mean_deg", "horizontal_per_angle", "median_per_angle",
                            "lr_accuracy", "tb_accuracy", "front_back_confusion")}
    audio_estimators = dict(audio_estimators or {})
    if set(audio_estimators) & set(estimators):
        raise ConfigError(f"method names used twice: {sorted(set(audio_estimators) & set(estimators))}")
    methods = [*estimators, *audio_estimators]
    estimates = {m: {"horizontal": [], "median": []} for m in methods}
    noise = noise_floor(world_hrtf, rng=rng)
    start = int(round(LEAD_S * SAMPLE_RATE))
    bar = progress_bar(total=len(horizontal) + len(median), desc="room", unit="src", disable=not progress)
    for plane, dirs in (("horizontal", horizontal), ("median", median)):
        for d in dirs:
            audio = render_room_trial(world_hrtf, d, rng=rng)
            spectra = frames_after(audio, start)
            for m, est in estimators.items():
                estimates[m][plane].append(np.asarray(est(spectra, noise), float))
            for m, est in audio_estimators.items():
                estimates[m][plane].append(np.asarray(est(audio, noise), float))
            bar.update()
    bar.close()
    for m in methods:
        for plane, dirs in (("horizontal", horizontal), ("median", median)):
            est = np.array(estimates[m][plane])
            err = angular_error_deg(est, dirs)
            az, el = vec_to_sph(dirs)
            out[f"{plane}_mean_deg"][m] = round(float(np.mean(err)), 2)
            per = err.reshape(-1, trials).mean(axis=1)
            out[f"{plane}_per_angle"][m] = [
                {"azimuth_deg": round(float(a), 1), "elevation_deg": round(float(e), 1), "error_deg": round(float(x), 2)}
                for a, e, x in zip(az[::trials], el[::trials], per)
            ]
        est_h = np.array(estimates[m]["horizontal"])
        est_m = np.array(estimates[m]["median"])
        # Left/right: horizontal-plane sources off the median plane.
        lateral = np.abs(horizontal[:, 1]) > 1e-6
        out["lr_accuracy"][m] = round(float(np.mean(is_left(est_h[lateral]) == is_left(horizontal[lateral]))), 4)
        # Top/bottom: median-plane sources off the horizontal plane.
        vertical = np.abs(median[:, 2]) > 1e-6
        out["tb_accuracy"][m] = round(float(np.mean(is_up(est_m[vertical]) == is_up(median[vertical]))), 4)
        # Front/back confusion: every source not on the frontal plane (x = 0).
        every = np.concatenate([horizontal, median])
        est_all = np.concatenate([est_h, est_m])
        fb = np.abs(every[:, 0]) > 1e-6
        out["front_back_confusion"][m] = round(float(np.mean(is_front(est_all[fb]) != is_front(every[fb]))), 4)
    out["trials_per_angle"] = int(trials)
    return out
