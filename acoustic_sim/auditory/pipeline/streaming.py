"""The streaming auditory pipeline: audio blocks in, one Percept per ear frame out.

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

A class's direction sums the recent frames because the MelCNN declares a class some frames
after its sound began (a click is over by then). Which frames and cues count is the
precedence rule (the first wavefront of onsets in a reverberant cabin, or the bins where the
ears agree), and the attribution rules (``coverage``, ``specificity``) keep another sound's
onset out of a class's evidence: :class:`~acoustic_sim.auditory.pipeline.settings.PipelineSettings`.
Measurements: docs/notes/pipeline_rules.md.

The validity threshold refers to the robot's driving noise (the paper: 10 times its
spectrum per bin; :meth:`AuditoryPipeline.set_noise_power`), by default the microphone's floor.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.acoustics.microphone import Microphone
from acoustic_sim.auditory.features import MEL_FRAMES, MelHistory, ear_volume, ild_ipd
from acoustic_sim.auditory.frontend import N_BINS, N_FFT, EarFrontEnd, analyze, bin_frequencies
from acoustic_sim.auditory.melcnn import MelCNN, fuse_unchecked
from acoustic_sim.auditory.percept import Percept
from acoustic_sim.auditory.percept import map_estimate as _estimate
from acoustic_sim.auditory.pipeline.offline import Baselines, detect_recording, localize_recording
from acoustic_sim.auditory.pipeline.rows import SoundRows
from acoustic_sim.auditory.pipeline.settings import (
    ADDED_MS,
    COHERENCE_FRAMES,
    COHERENCE_MODES,
    WAVEFRONT_MODES,
    PipelineSettings,
    merged_settings,
)
from acoustic_sim.auditory.precedence import FirstWavefront
from acoustic_sim.auditory.ssdenet import SSDENetBank, fuse, noise_power_spectrum, pool_looks, valid_bins
from acoustic_sim.directions import DirectionGrid
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE, frame_end_sample


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
        (2, 1025) or (1025,) power per bin of the robot's driving noise in full-scale units,
        >= 0 (default: :func:`microphone_noise_power`).
    tracker : DirectionTracker or bool, optional
        Track the sounds' directions in the world frame
        (:class:`~acoustic_sim.auditory.tracker.DirectionTracker`; ``True`` for one with its
        defaults): every frame's evidence for a localized sound is handed to it once, with
        the frame's time, and the percepts carry its estimates (``Percept.tracked``). The
        head's pose must then be given with :meth:`note_pose`.
    settings : PipelineSettings, optional
        Detection, validity, precedence and attribution rules (default: the defaults).
    **fields
        Fields of :class:`PipelineSettings` that replace those of ``settings``
        (``coverage=0.5``).

    :meth:`attend` localizes a sound in every frame, detected or not (an experiment that
    knows what plays; white noise, which is no class, with all the bank's bins).

    Use :meth:`load` to get one with trained (cached) models.
    """

    def __init__(self, *, hrtf: HRTF, grid: DirectionGrid, ssdenet: SSDENetBank, melcnn: MelCNN, noise_power=None,
                 tracker=None, settings: PipelineSettings | None = None, **fields) -> None:
        if ssdenet.hrtf_ident != hrtf.ident:
            raise ConfigError(f"the SSDENet bank was trained for HRTF {ssdenet.hrtf_name!r} ({ssdenet.hrtf_ident}), "
                              f"not for {hrtf.name!r} ({hrtf.ident})")
        if ssdenet.grid.ident != grid.ident:
            raise ConfigError(f"the SSDENet bank outputs grid {ssdenet.grid.ident}, not {grid.ident}")
        self.settings = s = merged_settings(settings, fields)
        self.hrtf = hrtf
        self.grid = grid
        self.ssdenet = ssdenet
        self.melcnn = melcnn
        self.classes = tuple(melcnn.classes)
        self.rows = SoundRows(self.classes, melcnn.characteristic_bins, ssdenet.bins)
        self.set_noise_power(microphone_noise_power() if noise_power is None else noise_power)
        self._bank_mask = np.zeros(N_BINS, bool)  # the bank's bins: the only ones whose validity matters
        self._bank_mask[np.asarray(ssdenet.bins)] = True
        self.baselines = Baselines(hrtf, grid)
        self.frontend = EarFrontEnd()
        self.mel = MelHistory()
        self._volumes = np.zeros((MEL_FRAMES, 2))  # the last frames' ear volumes, oldest first
        self._n_volumes = 0  # how many of them are real frames
        # Per recent frame: [valid bank bins (n_bank,), ILD/IPD at them (n_valid, 5), existence
        # maps (n_bank, D) or None until a detection needs them, which bins of them are computed
        # (n_bank,), per row the share of the onset's energy in its characteristic bins (None:
        # specificity off), the window centre (s), the rows whose evidence the tracker has had].
        self.evidence: deque = deque(maxlen=s.direction_frames)
        self.wavefront = None
        if s.precedence in WAVEFRONT_MODES:
            # The attribution rule judges an onset by the energy it added (ADDED_MS segments).
            self.wavefront = FirstWavefront(added_ms=ADDED_MS if s.specificity > 0.0 else None, windows=s.onset_windows)
            self._short_ok = bin_frequencies()[ssdenet.bins] >= self.wavefront.min_hz  # (n_bank,)
        self._last_power: np.ndarray | None = None  # (n_bank,) both ears, the previous frame
        self._awaiting: dict = {}  # onset sample -> its evidence item, until its added energy is known
        self._cross: deque = deque(maxlen=COHERENCE_FRAMES)  # per recent frame (3, n_bank): S_lr, P_l, P_r
        if tracker is True:
            from acoustic_sim.auditory.tracker import DirectionTracker

            tracker = DirectionTracker(grid)
        self.tracker = tracker or None
        if self.tracker is not None:
            if self.tracker.grid.ident != grid.ident:
                raise ConfigError(f"the tracker's grid {self.tracker.grid.ident} is not the pipeline's {grid.ident}")
            for name in self.rows.names:
                self.tracker.track(name)

    @classmethod
    def load(cls, hrtf="kemar", profile: str = "paper", *, melcnn_profile: str | None = None, noise_power=None,
             tracker=None, settings: PipelineSettings | None = None, progress: bool = True, **fields) -> AuditoryPipeline:
        """A pipeline with the cached models of ``profile`` (trained first where missing).

        Parameters
        ----------
        hrtf : str or HRTF
            ``kemar``, ``spherical`` or a SOFA path.
        profile : str
            Model size: ``paper`` or ``fast`` (tests).
        melcnn_profile : str, optional
            MelCNN profile if it differs from ``profile``.
        progress : bool
            A progress bar while a model trains.

        The other parameters are the constructor's; the settings are checked before any training.
        """
        settings = merged_settings(settings, fields)
        ears = hrtf if isinstance(hrtf, HRTF) else HRTF.load(hrtf)
        grid = DirectionGrid.paper(ears)
        bank = SSDENetBank.load_or_train(ears, grid, profile, progress=progress)
        cnn = MelCNN.load_or_train(melcnn_profile or profile, progress=progress)
        return cls(hrtf=ears, grid=grid, ssdenet=bank, melcnn=cnn, noise_power=noise_power, tracker=tracker,
                   settings=settings)

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
        self.rows.clear_attention()

    def attend(self, name: str, bins=None) -> None:
        """Localize ``name`` in every frame, detected or not: a class, or another sound with
        its characteristic bins (indices into the 1025, 0..1024; None: all the bank's bins)."""
        if self.evidence:
            raise ConfigError("attend to a sound before the first block, or after reset()")
        known = len(self.rows)
        self.rows.attend(name, bins)
        if self.tracker is not None and len(self.rows) > known:
            self.tracker.track(name)

    def sound_bins(self, name: str) -> np.ndarray:
        """The bank bins (indices into the 1025) that sound ``name``'s direction uses."""
        return self.rows.bins(name)

    def valid_bins(self, x: np.ndarray) -> np.ndarray:
        """Valid bins (..., 1025) of spectra (..., 2, 1025): the bank's bins that pass the noise and leakage tests."""
        return valid_bins(x, self.noise_power, self.settings.factor, class_bins=self._bank_mask,
                          leakage=self.settings.leakage)

    # -- streaming ----------------------------------------------------------------------------
    def process(self, block) -> list[Percept]:
        """Push a (2, n) block of digital ear samples (full scale); one Percept per completed ear frame."""
        frames = self.frontend.push(block)
        if self.wavefront is not None:
            self.wavefront.push(block)
        return [self._frame(int(k), float(t), x) for k, t, x in zip(frames.index, frames.time_s, frames.spectra)]

    def _frame(self, k: int, t: float, x: np.ndarray) -> Percept:
        s = self.settings
        self.mel.push(x)
        self._volumes[:-1] = self._volumes[1:]
        self._volumes[-1] = ear_volume(x)
        self._n_volumes = min(self._n_volumes + 1, MEL_FRAMES)
        valid, cues, taken = self._evidence_bins(k, x)
        shares = None
        if valid.any():
            sel = cues[..., valid]
            features = ild_ipd(sel[..., 0, :], sel[..., 1, :])  # (n_valid, 5), or (k, n_valid, 5) for k windows
            if s.specificity > 0.0:
                if taken is not None:
                    # Judged once the energy the onset added is known (this frame or the next);
                    # until then the frame counts for no class.
                    shares = np.zeros(len(self.rows))
                else:
                    shares = self.rows.shares((x.real**2 + x.imag**2).sum(axis=0))
        else:
            features = np.empty((0, 5), np.float32)
        # The frame's window centre: the time its cues describe (the tracker's pose).
        item = [valid, features, None, np.zeros_like(valid), shares, t - N_FFT / 2 / SAMPLE_RATE, set()]
        self.evidence.append(item)
        if s.specificity > 0.0 and self.wavefront is not None:
            if taken is not None and valid.any():
                self._awaiting[taken[0]] = item
            for onset, added in self.wavefront.take_added(int(frame_end_sample(k))):
                waiting = self._awaiting.pop(onset, None)
                if waiting is not None:
                    waiting[4] = self.rows.shares(added)
        patch = self.mel.patch()
        volume = self._volumes[-self._n_volumes:].mean(axis=0)  # over the patch's frames heard so far
        p_ears = self.melcnn.predict(patch).astype(np.float64)  # (2, C)
        probs = fuse_unchecked(p_ears[0], p_ears[1], volume[0], volume[1]).astype(np.float32)
        order = np.argsort(-probs, kind="stable")
        detected = tuple(self.classes[i] for i in order if probs[i] >= s.threshold)
        rows = [self.classes.index(c) for c in detected]
        rows += [r for r in self.rows.attended if r not in rows]
        directions = self._directions(rows) if rows else {}
        tracked = {}
        if self.tracker is not None:
            for name in self.rows.names:
                if self.tracker.frames(name):
                    tracked[name] = self.tracker.estimate(name)
        return Percept(frame=k, time_s=t, classes=self.classes, probabilities=probs, detected=detected,
                       directions=directions, mel=patch[:, -1, :].copy(), volume=volume, tracked=tracked)

    def _evidence_bins(self, k: int, x: np.ndarray):
        """The frame's bank bins that give direction evidence (n_bank,) bool, the cues to take
        their features from ((2, n_bank), or (k, 2, n_bank) for k onset windows), and the
        onset taken in the frame (``(sample, spectra)``, or None)."""
        s = self.settings
        bins = self.ssdenet.bins
        coherent = self._coherent(x[:, bins]) if s.precedence in COHERENCE_MODES else None
        taken = None
        if self.wavefront is not None:
            taken = self.wavefront.take_onset(int(frame_end_sample(k)))
            onset = None if taken is None else taken[1]
            if onset is None and coherent is not None:  # no onset: the frame's cues where the ears agree
                return self.valid_bins(x)[bins] & coherent, x[:, bins], taken
            if onset is None:  # no onset, no direction evidence: the validity test is not needed
                return np.zeros(bins.size, bool), x[:, bins], taken
            # The window spans too few periods of the lowest bins to carry their phase: there
            # the frame's own spectra give the features.
            return self.valid_bins(x)[bins], np.where(self._short_ok, onset[..., bins], x[:, bins]), taken
        valid = self.valid_bins(x)[bins]
        cues = x[:, bins]
        if coherent is not None:
            valid &= coherent
        if s.precedence == "ratio":
            power = (cues.real**2 + cues.imag**2).sum(axis=0)
            last = self._last_power
            self._last_power = power
            valid &= power > s.onset_ratio * last if last is not None else True
        return valid, cues, taken

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
        return np.nan_to_num(coh) >= self.settings.coherence

    def _directions(self, class_indices: list[int]) -> dict:
        """SSDENet estimates for the given rows from the recent frames' evidence.

        Only the networks of valid bins within the rows' characteristic bins run (the others
        would be summed by no row); a frame's maps are computed once per bin and kept while
        the frame is in the evidence window.
        """
        s = self.settings
        n_dirs = len(self.grid)
        masks = self.rows.masks[class_indices]  # (c, n_bank)
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
                maps[pos] = pool_looks(m, s.fusion) if m.ndim == 3 else m  # several onset windows, pooled per bin
                have |= need
            sel = masks[:, used]  # (c, n_used)
            if s.coverage > 0.0:
                # A frame counts for a class only when its valid bins cover enough of the
                # class's bins: another sound's onset lights up few of them.
                sel = sel & (sel.sum(axis=1) >= s.coverage * self.rows.sizes[class_indices])[:, None]
            if shares is not None:
                # ... and only when the onset's energy lies enough in the class's bins.
                sel = sel & (shares[class_indices] >= s.specificity)[:, None]
            fused = fuse(maps[used], sel, s.fusion)
            total += fused
            counts += sel.sum(axis=1)
            if self.tracker is not None:
                # Each frame's evidence reaches the tracker once per sound, when it first counts.
                for i, c in enumerate(class_indices):
                    if c not in delivered and sel[i].any():
                        delivered.add(c)
                        self.tracker.add(self.rows.names[c], centre_s, fused[i])
        return {
            self.rows.names[c]: _estimate(total[i].astype(np.float32), self.grid, int(counts[i]), "ssdenet")
            for i, c in enumerate(class_indices) if counts[i]
        }

    # -- whole recordings ---------------------------------------------------------------------
    def localize(self, audio, *, method: str = "ssdenet", sound: str | None = None, window: int = MEL_FRAMES):
        """Direction estimates of a whole (2, n) recording (the paper's rule alone).

        Parameters
        ----------
        audio : array_like (2, n)
            Digital ear samples (full scale, as ``render`` writes), at least one ear frame.
        method : str
            ``ssdenet`` (the paper's), ``music`` or ``gcc-phat`` (baselines).
        sound : str, optional
            Restrict SSDENet to this class's characteristic bins.
        window : int
            Frames per running estimate, >= 1 (the per-frame results use the last ``window``
            frames; MUSIC needs several frames for its correlation matrix).

        Returns
        -------
        per_frame : list of (time_s, DirectionEstimate or None)
        overall : DirectionEstimate or None
            From all frames together; None when nothing could be estimated (silence).
        """
        return localize_recording(self, audio, method=method, sound=sound, window=window)

    def detect(self, audio):
        """Class probabilities of a whole (2, n) recording: :func:`detect_recording`."""
        return detect_recording(self.melcnn, audio)
