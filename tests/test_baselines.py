"""MUSIC with HRTF steering vectors and GCC-PHAT: known answers, renders, silence, errors."""

import numpy as np
import pytest

from acoustic_sim.acoustics.renderer import BinauralRenderer
from acoustic_sim.acoustics.room import room_preset
from acoustic_sim.auditory.baselines import GccPhat, Music
from acoustic_sim.auditory.frontend import N_BINS, analyze, frequency_to_bin
from acoustic_sim.directions import DirectionGrid, angular_error_deg
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE, SPEED_OF_SOUND, sph_to_vec


@pytest.fixture(scope="module")
def grid(kemar):
    return DirectionGrid.paper(kemar)


@pytest.fixture(scope="module")
def music(kemar, grid):
    return Music(kemar, grid)


@pytest.fixture(scope="module")
def gcc(kemar):
    return GccPhat(kemar)


def cnoise(rng, shape):
    return rng.standard_normal(shape) + 1j * rng.standard_normal(shape)


def synthetic(kemar, direction, rng, frames=12, noise=1e-3):
    """Spectra (K, 2, N_BINS): the HRTF of ``direction`` times a random source, plus noise."""
    a = kemar.transfer_function(direction[None], n_fft=2048)[0]  # (2, N_BINS)
    s = cnoise(rng, (frames, 1, N_BINS))
    return a[None] * s + noise * cnoise(rng, (frames, 2, N_BINS))


def render(hrtf, azimuth, elevation, signal, seconds=0.4):
    r = BinauralRenderer(hrtf, room_preset("anechoic"), rng=np.random.default_rng(0), background=False)
    r.set_head_pose([0.0, 0.0, 0.0], np.eye(3))
    r.add_source("s", signal, sph_to_vec(azimuth, elevation) * 1.5, level_db=70.0)
    return analyze(r.render(seconds)).spectra


def delayed(x, d):
    """``x`` delayed (circularly) by ``d`` samples, fractional allowed."""
    spec = np.fft.rfft(x)
    w = 2 * np.pi * np.arange(spec.size) / x.size
    return np.fft.irfft(spec * np.exp(-1j * w * d), x.size)


# -- MUSIC ------------------------------------------------------------------------------------


def off_median(grid):
    """Grid indices off the median plane (|y| > 0.05)."""
    return np.flatnonzero(np.abs(grid.vectors[:, 1]) > 0.05)


def test_music_finds_a_synthetic_source_exactly(kemar, grid, music, rng):
    side = off_median(grid)
    for d in list(rng.choice(side, 12, replace=False)) + [side[0], side[-1]]:
        res = music.analyze(synthetic(kemar, grid.vectors[d], rng))
        assert res.index == d
        assert not res.fallback and not res.silent
        assert np.allclose(res.vector, grid.vectors[d])
        assert (res.azimuth_deg, res.elevation_deg) == (grid.azimuth_deg[d], grid.elevation_deg[d])


def test_music_cannot_tell_median_plane_directions_apart(kemar, grid, music, rng):
    """The bundled KEMAR is mirror-symmetric (its right ear is the mirrored left ear), so in
    the median plane A_l = A_r exactly and every median-plane steering vector is parallel to
    (1, 1): a median-plane source scores the maximum at all of them (the paper: MUSIC fails
    in the median plane). Ties resolve to the lowest grid index."""
    median = np.flatnonzero(np.abs(grid.vectors[:, 1]) < 1e-9)
    d = int(grid.nearest(sph_to_vec(0.0, 30.0)))
    assert d in median
    p = music.spectrum(synthetic(kemar, grid.vectors[d], rng))
    assert np.allclose(p[median], 1.0)
    assert np.all(p[np.setdiff1d(np.arange(len(grid)), median)] < 1.0)


def test_music_spectrum_shape_range_and_tuple_api(kemar, grid, music, rng):
    d = 100
    x = synthetic(kemar, grid.vectors[d], rng)
    p = music.spectrum(x)
    assert p.shape == (len(grid),) and np.all(np.isfinite(p))
    assert p.min() >= 0.0 and p.max() <= 1.0 + 1e-12
    vec, az, el = music.estimate(x)
    assert vec.shape == (3,) and np.isclose(np.linalg.norm(vec), 1.0)
    assert (az, el) == (grid.azimuth_deg[d], grid.elevation_deg[d])


def test_music_single_frame_and_float32_input(kemar, grid, music, rng):
    d = 200
    x = synthetic(kemar, grid.vectors[d], rng, frames=1).astype(np.complex64)
    assert music.analyze(x).index == d  # one frame: every bin is rank one, the power floor selects


def test_music_selected_bins_stay_within_the_given_bins(kemar, grid, rng):
    bins = frequency_to_bin([500.0, 1000.0, 2000.0, 4000.0, 8000.0])
    m = Music(kemar, grid, bins=bins)
    d = 42
    res = m.analyze(synthetic(kemar, grid.vectors[d], rng))
    assert set(res.bins.tolist()) <= set(bins.tolist())
    assert res.index == d


def test_music_on_a_sine_may_be_ambiguous_but_does_not_crash(kemar, grid, music, rng):
    """All energy in one bin: two ear values cannot pin down a 3-D direction (any answer is
    allowed), but the result must be a finite grid direction."""
    x = 1e-4 * cnoise(rng, (12, 2, N_BINS))
    b = int(frequency_to_bin(1000.0))
    a = kemar.transfer_function(grid.vectors[7][None], n_fft=2048, bins=[b])[0, :, 0]
    x[:, :, b] += a[None] * cnoise(rng, (12, 1))
    res = music.analyze(x)
    assert np.all(np.isfinite(res.spectrum)) and 0 <= res.index < len(grid)
    assert np.isclose(np.linalg.norm(res.vector), 1.0)
    assert b in res.bins


def test_music_falls_back_when_no_bin_has_a_single_source(music, rng):
    """Independent noise in the two ears: R is full rank in every bin (ratio ~1 < 10)."""
    res = music.analyze(cnoise(rng, (400, 2, N_BINS)))
    assert res.fallback and not res.silent
    assert res.bins.size == music.bins.size
    assert np.all(np.isfinite(res.spectrum))


def test_music_on_a_kemar_render(kemar, grid, music, rng):
    """Broadband noise rendered (anechoic, 1.5 m) at a paper-grid direction: found within 10 deg."""
    for d in (grid.nearest(sph_to_vec(60.0, 0.0)), grid.nearest(sph_to_vec(-120.0, 20.0))):
        spectra = render(kemar, grid.azimuth_deg[d], grid.elevation_deg[d], rng.standard_normal(SAMPLE_RATE))
        vec, _, _ = music.estimate(spectra)
        assert angular_error_deg(vec, grid.vectors[d]) <= 10.0


def test_music_silence_is_straight_ahead(grid, music):
    res = music.analyze(np.zeros((5, 2, N_BINS), np.complex64))
    assert res.silent and not res.fallback and res.bins.size == 0
    assert np.all(res.spectrum == 0.0)
    assert res.index == grid.nearest(np.array([1.0, 0.0, 0.0]))


@pytest.mark.parametrize("shape", [(2, N_BINS), (3, 1, N_BINS), (3, 2, 513), (4, 3, N_BINS), (0, 2, N_BINS)])
def test_music_rejects_bad_shapes(music, shape):
    with pytest.raises(ConfigError):
        music.spectrum(np.zeros(shape, complex))


def test_music_rejects_nan(music):
    x = np.zeros((3, 2, N_BINS), complex)
    x[1, 0, 5] = np.nan
    with pytest.raises(ConfigError, match="NaN"):
        music.estimate(x)


@pytest.mark.parametrize("kwargs", [{"bins": []}, {"bins": [1, 2000]}, {"bins": [-1]}, {"bins": [3, 3]},
                                    {"bins": [1.5]}, {"ratio_threshold": 1.0}, {"min_power_db": 0.0},
                                    {"n_fft": 1023}])
def test_music_rejects_bad_arguments(kemar, grid, kwargs):
    with pytest.raises(ConfigError):
        Music(kemar, grid, **kwargs)


def test_music_rejects_a_grid_that_is_not_a_direction_grid(kemar, grid):
    with pytest.raises(ConfigError, match="DirectionGrid"):
        Music(kemar, grid.vectors)


# -- GCC-PHAT ---------------------------------------------------------------------------------


@pytest.mark.parametrize("delay", [7.3, -12.6, 0.0])
def test_gcc_phat_recovers_a_pure_delay(gcc, rng, delay):
    x = rng.standard_normal(SAMPLE_RATE // 2)
    res = gcc.analyze(analyze(np.stack([x, delayed(x, delay)])).spectra)  # right ear lags: left leads
    assert abs(res.itd_samples - delay) < 0.05  # samples
    assert res.azimuth_deg == pytest.approx(float(gcc.itd_to_azimuth(delay)), abs=0.5)
    assert np.sign(round(res.azimuth_deg, 6)) == np.sign(delay)  # ITD 0 is azimuth 0 exactly
    assert res.elevation_deg == 0.0 and not res.silent


@pytest.mark.parametrize("azimuth", [20.0, 40.0, 60.0])
def test_gcc_phat_woodworth_delay_on_a_sphere(spherical, rng, azimuth):
    """A pure delay equal to Woodworth's ITD (a / c)(theta + sin theta) of the sphere's radius
    maps back to theta within 4 deg through the sphere's own calibration."""
    th = np.deg2rad(azimuth)
    itd = 0.0875 / SPEED_OF_SOUND * (th + np.sin(th)) * SAMPLE_RATE
    x = rng.standard_normal(SAMPLE_RATE // 2)
    _, az, el = GccPhat(spherical).estimate(analyze(np.stack([x, delayed(x, itd)])).spectra)
    assert abs(az - azimuth) <= 4.0 and el == 0.0


@pytest.mark.parametrize("azimuth", [60.0, -60.0])
def test_gcc_phat_on_kemar_renders(kemar, gcc, rng, azimuth):
    vec, az, el = gcc.estimate(render(kemar, azimuth, 0.0, rng.standard_normal(SAMPLE_RATE)))
    assert np.sign(az) == np.sign(azimuth)
    assert abs(az - azimuth) <= 8.0
    assert el == 0.0 and np.allclose(vec, sph_to_vec(az, 0.0))


def test_gcc_phat_folds_a_rear_source_to_the_front(kemar, gcc, rng):
    """The documented limitation: a source at azimuth 150 deg is reported near 30 deg."""
    _, az, _ = gcc.estimate(render(kemar, 150.0, 0.0, rng.standard_normal(SAMPLE_RATE)))
    assert -90.0 <= az <= 90.0 and abs(az - 30.0) <= 10.0


def test_gcc_phat_calibration_is_monotonic(gcc):
    assert np.all(np.diff(gcc.table_itd_samples) > 0)
    assert gcc.itd_to_azimuth(1e3) == 90.0 and gcc.itd_to_azimuth(-1e3) == -90.0
    # KEMAR's largest ITD is about 0.7 ms.
    assert 0.6e-3 < gcc.table_itd_samples[-1] / SAMPLE_RATE < 0.8e-3


def test_gcc_phat_silence_is_straight_ahead(gcc):
    res = gcc.analyze(np.zeros((4, 2, N_BINS)))
    assert res.silent and res.azimuth_deg == 0.0 and res.itd_samples == 0.0
    assert np.allclose(res.vector, [1.0, 0.0, 0.0])


@pytest.mark.parametrize("shape", [(2, N_BINS), (3, 2, 100), (0, 2, N_BINS)])
def test_gcc_phat_rejects_bad_shapes(gcc, shape):
    with pytest.raises(ConfigError):
        gcc.estimate(np.zeros(shape, complex))


@pytest.mark.parametrize("band", [(500.0, 100.0), (0.0, 30000.0), (float("nan"), 1000.0), (100.0, 105.0)])
def test_gcc_phat_rejects_bad_bands(kemar, band):
    with pytest.raises(ConfigError):
        GccPhat(kemar, band_hz=band)
