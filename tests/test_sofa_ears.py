"""Which SOFA receiver is the left ear (issue 32, item 1).

The ARI SOFA API for Matlab/Octave up to 1.1.0 could store ``ReceiverPosition`` with the
ears' y mirrored while receiver 0 is still the left ear (CIPIC, LISTEN, MIT KEMAR large
pinna as converted with it); libmysofa (``src/hrtf/check.c``) reads such files with
receiver 0 as the left ear. The loader does the same and checks the metadata against the
data: at the most lateral source directions the ear facing the source is the louder one.
"""

import warnings

import numpy as np
import pytest
import sofar

from acoustic_sim.acoustics.hrtf import hrtf_set as hrtf_module
from acoustic_sim.acoustics.hrtf import sofa_geometry as sofa_io
from acoustic_sim.acoustics.hrtf import HRTF, KEMAR_PATH, sofa_left_receiver
from acoustic_sim.errors import HRTFError
from acoustic_sim.frames import sph_to_vec

LEFT_FIRST = np.array([[0.0, 0.09, 0.0], [0.0, -0.09, 0.0]])
MIRRORED = LEFT_FIRST[::-1].copy()
ARI = "ARI SOFA API for Matlab/Octave"


@pytest.fixture(scope="module")
def sphere():
    """The rigid-sphere model (receiver 0 = left) on 24 horizontal directions and 12 at +-45 deg."""
    az = np.concatenate([np.arange(0, 360, 15), np.arange(0, 360, 60), np.arange(30, 390, 60)])
    el = np.concatenate([np.zeros(24), np.full(6, 45.0), np.full(6, -45.0)])
    return HRTF.spherical_head(directions=sph_to_vec(az, el), n_taps=128)


@pytest.fixture(scope="module")
def median_plane():
    """The sphere in the median plane only: both ears alike, no lateral direction."""
    el = np.arange(-40, 220, 20.0)
    return HRTF.spherical_head(directions=sph_to_vec(np.zeros_like(el), el), n_taps=128)


def write_set(path, hrir, directions, receivers, *, api=None, version=None, delay=None):
    sofa = sofar.Sofa("SimpleFreeFieldHRIR")
    if api is not None:
        sofa.protected = False
        sofa.GLOBAL_APIName, sofa.GLOBAL_APIVersion = api, version
        sofa.protected = True
    sofa.Data_IR = np.asarray(hrir)
    sofa.SourcePosition = np.column_stack([np.degrees(np.arctan2(directions[:, 1], directions[:, 0])),
                                           np.degrees(np.arcsin(np.clip(directions[:, 2], -1, 1))),
                                           np.ones(len(directions))])
    sofa.ReceiverPosition = np.asarray(receivers, dtype=float)
    if delay is not None:
        sofa.Data_Delay = np.asarray(delay, dtype=float)
    sofar.write_sofa(str(path), sofa)
    return path


def load_quietly(path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return HRTF.load(path)


def reference(hrtf, tmp_path):
    """``hrtf`` as loaded from a correct modern file (left ear first, positions saying so)."""
    return load_quietly(write_set(tmp_path / "reference.sofa", hrtf.hrir, hrtf.directions, LEFT_FIRST)).hrir


def left_ear_is_left(h):
    """The ear facing a source at +-90 deg azimuth is the louder by more than 6 dB."""
    left, right = (10 * np.log10(np.sum(h.hrir_at(az, 0) ** 2, axis=-1)) for az in (90, -90))
    return left[0] - left[1] > 6 and right[1] - right[0] > 6


def test_modern_file_loads_as_written(sphere, tmp_path):
    h = load_quietly(write_set(tmp_path / "modern.sofa", sphere.hrir, sphere.directions, LEFT_FIRST))
    assert left_ear_is_left(h)
    reversed_ = load_quietly(write_set(tmp_path / "reversed.sofa", sphere.hrir[:, ::-1], sphere.directions, MIRRORED))
    np.testing.assert_array_equal(reversed_.hrir, h.hrir)


@pytest.mark.parametrize("version", ["0.4.0", "1.0.2", "1.1.0"])
def test_old_ari_file_with_mirrored_receivers_keeps_receiver_0_left(sphere, tmp_path, version):
    """libmysofa's reading; the data confirm it, so there is nothing to warn about."""
    path = write_set(tmp_path / f"ari_{version}.sofa", sphere.hrir, sphere.directions, MIRRORED,
                     api=ARI, version=version)
    h = load_quietly(path)
    assert left_ear_is_left(h)
    np.testing.assert_array_equal(h.hrir, reference(sphere, tmp_path))
    assert sofa_left_receiver(path) == 0


@pytest.mark.parametrize(("api", "version"), [(ARI, "1.1.1"), (ARI, "1.2.0"), (ARI, "2.1.0"), (ARI, "1.1"),
                                              ("sofar SOFA API for Python (pyfar.org)", "1.0.0")])
def test_mirrored_receivers_outside_the_ari_versions_are_corrected_by_the_data(sphere, tmp_path, api, version):
    """Later ARI versions (and other APIs) are taken at their word, so mirrored positions
    over left-first data are a contradiction: the data win, with a warning."""
    path = write_set(tmp_path / "mirrored.sofa", sphere.hrir, sphere.directions, MIRRORED, api=api, version=version)
    with pytest.warns(UserWarning, match="receiver 0 is the left ear") as record:
        h = HRTF.load(path)
    assert str(path) in str(record[0].message)
    assert left_ear_is_left(h)
    np.testing.assert_array_equal(h.hrir, reference(sphere, tmp_path))


def test_data_contradicting_the_metadata_win_with_a_warning(sphere, tmp_path):
    path = write_set(tmp_path / "right_first.sofa", sphere.hrir[:, ::-1], sphere.directions, LEFT_FIRST)
    with pytest.warns(UserWarning) as record:
        h = HRTF.load(path)
    message = str(record[0].message)
    assert str(path) in message and "receiver 1 is the left ear" in message, message
    assert left_ear_is_left(h)
    np.testing.assert_array_equal(h.hrir, reference(sphere, tmp_path))


def test_old_ari_file_whose_data_follow_its_positions(sphere, tmp_path):
    """An ARI 1.0 file that did put the right ear first (positions and data agree): the
    data overrule libmysofa's rule, with a warning."""
    path = write_set(tmp_path / "ari_right_first.sofa", sphere.hrir[:, ::-1], sphere.directions, MIRRORED,
                     api=ARI, version="1.0.0")
    with pytest.warns(UserWarning, match="receiver 1 is the left ear") as record:
        h = HRTF.load(path)
    assert str(path) in str(record[0].message)
    assert left_ear_is_left(h)


def test_per_measurement_receiver_positions(sphere, tmp_path):
    """ReceiverPosition (R, C, M), the right ear first in every measurement, data agreeing."""
    m = sphere.n_directions
    receivers = np.repeat(MIRRORED[:, :, None], m, axis=2)
    h = load_quietly(write_set(tmp_path / "rcm.sofa", sphere.hrir[:, ::-1], sphere.directions, receivers))
    assert left_ear_is_left(h)
    np.testing.assert_array_equal(h.hrir, reference(sphere, tmp_path))


def test_data_delay_follows_its_receiver(sphere, tmp_path):
    """Data.Delay is in the file's receiver order: with the right ear stored first, its
    second column delays the left ear."""
    path = write_set(tmp_path / "delay.sofa", sphere.hrir[:, ::-1], sphere.directions, MIRRORED,
                     delay=[[0.0, 6.0]])
    h = load_quietly(path)
    undelayed = write_set(tmp_path / "undelayed.sofa", sphere.hrir[:, ::-1], sphere.directions, MIRRORED)
    shift = h.onsets() - load_quietly(undelayed).onsets()
    # ~5.5: the onset detector sees the sphere's band-limited pre-ringing move with it.
    np.testing.assert_allclose(shift[:, 0], 6.0, atol=1.0)
    np.testing.assert_allclose(shift[:, 1], 0.0, atol=0.01)


def test_without_receiver_positions_the_data_decide(sphere, tmp_path):
    same = np.zeros((2, 3))
    h = load_quietly(write_set(tmp_path / "left_first.sofa", sphere.hrir, sphere.directions, same))
    np.testing.assert_array_equal(h.hrir, reference(sphere, tmp_path))
    path = write_set(tmp_path / "right_first.sofa", sphere.hrir[:, ::-1], sphere.directions, same)
    with pytest.warns(UserWarning, match="receiver 1 is the left ear") as record:
        h = HRTF.load(path)
    assert str(path) in str(record[0].message)
    np.testing.assert_array_equal(h.hrir, reference(sphere, tmp_path))


def _undecidable(sphere, median_plane):
    equal = np.repeat(sphere.hrir[:, :1], 2, axis=1)  # both ears alike everywhere
    one_hot = sphere.hrir * np.array([10.0, 1.0])[None, :, None]  # receiver 0 20 dB louder everywhere
    return {
        "median plane only": (median_plane.hrir, median_plane.directions, "off the median plane"),
        "equal levels": (equal, sphere.directions, "differ by less than"),
        "contradicting sides": (one_hot, sphere.directions, "contradict"),
    }


@pytest.mark.parametrize("case", ["median plane only", "equal levels", "contradicting sides"])
def test_undecidable_ears_are_an_error(sphere, median_plane, tmp_path, case):
    hrir, directions, reason = _undecidable(sphere, median_plane)[case]
    path = write_set(tmp_path / "undecidable.sofa", hrir, directions, np.zeros((2, 3)))
    with pytest.raises(HRTFError) as info:
        HRTF.load(path)
    message = str(info.value)
    assert str(path) in message and "left ear" in message and reason in message, message


def test_undecidable_data_leave_the_metadata(sphere, median_plane, tmp_path):
    """Good positions, data that cannot tell: as written, silently. Mirrored positions of
    an old ARI file: receiver 0 left (libmysofa), with a warning that the data cannot tell."""
    h = load_quietly(write_set(tmp_path / "modern.sofa", median_plane.hrir[:, ::-1], median_plane.directions, MIRRORED))
    np.testing.assert_array_equal(h.hrir, reference(median_plane, tmp_path))
    path = write_set(tmp_path / "ari.sofa", median_plane.hrir, median_plane.directions, MIRRORED,
                     api=ARI, version="1.0.0")
    with pytest.warns(UserWarning, match="cannot confirm") as record:
        h = HRTF.load(path)
    assert str(path) in str(record[0].message)
    np.testing.assert_array_equal(h.hrir, reference(median_plane, tmp_path))


def test_ari_version_rule():
    """libmysofa: APIName exactly the ARI API's and APIVersion a.b.c <= 1.1.0 as integers."""
    class Meta:
        GLOBAL_APIName = ARI

    for version, expected in [("0.4.0", True), ("1.0.10", True), ("1.1.0", True), ("1.1.1", False),
                              ("1.10.0", False), ("2.0.0", False), ("1.1", False), ("", False)]:
        Meta.GLOBAL_APIVersion = version
        assert sofa_io.ari_mirrored_receivers(Meta) is expected, version
    Meta.GLOBAL_APIName, Meta.GLOBAL_APIVersion = "ARI SOFA API for Matlab", "1.0.0"
    assert not sofa_io.ari_mirrored_receivers(Meta)


# The bundled file's ReceiverPosition is right (receiver 0 is the left ear), so the ear check
# must not change a bit of what the loader makes of it. The reference is the same load with
# the check bypassed (the loader as it was before the check: follow ReceiverPosition), not a
# stored hash: resample_poly's last bits differ between scipy releases, and a hash taken on
# one machine failed on every fresh one. The native-rate set, which is not resampled, keeps
# its stored ident as an anchor for the loader itself.
NATIVE_KEMAR_IDENT = "ead8cbc807f2624b"


def _load_fresh(name, rate):
    hrtf_module._musashi.cache_clear()
    try:
        return HRTF.load(name, sample_rate=rate)
    finally:
        hrtf_module._musashi.cache_clear()


@pytest.mark.parametrize(("name", "rate"), [("kemar", 44100), ("kemar", 48000),
                                            ("musashi", 44100), ("musashi", 16000)])
def test_bundled_sets_load_exactly_as_before(name, rate, monkeypatch):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        h = _load_fresh(name, rate)
    assert left_ear_is_left(h)
    with monkeypatch.context() as m:
        m.setattr(sofa_io, "left_receiver", lambda *args, **kwargs: 0)
        unchecked = _load_fresh(name, rate)
    assert h.ident == unchecked.ident
    np.testing.assert_array_equal(h.hrir, unchecked.hrir)
    if (name, rate) == ("kemar", 44100):
        assert h.ident == NATIVE_KEMAR_IDENT


def test_bundled_file_needs_no_correction():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert sofa_left_receiver(KEMAR_PATH) == 0
