"""Training an SSDENet bank's weights: the paper's virtual-source data, Gaussian targets, MSE and Adam.

Training data (the paper's equations)
    Per bin, a virtual source in direction d_h::

        X_{l,r}(w_i) = A_{l,r}(d_h, w_i) / sqrt(|A_l(d_h, w_i)|^2 + |A_r(d_h, w_i)|^2) * s + n_{l,r}
        P_train(d_k) = exp(-angle(d_k, d_h)^2 / (2 sigma^2))

    - ``d_h``: each "sound" has one source near every grid direction (so one sound is D
      examples). In the paper the HRTF was measured on the estimation grid itself; here the
      HRTF set has its own directions (KEMAR: 710, the grid 327), so each source is drawn
      uniformly within ``jitter_deg`` of its grid direction and put on the nearest measured
      direction (:func:`source_directions`); d_h is that measured direction, and ``A`` its
      HRTF (the HRIR the renderer plays there; 2048-point rFFT at the front end's bins).
      ``jitter_deg = 0`` is the paper's case: the measured direction nearest to each grid
      direction.
    - ``s``: one random spectrum value per (bin, sound): phase uniform in [0, 2 pi),
      magnitude log-uniform over +-30 dB (the features do not depend on it, the SNR does).
    - ``n``: background noise as a diffuse field: complex Gaussian per ear, with the HRTF's
      diffuse-field power split between the ears and its diffuse-field interaural coherence
      (what the renderer's background noise has), drawn anew for every example. Its total
      power ``E|n_l|^2 + E|n_r|^2`` is ``|s|^2 10^(-SNR/10)``, with SNR uniform in the
      profile's ``snr_db`` range (default 10-40 dB) per (bin, sound): estimation uses only
      bins at least 10 dB above the noise (:func:`acoustic_sim.auditory.ssdenet.validity.valid_bins`).
    - ``P_train``: the paper's Gaussian of the angle between d_k and d_h with ``sigma_deg``
      (``paper``: 6 deg, so a grid neighbour 10.8 deg away gets 0.2; ``fast``: 4 deg),
      *without* the paper's 1/(2 pi sigma^2) factor: the outputs are sigmoids and cannot
      exceed 1, so the peak is 1 (with sigma in radians the factor would be 14.5 for 6 deg; in
      degrees 0.004, which would leave nothing to learn). Narrow targets localise better:
      with a fast bank, sigma 12, 8, 6 and 4 deg gave mean errors of 17, 11, 7 and 4 deg.
    - Loss: mean squared error; optimiser Adam; initial weights as
      :func:`acoustic_sim.auditory.ssdenet.networks.init_weights`.

Entry points: :func:`train_weights` (the trained stacked weights; this module knows no
bank), :func:`acoustic_sim.auditory.ssdenet.bank.train_bank` (a bank of them),
:func:`acoustic_sim.auditory.ssdenet.command.train_command` (``acoustic-sim train ssdenet``)
and :meth:`acoustic_sim.auditory.ssdenet.bank.SSDENetBank.load_or_train` (trains on first use).
"""

from __future__ import annotations

import math
import time

import numpy as np
import torch

from acoustic_sim.auditory.features import ild_ipd
from acoustic_sim.auditory.frontend import N_FFT
from acoustic_sim.auditory.ssdenet.networks import PARAMETER_NAMES, init_weights, ssdenet_forward
from acoustic_sim.auditory.ssdenet.recipes import N_FEATURES, SSDENetProfile, get_profile
from acoustic_sim.directions import DirectionGrid
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE, angle_between_deg


def target_table(grid: DirectionGrid, sigma_deg: float, sources=None) -> np.ndarray:
    """Training targets P_train(d_k) of sources at given directions d_h.

    Parameters
    ----------
    grid : DirectionGrid
        The D output directions d_k.
    sigma_deg : float
        Width of the Gaussian in deg, > 0.
    sources : array_like, shape (S, 3), optional
        Source directions d_h (unit vectors); default the grid's own directions.

    Returns
    -------
    numpy.ndarray, float32 (S, D)
        Row h: ``exp(-angle(d_k, d_h)^2 / (2 sigma^2))`` over k (1 where d_k = d_h).
    """
    src = grid.vectors if sources is None else np.asarray(sources, dtype=float)
    ang = angle_between_deg(src[:, None, :], grid.vectors[None, :, :])
    return np.exp(-(ang**2) / (2.0 * float(sigma_deg) ** 2)).astype(np.float32)


# ------------------------------------------------------------------------------------------
# Training data
# ------------------------------------------------------------------------------------------


def _check_hrtf(hrtf) -> None:
    if int(hrtf.sample_rate) != SAMPLE_RATE:
        raise ConfigError(f"HRTF {hrtf.name!r} is at {hrtf.sample_rate} Hz; the ear front end runs at {SAMPLE_RATE} Hz")


def normalized_transfer(hrtf, bins) -> np.ndarray:
    """The paper's normalised HRTF A_{l,r} / sqrt(|A_l|^2 + |A_r|^2) of every measured direction.

    Returns complex128 (n_measured, 2, n_bins): the 2048-point rFFT of each HRIR at the
    given bins. A bin where both ears are exactly zero gets (1, 1)/sqrt(2).
    """
    _check_hrtf(hrtf)
    a = hrtf.spectra(N_FFT, bins=np.asarray(bins, dtype=np.int64)).astype(np.complex128)
    norm = np.sqrt(np.abs(a[:, 0]) ** 2 + np.abs(a[:, 1]) ** 2)[:, None, :]
    return np.where(norm > 0, a / np.where(norm > 0, norm, 1.0), 1.0 / math.sqrt(2.0))


def source_directions(hrtf, grid: DirectionGrid, n_sounds: int, jitter_deg: float,
                      rng: np.random.Generator) -> np.ndarray:
    """The measured HRTF direction of every virtual source: one per (sound, grid direction).

    Each sound puts one source near every grid direction: uniformly (by area) within a cap
    of ``jitter_deg`` around it, then on the measured direction nearest to that point (the
    HRIR the renderer would play there). ``jitter_deg = 0`` gives exactly the measured
    direction nearest to each grid direction.

    Returns
    -------
    numpy.ndarray, int64 (n_sounds, D)
        Indices into ``hrtf.directions``.
    """
    d = len(grid)
    if jitter_deg <= 0:
        return np.broadcast_to(hrtf.nearest_index(grid.vectors), (n_sounds, d)).astype(np.int64)
    g = grid.vectors
    # An orthonormal frame (u, v, g) around each grid direction.
    helper = np.where(np.abs(g[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    u = np.cross(helper, g)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(g, u)
    cos_t = 1.0 - rng.random((n_sounds, d)) * (1.0 - math.cos(math.radians(jitter_deg)))
    sin_t = np.sqrt(np.clip(1.0 - cos_t**2, 0.0, None))
    phi = 2.0 * np.pi * rng.random((n_sounds, d))
    pts = (cos_t[..., None] * g + (sin_t * np.cos(phi))[..., None] * u + (sin_t * np.sin(phi))[..., None] * v)
    return hrtf.nearest_index(pts).astype(np.int64)


_CHUNK_SOUNDS = 25  # sounds generated at once (bounds memory; part of the random stream's order)


def training_set(hrtf, grid: DirectionGrid, profile, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The training examples of a profile: features and true source directions.

    Parameters
    ----------
    hrtf : HRTF
        The ears (44.1 kHz).
    grid : DirectionGrid
        One virtual source near each of its directions per sound (:func:`source_directions`).
    profile : SSDENetProfile or str
    rng : numpy.random.Generator
        The only source of randomness.

    Returns
    -------
    features : numpy.ndarray, float32 (n_bins, sounds * D, 5)
        ILD/IPD of ``X_train`` (module docstring); example ``j`` is sound ``j // D`` near
        grid direction ``j % D``.
    source : numpy.ndarray, int64 (sounds * D,)
        Index into ``hrtf.directions`` of each example's source direction.
    """
    p = get_profile(profile)
    a_hat = normalized_transfer(hrtf, p.bins)  # (M, 2, B)
    n_dir, n_bins = len(grid), a_hat.shape[2]
    source = source_directions(hrtf, grid, p.sounds, p.jitter_deg, rng)  # (sounds, D)
    power = hrtf.diffuse_field_power(N_FFT)[:, list(p.bins)]  # (2, B)
    share = power / np.maximum(power.sum(axis=0, keepdims=True), 1e-300)
    coh = np.clip(hrtf.diffuse_field_coherence(N_FFT)[list(p.bins)], -1.0, 1.0)  # (B,)
    common = np.sqrt(np.abs(coh))[:, None, None]
    own = np.sqrt(1.0 - np.abs(coh))[:, None, None]
    sign = np.where(coh < 0, -1.0, 1.0)[:, None, None]
    a_t = a_hat.transpose(2, 1, 0)  # (B, 2, M)
    feats = np.empty((n_bins, p.sounds * n_dir, N_FEATURES), np.float32)
    for start in range(0, p.sounds, _CHUNK_SOUNDS):
        m = min(_CHUNK_SOUNDS, p.sounds - start)
        src = source[start:start + m]  # (m, D)
        mag = 10.0 ** (rng.uniform(-30.0, 30.0, (n_bins, m)) / 20.0)
        s = (mag * np.exp(2j * np.pi * rng.random((n_bins, m))))[..., None]  # (B, m, 1)
        snr = rng.uniform(p.snr_db[0], p.snr_db[1], (n_bins, m))
        noise_pow = (np.abs(s[..., 0]) ** 2 * 10.0 ** (-snr / 10.0))[..., None]  # (B, m, 1), both ears
        z = (rng.standard_normal((3, n_bins, m, n_dir)) + 1j * rng.standard_normal((3, n_bins, m, n_dir))) / math.sqrt(2)
        n_l = np.sqrt(noise_pow * share[0][:, None, None]) * (common * z[0] + own * z[1])
        n_r = np.sqrt(noise_pow * share[1][:, None, None]) * (sign * common * z[0] + own * z[2])
        x_l = a_t[:, 0][:, src] * s + n_l  # (B, m, D)
        x_r = a_t[:, 1][:, src] * s + n_r
        feats[:, start * n_dir:(start + m) * n_dir] = ild_ipd(x_l, x_r).reshape(n_bins, m * n_dir, N_FEATURES)
    return feats, source.reshape(-1)


# ------------------------------------------------------------------------------------------
# Training
# ------------------------------------------------------------------------------------------


def train_weights(hrtf, grid: DirectionGrid, profile, *, seed: int | None = None, progress: bool = True,
                  stats: dict | None = None) -> dict[str, torch.Tensor]:
    """Train the stacked weights of an SSDENet bank on the paper's virtual-source data
    (module docstring); :func:`~acoustic_sim.auditory.ssdenet.bank.train_bank` wraps them
    in a bank.

    Parameters
    ----------
    hrtf : HRTF
        The ears (44.1 kHz).
    grid : DirectionGrid
        Output directions; each sound has a virtual source near each of them
        (:func:`source_directions`).
    profile : SSDENetProfile or str
    seed : int, optional
        Seeds the data (``numpy.random.default_rng(seed)``) and the initial weights
        (``torch.Generator().manual_seed(seed)``); default the profile's seed.
    progress : bool
        tqdm progress bar over the Adam steps (stderr).
    stats : dict, optional
        Filled with ``data_s``, ``train_s`` (seconds), ``final_loss`` (mean per-bin MSE
        over the last epoch) and ``steps``.

    Returns
    -------
    dict of str to torch.Tensor
        The trained weights, float32, named and shaped as
        :func:`~acoustic_sim.auditory.ssdenet.networks.init_weights` returns them.
    """
    prof = get_profile(profile)
    seed = prof.seed if seed is None else int(seed)
    if seed < 0:
        raise ConfigError(f"seed must be >= 0, got {seed}")
    threads = torch.get_num_threads()
    if prof.threads:
        torch.set_num_threads(prof.threads)
    try:
        return _train(hrtf, grid, prof, seed, progress, stats)
    finally:
        torch.set_num_threads(threads)


def _train(hrtf, grid: DirectionGrid, prof: SSDENetProfile, seed: int, progress: bool,
           stats: dict | None) -> dict[str, torch.Tensor]:
    from acoustic_sim.progress import progress_bar

    rng = np.random.default_rng(seed)
    gen = torch.Generator().manual_seed(seed)
    t0 = time.perf_counter()
    feats, source = training_set(hrtf, grid, prof, rng)
    targets = torch.from_numpy(target_table(grid, prof.sigma_deg, hrtf.directions))  # (M, D)
    source_t = torch.from_numpy(source)
    data_s = time.perf_counter() - t0
    counts = torch.bincount(source_t, minlength=targets.shape[0]).to(torch.float64)
    prior = float(counts @ targets.mean(dim=1, dtype=torch.float64)) / source.size  # mean target value
    init = init_weights(prof.n_bins, prof.hidden, len(grid), gen, output_prior=prior)
    weights = tuple(init[name].requires_grad_(True) for name in PARAMETER_NAMES)
    x_all = torch.from_numpy(feats)  # (n_bins, N, 5)
    n = x_all.shape[1]
    steps = math.ceil(n / prof.batch_size)
    opt = torch.optim.Adam(weights, lr=prof.learning_rate)
    bar = progress_bar(total=prof.epochs * steps, disable=not progress, unit="step", leave=False,
               desc=f"SSDENet {prof.name} ({prof.n_bins} bins, H={prof.hidden})")
    epoch_loss = float("nan")
    try:
        for _ in range(prof.epochs):
            order = torch.from_numpy(rng.permutation(n))
            total = 0.0
            for i in range(steps):
                idx = order[i * prof.batch_size:(i + 1) * prof.batch_size]
                x = x_all.index_select(1, idx)
                y = targets.index_select(0, source_t.index_select(0, idx))  # (batch, D)
                out = ssdenet_forward(x, *weights)
                # Sum over bins of each bin's mean error: every network trains as if alone.
                per_bin = ((out - y) ** 2).mean(dim=(1, 2))
                loss = per_bin.sum()
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
                total += float(per_bin.detach().mean()) * idx.numel()
                bar.update(1)
                if i % 50 == 0:
                    bar.set_postfix(loss=f"{float(per_bin.detach().mean()):.4f}")
            epoch_loss = total / n
    finally:
        bar.close()
    if stats is not None:
        stats.update(data_s=data_s, train_s=time.perf_counter() - t0 - data_s, final_loss=epoch_loss,
                     steps=prof.epochs * steps)
    return {name: w.detach() for name, w in zip(PARAMETER_NAMES, weights)}

