"""Tests of the sound bank: conventions, class models, test signals, WAV loading, errors."""

from __future__ import annotations

import numpy as np
import pytest
import soundfile as sf
from scipy import signal

from acoustic_sim.acoustics import sounds
from acoustic_sim.acoustics.sounds import espeak
from acoustic_sim.errors import SoundError

SR = 44100
HAS_ESPEAK = espeak.available()


def rng(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def band_fraction(x: np.ndarray, lo: float, hi: float, sr: int = SR) -> float:
    """Fraction of the signal's energy in [lo, hi) Hz."""
    power = np.abs(np.fft.rfft(x)) ** 2
    f = np.fft.rfftfreq(len(x), 1 / sr)
    return float(power[(f >= lo) & (f < hi)].sum() / power.sum())


def count_onsets(x: np.ndarray, frame_s: float = 0.002, refractory_s: float = 0.025,
                 threshold_db: float = -20.0) -> int:
    """Rising crossings of a frame-energy threshold (dB re the loudest frame)."""
    h = round(frame_s * SR)
    e = np.sum(x[: len(x) // h * h].reshape(-1, h) ** 2, axis=1)
    above = 10 * np.log10(e / e.max() + 1e-12) > threshold_db
    starts = np.flatnonzero(above & ~np.r_[False, above[:-1]])
    kept: list[int] = []
    for i in starts:
        if not kept or (i - kept[-1]) * frame_s >= refractory_s:
            kept.append(int(i))
    return len(kept)


# --------------------------------------------------------------------------- conventions

def test_available_sounds():
    assert sounds.available_sounds() == sounds.SOUND_CLASSES + ("white_noise",)
    assert len(sounds.SOUND_CLASSES) == 6
    assert sounds.TEST_WAVEFORMS == ("sine", "triangle", "square", "sawtooth")


@pytest.mark.parametrize("name", sounds.available_sounds())
@pytest.mark.parametrize("seed", [0, 1])
def test_natural_instance_is_finite_mono_rms_one(name, seed):
    x = sounds.generate(name, rng(seed))
    assert x.dtype == np.float64 and x.ndim == 1
    assert np.all(np.isfinite(x))
    assert rms(x) == pytest.approx(1.0, abs=1e-12)
    assert 0.1 * SR < len(x) < 8 * SR  # one natural instance: 0.1-8 s


@pytest.mark.parametrize("name", sounds.available_sounds())
def test_same_seed_is_bit_identical(name):
    assert np.array_equal(sounds.generate(name, rng(42)), sounds.generate(name, rng(42)))
    a = sounds.generate(name, rng(42), seconds=1.5)
    assert np.array_equal(a, sounds.generate(name, rng(42), seconds=1.5))


@pytest.mark.parametrize("name", sounds.available_sounds())
def test_different_seeds_differ(name):
    a, b = sounds.generate(name, rng(1), seconds=2.0), sounds.generate(name, rng(2), seconds=2.0)
    # Not the same waveform shifted or rescaled: correlation well below 0.9.
    assert abs(np.corrcoef(a, b)[0, 1]) < 0.9
    if name != "white_noise":  # natural durations vary from instance to instance
        assert len({len(sounds.generate(name, rng(s))) for s in range(6)}) >= 3


@pytest.mark.parametrize("name", sounds.available_sounds())
@pytest.mark.parametrize("seconds", [0.01, 2.5, 3.7001])
def test_seconds_gives_exact_length(name, seconds):
    x = sounds.generate(name, rng(3), seconds=seconds)
    assert len(x) == round(seconds * SR)
    assert np.all(np.isfinite(x)) and rms(x) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("name", sounds.available_sounds())
def test_other_sample_rates(name):
    x = sounds.generate(name, rng(4), seconds=0.5, sample_rate=16000)
    assert len(x) == 8000 and np.all(np.isfinite(x))
    assert rms(x) == pytest.approx(1.0, abs=1e-12)


# --------------------------------------------------------------------------- class models

@pytest.mark.parametrize("seed", range(8))
def test_reverse_alarm_tone_and_beep_period(seed):
    x = sounds.generate("reverse_alarm", rng(seed), seconds=6.0)
    power = np.abs(np.fft.rfft(x)) ** 2
    dominant = np.fft.rfftfreq(len(x), 1 / SR)[power.argmax()]
    assert 1000 <= dominant <= 1300
    # It keeps beeping at a 0.8-1.1 s period: 6 s hold 6-8 beep onsets.
    assert 6 <= count_onsets(x, frame_s=0.01, refractory_s=0.3) <= 8
    env = np.abs(signal.hilbert(x))
    duty = np.mean(env > 0.5 * env.max())
    assert 0.35 < duty < 0.65  # ~50 % duty cycle, the ramps shaving a little off


@pytest.mark.parametrize("seed", range(8))
def test_car_horn_band_and_harmonics(seed):
    x = sounds.generate("car_horn", rng(seed))
    assert band_fraction(x, 300, 3000) > 0.9
    assert band_fraction(x, 1000, 3000) > 0.03  # driven diaphragm: not two pure tones
    spec = np.abs(np.fft.rfft(x * np.hanning(len(x))))
    f = np.fft.rfftfreq(len(x), 1 / SR)
    db = 20 * np.log10(spec / spec.max() + 1e-12)
    peaks, _ = signal.find_peaks(db, height=-40, prominence=10, distance=int(50 * len(x) / SR))
    peaks = f[peaks][(f[peaks] >= 300) & (f[peaks] <= 3000)]
    assert 360 <= peaks.min() <= 520  # the low horn's fundamental
    assert len(peaks) >= 6  # two tones, each with harmonics


@pytest.mark.parametrize("seed", range(8))
def test_ratchet_is_a_train_of_bright_clicks(seed):
    x = sounds.generate("ratchet", rng(seed))
    assert count_onsets(x) >= 5
    assert band_fraction(x, 2000, SR / 2) > 0.8


@pytest.mark.parametrize("seed", range(8))
def test_gearshift_is_low_and_key_turning_is_bright(seed):
    assert band_fraction(sounds.generate("gearshift", rng(seed)), 0, 1000) > 0.8
    keys = sounds.generate("key_turning", rng(seed))
    assert band_fraction(keys, 3000, SR / 2) > 0.8
    assert count_onsets(keys, refractory_s=0.01) >= 1


def test_classes_are_spectrally_distinct():
    def centroid(x):
        p = np.abs(np.fft.rfft(x)) ** 2
        return float((p * np.fft.rfftfreq(len(x), 1 / SR)).sum() / p.sum())

    c = {name: np.median([centroid(sounds.generate(name, rng(s))) for s in range(4)])
         for name in ("gearshift", "car_horn", "reverse_alarm", "ratchet", "key_turning")}
    assert c["gearshift"] < c["car_horn"] < c["reverse_alarm"] < min(c["ratchet"], c["key_turning"])


# --------------------------------------------------------------------------- speech

def _loudest_window_f0(x: np.ndarray) -> tuple[float, float]:
    """(f0 in Hz, normalized autocorrelation peak) of the loudest 40 ms."""
    w = round(0.04 * SR)
    i = int(np.convolve(x ** 2, np.ones(w), "valid").argmax())
    seg = x[i:i + w] - x[i:i + w].mean()
    ac = np.correlate(seg, seg, "full")[w - 1:]
    ac /= ac[0]
    lo, hi = SR // 400, SR // 70
    lag = lo + int(ac[lo:hi].argmax())
    return SR / lag, float(ac[lag])


@pytest.mark.parametrize("seed", range(4))
def test_formant_voice_is_voiced_speech(seed):
    x = sounds.speech("Musashi, over here!", rng(seed), engine="formant")
    assert np.all(np.isfinite(x)) and rms(x) == pytest.approx(1.0, abs=1e-12)
    assert 0.6 * SR < len(x) < 3.5 * SR
    f0, periodicity = _loudest_window_f0(x)
    assert 90 <= f0 <= 400 and periodicity > 0.6  # glottal pulses, 110-260 Hz with intonation
    assert band_fraction(x, 80, 5000) > 0.9
    assert np.array_equal(x, sounds.speech("Musashi, over here!", rng(seed), engine="formant"))


def test_auto_without_espeak_is_the_formant_engine(monkeypatch):
    monkeypatch.setattr(sounds, "_find_espeak", lambda: None)
    a = sounds.speech("Hey, Musashi!", rng(5), engine="auto")
    assert np.array_equal(a, sounds.speech("Hey, Musashi!", rng(5), engine="formant"))
    with pytest.raises(SoundError, match="espeak-ng is not installed"):
        sounds.speech("Hello!", rng(5), engine="espeak")
    voice = sounds.generate("human_voice", rng(6), seconds=3.0)
    assert len(voice) == 3 * SR and rms(voice) == pytest.approx(1.0, abs=1e-12)


def test_broken_espeak_falls_back_with_warning(monkeypatch):
    monkeypatch.setattr(espeak, "_paths", lambda: ("/nonexistent/libespeak-ng.so", "/nonexistent/data"))
    with pytest.warns(RuntimeWarning, match="formant synthesizer"):
        x = sounds.speech("Hello!", rng(7))
    assert np.all(np.isfinite(x)) and rms(x) == pytest.approx(1.0, abs=1e-12)
    with pytest.raises(SoundError, match="espeak-ng exited with 1"):
        sounds.speech("Hello!", rng(7), engine="espeak")


@pytest.mark.skipif(not HAS_ESPEAK, reason="espeak-ng is not installed")
def test_espeak_voice():
    x = sounds.speech("Musashi, over here!", rng(8), engine="espeak")
    assert np.all(np.isfinite(x)) and rms(x) == pytest.approx(1.0, abs=1e-12)
    assert 0.5 * SR < len(x) < 4 * SR
    assert band_fraction(x, 80, 6000) > 0.8
    assert np.array_equal(x, sounds.speech("Musashi, over here!", rng(8), engine="espeak"))
    assert not np.array_equal(x[:1000], sounds.speech("Musashi, over here!", rng(9))[:1000])


@pytest.mark.skipif(not HAS_ESPEAK, reason="no espeakng-loader wheel for this platform")
def test_espeak_needs_no_program_and_forgets_what_it_said(monkeypatch):
    """The voices come from the pip-installed library, not a program on the PATH, and a phrase
    does not depend on the phrases said before it (the library keeps state within a process)."""
    monkeypatch.setenv("PATH", "")
    assert sounds.voice_engine() == espeak.VERSION
    first = sounds.speech("Hey, Musashi!", rng(10), engine="espeak")
    for seed in (11, 12):
        sounds.speech("Over here!", rng(seed), engine="espeak")
    assert np.array_equal(first, sounds.speech("Hey, Musashi!", rng(10), engine="espeak"))



def test_espeak_phrase_does_not_depend_on_the_clock():
    """espeak-ng seeds its noise source from time(NULL) when it starts; the worker fixes the
    seed, so a phrase said in another second is the same phrase, sample for sample."""
    import time

    first, sr = espeak.synthesize("Over here!", "en-us+f5", 35, 181)
    time.sleep(1.05 - time.time() % 1.0)  # into the next second of the clock
    again, sr_again = espeak.synthesize("Over here!", "en-us+f5", 35, 181)
    assert sr == sr_again and np.array_equal(first, again)


# --------------------------------------------------------------------------- test signals

EXPECTED_HARMONICS = {  # relative amplitude of harmonic n (sign dropped), 0 = absent
    "sine": lambda n: 1.0 if n == 1 else 0.0,
    "square": lambda n: 1.0 / n if n % 2 else 0.0,
    "triangle": lambda n: 1.0 / n**2 if n % 2 else 0.0,
    "sawtooth": lambda n: 1.0 / n,
}


@pytest.mark.parametrize("waveform", sounds.TEST_WAVEFORMS)
@pytest.mark.parametrize("f0", [500, 1000, 2000])  # the paper's fundamentals
def test_waveform_harmonics_and_no_aliasing(waveform, f0):
    x = sounds.test_signal(waveform, f0, 1.0)
    assert len(x) == SR and rms(x) == pytest.approx(1.0, abs=1e-12)
    # 1 s holds whole periods, so FFT bin k is exactly k Hz (no leakage).
    mag = np.abs(np.fft.rfft(x))
    n_max = int(np.ceil(SR / 2 / f0)) - 1  # last harmonic strictly below Nyquist
    harmonics = np.arange(1, n_max + 1) * f0
    for n, k in enumerate(harmonics, start=1):
        assert mag[k] / mag[f0] == pytest.approx(EXPECTED_HARMONICS[waveform](n), abs=1e-9)
    # Everything off the harmonics (aliases, leakage) is numerically zero.
    off = np.ones(len(mag), bool)
    off[harmonics] = False
    assert np.sum(mag[off] ** 2) < 1e-18 * np.sum(mag ** 2)


def test_waveforms_are_deterministic_phase_zero():
    for waveform in sounds.TEST_WAVEFORMS:
        x = sounds.test_signal(waveform, 997.3, 0.2)
        assert np.array_equal(x, sounds.test_signal(waveform, 997.3, 0.2))
        assert abs(x[0]) < 1e-12  # sine-phase harmonics all start at zero
    assert sounds.test_signal("sine", 1000, 0.5, sample_rate=48000).shape == (24000,)


def test_white_noise_is_flat_and_seeded():
    x = sounds.test_signal("white_noise", 123.0, 2.0, rng=rng(1))  # f0 ignored
    assert len(x) == 2 * SR and rms(x) == pytest.approx(1.0, abs=1e-12)
    assert band_fraction(x, 0, SR / 4) == pytest.approx(0.5, abs=0.02)
    assert np.array_equal(x, sounds.white_noise(2.0, rng(1)))
    assert not np.array_equal(x, sounds.white_noise(2.0, rng(2)))


# --------------------------------------------------------------------------- load_wav

def test_load_wav_resamples_48k(tmp_path):
    path = tmp_path / "tone.wav"
    t = np.arange(48000) / 48000
    tone = 0.3 * np.sin(2 * np.pi * 1000 * t)
    sf.write(path, np.stack([tone, 0.5 * tone], axis=1), 48000, subtype="FLOAT")
    x = sounds.load_wav(path)
    assert x.shape == (44100,) and x.dtype == np.float64
    ref = 0.75 * 0.3 * np.sin(2 * np.pi * 1000 * np.arange(44100) / SR)
    # Away from the filter's edge transients the resampled tone matches to 1e-3 (of 0.225).
    assert np.max(np.abs(x[200:-200] - ref[200:-200])) < 1e-3
    both = sounds.load_wav(str(path), mono=False)
    assert both.shape == (44100, 2)
    assert np.max(np.abs(both[200:-200, 1] - 0.5 * both[200:-200, 0])) < 1e-9


def test_load_wav_same_rate_is_exact_and_unscaled(tmp_path):
    path = tmp_path / "same.wav"
    data = 0.1 * rng(0).standard_normal(1000)
    sf.write(path, data, SR, subtype="DOUBLE")
    assert np.array_equal(sounds.load_wav(path), data)


def test_load_wav_errors(tmp_path):
    def fails(path, match):
        with pytest.raises(SoundError, match=match) as info:
            sounds.load_wav(path)
        assert str(path) in str(info.value)

    fails(tmp_path / "missing.wav", "no such file")
    fails(tmp_path, "not a regular file")
    garbage = tmp_path / "garbage.wav"
    garbage.write_bytes(b"RIFF not really a wave file" * 10)
    fails(garbage, "not a readable sound file")
    empty = tmp_path / "empty.wav"
    empty.write_bytes(b"")
    fails(empty, "not a readable sound file")
    no_frames = tmp_path / "no_frames.wav"
    sf.write(no_frames, np.zeros(0), SR)
    fails(no_frames, "contains no samples")
    for bad in (np.nan, np.inf):
        path = tmp_path / f"bad_{bad}.wav"
        data = np.zeros(100)
        data[50] = bad
        sf.write(path, data, SR, subtype="FLOAT")
        fails(path, "1 NaN or infinite samples")
    with pytest.raises(SoundError, match="path must be"):
        sounds.load_wav(None)
    with pytest.raises(SoundError, match="sample_rate"):
        sounds.load_wav(garbage, sample_rate=0)


# --------------------------------------------------------------------------- bad input

@pytest.mark.parametrize("call, match", [
    (lambda: sounds.generate("trumpet", rng()), "unknown sound 'trumpet'; valid names: car_horn"),
    (lambda: sounds.generate(3, rng()), "unknown sound"),
    (lambda: sounds.generate("ratchet", 42), "numpy.random.Generator"),
    (lambda: sounds.generate("ratchet", np.random.RandomState(0)), "numpy.random.Generator"),
    (lambda: sounds.generate("ratchet", rng(), seconds=0), "seconds must be in"),
    (lambda: sounds.generate("ratchet", rng(), seconds=-1.0), "seconds must be in"),
    (lambda: sounds.generate("ratchet", rng(), seconds=float("nan")), "seconds must be finite"),
    (lambda: sounds.generate("ratchet", rng(), seconds=float("inf")), "seconds must be finite"),
    (lambda: sounds.generate("ratchet", rng(), seconds=1e6), "seconds must be in"),
    (lambda: sounds.generate("ratchet", rng(), seconds="2"), "seconds must be a number"),
    (lambda: sounds.generate("ratchet", rng(), seconds=[1.0]), "seconds must be a number"),
    (lambda: sounds.generate("ratchet", rng(), seconds=True), "seconds must be a number"),
    (lambda: sounds.generate("ratchet", rng(), seconds=1e-9), "shorter than one sample"),
    (lambda: sounds.generate("ratchet", rng(), sample_rate=0), "sample_rate must be"),
    (lambda: sounds.generate("ratchet", rng(), sample_rate=44100.5), "sample_rate must be"),
    (lambda: sounds.generate("ratchet", rng(), sample_rate=True), "sample_rate must be"),
    (lambda: sounds.test_signal("pulse", 1000, 1.0), "unknown test waveform 'pulse'; valid: sine"),
    (lambda: sounds.test_signal("sine", 0, 1.0), "f0_hz must be in"),
    (lambda: sounds.test_signal("sine", -5, 1.0), "f0_hz must be in"),
    (lambda: sounds.test_signal("sine", 22050, 1.0), "f0_hz must be in"),
    (lambda: sounds.test_signal("sine", float("nan"), 1.0), "f0_hz must be finite"),
    (lambda: sounds.test_signal("sine", None, 1.0), "f0_hz must be a number"),
    (lambda: sounds.test_signal("sine", 1000, 0.0), "seconds must be in"),
    (lambda: sounds.test_signal("sine", 1000, 1 / SR / 4), "shorter than one sample"),
    (lambda: sounds.test_signal("sine", 1000, 1 / SR), "silent"),  # one sample at phase 0
    (lambda: sounds.test_signal("white_noise", 0, 1.0), "needs rng"),
    (lambda: sounds.white_noise(1.0, None), "numpy.random.Generator"),
    (lambda: sounds.white_noise(-1.0, rng()), "seconds must be in"),
    (lambda: sounds.speech("", rng()), "non-blank str"),
    (lambda: sounds.speech("   ", rng()), "non-blank str"),
    (lambda: sounds.speech(42, rng()), "non-blank str"),
    (lambda: sounds.speech("a" * 501, rng()), "non-blank str"),
    (lambda: sounds.speech("Hello!", rng(), engine="festival"), "engine must be"),
    (lambda: sounds.speech("Hello!", "seed"), "numpy.random.Generator"),
    (lambda: sounds.speech("123 456!", rng(), engine="formant"), "cannot speak"),
])
def test_bad_input_raises_sound_error(call, match):
    with pytest.raises(SoundError, match=match):
        call()


def test_sound_error_is_a_value_error():
    with pytest.raises(ValueError):
        sounds.generate("nope", rng())
