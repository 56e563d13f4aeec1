"""HRTF sets (acoustic_sim.acoustics.hrtf): KEMAR, the rigid sphere, SOFA I/O, lookups."""

import hashlib
import re
import time

import netCDF4
import numpy as np
import pytest
import sofar

from acoustic_sim.acoustics.hrtf import HRTF, KEMAR_PATH, MIN_LEAD_SAMPLES, kemar_directions
from acoustic_sim.errors import ConfigError, HRTFError
from acoustic_sim.frames import SPEED_OF_SOUND, angle_between_deg, sph_to_vec

FS = 44100


@pytest.fixture(scope="module")
def kemar():
    return HRTF.load("kemar")


@pytest.fixture(scope="module")
def sphere():
    return HRTF.load("spherical")


def level_db(h):
    return 10 * np.log10(np.sum(h**2, axis=-1))


def mag_db(h, n_fft=2048):
    return 20 * np.log10(np.abs(np.fft.rfft(h, n_fft, axis=-1)) + 1e-12)


def interaural_phase_delay_ms(h, lo=2000.0, hi=8000.0, fs=FS):
    """ITD as the slope of the interaural phase arg(A_r / A_l) over lo..hi Hz (group delay)."""
    n = 8192
    spec = np.fft.rfft(h, n, axis=-1)
    f = np.fft.rfftfreq(n, 1 / fs)
    band = (f >= lo) & (f <= hi)
    phase = np.unwrap(np.angle(spec[1] * np.conj(spec[0])))[band]
    return -np.polyfit(2 * np.pi * f[band], phase, 1)[0] * 1e3


# ---------------------------------------------------------------------------------------
# The bundled KEMAR set
# ---------------------------------------------------------------------------------------


def test_kemar_loads(kemar):
    assert kemar.name == "kemar" and kemar.sample_rate == FS
    assert kemar.hrir.shape == (710, 2, 512) and kemar.hrir.dtype == np.float64
    assert kemar.directions.shape == (710, 3)
    assert np.isclose(kemar.min_elevation_deg, -40) and np.isclose(kemar.max_elevation_deg, 90)
    assert np.isclose(kemar.distance_m, 1.4)
    assert len(kemar.ident) == 16 and re.fullmatch(r"[0-9a-f]{16}", kemar.ident)
    np.testing.assert_allclose(angle_between_deg(kemar.directions, kemar_directions()), 0, atol=1e-6)
    assert str(KEMAR_PATH) in kemar.source
    print(f"\nKEMAR: onset_samples {kemar.onset_samples:.3f}, normalization gain "
          f"{kemar.normalization_gain:.4f}, ident {kemar.ident}")


def test_bundled_file_matches_readme():
    readme = (KEMAR_PATH.parent / "README.md").read_text()
    digest = hashlib.sha256(KEMAR_PATH.read_bytes()).hexdigest()
    assert digest in readme, "assets/hrtf/README.md must state the SOFA file's sha256"
    assert KEMAR_PATH.stat().st_size < 4e6


@pytest.mark.parametrize("name", ["kemar", "spherical"])
def test_left_source_is_louder_and_earlier_on_the_left(name, kemar, sphere):
    hrtf = {"kemar": kemar, "spherical": sphere}[name]
    h = hrtf.hrir_at(90, 0)
    assert level_db(h)[0] - level_db(h)[1] > 6
    on = hrtf.onsets()[hrtf.nearest_index(sph_to_vec(90, 0))]
    assert on[0] < on[1] - 15  # about 0.66 ms = 29 samples
    mirrored = hrtf.hrir_at(-90, 0)
    assert level_db(mirrored)[1] - level_db(mirrored)[0] > 6


def test_amplitude_normalization(kemar, sphere):
    n_fft = 4096
    f = np.fft.rfftfreq(n_fft, 1 / FS)
    band = (f >= 200) & (f <= 400)
    assert np.isclose(kemar.diffuse_field_power(n_fft)[:, band].mean(), 1.0, rtol=1e-9)
    assert 1 < kemar.normalization_gain < 10
    # The sphere obeys the convention by physics: within 0.1 dB of 1 without rescaling.
    assert sphere.normalization_gain == 1.0
    assert abs(10 * np.log10(sphere.diffuse_field_power(n_fft)[:, band].mean())) < 0.1


def test_onsets_and_lead(kemar, sphere):
    for hrtf in (kemar, sphere):
        assert hrtf.onsets().min() >= MIN_LEAD_SAMPLES
        assert hrtf.onsets().min() <= hrtf.onset_samples <= hrtf.onsets().max()
    assert np.isclose(kemar.onset_samples, kemar.onsets().mean())
    # Sphere: exact by construction (pre-delay) and consistent with the geometry: the
    # frontal direction reaches both ears about when it reaches the centre (the onset
    # detector fires a few samples before the wavefront).
    assert sphere.onset_samples == float(int(sphere.onset_samples))
    front = sphere.onsets()[sphere.nearest_index(sph_to_vec(0, 0))]
    assert sphere.onset_samples - 10 < front.mean() < sphere.onset_samples + 2


# ---------------------------------------------------------------------------------------
# The rigid sphere
# ---------------------------------------------------------------------------------------


def test_sphere_itd_matches_woodworth(sphere):
    """ITD at azimuth 90 deg, measured (a) as the difference of the -20 dB envelope onsets
    of the two ears (HRTF.onsets) and (b) as the interaural group delay (phase slope) over
    2-8 kHz; both within 5 % of Woodworth's a/c (pi/2 + 1) = 0.656 ms for a = 8.75 cm."""
    woodworth = 0.0875 / SPEED_OF_SOUND * (np.pi / 2 + 1) * 1e3
    assert np.isclose(woodworth, 0.656, atol=1e-3)
    i = sphere.nearest_index(sph_to_vec(90, 0))
    on = sphere.onsets()[i]
    itd_onset = (on[1] - on[0]) / FS * 1e3
    itd_phase = interaural_phase_delay_ms(sphere.hrir[i])
    print(f"\nsphere ITD(90 deg): onsets {itd_onset:.4f} ms, 2-8 kHz group delay "
          f"{itd_phase:.4f} ms, Woodworth {woodworth:.4f} ms")
    assert abs(itd_onset / woodworth - 1) < 0.05
    assert abs(itd_phase / woodworth - 1) < 0.05


def test_sphere_low_frequency_magnitude_is_unity(sphere):
    f = np.fft.rfftfreq(4096, 1 / FS)
    k = np.argmin(np.abs(f - 200))
    for az in (0, 180):
        mag = mag_db(sphere.hrir_at(az, 0), 4096)[:, k]
        assert np.all(np.abs(mag) < 1.0), mag
    # Lateral sources: still within a couple of dB at 200 Hz, ipsilateral above contralateral.
    mag = mag_db(sphere.hrir_at(90, 0), 4096)[:, k]
    assert np.all(np.abs(mag) < 2.0) and mag[0] > mag[1]


def test_sphere_is_symmetric_and_fast():
    t0 = time.perf_counter()
    s = HRTF.spherical_head(radius=0.09, n_taps=256)
    elapsed = time.perf_counter() - t0
    assert elapsed < 5.0, f"spherical head took {elapsed:.2f} s"
    assert HRTF.spherical_head(radius=0.09, n_taps=256) is s  # cached
    left = s.hrir_at(40, 20)
    right = s.hrir_at(-40, 20)
    np.testing.assert_allclose(left[0], right[1], atol=1e-12)
    assert s.hrir.shape == (710, 2, 256)


def test_sphere_rejects_bad_arguments():
    with pytest.raises(ConfigError):
        HRTF.spherical_head(radius=-0.1)
    with pytest.raises(ConfigError):
        HRTF.spherical_head(distance=0.05)
    with pytest.raises(ConfigError):
        HRTF.spherical_head(n_taps=16)
    with pytest.raises(ConfigError):
        HRTF.spherical_head(directions=[[0, 0, 0]])


def test_pinna_cues_only_in_kemar(kemar, sphere):
    """Median-plane spectra above 5 kHz change with elevation for KEMAR (pinna notches
    move) but not for the pinna-less sphere: std over elevations of the 6-12 kHz left-ear
    magnitude spectrum (dB), averaged over frequency."""
    f = np.fft.rfftfreq(2048, 1 / FS)
    band = (f >= 6000) & (f <= 12000)
    el = np.arange(-40, 91, 10)
    stats = {}
    for name, hrtf in (("kemar", kemar), ("sphere", sphere)):
        spectra = mag_db(hrtf.hrirs_for(sph_to_vec(np.zeros_like(el), el))[:, 0])[:, band]
        stats[name] = float(np.mean(np.std(spectra, axis=0)))
    print(f"\nmedian-plane 6-12 kHz spectral std over elevation: {stats}")
    assert stats["kemar"] > 3.0
    assert stats["sphere"] < 0.3
    assert stats["kemar"] > 10 * stats["sphere"]


# ---------------------------------------------------------------------------------------
# Lookup and interpolation
# ---------------------------------------------------------------------------------------


def test_nearest_lookup(kemar):
    idx = kemar.nearest_index(kemar.directions)
    np.testing.assert_array_equal(idx, np.arange(710))
    np.testing.assert_array_equal(kemar.hrir_at(92, 1), kemar.hrir[kemar.nearest_index(sph_to_vec(90, 0))])
    v = np.random.default_rng(0).normal(size=(4, 5, 3))
    assert kemar.nearest_index(v).shape == (4, 5)
    assert kemar.hrirs_for(v).shape == (4, 5, 2, 512)
    with pytest.raises(ConfigError):
        kemar.hrirs_for(v, mode="cubic")
    with pytest.raises(ConfigError):
        kemar.nearest_index([0, 0, 0])


def test_interpolated_at_measured_direction_is_exact(kemar):
    for az, el in ((0, 0), (45, 20), (-90, -40), (0, 90)):
        np.testing.assert_allclose(kemar.hrir_at(az, el, mode="interpolated"), kemar.hrir_at(az, el),
                                   atol=1e-12)


def test_interpolation_between_neighbours(kemar):
    """Halfway between KEMAR neighbours 5 deg apart on the horizontal ring: the ITD lies
    between theirs and the ipsilateral magnitude (0.3-8 kHz) does not dip below both (no
    comb filter). Above 8 kHz the pinna notches move between neighbours (see hrirs_for)."""
    f = np.fft.rfftfreq(4096, 1 / FS)
    band = (f >= 300) & (f <= 8000)
    az = np.arange(0, 360, 5.0)
    a, b = kemar.hrirs_for(sph_to_vec(az, 0)), kemar.hrirs_for(sph_to_vec(az + 5, 0))
    m = kemar.hrirs_for(sph_to_vec(az + 2.5, 0), mode="interpolated")
    tmp = HRTF(np.concatenate([a, m, b]), kemar_directions()[: 3 * az.size], FS)  # for onsets()
    itd = (tmp.onsets()[:, 1] - tmp.onsets()[:, 0]).reshape(3, -1)
    lo, hi = np.minimum(itd[0], itd[2]), np.maximum(itd[0], itd[2])
    assert np.all((itd[1] >= lo - 0.25) & (itd[1] <= hi + 0.25)), np.c_[az, itd.T]
    ipsi = np.where(np.sin(np.deg2rad(az + 2.5)) >= 0, 0, 1)
    rows = np.arange(az.size)
    mag = [mag_db(x, 4096)[rows, ipsi][:, band] for x in (a, m, b)]
    assert (mag[1] - np.minimum(mag[0], mag[2])).min() > -1.5


def test_interpolation_avoids_comb_filtering():
    """On a coarse (10 deg) grid the onset-aligned interpolation reproduces the sphere's
    true HRIR in between; plain averaging of the neighbours comb-filters."""
    az, el = [], []
    for e in range(-40, 91, 10):
        n = max(1, round(36 * np.cos(np.deg2rad(e))))
        az += list(np.arange(n) * 360 / n)
        el += [e] * n
    coarse = HRTF.spherical_head(directions=sph_to_vec(az, el), n_taps=256)
    q = np.arange(15, 80, 10.0)  # midpoints of the horizontal ring on the left
    truth = HRTF.spherical_head(directions=sph_to_vec(q, 0), n_taps=256).hrir
    interp = coarse.hrirs_for(sph_to_vec(q, 0), mode="interpolated")
    naive = 0.5 * (coarse.hrirs_for(sph_to_vec(q - 5, 0)) + coarse.hrirs_for(sph_to_vec(q + 5, 0)))
    err_i = np.linalg.norm(interp - truth, axis=-1) / np.linalg.norm(truth, axis=-1)
    err_n = np.linalg.norm(naive - truth, axis=-1) / np.linalg.norm(truth, axis=-1)
    assert np.median(err_i[:, 0]) < 0.1 < np.median(err_n[:, 0])
    f = np.fft.rfftfreq(2048, 1 / FS)
    band = (f >= 300) & (f <= 12000)
    dip_i = (mag_db(interp) - mag_db(truth))[:, 0, band].min()
    dip_n = (mag_db(naive) - mag_db(truth))[:, 0, band].min()
    assert dip_i > -1.5 and dip_n < -6


def test_coverage_and_fallback(kemar):
    below = sph_to_vec([0, 90, 200], -60)
    assert not kemar.covers(below).any()
    assert kemar.covers(sph_to_vec([0, 10], [-40, 90])).all()
    np.testing.assert_array_equal(kemar.hrirs_for(below, mode="interpolated"), kemar.hrirs_for(below))


def test_transfer_functions(kemar):
    spec = kemar.spectra(2048)
    assert spec.shape == (710, 2, 1025) and np.iscomplexobj(spec)
    np.testing.assert_allclose(spec, np.fft.rfft(kemar.hrir, 2048, axis=-1))
    bins = np.array([10, 100, 500])
    assert kemar.spectra(2048, bins).shape == (710, 2, 3)
    tf = kemar.transfer_function(azimuth_deg=[90, -90], elevation_deg=0, bins=bins)
    assert tf.shape == (2, 2, 3)
    np.testing.assert_allclose(tf[0], spec[kemar.nearest_index(sph_to_vec(90, 0))][:, bins])
    tfv = kemar.transfer_function(sph_to_vec(33, 12), mode="interpolated")
    assert tfv.shape == (2, 1025)
    with pytest.raises(ConfigError):
        kemar.spectra(256)  # shorter than the HRIRs
    with pytest.raises(ConfigError):
        kemar.spectra(2048, bins=[2000])
    with pytest.raises(ConfigError):
        kemar.transfer_function()


def test_diffuse_field(kemar, sphere):
    for hrtf in (kemar, sphere):
        w = hrtf.solid_angle_weights()
        assert np.isclose(w.sum(), 1) and np.all(w >= 0)
        coh = hrtf.diffuse_field_coherence(1024)
        f = np.fft.rfftfreq(1024, 1 / FS)
        assert coh.shape == (513,) and np.all(np.abs(coh) <= 1 + 1e-9)
        assert coh[np.argmin(np.abs(f - 130))] > 0.85  # ears close together at low frequency
        assert np.mean(np.abs(coh[(f > 4000) & (f < 12000)])) < 0.2
        assert hrtf.diffuse_field_power(1024).shape == (2, 513)
    # KEMAR covers -40..90: the lowest ring's cells are cut at -45 deg, not extended to -90.
    w = kemar.solid_angle_weights()
    low = np.isclose(kemar.elevation_deg, -40)
    mid = np.isclose(kemar.elevation_deg, 0)
    assert w[low].sum() / w[mid].sum() < 1.0


def test_immutable(kemar):
    with pytest.raises(AttributeError):
        kemar.name = "x"
    with pytest.raises(ValueError):
        kemar.hrir[0, 0, 0] = 1.0


# ---------------------------------------------------------------------------------------
# SOFA round trips and resampling
# ---------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def small():
    """A small valid set: the sphere on 20 directions, 128 taps."""
    rng = np.random.default_rng(3)
    v = rng.normal(size=(20, 3))
    return HRTF.spherical_head(directions=v, n_taps=128)


def test_save_load_round_trip(small, tmp_path):
    path = small.save_sofa(tmp_path / "small.sofa")
    back = HRTF.load(path)
    assert back.ident == small.ident and back.name == "small"
    np.testing.assert_array_equal(back.hrir, small.hrir)
    np.testing.assert_allclose(back.directions, small.directions, atol=1e-12)
    assert back.onset_samples == small.onset_samples and back.distance_m == small.distance_m


def test_kemar_round_trip(kemar, tmp_path):
    back = HRTF.load(kemar.save_sofa(tmp_path / "k.sofa"))
    assert back.ident == kemar.ident and back.onset_samples == kemar.onset_samples


def test_saved_metadata_is_trusted_only_for_unchanged_data(small, tmp_path):
    path = small.save_sofa(tmp_path / "a.sofa")
    with netCDF4.Dataset(path, "r+") as nc:  # a third party rescales the data, keeps the attributes
        nc["Data.IR"][:] = 5.0 * nc["Data.IR"][:]
    back = HRTF.load(path)
    assert back.ident != small.ident
    assert np.isclose(back.normalization_gain, 0.2 / small.normalization_gain, rtol=0.01)
    np.testing.assert_allclose(back.hrir, small.hrir, atol=0.01 * np.abs(small.hrir).max())


def test_data_delay_and_duplicate_directions(small, tmp_path):
    sofa = sofar.read_sofa(str(small.save_sofa(tmp_path / "a.sofa")), verbose=False)
    sofa.Data_Delay = np.array([[3.0, 5.0]])
    sofar.write_sofa(str(tmp_path / "delay.sofa"), sofa)
    delayed = HRTF.load(tmp_path / "delay.sofa")
    assert delayed.n_taps == small.n_taps + 5
    np.testing.assert_allclose(delayed.onsets() - small.onsets(), np.broadcast_to([3.0, 5.0], (20, 2)), atol=0.2)
    sofa = sofar.read_sofa(str(small.save_sofa(tmp_path / "b.sofa")), verbose=False)
    sofa.Data_IR = np.concatenate([small.hrir, small.hrir[:2]])
    sofa.SourcePosition = np.concatenate([sofa.SourcePosition, sofa.SourcePosition[:2]])
    sofar.write_sofa(str(tmp_path / "dup.sofa"), sofa)
    with pytest.warns(UserWarning, match="dropped 2 measurements"):
        dup = HRTF.load(tmp_path / "dup.sofa")
    assert dup.n_directions == 20


def test_other_suffix_and_cartesian_positions(small, tmp_path):
    path = small.save_sofa(tmp_path / "a.sofa")
    other = tmp_path / "copy.bin"
    other.write_bytes(path.read_bytes())
    assert HRTF.load(other).ident == small.ident
    sofa = sofar.read_sofa(str(path), verbose=False)
    sofa.SourcePosition = small.directions * 2.0
    sofa.SourcePosition_Type = "cartesian"
    sofa.SourcePosition_Units = "metre"
    sofar.write_sofa(str(tmp_path / "cart.sofa"), sofa)
    back = HRTF.load(tmp_path / "cart.sofa")
    np.testing.assert_allclose(back.directions, small.directions, atol=1e-12)
    assert np.isclose(back.distance_m, 2.0)


def test_receiver_order_follows_receiver_position(small, tmp_path):
    sofa = sofar.read_sofa(str(small.save_sofa(tmp_path / "a.sofa")), verbose=False)
    sofa.Data_IR = small.hrir[:, ::-1, :]
    sofa.ReceiverPosition = np.array([[0, -0.09, 0], [0, 0.09, 0]])  # receiver 0 = right ear
    sofar.write_sofa(str(tmp_path / "swapped.sofa"), sofa)
    np.testing.assert_array_equal(HRTF.load(tmp_path / "swapped.sofa").hrir, small.hrir)


def test_resampling_from_48k(tmp_path):
    s48 = HRTF.spherical_head(directions=sph_to_vec([90, 0, -90, 180], 0), n_taps=256, sample_rate=48000)
    back = HRTF.load(s48.save_sofa(tmp_path / "s48.sofa"), sample_rate=44100)
    assert back.sample_rate == 44100
    assert back.n_taps == int(np.ceil(256 * 44100 / 48000))
    assert np.isclose(back.onset_samples, s48.onset_samples * 44100 / 48000)
    itd48 = (s48.onsets()[0, 1] - s48.onsets()[0, 0]) / 48000
    itd44 = (back.onsets()[0, 1] - back.onsets()[0, 0]) / 44100
    assert abs(itd44 - itd48) < 20e-6
    kemar48 = HRTF.load("kemar", sample_rate=48000)
    assert kemar48.sample_rate == 48000 and kemar48.n_taps == int(np.ceil(512 * 48000 / 44100))
    with pytest.raises(ConfigError):
        HRTF.load("kemar", sample_rate=0)


# ---------------------------------------------------------------------------------------
# Malformed files: always an HRTFError naming the file, never a crash or a raw exception
# ---------------------------------------------------------------------------------------


def write_raw_sofa(path, ir, positions, *, fs=44100.0, convention="SimpleFreeFieldHRIR",
                   position_type="spherical"):
    """A minimal SOFA file written with netCDF4 directly (shapes sofar would refuse)."""
    ir = np.asarray(ir, dtype=float)
    positions = np.asarray(positions, dtype=float)
    with netCDF4.Dataset(path, "w", format="NETCDF4") as nc:
        attributes = {"Conventions": "SOFA", "Version": "2.1", "SOFAConventions": convention,
                      "SOFAConventionsVersion": "1.0", "DataType": "FIR", "RoomType": "free field",
                      "APIName": "test", "APIVersion": "0"}
        for key, value in attributes.items():
            setattr(nc, key, value)
        nc.createDimension("M", ir.shape[0] if ir.shape[0] else None)
        nc.createDimension("R", ir.shape[1])
        nc.createDimension("N", ir.shape[2])
        nc.createDimension("C", 3)
        nc.createDimension("I", 1)
        if positions.shape[0] != ir.shape[0]:  # a mis-shaped SourcePosition gets its own dimension
            nc.createDimension("P", positions.shape[0])
        var = nc.createVariable("Data.IR", "f8", ("M", "R", "N"))
        var[:] = ir
        sr = nc.createVariable("Data.SamplingRate", "f8", ("I",))
        sr[:] = fs
        dims = ("M", "C") if positions.shape[0] == ir.shape[0] else ("P", "C")
        pos = nc.createVariable("SourcePosition", "f8", dims)
        pos[:] = positions
        pos.Type = position_type
        pos.Units = "degree, degree, metre"
    return path


@pytest.fixture()
def valid_file(small, tmp_path):
    return small.save_sofa(tmp_path / "valid.sofa")


def assert_hrtf_error(path, *fragments):
    with pytest.raises(HRTFError) as info:
        HRTF.load(path)
    message = str(info.value)
    assert str(path) in message or path.name in message, message
    for fragment in fragments:
        assert fragment.lower() in message.lower(), message
    return message


def test_error_missing_file_and_directory(tmp_path):
    assert_hrtf_error(tmp_path / "nope.sofa", "does not exist")
    assert_hrtf_error(tmp_path, "directory")
    with pytest.raises(HRTFError):
        HRTF.load(12345)
    with pytest.raises(HRTFError, match="unknown HRTF 'Kemar'"):
        HRTF.load("Kemar")


def test_error_empty_and_random_bytes(tmp_path):
    empty = tmp_path / "empty.sofa"
    empty.write_bytes(b"")
    assert_hrtf_error(empty, "empty")
    noise = tmp_path / "noise.sofa"
    noise.write_bytes(np.random.default_rng(0).bytes(5000))
    assert_hrtf_error(noise, "not a SOFA file")


def test_error_truncated(valid_file, tmp_path):
    data = valid_file.read_bytes()
    for cut in (len(data) // 2, 600, len(data) - 1):
        truncated = tmp_path / f"truncated_{cut}.sofa"
        truncated.write_bytes(data[:cut])
        assert_hrtf_error(truncated, "truncated")


def test_error_corrupted_body(valid_file, tmp_path):
    data = bytearray(valid_file.read_bytes())
    rng = np.random.default_rng(1)
    data[2048:] = rng.bytes(len(data) - 2048)  # superblock intact, everything else garbage
    bad = tmp_path / "corrupt.sofa"
    bad.write_bytes(bytes(data))
    assert_hrtf_error(bad)


def test_error_wrong_convention(small, tmp_path):
    fir = sofar.Sofa("GeneralFIR")
    fir.Data_IR = small.hrir
    fir.Data_Delay = np.zeros((1, 2))
    fir.ReceiverPosition = np.array([[0, 0.09, 0], [0, -0.09, 0]])
    fir.Data_SamplingRate = 44100.0
    fir.SourcePosition = np.column_stack([small.azimuth_deg % 360, small.elevation_deg,
                                          np.full(small.n_directions, 1.5)])
    sofar.write_sofa(str(tmp_path / "fir.sofa"), fir)
    assert_hrtf_error(tmp_path / "fir.sofa", "GeneralFIR", "SimpleFreeFieldHRIR")
    tf = sofar.Sofa("SimpleFreeFieldHRTF")
    spec = np.fft.rfft(small.hrir, axis=-1)
    tf.Data_Real, tf.Data_Imag = spec.real, spec.imag
    tf.N = np.fft.rfftfreq(small.n_taps, 1 / 44100)
    tf.SourcePosition = fir.SourcePosition
    sofar.write_sofa(str(tmp_path / "tf.sofa"), tf)
    assert_hrtf_error(tmp_path / "tf.sofa", "SimpleFreeFieldHRTF", "frequency-domain")


@pytest.mark.parametrize("variable", ["Data.IR", "SourcePosition"])
def test_error_missing_variable(valid_file, variable):
    with netCDF4.Dataset(valid_file, "r+") as nc:
        nc.renameVariable(variable, "Renamed")
    assert_hrtf_error(valid_file, "missing", variable)


def test_error_nan_and_inf(small, tmp_path):
    for bad_value in (np.nan, np.inf):
        ir = small.hrir.copy()
        ir[3, 1, 10] = bad_value
        path = write_raw_sofa(tmp_path / f"bad_{bad_value}.sofa", ir,
                              np.column_stack([small.azimuth_deg, small.elevation_deg, np.ones(20)]))
        assert_hrtf_error(path, "NaN or infinite")


def test_error_zero_directions(tmp_path):
    path = write_raw_sofa(tmp_path / "zero.sofa", np.zeros((0, 2, 64)), np.zeros((0, 3)))
    assert_hrtf_error(path, "Data.IR")


def test_error_misshaped(small, tmp_path):
    pos = np.column_stack([small.azimuth_deg, small.elevation_deg, np.ones(20)])
    one = write_raw_sofa(tmp_path / "one_receiver.sofa", small.hrir[:, :1], pos)
    assert_hrtf_error(one, "1 receivers")
    mismatch = write_raw_sofa(tmp_path / "mismatch.sofa", small.hrir, pos[:7])
    assert_hrtf_error(mismatch, "SourcePosition", "20")


def test_error_zero_energy(small, tmp_path):
    pos = np.column_stack([small.azimuth_deg, small.elevation_deg, np.ones(20)])
    assert_hrtf_error(write_raw_sofa(tmp_path / "silent.sofa", np.zeros_like(small.hrir), pos), "all zeros")
    ir = small.hrir.copy()
    ir[5, 0] = 0
    assert_hrtf_error(write_raw_sofa(tmp_path / "one_silent.sofa", ir, pos), "measurement 5")


@pytest.mark.parametrize("fs", [0.0, -44100.0, np.nan, 1e9])
def test_error_bad_sample_rate(small, tmp_path, fs):
    pos = np.column_stack([small.azimuth_deg, small.elevation_deg, np.ones(20)])
    path = write_raw_sofa(tmp_path / "fs.sofa", small.hrir, pos, fs=fs)
    assert_hrtf_error(path, "SamplingRate")


def test_error_source_at_listener(small, tmp_path):
    pos = np.column_stack([small.azimuth_deg, small.elevation_deg, np.ones(20)])
    pos[2] = [0, 0, 0]
    assert_hrtf_error(write_raw_sofa(tmp_path / "origin.sofa", small.hrir, pos), "zero distance")


# -- the robot's ears: KEMAR with the right pinna tilted -----------------------------------------


def _ild_db(h, band=(4000.0, 12000.0)):
    s = h.spectra(2048)
    f = np.fft.rfftfreq(2048, 1 / h.sample_rate)
    sel = (f >= band[0]) & (f <= band[1])
    return 20 * np.log10(np.abs(s[:, 0, sel]) + 1e-12) - 20 * np.log10(np.abs(s[:, 1, sel]) + 1e-12)


def test_musashi_ears_break_the_median_plane_symmetry(kemar):
    from acoustic_sim.acoustics.hrtf import tilted_right_pinna

    m = HRTF.load("musashi")
    assert m.name == "musashi" and m.ident != kemar.ident
    np.testing.assert_allclose(m.directions, kemar.directions)
    # The left ear is KEMAR's up to the common normalization gain.
    ratio = np.linalg.norm(m.hrir[:, 0]) / np.linalg.norm(kemar.hrir[:, 0])
    np.testing.assert_allclose(m.hrir[:, 0], ratio * kemar.hrir[:, 0], atol=1e-9)
    median = np.abs(((kemar.azimuth_deg + 180.0) % 180.0)) < 1e-6
    median |= np.abs(kemar.azimuth_deg % 180.0) < 1e-6
    # KEMAR is the left ear mirrored: no interaural cue in the median plane at all ...
    assert np.abs(_ild_db(kemar)[median]).max() < 1e-6
    # ... the robot's ears have one: >= 1.5 dB mean |ILD| over 4-12 kHz there, and it
    # differs between front-up and back-down (the tilt moves them opposite ways).
    ild = _ild_db(m)
    assert np.abs(ild[median]).mean() >= 1.5
    up = m.nearest_index(sph_to_vec(0.0, 30.0))
    down = m.nearest_index(sph_to_vec(180.0, 30.0))
    assert np.abs(ild[up] - ild[down]).mean() >= 1.5
    # The rotation keeps each direction's lateral angle: interaural delays move < 40 us.
    itd_k = np.diff(kemar.onsets(), axis=1)[:, 0]
    itd_m = np.diff(m.onsets(), axis=1)[:, 0]
    assert np.median(np.abs(itd_k - itd_m)) / m.sample_rate < 40e-6
    with pytest.raises(ConfigError, match="tilt_deg"):
        tilted_right_pinna(kemar, 60.0, name="x")
