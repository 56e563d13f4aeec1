"""The auditory pipeline: audio blocks in, percepts out (DESIGN.md section 1).

Per ear frame (62.5 Hz on the sample clock)::

    X_l, X_r   = front end (2048-point Hamming rFFT)               frontend.EarFrontEnd
    p_l, p_r   = MelCNN(log-mel of the last 25 frames, per ear)    melcnn.MelCNN
    p          = (V_l p_l + V_r p_r) / (V_l + V_r)                 melcnn.fuse
    detected   = classes with p >= threshold
    valid_c    = bins with power > factor x noise and > leakage x the window's leakage of
                 any other bin, within the characteristic bins of c
    P_c(d)     = fuse over valid_c of SSDENet_i(ILD, IPD),         ssdenet.fuse
                 summed over the last ``direction_frames`` frames
    estimate_c = argmax_d P_c(d)

Fusion (``fusion``): a frame's bins are fused by n times their geometric mean (default,
``"product"``) or by the paper's sum (``"sum"``); :data:`~acoustic_sim.auditory.ssdenet.FUSIONS`
says why and what each gave on the tasks. Frames are summed either way.

Why a class's direction sums the last frames, not only the current one: the MelCNN sees
the last 25 frames, so it declares a class some frames after its sound began. A click
(the ratchet) is over by then: the current frame holds no energy in its bins, and its
direction lies in the frames it was detected from. Summing the existence maps of the
recent frames (the paper's sum, extended over time) keeps that evidence and
averages out the frame-to-frame scatter that reverberation gives the interaural cues.
The maps are computed only when some class is detected, only for valid bins within the
detected classes' characteristic bins (no class sums the others), once per frame and bin,
and kept; the networks of a class set run on weights gathered once
(:meth:`SSDENetBank.existence <acoustic_sim.auditory.ssdenet.SSDENetBank.existence>`,
``within=``). With the paper models that brought ``acoustic-sim bench pipeline``'s
``frame_ms_median`` from 4.5 to 3.2 ms (the alarm has 3 of the 32 bank bins).

Precedence (``precedence``): in a small reverberant space (the car cabin: RT60 0.13 s,
the direct sound 7 dB below the reverberant field at 0.8 m) a frame's interaural cues are
those of the direct sound mixed with its reflections, whose energy arrives within 1-2 ms
of it; listeners localize by the first wavefront (the precedence effect). The default,
``"wavefront"``, does so: the features of a frame come from the spectrum of a 1.75 ms
window at an onset in the ear signals (:class:`~acoustic_sim.auditory.precedence.FirstWavefront`,
which has the measurements), and frames without an onset give no direction evidence; the
bins used are the frame's valid bins. ``"ratio"`` is the previous design: a bin counts
only in frames where its power (both ears) rose ``onset_ratio`` times over the previous
frame (session 3: a ratchet click at -108 deg, 0.65 m, on the right in 5/8 instead of 1/8;
the first wavefront: 98 % of 46 clicks, see :mod:`~acoustic_sim.auditory.precedence`).
``None`` is the paper's rule alone, which :meth:`localize` (the paper's experiments) keeps.

Attribution (``coverage``): a class's direction sums the recent frames' evidence in the
class's bins, whatever sound put it there. In the cabin the radio's speech starts while the
relay clicks (the relay's clicks are ratchet-like, so the ratchet class is detected), and
the speech's onset lights up two of the ratchet's twelve bins: summed into the ratchet's
evidence, it placed the ratchet at -87 deg. A frame therefore counts for a class only when
its valid bins cover at least ``coverage`` of the class's bank bins (the cabin tasks:
0.5, ``tasks.cabin.CabinLeverTask.coverage``; the default 0 keeps every frame): a sound of the class excites its
band, another sound's onset only some of it. Speech does not always (voiced frames light
up its harmonics), so the room task keeps 0 (CallResponse, fast models, 20 episodes: 1.0
at 0, 0.95 at 0.5). Measured with the
scripted policies over 90 episodes (seeds 100-189, paper models, kemar), coverage 0 -> 0.5:
ParkingBrake success 0.90 -> 0.92, false releases 0.06 -> 0.02; ReverseAlarm 0.82 -> 0.81,
false releases 0.03 -> 0.03 (fast models, 30 episodes: ParkingBrake 0.67 both, ReverseAlarm
0.73 both).

The second rule (``specificity``) asks where the onset's energy lies: a car horn outside
starting while another vehicle's beeper is heard as the reverse alarm covers all of the
alarm's bins (it is broadband), so coverage lets it through, and it placed the "alarm" in
front of the car (an early release). Its energy hardly lies in those bins. A frame counts
for a class only when at least ``specificity`` of the energy that its onset *added* lies in
the class's bins (300 Hz-12 kHz, both ears; the power of the 10 ms after the onset minus
that of the 10 ms before, :data:`ADDED_MS`, :meth:`FirstWavefront.take_added
<acoustic_sim.auditory.precedence.FirstWavefront.take_added>`; without precedence, the
frame's energy); the frame counts once that is known, at most a frame after its onset. The
cabin's ReverseAlarm uses 0.2 (``tasks.cabin.CabinLeverTask.specificity``; default 0,
off). Measured over 20 ReverseAlarm episodes (fast models): the onsets of the horn put
0.03-0.15 of their added energy in the alarm's bins, the radio's 0.04-0.14, the alarm's
first beeps (with the gearshift's slide) 0.39-0.91 and the other vehicle's beeps
0.35-0.87. The first design took the share from the first wavefront's 1.75 ms
window, which spreads a tone over a kilohertz and holds whatever else sounds: the alarm's
onsets gave 0.24-0.59 there (paper models), the horn's 0.06-0.26, and an alarm onset with
the gearshift's slide 0.15 (a late release). The paper's own rule (:meth:`localize`) has
neither test.

The noise that the validity threshold refers to is the robot's own driving noise (the
paper: 10 times its spectrum per bin). Without a robot (a WAV file), the default is the
microphone's self-noise floor; a task sets the ego-noise spectrum with
:meth:`AuditoryPipeline.set_noise_power`.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.acoustics.microphone import Microphone
from acoustic_sim.auditory.baselines import GccPhat, Music
from acoustic_sim.auditory.features import MEL_FRAMES, MelHistory, ear_volume, ild_ipd, log_mel_patches
from acoustic_sim.auditory.frontend import N_BINS, N_FFT, EarFrontEnd, analyze, bin_frequencies
from acoustic_sim.auditory.melcnn import MelCNN, fuse_unchecked
from acoustic_sim.auditory.percept import DirectionEstimate, Percept
from acoustic_sim.auditory.percept import map_estimate as _estimate
from acoustic_sim.auditory.precedence import FirstWavefront
from acoustic_sim.auditory.ssdenet import (
    DEFAULT_FUSION,
    LEAKAGE,
    SSDENetBank,
    check_fusion,
    fuse,
    noise_power_spectrum,
    pool_looks,
    valid_bins,
)
from acoustic_sim.directions import DirectionGrid
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE, frame_end_sample, sph_to_vec, vec_to_sph

METHODS = ("ssdenet", "music", "gcc-phat")
"""Localization methods of :meth:`AuditoryPipeline.localize`."""

VALIDITY_FACTOR = 10.0
"""The paper's threshold: a bin is valid when its power exceeds 10 x the noise's."""

DIRECTION_FRAMES = 12
"""Frames (0.19 s) of existence maps that a detected class's direction sums by default."""

ONSET_RATIO = 2.0
"""The ``"ratio"`` precedence gate: a bin's power must have doubled (+3 dB) since the last frame."""

SPECIFICITY_BAND_HZ = (300.0, 12000.0)
"""The band (Hz) over which ``specificity`` measures an onset's energy: the networks' range."""

ADDED_MS = 10.0
"""With precedence and ``specificity``: the segments (ms) before and after an onset whose power
difference is the energy the onset added
(:meth:`~acoustic_sim.auditory.precedence.FirstWavefront.take_added`)."""

COHERENCE = 0.97
"""The ``"coherence"`` precedence gate: a bin counts when the interaural coherence of its last
:data:`COHERENCE_FRAMES` frames is at least this."""

COHERENCE_FRAMES = 4
"""Frames (64 ms) over which the ``"coherence"`` gate averages the interaural cross-spectrum."""

PRECEDENCE = ("wavefront", "ratio", "coherence", "wavefront+coherence", None)
"""Precedence modes of the streaming pipeline (module docstring); the first is the default."""


def microphone_noise_power(seconds: float = 1.0) -> np.ndarray:
    """Mean power per ear and bin (2, 1025) of the microphone's self-noise in silence.

    Full-scale units, as the front end sees them; the default noise reference when no
    driving-noise spectrum is known. Deterministic (its own fixed seed: it is a property of
    the microphone, not of an episode).
    """
    mic = Microphone(rng=np.random.default_rng(20220101))
    return noise_power_spectrum(analyze(mic(np.zeros((2, int(seconds * SAMPLE_RATE))))).spectra[3:])


class AuditoryPipeline:
    """The ear unit's board plus the paper's "central nervous system".

    Parameters
    ----------
    hrtf : HRTF
        The ears the networks were trained for (and MUSIC's steering vectors).
    grid : DirectionGrid
        Output directions.
    ssdenet : SSDENetBank
    melcnn : MelCNN
    noise_power : array_like, optional
        (2, 1025) or (1025,) power per bin of the robot's driving noise in full-scale units
        (default: :func:`microphone_noise_power`).
    threshold : float
        Detection threshold on the fused class probability, 0..1 (default 0.5).
    factor : float
        Validity factor over the noise power (the paper: 10).
    leakage : float
        Validity factor over the window's sidelobe leakage from other bins (default
        :data:`~acoustic_sim.auditory.ssdenet.LEAKAGE`, 10; 0: off, the paper's rule alone):
        the neighbours of a strong tone carry its interaural cues, not their own
        (:func:`~acoustic_sim.auditory.ssdenet.valid_bins`).
    direction_frames : int
        Frames whose existence maps a class's direction sums (default
        :data:`DIRECTION_FRAMES`, 0.19 s; 1 = the current frame only).
    precedence : str or None
        ``"wavefront"`` (default: features from the first wavefront of onsets),
        ``"ratio"`` (bins whose power rose ``onset_ratio`` times since the last frame) or
        None (the paper's rule alone); see the module docstring.
        ``"coherence"`` (bins whose interaural coherence over the last
        :data:`COHERENCE_FRAMES` frames is at least ``coherence``: the direct sound's cues,
        where the room's diffuse field has decorrelated the ears; for sounds without onsets)
        or ``"wavefront+coherence"`` (the first wavefront at onsets, the coherent bins of the
        frames between them).
    onset_ratio : float
        The ``"ratio"`` mode's factor (default :data:`ONSET_RATIO`), >= 1.
    coherence : float
        The ``"coherence"`` mode's threshold, 0..1 (default :data:`COHERENCE`).
    coverage : float
        A frame counts for a class's direction only when its valid bins cover at least this
        fraction of the class's bank bins, 0..1 (default 0: every frame; the cabin tasks use
        0.5).
    specificity : float
        A frame counts for a class's direction only when at least this fraction of the
        energy its onset added (:data:`ADDED_MS`; the frame's energy without precedence;
        :data:`SPECIFICITY_BAND_HZ`, both ears) lies in the class's characteristic bins,
        0..1 (default 0: every frame; ReverseAlarm uses 0.2). A broadband onset (a car
        horn, a door) while a tonal alarm is detected lights up the alarm's bins too, and
        would put the alarm where the horn is; its energy, spread over all frequencies,
        hardly lies in the alarm's bins.
    onset_windows : int
        With ``precedence="wavefront"``: windows taken at a rising onset (the first
        wavefront's and more, 1 ms apart; default 1), whose existence maps are pooled per
        bin (:func:`~acoustic_sim.auditory.ssdenet.pool_looks`: the mean under the sum, the
        geometric mean under the product; :class:`~acoustic_sim.auditory.precedence.FirstWavefront`,
        ``windows``; what it measured is in that module's docstring).
    fusion : str
        How the existence maps of a frame's bins are fused: ``"product"`` (default) or
        ``"sum"`` (the paper's equation); :data:`~acoustic_sim.auditory.ssdenet.FUSIONS`.
    tracker : DirectionTracker or bool, optional
        Track the sounds' directions in the world frame
        (:class:`~acoustic_sim.auditory.tracker.DirectionTracker`; ``True`` for one with its
        defaults): every frame's evidence for a localized sound is handed to it once, with
        the frame's time, and the percepts carry its estimates (``Percept.tracked``). The
        head's pose must then be given with :meth:`note_pose`.

    :meth:`attend` localizes a sound in every frame, detected or not (an experiment that
    knows what plays; white noise, which is no class, with all the bank's bins).

    Use :meth:`load` to get one with trained (cached) models.
    """

    def __init__(self, *, hrtf: HRTF, grid: DirectionGrid, ssdenet: SSDENetBank, melcnn: MelCNN, noise_power=None,
                 threshold: float = 0.5, factor: float = VALIDITY_FACTOR,
                 direction_frames: int | None = None, precedence: str | None = "wavefront",
                 onset_ratio: float = ONSET_RATIO, coverage: float = 0.0, specificity: float = 0.0,
                 leakage: float = LEAKAGE, onset_windows: int = 1, fusion: str = DEFAULT_FUSION,
                 coherence: float = COHERENCE, tracker=None) -> None:
        if ssdenet.hrtf_ident != hrtf.ident:
            raise ConfigError(f"the SSDENet bank was trained for HRTF {ssdenet.hrtf_name!r} ({ssdenet.hrtf_ident}), "
                              f"not for {hrtf.name!r} ({hrtf.ident})")
        if ssdenet.grid.ident != grid.ident:
            raise ConfigError(f"the SSDENet bank outputs grid {ssdenet.grid.ident}, not {grid.ident}")
        if not (np.isfinite(threshold) and 0.0 < threshold < 1.0):
            raise ConfigError(f"threshold must be in (0, 1), got {threshold}")
        if not (np.isfinite(factor) and factor > 0):
            raise ConfigError(f"factor must be > 0, got {factor}")
        if not (leakage is not None and np.isfinite(leakage) and leakage >= 0):
            raise ConfigError(f"leakage must be >= 0, got {leakage}")
        direction_frames = DIRECTION_FRAMES if direction_frames is None else direction_frames
        if precedence not in PRECEDENCE:
            raise ConfigError(f"precedence must be one of {PRECEDENCE}, got {precedence!r}")
        if not (coherence is not None and np.isfinite(coherence) and 0.0 <= coherence <= 1.0):
            raise ConfigError(f"coherence must be in [0, 1], got {coherence}")
        if not (onset_ratio is not None and np.isfinite(onset_ratio) and onset_ratio >= 1.0):
            raise ConfigError(f"onset_ratio must be >= 1, got {onset_ratio}")
        if not (coverage is not None and np.isfinite(coverage) and 0.0 <= coverage <= 1.0):
            raise ConfigError(f"coverage must be in [0, 1], got {coverage}")
        if not (specificity is not None and np.isfinite(specificity) and 0.0 <= specificity <= 1.0):
            raise ConfigError(f"specificity must be in [0, 1], got {specificity}")
        if not (isinstance(onset_windows, (int, np.integer)) and onset_windows >= 1):
            raise ConfigError(f"onset_windows must be an integer >= 1, got {onset_windows!r}")
        if not isinstance(direction_frames, (int, np.integer)) or not 1 <= direction_frames <= MEL_FRAMES:
            raise ConfigError(f"direction_frames must be an integer in 1..{MEL_FRAMES}, got {direction_frames!r}")
        self.fusion = check_fusion(fusion)
        self.hrtf = hrtf
        self.grid = grid
        self.ssdenet = ssdenet
        self.melcnn = melcnn
        self.classes = tuple(melcnn.classes)
        self._rows = list(self.classes)  # the localizable sounds: the classes, then attended others
        self._attended: list[int] = []  # rows localized in every frame
        self.threshold = float(threshold)
        self.factor = float(factor)
        self.leakage = float(leakage)
        self.set_noise_power(microphone_noise_power() if noise_power is None else noise_power)
        bins = np.asarray(ssdenet.bins)
        self._bank_mask = np.zeros(N_BINS, bool)  # the bank's bins: the only ones whose validity matters
        self._bank_mask[bins] = True
        # Class masks restricted to the bank's bins: (C, n_bank) bool.
        self._class_masks = np.zeros((len(self.classes), bins.size), bool)
        for c, name in enumerate(self.classes):
            cb = melcnn.characteristic_bins.get(name)
            self._class_masks[c] = np.isin(bins, cb) if cb is not None and np.size(cb) else True
        self._class_sizes = self._class_masks.sum(axis=1)  # (C,)
        self.coverage = float(coverage)
        self.specificity = float(specificity)
        f = bin_frequencies()
        self._band = (f >= SPECIFICITY_BAND_HZ[0]) & (f <= SPECIFICITY_BAND_HZ[1])
        # Per class, which of the band's bins are characteristic (all of them for a class without).
        self._class_band = np.ones((len(self.classes), int(self._band.sum())))
        for c, name in enumerate(self.classes):
            cb = melcnn.characteristic_bins.get(name)
            if cb is not None and np.size(cb):
                own = np.zeros(N_BINS, bool)
                own[np.asarray(cb)] = True
                self._class_band[c] = own[self._band]
        self._music: Music | None = None
        self._gcc: GccPhat | None = None
        self.frontend = EarFrontEnd()
        self.mel = MelHistory()
        self._volumes = np.zeros((MEL_FRAMES, 2))  # the last frames' ear volumes, oldest first
        self._n_volumes = 0  # how many of them are real frames
        self.direction_frames = int(direction_frames)
        # Per recent frame: [valid bank bins (n_bank,), ILD/IPD at them (n_valid, 5),
        # existence maps (n_bank, D) or None until a detection needs them, which bins of
        # them have been computed (n_bank,), per class the share of the onset's energy in
        # its characteristic bins (C,) or None when specificity is off].
        self.evidence: deque = deque(maxlen=self.direction_frames)
        self.precedence = precedence
        self.onset_ratio = float(onset_ratio)
        self.wavefront = None
        if precedence in ("wavefront", "wavefront+coherence"):
            # The attribution rule judges an onset by the energy it added (ADDED_MS segments).
            self.wavefront = FirstWavefront(added_ms=ADDED_MS if self.specificity > 0.0 else None,
                                            windows=int(onset_windows))
        if self.wavefront is not None:
            self._short_ok = bin_frequencies()[ssdenet.bins] >= self.wavefront.min_hz  # (n_bank,)
        self._last_power: np.ndarray | None = None  # (n_bank,) both ears, the previous frame
        self._awaiting: dict = {}  # onset sample -> its evidence item, until its added energy is known
        self.coherence = float(coherence)
        self._cross: deque = deque(maxlen=COHERENCE_FRAMES)  # per recent frame (3, n_bank): S_lr, P_l, P_r
        if tracker is True:
            from acoustic_sim.auditory.tracker import DirectionTracker

            tracker = DirectionTracker(grid)
        self.tracker = tracker or None
        if self.tracker is not None:
            if self.tracker.grid.ident != grid.ident:
                raise ConfigError(f"the tracker's grid {self.tracker.grid.ident} is not the pipeline's {grid.ident}")
            for name in self._rows:
                self.tracker.track(name)

    @classmethod
    def load(cls, hrtf="kemar", profile: str = "paper", *, melcnn_profile: str | None = None, noise_power=None,
             threshold: float = 0.5, direction_frames: int | None = None,
             precedence: str | None = "wavefront", onset_ratio: float = ONSET_RATIO, coverage: float = 0.0,
             specificity: float = 0.0, leakage: float = LEAKAGE, onset_windows: int = 1,
             fusion: str = DEFAULT_FUSION, coherence: float = COHERENCE, tracker=None,
             progress: bool = True) -> AuditoryPipeline:
        """A pipeline with the cached models of ``profile`` (trained first where missing).

        Parameters
        ----------
        hrtf : str or HRTF
            ``kemar``, ``spherical`` or a SOFA path.
        profile : str
            Model size: ``paper`` or ``fast`` (tests).
        melcnn_profile : str, optional
            MelCNN profile if it differs from ``profile``.

        The other parameters are the constructor's.
        """
        check_fusion(fusion)  # before any training
        ears = hrtf if isinstance(hrtf, HRTF) else HRTF.load(hrtf)
        grid = DirectionGrid.paper(ears)
        bank = SSDENetBank.load_or_train(ears, grid, profile, progress=progress)
        cnn = MelCNN.load_or_train(melcnn_profile or profile, progress=progress)
        return cls(hrtf=ears, grid=grid, ssdenet=bank, melcnn=cnn, noise_power=noise_power, threshold=threshold,
                   direction_frames=direction_frames, precedence=precedence, onset_ratio=onset_ratio,
                   coverage=coverage, specificity=specificity, leakage=leakage, onset_windows=onset_windows,
                   fusion=fusion, coherence=coherence, tracker=tracker)

    # -- state --------------------------------------------------------------------------------
    def set_noise_power(self, noise_power) -> None:
        """The driving-noise power per bin, (2, 1025) or (1025,) full-scale units, >= 0."""
        n = np.asarray(noise_power, float)
        try:
            n = np.broadcast_to(n, (2, N_BINS)).copy()
        except ValueError:
            raise ConfigError(f"noise_power must have shape (2, {N_BINS}) or ({N_BINS},), got {n.shape}") from None
        if not np.all(np.isfinite(n)) or np.any(n < 0):
            raise ConfigError("noise_power must be finite and >= 0")
        self.noise_power = n

    def reset(self) -> None:
        """Forget all audio (a new episode): clock back to sample 0."""
        self.frontend.reset()
        self.mel.reset()
        self._volumes[:] = 0.0
        self._n_volumes = 0
        self.evidence.clear()
        self._last_power = None
        self._awaiting.clear()
        self._cross.clear()
        if self.wavefront is not None:
            self.wavefront.reset()
        if self.tracker is not None:
            self.tracker.reset()

    def note_pose(self, time_s: float, rotation) -> None:
        """The head's pose from ``time_s`` on (s, the sample clock; ``rotation`` (3, 3) head to
        world), for the tracker; ignored without one."""
        if self.tracker is not None:
            self.tracker.note_pose(time_s, rotation)

    def clear_attention(self) -> None:
        """Localize only the detected classes again (:meth:`attend`)."""
        self._attended.clear()

    def attend(self, name: str, bins=None) -> None:
        """Localize ``name`` in every frame, detected or not: a class, or another sound with
        its characteristic bins (indices into the 1025; None: all the bank's bins)."""
        if self.evidence:
            raise ConfigError("attend to a sound before the first block, or after reset()")
        if name in self._rows:
            if bins is not None and name in self.classes:
                raise ConfigError(f"{name!r} is a class: its characteristic bins are the MelCNN's")
            row = self._rows.index(name)
        else:
            if not isinstance(name, str) or not name:
                raise ConfigError(f"an attended sound needs a name, got {name!r}")
            own = np.zeros(N_BINS, bool)
            try:
                own[np.arange(N_BINS) if bins is None else np.asarray(bins, np.int64)] = True
            except (IndexError, ValueError, TypeError):
                raise ConfigError(f"bins must be indices 0..{N_BINS - 1}, got {bins!r}") from None
            mask = own[self.ssdenet.bins]
            if not mask.any():
                raise ConfigError(f"none of the bins given for {name!r} is one of the bank's")
            self._rows.append(name)
            self._class_masks = np.vstack([self._class_masks, mask[None]])
            self._class_sizes = self._class_masks.sum(axis=1)
            self._class_band = np.vstack([self._class_band, own[self._band][None].astype(float)])
            row = len(self._rows) - 1
            if self.tracker is not None:
                self.tracker.track(name)
        if row not in self._attended:
            self._attended.append(row)

    # -- streaming ----------------------------------------------------------------------------
    def process(self, block) -> list[Percept]:
        """Push a (2, n) block of digital ear samples; one Percept per completed ear frame."""
        frames = self.frontend.push(block)
        if self.wavefront is not None:
            self.wavefront.push(block)
        return [self._frame(int(k), float(t), x) for k, t, x in zip(frames.index, frames.time_s, frames.spectra)]

    def _frame(self, k: int, t: float, x: np.ndarray) -> Percept:
        self.mel.push(x)
        self._volumes[:-1] = self._volumes[1:]
        self._volumes[-1] = ear_volume(x)
        self._n_volumes = min(self._n_volumes + 1, MEL_FRAMES)
        bins = self.ssdenet.bins
        coherent = self._coherent(x[:, bins]) if self.precedence in ("coherence", "wavefront+coherence") else None
        taken = None
        if self.wavefront is not None:
            taken = self.wavefront.take_onset(int(frame_end_sample(k)))
            onset = None if taken is None else taken[1]
            if onset is None and coherent is not None:  # no onset: the frame's cues where the ears agree
                valid = self._valid(x)[bins] & coherent
                cues = x[:, bins]
            elif onset is None:  # no onset, no direction evidence: the validity test is not needed
                valid = np.zeros(bins.size, bool)
                cues = x[:, bins]
            else:
                valid = self._valid(x)[bins]
                # The window spans too few periods of the lowest bins to carry their
                # phase: there the frame's own spectra give the features. With more
                # onset windows (a rising onset), (k, 2, n_bank).
                cues = np.where(self._short_ok, onset[..., bins], x[:, bins])
        else:
            valid = self._valid(x)[bins]
            cues = x[:, bins]
            if coherent is not None:
                valid &= coherent
            if self.precedence == "ratio":
                power = (cues.real**2 + cues.imag**2).sum(axis=0)
                last = self._last_power
                self._last_power = power
                valid &= power > self.onset_ratio * last if last is not None else True
        shares = None
        if valid.any():
            sel = cues[..., valid]
            features = ild_ipd(sel[..., 0, :], sel[..., 1, :])  # (n_valid, 5), or (k, n_valid, 5) for k windows
            if self.specificity > 0.0:
                if taken is not None:
                    # Judged once the energy the onset added is known (this frame or the next);
                    # until then the frame counts for no class.
                    shares = np.zeros(len(self._rows))
                else:
                    shares = self._shares((x.real**2 + x.imag**2).sum(axis=0))
        else:
            features = np.empty((0, 5), np.float32)
        # The frame's window centre: the time its cues describe (the tracker's pose).
        item = [valid, features, None, np.zeros_like(valid), shares, t - N_FFT / 2 / SAMPLE_RATE, set()]
        self.evidence.append(item)
        if self.specificity > 0.0 and self.wavefront is not None:
            if taken is not None and valid.any():
                self._awaiting[taken[0]] = item
            for s, added in self.wavefront.take_added(int(frame_end_sample(k))):
                waiting = self._awaiting.pop(s, None)
                if waiting is not None:
                    waiting[4] = self._shares(added)
        patch = self.mel.patch()
        volume = self._volumes[-self._n_volumes:].mean(axis=0)  # over the patch's frames heard so far
        p_ears = self.melcnn.predict(patch).astype(np.float64)  # (2, C)
        probs = fuse_unchecked(p_ears[0], p_ears[1], volume[0], volume[1]).astype(np.float32)
        order = np.argsort(-probs, kind="stable")
        detected = tuple(self.classes[i] for i in order if probs[i] >= self.threshold)
        rows = [self.classes.index(c) for c in detected]
        rows += [r for r in self._attended if r not in rows]
        directions = self._directions(rows) if rows else {}
        tracked = {}
        if self.tracker is not None:
            for name in self._rows:
                if self.tracker.frames(name):
                    tracked[name] = self.tracker.estimate(name)
        return Percept(frame=k, time_s=t, classes=self.classes, probabilities=probs, detected=detected,
                       directions=directions, mel=patch[:, -1, :].copy(), volume=volume, tracked=tracked)

    def _coherent(self, cues: np.ndarray) -> np.ndarray:
        """Which bank bins (n_bank,) had an interaural coherence of at least ``coherence``
        over the last :data:`COHERENCE_FRAMES` frames (this one, ``cues`` (2, n_bank), the
        last): ``|sum X_l X_r*| / sqrt(sum |X_l|^2 sum |X_r|^2)``; none until that many frames."""
        xl, xr = cues[0], cues[1]
        self._cross.append(np.stack([xl * np.conj(xr), np.abs(xl) ** 2, np.abs(xr) ** 2]))
        if len(self._cross) < COHERENCE_FRAMES:
            return np.zeros(xl.size, bool)
        s_lr, p_l, p_r = np.sum(self._cross, axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            coh = np.abs(s_lr) / np.sqrt(p_l.real * p_r.real)
        return np.nan_to_num(coh) >= self.coherence

    def _valid(self, x: np.ndarray) -> np.ndarray:
        """Valid bins (..., 1025) of spectra (..., 2, 1025): the bank's bins that pass the noise and leakage tests."""
        return valid_bins(x, self.noise_power, self.factor, class_bins=self._bank_mask, leakage=self.leakage)

    def _shares(self, power: np.ndarray) -> np.ndarray:
        """Per class, the share of ``power`` (per bin, (1025,)) within the specificity band that
        lies in the class's characteristic bins (1 for every class when the band is silent)."""
        e = power[self._band]
        total = float(e.sum())
        return self._class_band @ e / total if total > 0 else np.ones(len(self.classes))

    def _directions(self, class_indices: list[int]) -> dict:
        """SSDENet estimates for the given classes from the recent frames' evidence.

        Only the networks of valid bins within the detected classes' characteristic bins
        run (the others would be summed by no class); a frame's maps are computed once per
        bin and kept while the frame is in the evidence window.
        """
        n_dirs = len(self.grid)
        masks = self._class_masks[class_indices]  # (c, n_bank)
        union = masks.any(axis=0)
        within = np.flatnonzero(union)
        total = np.zeros((len(class_indices), n_dirs), np.float64)
        counts = np.zeros(len(class_indices), np.int64)
        for item in self.evidence:
            valid, features, maps, have, shares, centre_s, delivered = item
            used = valid & union
            if not used.any():
                continue
            need = used & ~have
            if need.any():
                if maps is None:
                    maps = item[2] = np.zeros((valid.size, n_dirs), np.float32)
                pos = np.flatnonzero(need)
                rows = np.searchsorted(np.flatnonzero(valid), pos)  # features are stored for the valid bins
                m = self.ssdenet.existence(features[..., rows, :], subset=pos, within=within)
                maps[pos] = pool_looks(m, self.fusion) if m.ndim == 3 else m  # several onset windows, pooled per bin
                have |= need
            sel = masks[:, used]  # (c, n_used)
            if self.coverage > 0.0:
                # A frame counts for a class only when its valid bins cover enough of the
                # class's bins: another sound's onset lights up few of them.
                sel = sel & (sel.sum(axis=1) >= self.coverage * self._class_sizes[class_indices])[:, None]
            if shares is not None:
                # ... and only when the onset's energy lies enough in the class's bins.
                sel = sel & (shares[class_indices] >= self.specificity)[:, None]
            fused = fuse(maps[used], sel, self.fusion)
            total += fused
            counts += sel.sum(axis=1)
            if self.tracker is not None:
                # Each frame's evidence reaches the tracker once per sound, when it first counts.
                for i, c in enumerate(class_indices):
                    if c not in delivered and sel[i].any():
                        delivered.add(c)
                        self.tracker.add(self._rows[c], centre_s, fused[i])
        return {
            self._rows[c]: _estimate(total[i].astype(np.float32), self.grid, int(counts[i]), "ssdenet")
            for i, c in enumerate(class_indices) if counts[i]
        }

    # -- whole recordings ---------------------------------------------------------------------
    def _check_method(self, method: str) -> None:
        if method not in METHODS:
            raise ConfigError(f"unknown localization method {method!r}; valid: {', '.join(METHODS)}")

    def localize(self, audio, *, method: str = "ssdenet", sound: str | None = None, window: int = MEL_FRAMES):
        """Direction estimates of a whole (2, n) recording.

        Parameters
        ----------
        audio : array_like (2, n)
            Digital ear samples (full scale, as ``render`` writes).
        method : str
            ``ssdenet`` (the paper's), ``music`` or ``gcc-phat`` (baselines).
        sound : str, optional
            Restrict SSDENet to this class's characteristic bins.
        window : int
            Frames per running estimate (the per-frame results use the last ``window``
            frames; MUSIC needs several frames for its correlation matrix).

        Returns
        -------
        per_frame : list of (time_s, DirectionEstimate or None)
        overall : DirectionEstimate or None
            From all frames together; None when nothing could be estimated (silence).
        """
        self._check_method(method)
        frames = analyze(audio)
        if len(frames) == 0:
            raise ConfigError(f"the recording is shorter than one ear frame ({int(np.ceil(SAMPLE_RATE / 62.5))} samples)")
        x = frames.spectra
        if method == "ssdenet":
            valid = self._valid(x)
            if sound is not None:
                if sound not in self.classes:
                    raise ConfigError(f"unknown sound class {sound!r}; valid: {', '.join(self.classes)}")
                mask = np.zeros(N_BINS, bool)
                mask[self.ssdenet.bins[self._class_masks[self.classes.index(sound)]]] = True
                valid = valid & mask
            maps, n_valid = self.ssdenet.frame_maps(x, valid, self.fusion)
            csum = np.cumsum(maps, axis=0)
            nsum = np.cumsum(n_valid)
            per_frame = []
            for i, t in enumerate(frames.time_s):
                lo = i - window
                m = csum[i] - (csum[lo] if lo >= 0 else 0.0)
                nb = int(nsum[i] - (nsum[lo] if lo >= 0 else 0))
                per_frame.append((float(t), _estimate(m, self.grid, nb, method) if nb else None))
            overall = _estimate(maps.sum(axis=0), self.grid, int(n_valid.sum()), method) if n_valid.sum() else None
            return per_frame, overall
        est = self._baseline(method)
        per_frame = []
        for i, t in enumerate(frames.time_s):
            per_frame.append((float(t), est(x[max(0, i - window + 1) : i + 1])))
        return per_frame, est(x)

    def _baseline(self, method: str):
        if method == "music":
            if self._music is None:
                self._music = Music(self.hrtf, self.grid)
            music = self._music

            def run(x):
                r = music.analyze(x)
                if r.silent:
                    return None
                return _estimate(np.asarray(r.spectrum, np.float32), self.grid, len(r.bins), "music")

            return run
        if self._gcc is None:
            self._gcc = GccPhat(self.hrtf)
        gcc = self._gcc

        def run(x):
            r = gcc.analyze(x)
            if r.silent:
                return None
            v = sph_to_vec(r.azimuth_deg, 0.0)
            az, el = vec_to_sph(v)
            return DirectionEstimate(vector=v, azimuth_deg=float(az), elevation_deg=float(el), existence=np.zeros(0, np.float32),
                                     confidence=1.0, n_bins=0, method="gcc-phat")

        return run

    def detect(self, audio):
        """Class probabilities of a whole (2, n) recording: :func:`detect_recording`."""
        return detect_recording(self.melcnn, audio)


def detect_recording(melcnn: MelCNN, audio):
    """Class probabilities of a whole (2, n) recording.

    Returns
    -------
    times : numpy.ndarray (K,)
        Frame times (s).
    probabilities : numpy.ndarray float32 (K, C)
        Fused probabilities per frame (each from the 25 frames ending there).
    overall : numpy.ndarray float32 (C,)
        The maximum over frames: the probability that each class occurs in the file.
    """
    frames = analyze(audio)
    if len(frames) == 0:
        raise ConfigError(f"the recording is shorter than one ear frame ({int(np.ceil(SAMPLE_RATE / 62.5))} samples)")
    patches = log_mel_patches(frames.spectra)
    vol = ear_volume(frames.spectra)  # (K, 2)
    kernel = np.ones(MEL_FRAMES) / MEL_FRAMES
    # Mean volume over each patch's frames (frames before the start count as silent).
    vol = np.stack([np.convolve(vol[:, e], kernel)[: len(vol)] for e in range(2)], axis=1)
    probs = np.concatenate([melcnn.detect(patches[i : i + 256], vol[i : i + 256]) for i in range(0, len(patches), 256)])
    probs = probs.astype(np.float32)
    return frames.time_s, probs, probs.max(axis=0)
