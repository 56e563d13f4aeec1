"""Writing output files: atomically, with one-line errors, and WAVs reproducible byte for byte.

Every command that writes a file goes through :func:`atomic_path`: the data is written to a
hidden temporary file in the target folder, which is renamed onto the target only once it
is complete (``os.replace``, atomic on one file system). A failure, an exception or Ctrl-C
midway leaves the previous file (or none) and no temporary file behind, so a reader never
sees half a file. :func:`check_writable` lets a command refuse an output path it could not
write *before* it spends minutes computing what goes there.

:func:`write_wav` is the project's one way of writing audio: 32-bit float WAV, without
libsndfile's PEAK chunk (which holds the time of writing, so two renders with the same seed
would differ in those bytes).
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from acoustic_sim.errors import ConfigError

_SFC_SET_ADD_PEAK_CHUNK = 0x1050
"""libsndfile's ``sf_command`` code that switches the PEAK chunk of float WAVs on or off
(``sndfile.h``; soundfile does not export it)."""


def _why(err: OSError) -> str:
    return err.strerror or str(err) or type(err).__name__


def _nearest_existing(path: Path) -> Path:
    p = path.parent
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def check_writable(path, *, what: str = "output file") -> Path:
    """Raise :class:`ConfigError` unless a file could be written at ``path``; creates nothing.

    Checked: ``path`` is not a folder, its nearest existing parent is a folder, and a probe
    file can be created and removed in that folder, which also catches read-only and pseudo
    file systems such as ``/proc`` (and holds for root, whom permissions do not stop).

    Parameters
    ----------
    path : str or os.PathLike
        The file a command is going to write.
    what : str
        How the error message names it (``"--out"``, ``"output file"``).

    Returns
    -------
    pathlib.Path
        ``path`` as a Path.
    """
    p = Path(path)
    if p.is_dir():
        raise ConfigError(f"{what} {p} is a folder, expected a file path")
    base = _nearest_existing(p)
    if not base.is_dir():
        raise ConfigError(f"cannot write {what} {p}: {base} is not a folder")
    probe = base / f".{p.name}.{os.getpid()}.{secrets.token_hex(4)}.probe"
    try:
        with open(probe, "xb"):
            pass
        probe.unlink()
    except OSError as err:
        where = "" if base == p.parent else f" (in {base})"
        raise ConfigError(f"cannot write {what} {p}: {_why(err)}{where}") from None
    return p


def check_writable_folder(path, *, what: str = "output folder") -> Path:
    """Raise :class:`ConfigError` unless files could be written in the folder ``path``
    (existing or to be created); creates nothing. Returns ``path`` as a Path."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise ConfigError(f"{what} {p} is a file, expected a folder")
    check_writable(p / "probe", what=what)
    return p


@contextlib.contextmanager
def atomic_path(path, *, what: str = "") -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it onto ``path``.

    The temporary name keeps the suffix, so writers that choose the format from it (PIL,
    matplotlib, libsndfile) still do. Missing folders are created, and removed again if the
    write fails. An ``OSError`` (the writer's or the rename's) becomes a one-line
    :class:`ConfigError` naming ``path`` (after ``what``, e.g. ``"checkpoint"``, when given);
    other exceptions pass through, after cleaning up.

    Examples
    --------
    >>> with atomic_path("out/figure.png") as tmp:  # doctest: +SKIP
    ...     fig.savefig(tmp)
    """
    target = Path(path)
    name = f"{what} {target}" if what else str(target)
    if target.is_dir():
        raise ConfigError(f"cannot write {name}: it is a folder")
    created = []
    p = target.parent
    while not p.exists() and p != p.parent:
        created.append(p)
        p = p.parent
    tmp = target.parent / f".{target.stem}.{os.getpid()}.{secrets.token_hex(4)}.tmp{target.suffix}"
    try:
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            yield tmp
            os.replace(tmp, target)
        except BaseException:
            with contextlib.suppress(OSError):
                tmp.unlink(missing_ok=True)
            for folder in created:  # innermost first
                with contextlib.suppress(OSError):
                    folder.rmdir()
            raise
    except OSError as err:
        raise ConfigError(f"cannot write {name}: {_why(err)}") from None


def write_text(path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; returns the path."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def write_wav(path, audio, sample_rate: int) -> Path:
    """Write audio as a 32-bit float WAV, atomically and without a PEAK chunk.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.wav`` file.
    audio : array_like, shape (channels, n)
        Samples, channel first as everywhere in the project (full scale 1.0). Must be finite.
    sample_rate : int
        Sample rate in Hz.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ConfigError
        If ``audio`` is not 2-D or holds NaN or infinite samples, or the file cannot be written.
    """
    import soundfile as sf

    x = np.asarray(audio, np.float32)
    if x.ndim != 2 or x.shape[0] < 1:
        raise ConfigError(f"{path}: audio must have shape (channels, samples), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ConfigError(f"{path}: refusing to write {int(np.count_nonzero(~np.isfinite(x)))} NaN or infinite samples")
    with atomic_path(path) as tmp:
        try:
            with sf.SoundFile(tmp, "w", int(sample_rate), x.shape[0], subtype="FLOAT", format="WAV") as f:
                # Off before any sample is written: the chunk would hold the time of writing.
                sf._snd.sf_command(f._file, _SFC_SET_ADD_PEAK_CHUNK, sf._ffi.NULL, sf._snd.SF_FALSE)
                f.write(x.T)
        except (sf.LibsndfileError, RuntimeError) as err:
            raise OSError(str(err).splitlines()[0] if str(err) else type(err).__name__) from None
    return Path(path)


__all__ = ["atomic_path", "check_writable", "check_writable_folder", "write_text", "write_wav"]
