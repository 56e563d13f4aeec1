"""Reading SOFA files (``SimpleFreeFieldHRIR``) safely: the one reading path of the HRTF sets.

sofar reads the file (:func:`read_sofa`); what it does not check is checked here, and every
failure becomes an :class:`~acoustic_sim.errors.HRTFError` naming the file: the container
(:func:`check_container`), variables, shapes, delays, and the geometry: positions, the
listener's orientation, which receiver is the left ear (:mod:`~acoustic_sim.acoustics.hrtf.sofa_geometry`).
:func:`load_sofa` gives the arrays :meth:`~acoustic_sim.acoustics.hrtf.HRTF.load` builds a set from.
"""

from __future__ import annotations

import math
import os
import tempfile
import warnings
from fractions import Fraction
from pathlib import Path
from typing import NamedTuple

import numpy as np
from scipy import signal

from acoustic_sim.acoustics.hrtf import sofa_geometry
from acoustic_sim.acoustics.hrtf.responses import delay_spectra, hrir_ident
from acoustic_sim.acoustics.hrtf.sofa_write import (SAVED_IDENT_ATTR, SAVED_ONSET_ATTR, SAVED_SCALED_ATTR,
                                                    SAVED_SCALED_VALUE)
from acoustic_sim.errors import HRTFError

_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def check_container(path: Path) -> None:
    """Cheap checks before netCDF4 sees the file: existence, type, HDF5 superblock, size.

    Parameters
    ----------
    path : pathlib.Path
        The file.

    Raises
    ------
    HRTFError
        Missing, not a regular file, empty, netCDF-3, not HDF5, or truncated.
    """
    if not path.exists():
        raise HRTFError(f"HRTF file {path} does not exist")
    if path.is_dir():
        raise HRTFError(f"HRTF path {path} is a directory, expected a SOFA file")
    if not path.is_file():
        raise HRTFError(f"HRTF path {path} is not a regular file")
    size = path.stat().st_size
    if size == 0:
        raise HRTFError(f"HRTF file {path} is empty (0 bytes)")
    with open(path, "rb") as fh:
        head = fh.read(4096)
    if head[:4] in (b"CDF\x01", b"CDF\x02"):
        raise HRTFError(f"{path} is a netCDF-3 file; SOFA files are netCDF-4 (HDF5)")
    # The HDF5 superblock sits at offset 0, 512, 1024, 2048, ...
    offset = next((o for o in (0, 512, 1024, 2048) if head[o:o + 8] == _HDF5_SIGNATURE), None)
    if offset is None:
        raise HRTFError(f"{path} is not a SOFA file: no HDF5/netCDF-4 signature")
    sb = head[offset:]
    version = sb[8] if len(sb) > 8 else -1
    try:
        if version in (0, 1):
            n_off = sb[13]
            start = 24 + (4 if version == 1 else 0)
            base = int.from_bytes(sb[start:start + n_off], "little")
            eof = int.from_bytes(sb[start + 2 * n_off:start + 3 * n_off], "little")
        elif version in (2, 3):
            n_off = sb[9]
            base = int.from_bytes(sb[12:12 + n_off], "little")
            eof = int.from_bytes(sb[12 + 2 * n_off:12 + 3 * n_off], "little")
        else:
            raise HRTFError(f"{path}: unknown HDF5 superblock version {version}")
    except IndexError:
        raise HRTFError(f"{path} is truncated: incomplete HDF5 superblock") from None
    if base + eof > size:
        raise HRTFError(f"{path} is truncated: the HDF5 superblock records {base + eof} bytes, "
                        f"the file has {size}")


def read_sofa(path: Path):
    """Read a SOFA file with sofar (after :func:`check_container`), any suffix.

    Parameters
    ----------
    path : pathlib.Path
        The file.

    Returns
    -------
    sofar.Sofa
        The file's content, unverified (:func:`load_sofa` checks what it uses).

    Raises
    ------
    HRTFError
        Every failure, naming the file (sofar, netCDF4 and HDF5 errors included).
    """
    import sofar

    check_container(path)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            target = path
            if path.suffix != ".sofa":  # sofar silently swaps any other suffix for .sofa
                target = Path(tmp) / "hrtf.sofa"
                try:
                    os.symlink(path.resolve(), target)
                except OSError:
                    target.write_bytes(path.read_bytes())
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return sofar.read_sofa(str(target), verify=False, verbose=False)
    except HRTFError:
        raise
    except Exception as exc:  # sofar / netCDF4 / HDF5 errors of any kind
        raise HRTFError(f"cannot read SOFA file {path}: {type(exc).__name__}: {exc}") from exc


def sofa_array(sofa, name, path) -> np.ndarray:
    """A numeric variable of the file as a float array (masked values become NaN).

    Parameters
    ----------
    sofa : sofar.Sofa
        The file's content.
    name : str
        The attribute, e.g. ``"Data_IR"``.
    path : str or os.PathLike
        The file, for the messages.

    Returns
    -------
    numpy.ndarray, float
        The variable in the file's shape.

    Raises
    ------
    HRTFError
        The variable is missing, a string, or not numeric.
    """
    value = getattr(sofa, name, None)
    if value is None:
        raise HRTFError(f"{path}: missing variable {name.replace('Data_', 'Data.')}")
    if isinstance(value, str):
        raise HRTFError(f"{path}: {name} is a string, expected numbers")
    try:
        arr = np.ma.filled(np.ma.asarray(value, dtype=float), np.nan)
    except (TypeError, ValueError) as exc:
        raise HRTFError(f"{path}: {name} is not numeric: {exc}") from exc
    return np.asarray(arr)


def _read_measurements(path: Path):
    """(sofa, Data.IR (M, 2, N) in the file's receiver order with Data.Delay applied,
    sample rate in Hz, unit directions (M, 3) in the head frame, distances (M,) in m), all
    checked."""
    sofa = read_sofa(path)
    convention = str(getattr(sofa, "GLOBAL_SOFAConventions", "") or "")
    if convention != "SimpleFreeFieldHRIR":
        hint = (" (frequency-domain data; convert it to SimpleFreeFieldHRIR first)"
                if "TF" in convention else "")
        raise HRTFError(f"{path}: SOFA convention {convention or 'missing'!r} is not supported"
                        f"{hint}; expected SimpleFreeFieldHRIR")
    ir = sofa_array(sofa, "Data_IR", path)
    if ir.ndim == 2:  # sofar drops a trailing singleton N
        ir = ir[:, :, None]
    if ir.ndim != 3 or ir.shape[0] == 0 or ir.shape[2] == 0:
        raise HRTFError(f"{path}: Data.IR has shape {ir.shape}, expected (M >= 1, 2, N >= 1)")
    if ir.shape[1] != 2:
        raise HRTFError(f"{path}: Data.IR has {ir.shape[1]} receivers, expected 2 (left, right)")
    m = ir.shape[0]
    fs = np.ravel(sofa_array(sofa, "Data_SamplingRate", path))
    if fs.size == 0 or not np.all(np.isfinite(fs)) or np.any(fs != fs[0]):
        raise HRTFError(f"{path}: Data.SamplingRate {fs} is not one finite value")
    fs = float(fs[0])
    if not 1000.0 <= fs <= 1_000_000.0:
        raise HRTFError(f"{path}: Data.SamplingRate {fs} Hz is out of range (1 kHz .. 1 MHz)")
    if not np.all(np.isfinite(ir)):
        raise HRTFError(f"{path}: Data.IR contains NaN or infinite values")
    pos = np.atleast_2d(sofa_array(sofa, "SourcePosition", path))
    if pos.shape != (m, 3):
        raise HRTFError(f"{path}: SourcePosition has shape {pos.shape}, expected ({m}, 3) to "
                        f"match Data.IR's {m} measurements")
    if not np.all(np.isfinite(pos)):
        raise HRTFError(f"{path}: SourcePosition contains NaN or infinite values")
    xyz = sofa_geometry.positions_to_cartesian(pos, getattr(sofa, "SourcePosition_Type", None),
                                               getattr(sofa, "SourcePosition_Units", None), path,
                                               "SourcePosition")
    dist = np.linalg.norm(xyz, axis=-1)
    if np.any(dist <= 0):
        raise HRTFError(f"{path}: a SourcePosition is at the listener (zero distance)")
    rot = sofa_geometry.listener_frame(sofa, path)
    if rot is not None:
        xyz = xyz @ rot.T
    directions = xyz / dist[:, None]
    delay = getattr(sofa, "Data_Delay", None)
    if delay is not None:
        delay = np.asarray(delay, dtype=float)
        if not np.all(np.isfinite(delay)) or np.any(delay < 0):
            raise HRTFError(f"{path}: Data.Delay must be finite and >= 0")
        if delay.size not in (2, 2 * m):
            raise HRTFError(f"{path}: Data.Delay has shape {delay.shape}, expected (1, 2) or ({m}, 2)")
        if np.any(delay != 0):
            delay = np.broadcast_to(delay.reshape(-1, 2), (m, 2))
            n = ir.shape[-1] + math.ceil(delay.max())
            ir = np.fft.irfft(delay_spectra(np.fft.rfft(ir, n, axis=-1), n, delay), n, axis=-1)
    energy = np.sum(ir**2, axis=-1)
    if not np.any(energy > 0):
        raise HRTFError(f"{path}: Data.IR is all zeros")
    if np.any(energy == 0):
        bad = np.argwhere(energy == 0)[0]
        raise HRTFError(f"{path}: the HRIR of measurement {bad[0]}, receiver {bad[1]} is all zeros")
    return sofa, ir, fs, directions, dist


def sofa_left_receiver(path) -> int:
    """Which receiver of a SOFA file is the left ear, as
    :meth:`~acoustic_sim.acoustics.hrtf.HRTF.load` reads it (same checks, warnings and
    errors): for code that hands the file to another reader.

    Parameters
    ----------
    path : str or os.PathLike
        A SimpleFreeFieldHRIR SOFA file.

    Returns
    -------
    int
        0 or 1: the index of the left ear's receiver in ``Data.IR``.
    """
    path = Path(path)
    sofa, ir, _, directions, _ = _read_measurements(path)
    return sofa_geometry.left_receiver(sofa, ir, directions, path)


class LoadedSet(NamedTuple):
    """A SOFA file's set, for :meth:`~acoustic_sim.acoustics.hrtf.HRTF.load` to pad and
    normalize: ``hrir`` (D, 2, K) left ear first at ``sample_rate`` (Hz), unit ``directions``
    (D, 3) in the head frame, the mean ``distance_m``, ``source`` (the path), the
    ``onset_samples`` that :meth:`~acoustic_sim.acoustics.hrtf.HRTF.save_sofa` stored for
    exactly these data (None: estimate it) and whether they are already ``scaled`` to the
    amplitude convention (written by ``save_sofa``)."""

    hrir: np.ndarray
    directions: np.ndarray
    sample_rate: int
    name: str
    distance_m: float
    source: str
    onset_samples: float | None
    scaled: bool


def load_sofa(path: Path, sample_rate: int, name: str | None = None) -> LoadedSet:
    """Read a SimpleFreeFieldHRIR file into a set's arrays.

    ``Data.Delay`` applied, receivers ordered left ear first (:func:`sofa_geometry.left_receiver`),
    directions that repeat an earlier one dropped with a warning, resampled with
    :func:`scipy.signal.resample_poly`; the attributes written by
    :meth:`~acoustic_sim.acoustics.hrtf.HRTF.save_sofa` are trusted only for the data they
    were written with.

    Parameters
    ----------
    path : pathlib.Path
        The file.
    sample_rate : int
        Sample rate of the result in Hz, > 0.
    name : str, optional
        The set's name (default: the file stem).

    Returns
    -------
    LoadedSet
        ``hrir`` (D, 2, K), ``directions`` (D, 3) and the set's metadata.

    Raises
    ------
    HRTFError
        The file is not a readable, well-formed SimpleFreeFieldHRIR file, or the ears cannot
        be told apart (the message names the file and the problem).
    """
    sofa, ir, fs, directions, dist = _read_measurements(path)
    m = ir.shape[0]
    # Which receiver is the left ear: ReceiverPosition checked against the data (it is
    # wrong in some public sets); Data.Delay above is in the file's receiver order.
    if sofa_geometry.left_receiver(sofa, ir, directions, path) == 1:
        ir = ir[:, ::-1, :]
    # Attributes written by HRTF.save_sofa are trusted only for the data they were written with.
    trusted = str(getattr(sofa, SAVED_IDENT_ATTR, "")) == hrir_ident(fs, directions, ir)
    # Duplicate directions (several azimuths at a pole, several distances) break the
    # triangulation; keep the first of each.
    _, first = np.unique(np.round(directions, 6), axis=0, return_index=True)
    if first.size < m:
        keep = np.sort(first)
        warnings.warn(f"{path}: dropped {m - keep.size} measurements whose direction repeats "
                      "an earlier one", stacklevel=3)
        ir, directions, dist = ir[keep], directions[keep], dist[keep]
    if round(fs) != sample_rate:
        ratio = Fraction(int(sample_rate)) / Fraction(fs).limit_denominator(1000)
        ir = signal.resample_poly(ir, ratio.numerator, ratio.denominator, axis=-1)
    onset, scaled = None, False
    if trusted and first.size == m:
        try:
            onset = float(getattr(sofa, SAVED_ONSET_ATTR)) * sample_rate / fs
        except (AttributeError, TypeError, ValueError):
            onset = None
        if onset is not None and not (np.isfinite(onset) and 0.0 <= onset < ir.shape[-1]):
            onset = None
        scaled = str(getattr(sofa, SAVED_SCALED_ATTR, "")) == SAVED_SCALED_VALUE
    return LoadedSet(hrir=ir, directions=directions, sample_rate=sample_rate, name=name or path.stem,
                     distance_m=float(np.mean(dist)), source=str(path), onset_samples=onset, scaled=scaled)
