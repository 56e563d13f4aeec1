"""Head-related transfer function sets: SOFA files, the bundled MIT KEMAR, a rigid sphere.

An :class:`HRTF` holds head-related impulse responses (HRIRs) for ``D`` directions and two
ears, in the head frame of :mod:`acoustic_sim.frames` (x forward, y left, z up; receiver 0 is
the left ear). It is the quantity ``A_{l,r}(d, w)`` of the paper (Omura et al. 2022): the
spectra the SSDENet training data, the MUSIC steering vectors and the binaural renderer use.

Conventions shared by every set
-------------------------------
Amplitude
    An HRIR maps the free-field sound pressure at the head centre (head absent) to the
    pressure at the ear, so its magnitude tends to 1 (0 dB) at low frequencies, where the head
    is acoustically small. Measured sets include arbitrary loudspeaker and microphone gains,
    so data loaded from files are scaled once so that the diffuse-field (solid-angle weighted,
    direction-averaged) power of both ears over 200-400 Hz is 1.0. The analytic sphere obeys
    the convention by construction and is not rescaled.
Timing
    ``onset_samples`` is the (fractional) sample index within the HRIRs that corresponds to
    the arrival of the sound at the head centre: a renderer delays a source by its propagation
    time minus ``onset_samples``. For the sphere it is exact (the applied pre-delay); for
    measured sets it is the mean over directions of the mean left/right onset (see
    :meth:`HRTF.onsets`). Detected on band-limited responses, onsets fire a few samples
    before the wavefront's peak (on the sphere the estimate would come out ~8 samples below
    the exact value); all directions share that offset, so it shifts the absolute latency
    only, not ITDs or the timing of reflections relative to the direct sound. Every set is
    padded so that the earliest onset of any HRIR lies at least :data:`MIN_LEAD_SAMPLES`
    samples into the response (and a leading silence longer than 64 samples is trimmed).
Lookup
    ``mode="nearest"`` picks the measured direction with the largest dot product.
    ``mode="interpolated"`` interpolates barycentrically on the spherical Delaunay
    triangulation (the convex hull of the unit vectors) after aligning each HRIR on its own
    onset (magnitudes averaged separately), then re-applies the interpolated onsets as a
    fractional delay, so interpolating between directions with different ITDs does not
    comb-filter. Directions the set does not cover (:meth:`HRTF.covers`, e.g. below -40 deg
    for KEMAR) and directions in triangles that bridge a gap of the measurement grid fall
    back to the nearest direction.

Modules
-------
``hrtf_set``
    :class:`HRTF`, its constructors and basic properties.
``hrir_lookup``, ``transfer_functions``, ``diffuse_field``
    Its lookups, spectra and diffuse-field statistics (base classes of :class:`HRTF`).
``responses``
    Onset detection, fractional delay and the ident hash of HRIR arrays.
``sofa_read``, ``sofa_geometry``, ``sofa_write``
    The one path that reads SOFA files (sofar, every check), the file's geometry (positions,
    orientation, which receiver is the left ear), and writing a set.
``kemar``, ``sphere``, ``pinna``
    The bundled KEMAR set, the rigid sphere (Duda & Martens 1998), the robot's tilted pinna.

Measurements behind the docstrings: docs/notes/hrtf.md.
"""

from acoustic_sim.acoustics.hrtf.hrtf_set import HRTF, NORMALIZATION_BAND_HZ
from acoustic_sim.acoustics.hrtf.kemar import ASSET_DIR, KEMAR_PATH, kemar_directions
from acoustic_sim.acoustics.hrtf.pinna import MUSASHI_RIGHT_PINNA_TILT_DEG, tilted_right_pinna
from acoustic_sim.acoustics.hrtf.responses import MIN_LEAD_SAMPLES, ONSET_THRESHOLD_DB
from acoustic_sim.acoustics.hrtf.sofa_read import sofa_left_receiver
from acoustic_sim.acoustics.hrtf.sphere import sphere_transfer_function

__all__ = [
    "ASSET_DIR", "HRTF", "KEMAR_PATH", "MIN_LEAD_SAMPLES", "MUSASHI_RIGHT_PINNA_TILT_DEG",
    "NORMALIZATION_BAND_HZ", "ONSET_THRESHOLD_DB", "kemar_directions", "sofa_left_receiver",
    "sphere_transfer_function", "tilted_right_pinna",
]
