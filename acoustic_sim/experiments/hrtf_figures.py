"""The paper's HRTF experiments: pinna notches in the median plane, ILD/IPD of the HRTFs.

Both functions compute from HRTF data alone (no rendering), write one JSON file and PNG
figures into an output folder, and return the JSON content as a dict. They run in a few
seconds (most of it loading the HRTF and matplotlib).

``pinna`` (the paper's "Change of frequency response in the median plane")
    The magnitude response of the **left** ear, in dB re the free-field pressure at the head
    centre (the HRTF convention of :mod:`acoustic_sim.acoustics.hrtf`), in the median plane
    from -40 deg elevation in front over the top to -40 deg behind, 10 deg apart (the
    measured direction nearest each is used and recorded), with pinnae (KEMAR) and without
    (the rigid sphere). One ear suffices: the bundled KEMAR's right ear is its mirrored
    left ear, so in the median plane both ears are identical, and the sphere is symmetric.
    The paper moved the head from -90 to 90 deg with a loudspeaker in front; KEMAR was not
    measured below -40 deg, so the same polar range is covered with sources behind instead.
``hrtf_ild_ipd`` (the paper's "HRTF measurement", Figs. hrtf-ILD and hrtf-IPD)
    ILD (natural log, the paper's equation) and IPD = arg(A_l / A_r) of the HRTF at every
    direction of the paper's estimation grid, at the paper's six frequencies, and the ILD
    range per frequency beside the paper's numbers.

Notch detection (``notch_hz`` in ``pinna.json``): the first pinna notch (N1) is the
lowest-frequency local minimum of the dB magnitude between :data:`NOTCH_SEARCH_HZ` whose
prominence (:func:`scipy.signal.find_peaks` on the negated response over 100 Hz .. 0.95 of
Nyquist, i.e. the depth below the lower of the two highest points reachable on either side
without passing a deeper dip) is at least :data:`NOTCH_MIN_PROMINENCE_DB`. No smoothing: the
2048-point spectrum of a 512-tap HRIR is already smooth on the scale of a notch. ``null``
where no minimum qualifies.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from scipy.signal import find_peaks

from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.auditory.features import ild_ipd
from acoustic_sim.auditory.frontend import N_FFT, bin_frequencies, frequency_to_bin
from acoustic_sim.directions import DirectionGrid
from acoustic_sim.errors import ConfigError, HRTFError
from acoustic_sim.experiments.experiment_files import output_folder, rounded, save_figure, write_compact_json
from acoustic_sim.frames import vec_to_sph

PAPER_FREQUENCIES_HZ = (301.5, 560.0, 990.5, 5706.3, 8548.7, 11994.0)
"""The paper's six ILD/IPD frequencies (Hz): bins 14, 26, 46, 265, 397 and 557 of the
2048-point FFT at 44.1 kHz."""

PAPER_ILD_RANGE = (0.13, None, 0.47, 1.76, None, 2.17)
"""The paper's ILD ranges at :data:`PAPER_FREQUENCIES_HZ` (natural-log units). The text gives
"ranging from 0.13 to 0.47" for the low three and "increases from 1.76 to 2.17" for the high
three; read as the values at the lowest and highest frequency of each group (the middle
frequencies are not stated: None)."""

NOTCH_SEARCH_HZ = (4000.0, 16000.0)
"""Band (Hz) searched for the first pinna notch."""

NOTCH_MIN_PROMINENCE_DB = 10.0
"""Smallest prominence (dB) of a minimum that counts as a notch. On KEMAR the N1 notch is
10-33 dB deep wherever it exists, while the shallow dips of the response above 60 deg
elevation and every dip of the sphere stay below 10 dB."""

PINNA_BAND_HZ = (100.0, 16000.0)
"""Frequency range (Hz) of the responses stored in ``pinna.json`` and drawn."""

PINNA_STEP_DEG = 10.0
"""Polar-angle step (deg) of the median-plane directions."""


def _hrtf(spec, what: str) -> HRTF:
    if isinstance(spec, HRTF):
        return spec
    if isinstance(spec, str):
        return HRTF.load(spec)
    raise HRTFError(f"{what} must be an HRTF or a name/path for HRTF.load, got {spec!r}")


# --------------------------------------------------------------------------------------
# Experiment 1: pinna notches in the median plane
# --------------------------------------------------------------------------------------


def first_notch(magnitude_db, freqs_hz) -> tuple[float | None, float | None]:
    """First pinna notch of one magnitude response (see the module docstring).

    Parameters
    ----------
    magnitude_db : array_like, shape (F,)
        Magnitude in dB on the frequency grid ``freqs_hz``.
    freqs_hz : array_like, shape (F,)
        Increasing frequencies in Hz.

    Returns
    -------
    frequency_hz, depth_db : float or None
        Centre frequency (Hz) and prominence (dB) of the notch, or (None, None).
    """
    db = np.asarray(magnitude_db, dtype=float)
    f = np.asarray(freqs_hz, dtype=float)
    if db.shape != f.shape or db.ndim != 1:
        raise ConfigError(f"magnitude_db and freqs_hz must be 1-D of equal length, got {db.shape}, {f.shape}")
    peaks, props = find_peaks(-db, prominence=NOTCH_MIN_PROMINENCE_DB)
    inside = (f[peaks] >= NOTCH_SEARCH_HZ[0]) & (f[peaks] <= NOTCH_SEARCH_HZ[1])
    if not inside.any():
        return None, None
    j = int(np.flatnonzero(inside)[0])
    return float(f[peaks[j]]), float(props["prominences"][j])


def _median_plane_responses(hrtf: HRTF, grid: DirectionGrid, n_fft: int):
    """Left-ear dB magnitude (N, n_fft//2+1) at the measured directions nearest the grid,
    with their azimuth and elevation (deg)."""
    idx = hrtf.nearest_index(grid.vectors)
    az, el = vec_to_sph(hrtf.directions[idx])
    mag = np.abs(hrtf.spectra(n_fft)[idx, 0])
    return 20.0 * np.log10(np.maximum(mag, 1e-12)), az, el


def pinna(out_dir, hrtf_with="kemar", hrtf_without="spherical") -> dict:
    """Median-plane frequency response with and without pinnae; writes ``pinna.json`` and
    ``pinna.png``.

    Parameters
    ----------
    out_dir : str or os.PathLike
        Output folder (created if missing).
    hrtf_with, hrtf_without : HRTF or str
        The head with pinnae (default the bundled KEMAR) and without (default the rigid
        sphere, :meth:`HRTF.spherical_head`); names or paths go to :meth:`HRTF.load`. Both
        must have the project's 44.1 kHz sample rate.

    Returns
    -------
    dict
        The content of ``pinna.json``: ``ear``, ``unit``, ``frequencies_hz`` (F,),
        ``directions`` (N = 27 rows: ``polar_angle_deg``, ``azimuth_deg``,
        ``elevation_deg``, ``side``), ``notch_method``, ``with_pinna`` and
        ``without_pinna`` (each: ``hrtf``, ``ident``, ``measured_azimuth_deg`` (N,),
        ``measured_elevation_deg`` (N,), ``magnitude_db`` (N, F), ``notch_hz`` (N, None
        where absent), ``notch_depth_db`` (N), ``notch_count``, ``notch_range_hz``,
        ``elevation_spread_db``), ``paper`` (the claim) and ``figure``.

    Notes
    -----
    ``elevation_spread_db`` is the median over 1-16 kHz of the spread (max - min over the
    median-plane directions) of the response: how much the response changes with
    elevation (the paper: little without pinnae, a lot with them).
    """
    out = output_folder(out_dir)
    heads = {"with_pinna": _hrtf(hrtf_with, "hrtf_with"), "without_pinna": _hrtf(hrtf_without, "hrtf_without")}
    for h in heads.values():
        if h.sample_rate != 44100:
            raise HRTFError(f"HRTF {h.name!r} is at {h.sample_rate} Hz; the ear front end runs at 44100 Hz")
    lowest = max(h.min_elevation_deg for h in heads.values())
    grid = DirectionGrid.median_plane(PINNA_STEP_DEG, min_elevation_deg=max(-40.0, np.ceil(lowest / 10.0) * 10.0))
    psi = np.rad2deg(np.arctan2(grid.vectors[:, 2], grid.vectors[:, 0]))
    psi = np.where(psi < -90.0, psi + 360.0, psi)  # polar angle: front -40 .. top 90 .. back 220
    freqs = bin_frequencies(N_FFT)
    search = (freqs >= PINNA_BAND_HZ[0]) & (freqs <= 0.95 * freqs[-1])
    keep = (freqs >= PINNA_BAND_HZ[0]) & (freqs <= PINNA_BAND_HZ[1])
    spread_band = (freqs >= 1000.0) & (freqs <= 16000.0)
    result = {
        "experiment": "median-plane frequency response with and without pinnae",
        "ear": "left",
        "unit": "dB re free-field pressure at the head centre",
        "frequencies_hz": rounded(freqs[keep], 3),
        "directions": [
            {"polar_angle_deg": round(float(p), 3), "azimuth_deg": round(float(a), 3), "elevation_deg": round(float(e), 3),
             "side": "front" if p < 90.0 - 1e-6 else ("top" if abs(p - 90.0) < 1e-6 else "back")}
            for p, a, e in zip(psi, grid.azimuth_deg, grid.elevation_deg)
        ],
        "notch_method": (f"lowest-frequency local minimum in {NOTCH_SEARCH_HZ[0]:g}-{NOTCH_SEARCH_HZ[1]:g} Hz with "
                         f"prominence >= {NOTCH_MIN_PROMINENCE_DB:g} dB (scipy.signal.find_peaks on the negated dB "
                         "response, 2048-point FFT, no smoothing)"),
        "paper": "without pinnae the response changes little with elevation; with pinnae it changes strongly, "
                 "with clear notches above about 10 kHz (pinna notches from about 5 kHz)",
        "figure": "pinna.png",
    }
    for key, h in heads.items():
        db, az, el = _median_plane_responses(h, grid, N_FFT)
        notches = [first_notch(row[search], freqs[search]) for row in db]
        found = [f for f, _ in notches if f is not None]
        result[key] = {
            "hrtf": h.name,
            "ident": h.ident,
            "measured_azimuth_deg": rounded(az, 3),
            "measured_elevation_deg": rounded(el, 3),
            "magnitude_db": rounded(db[:, keep], 1),
            "notch_hz": [None if f is None else round(f, 1) for f, _ in notches],
            "notch_depth_db": [None if d is None else round(d, 2) for _, d in notches],
            "notch_count": len(found),
            "notch_range_hz": [round(min(found), 1), round(max(found), 1)] if found else None,
            "elevation_spread_db": round(float(np.median(np.ptp(db[:, spread_band], axis=0))), 2),
        }
    _pinna_figure(result, psi, out / "pinna.png")
    write_compact_json(out / "pinna.json", result)
    return result


def _polar_label(p: float) -> str:
    if p <= 90.0:
        return f"{p:.0f}"
    return f"{180.0 - p:.0f}B"


def _pinna_figure(result: dict, psi: np.ndarray, path: Path) -> None:
    f_khz = np.asarray(result["frequencies_hz"]) / 1000.0
    fig = Figure(figsize=(11, 4.6), layout="constrained")
    axes = fig.subplots(1, 2, sharey=True)
    mesh = None
    for ax, key, title in zip(axes, ("with_pinna", "without_pinna"), ("with pinnae", "without pinnae")):
        r = result[key]
        mesh = ax.pcolormesh(f_khz, psi, np.asarray(r["magnitude_db"]), shading="nearest", cmap="magma", vmin=-35.0, vmax=15.0)
        notch = np.array([np.nan if n is None else n / 1000.0 for n in r["notch_hz"]])
        ax.plot(notch, psi, "o", mfc="none", mec="cyan", ms=6, label="first notch (N1)")
        ax.set_title(f"{title} ({r['hrtf']}), left ear")
        ax.set_xlabel("frequency (kHz)")
        ax.axhline(90.0, color="white", lw=0.6, ls=":")
        ax.legend(loc="lower left", fontsize=8)
    ticks = psi[::2]
    axes[0].set_yticks(ticks, [_polar_label(p) for p in ticks])
    axes[0].set_ylabel("elevation (deg; B = behind)")
    fig.colorbar(mesh, ax=axes, label="magnitude (dB re free field at head centre)")
    save_figure(fig, path)


# --------------------------------------------------------------------------------------
# Experiment 2: ILD and IPD of the HRTFs
# --------------------------------------------------------------------------------------


def hrtf_ild_ipd(out_dir, hrtf="kemar") -> dict:
    """ILD and IPD of an HRTF set over the paper's grid at the paper's six frequencies;
    writes ``hrtf_ild_ipd.json``, ``hrtf_ild.png`` and ``hrtf_ipd.png``.

    ILD is ``features.ild_ipd``'s first number, ``log|A_l| - log|A_r|`` (natural log); IPD is
    ``arg(A_l / A_r)`` in radians, (-pi, pi], computed from ``ild_ipd``'s unit phasors (the
    paper's 4-number IPD is ``(cos, sin)`` of each ear's phase; their difference is this angle).
    The HRTF at a grid direction is that of the nearest measured direction.

    Parameters
    ----------
    out_dir : str or os.PathLike
        Output folder (created if missing).
    hrtf : HRTF or str
        The set (default the bundled KEMAR), at 44.1 kHz.

    Returns
    -------
    dict
        The content of ``hrtf_ild_ipd.json``: ``hrtf``, ``ident``, ``grid`` (name, ident,
        size D), ``directions`` (``azimuth_deg``, ``elevation_deg``: (D,) each),
        ``frequencies`` (6 rows: ``requested_hz``, ``bin``, ``frequency_hz``), ``ild`` (6, D),
        ``ipd_rad`` (6, D), ``ild_range_definition``, ``ild_range`` (6 rows:
        ``frequency_hz``, ``ours`` = max |ILD|, ``max_minus_min``, ``paper``),
        ``ild_range_ratio`` (mean of the high three over the low three, ours and the paper's),
        ``figures``.
    """
    out = output_folder(out_dir)
    h = _hrtf(hrtf, "hrtf")
    if h.sample_rate != 44100:
        raise HRTFError(f"HRTF {h.name!r} is at {h.sample_rate} Hz; the ear front end runs at 44100 Hz")
    grid = DirectionGrid.paper(h)
    bins = frequency_to_bin(PAPER_FREQUENCIES_HZ)
    exact = bin_frequencies(N_FFT)[bins]
    a = h.transfer_function(grid.vectors, n_fft=N_FFT, bins=bins)  # (D, 2, 6)
    feats = ild_ipd(a[:, 0], a[:, 1]).astype(np.float64)  # (D, 6, 5)
    ild = feats[..., 0].T  # (6, D)
    ipd = np.angle((feats[..., 1] + 1j * feats[..., 2]) * (feats[..., 3] - 1j * feats[..., 4])).T
    max_abs = np.abs(ild).max(axis=1)
    span = ild.max(axis=1) - ild.min(axis=1)
    low, high = slice(0, 3), slice(3, 6)
    paper = np.array([np.nan if v is None else v for v in PAPER_ILD_RANGE])
    result = {
        "experiment": "ILD and IPD of the HRTFs at the paper's frequencies",
        "hrtf": h.name,
        "ident": h.ident,
        "grid": {"name": grid.name, "ident": grid.ident, "size": len(grid)},
        "directions": {"azimuth_deg": rounded(grid.azimuth_deg, 3), "elevation_deg": rounded(grid.elevation_deg, 3)},
        "frequencies": [{"requested_hz": r, "bin": int(b), "frequency_hz": round(float(f), 3)}
                        for r, b, f in zip(PAPER_FREQUENCIES_HZ, bins, exact)],
        "ild": rounded(ild, 4),
        "ipd_rad": rounded(ipd, 4),
        "ild_range_definition": ("max over the grid directions of |ILD| (natural log); for a left-right symmetric "
                                 "head this is half of max - min, which is also given"),
        "ild_range": [{"frequency_hz": round(float(f), 3), "ours": round(float(m), 3), "max_minus_min": round(float(s), 3),
                       "paper": p} for f, m, s, p in zip(exact, max_abs, span, PAPER_ILD_RANGE)],
        "ild_range_ratio": {
            "definition": "mean ILD range of the high three frequencies / mean of the low three",
            "ours": round(float(max_abs[high].mean() / max_abs[low].mean()), 3),
            "paper": round(float(np.nanmean(paper[high]) / np.nanmean(paper[low])), 3),
        },
        "note": ("the paper's numbers are for Musashi's ear unit on its own head, not for KEMAR: compare the "
                 "growth from the low to the high frequencies (ild_range_ratio), not the absolute values"),
        "median_plane": median_plane_differences(h),
        "figures": ["hrtf_ild.png", "hrtf_ipd.png"],
    }
    _map_figure(grid, ild, exact, out / "hrtf_ild.png", "ILD (natural log)", "RdBu_r", symmetric=True)
    _map_figure(grid, ipd, exact, out / "hrtf_ipd.png", "IPD = arg(A_l / A_r) (rad)", "twilight", symmetric=False)
    write_compact_json(out / "hrtf_ild_ipd.json", result)
    return result


MEDIAN_PLANE_BAND_HZ = (300.0, 12000.0)
"""The band over which :func:`median_plane_differences` looks (the SSDENet bank's)."""


def median_plane_differences(h: HRTF) -> dict:
    """The largest interaural level and phase differences over the HRTF's measured
    directions on the median plane.

    On the median plane of a left-right mirror-symmetric head (KEMAR's "normal pinna" set is
    one ear mirrored) both ears receive the same signal from every direction: ILD and IPD
    are 0 at every frequency, so interaural features (SSDENet's, MUSIC's steering vectors)
    hold nothing about elevation or front and back there, in the free field. Only unequal
    ears (Musashi's) or the room's reflections can add it.

    Returns
    -------
    dict
        ``directions`` (measured directions on the median plane), ``band_hz``,
        ``max_abs_ild_db``, ``max_abs_ipd_rad``, ``consequence`` (a sentence).
    """
    vectors = h.directions
    on = np.flatnonzero(np.abs(vectors[:, 1]) < 1e-6)
    f = bin_frequencies(N_FFT)
    bins = np.flatnonzero((f >= MEDIAN_PLANE_BAND_HZ[0]) & (f <= MEDIAN_PLANE_BAND_HZ[1]))
    a = h.transfer_function(vectors[on], n_fft=N_FFT, bins=bins)  # (M, 2, B)
    ratio = a[:, 0] / np.where(np.abs(a[:, 1]) > 0, a[:, 1], 1.0)
    ild_db = float(np.max(np.abs(20.0 * np.log10(np.maximum(np.abs(ratio), 1e-12)))))
    ipd = float(np.max(np.abs(np.angle(ratio))))
    if ild_db < 0.01 and ipd < 1e-3:
        consequence = ("Both ears get the same signal from every median-plane direction (a mirror-symmetric head), "
                       "so the interaural features cannot tell top from bottom or front from back there: in the free "
                       "field a top-bottom accuracy above chance can only come from the room's reflections.")
    else:
        consequence = ("The ears differ, so the interaural features carry some median-plane (top-bottom, "
                       "front-back) information.")
    return {"directions": int(on.size), "band_hz": list(MEDIAN_PLANE_BAND_HZ), "max_abs_ild_db": round(ild_db, 4),
            "max_abs_ipd_rad": round(ipd, 4), "consequence": consequence}


def _map_figure(grid: DirectionGrid, values: np.ndarray, freqs: np.ndarray, path: Path, label: str, cmap: str,
                *, symmetric: bool) -> None:
    """One map per frequency: grid directions at (azimuth, elevation), coloured by value."""
    fig = Figure(figsize=(13, 6.4), layout="constrained")
    axes = fig.subplots(2, 3, sharex=True, sharey=True)
    for ax, v, f in zip(axes.ravel(), values, freqs):
        if symmetric:
            lim = max(float(np.abs(v).max()), 1e-6)
            vmin, vmax = -lim, lim
        else:
            vmin, vmax = -np.pi, np.pi
        sc = ax.scatter(grid.azimuth_deg, grid.elevation_deg, c=v, cmap=cmap, vmin=vmin, vmax=vmax, s=34, marker="s")
        ax.set_title(f"{f:.1f} Hz")
        fig.colorbar(sc, ax=ax, shrink=0.85)
    for ax in axes[-1]:
        ax.set_xlabel("azimuth (deg, left +)")
        ax.set_xticks(np.arange(-180, 181, 90))
    for ax in axes[:, 0]:
        ax.set_ylabel("elevation (deg)")
    fig.suptitle(label)
    save_figure(fig, path)
