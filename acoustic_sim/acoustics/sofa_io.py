"""Reading SOFA files (``SimpleFreeFieldHRIR``) safely, for :mod:`acoustic_sim.acoustics.hrtf`.

sofar reads the file; what it does not check is checked here, and every failure becomes an
:class:`~acoustic_sim.errors.HRTFError` naming the file: a missing, empty, truncated or
non-HDF5 file before netCDF4 sees it (:func:`check_container`), a variable that is missing
or not numeric (:func:`sofa_array`), positions in an unsupported coordinate type
(:func:`positions_to_cartesian`), and the listener's orientation (:func:`listener_frame`).
What the responses mean (conventions, delays, normalization) is the HRTF loader's
(``HRTF.load``).
"""

from __future__ import annotations

import os
import tempfile
import warnings
from pathlib import Path

import numpy as np

from acoustic_sim.errors import HRTFError
from acoustic_sim.frames import sph_to_vec


_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def check_container(path: Path) -> None:
    """Cheap checks before netCDF4 sees the file: existence, type, HDF5 superblock, size."""
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
    """Read a SimpleFreeFieldHRIR file with sofar; every failure becomes an HRTFError."""
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


def positions_to_cartesian(pos, kind, units, path, name) -> np.ndarray:
    kind = str(kind or "spherical").strip().lower()
    if kind == "cartesian":
        return pos.copy()
    if kind != "spherical":
        raise HRTFError(f"{path}: {name}_Type {kind!r} is not supported (spherical or cartesian)")
    ang = pos[:, :2]
    if "rad" in str(units or "").lower():
        ang = np.rad2deg(ang)
    return sph_to_vec(ang[:, 0], ang[:, 1]) * pos[:, 2:3]


def listener_frame(sofa, path) -> np.ndarray | None:
    """Rotation (3, 3) from the file's frame to the listener's head frame, or None."""
    view = getattr(sofa, "ListenerView", None)
    up = getattr(sofa, "ListenerUp", None)
    if view is None:
        return None
    view = np.atleast_2d(np.asarray(view, dtype=float))
    up = np.atleast_2d(np.asarray(up if up is not None else [0.0, 0.0, 1.0], dtype=float))
    if view.shape[0] != 1 or up.shape[0] != 1 or view.shape[1] != 3 or up.shape[1] != 3:
        raise HRTFError(f"{path}: a ListenerView/ListenerUp per measurement is not supported")
    vtype = str(getattr(sofa, "ListenerView_Type", "cartesian")).lower()
    if vtype == "spherical":
        view = sph_to_vec(view[0, 0], view[0, 1])[None]
        up = sph_to_vec(up[0, 0], up[0, 1])[None]
    x, z = view[0], up[0]
    if np.linalg.norm(x) == 0 or np.linalg.norm(z) == 0:
        raise HRTFError(f"{path}: ListenerView or ListenerUp is a zero vector")
    x = x / np.linalg.norm(x)
    z = z - x * (z @ x)
    if np.linalg.norm(z) < 1e-9:
        raise HRTFError(f"{path}: ListenerView and ListenerUp are parallel")
    z = z / np.linalg.norm(z)
    rot = np.stack([x, np.cross(z, x), z])
    return None if np.allclose(rot, np.eye(3)) else rot
