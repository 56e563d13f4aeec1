"""Trained-model checkpoints: a ``state_dict`` plus JSON metadata, cached on disk.

Every trained model of the project (the SSDENet bank, MelCNN) is stored the same way
(DESIGN.md, "Trained models"): one ``.pt`` file holding

- ``"state_dict"``: the model's tensors (loaded with ``torch.load(weights_only=True)``, so a
  checkpoint can never run code), and
- ``"metadata"``: a JSON string with at least ``kind`` (which model), ``format``
  (:data:`FORMAT_VERSION`), ``version`` (the model code's recipe version), ``profile``, and
  whatever the model depends on: ``hrtf`` (the HRTF ident), ``grid`` (the direction-grid
  ident), ``bins``, ``sample_rate``, the profile's hyper-parameters, the seed.

Files are written atomically (a temporary file in the same folder, then ``os.replace``), so
an interrupted training never leaves a half-written checkpoint that a later run would load.

Models are trained on first use and cached in :func:`cache_dir`: the environment variable
``ACOUSTIC_SIM_CACHE`` when set, else ``~/.cache/acoustic-sim``. A cache file's name holds
the model kind, the profile and the idents it was trained for (:func:`cache_path`), so a
different HRTF or grid never finds another's file; loading a file explicitly against the
wrong HRTF or grid raises :class:`~acoustic_sim.errors.ConfigError` naming both idents
(:func:`check_metadata`).
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import torch

from acoustic_sim.errors import ConfigError
from acoustic_sim.files import atomic_path

FORMAT_VERSION = 1
"""Version of the file layout written by :func:`save_checkpoint`."""

CACHE_ENV = "ACOUSTIC_SIM_CACHE"
"""Environment variable that overrides the cache folder."""

_SAFE = re.compile(r"[^A-Za-z0-9_.-]+")

_LABELS = {"hrtf": "HRTF", "grid": "direction grid", "bins": "frequency bins", "sample_rate": "sample rate",
           "kind": "model kind", "profile": "profile", "version": "model version"}


def cache_dir() -> Path:
    """The folder of cached trained models (not created here).

    ``$ACOUSTIC_SIM_CACHE`` when set and non-empty, else ``~/.cache/acoustic-sim``.
    """
    env = os.environ.get(CACHE_ENV, "").strip()
    return Path(env).expanduser() if env else Path.home() / ".cache" / "acoustic-sim"


def cache_path(kind: str, profile: str, *idents: str, directory=None) -> Path:
    """The cache file of a model: ``<dir>/<kind>-<profile>-<ident>-<ident>....pt``.

    Parameters
    ----------
    kind : str
        Model kind, e.g. ``"ssdenet"``.
    profile : str
        Profile name, e.g. ``"paper"``.
    *idents : str
        What the model was trained for (HRTF ident, grid ident, ...), in a fixed order.
    directory : path-like, optional
        Folder; default :func:`cache_dir`.
    """
    parts = [kind, profile, *idents]
    if not all(isinstance(p, str) and p for p in parts):
        raise ConfigError(f"cache file name parts must be non-empty strings, got {parts!r}")
    name = "-".join(_SAFE.sub("_", p) for p in parts) + ".pt"
    return Path(cache_dir() if directory is None else directory) / name


def save_checkpoint(path, state_dict: Mapping[str, torch.Tensor], metadata: Mapping[str, Any]) -> Path:
    """Write a checkpoint atomically; returns its path.

    Parameters
    ----------
    path : path-like
        Destination ``.pt`` file; parent folders are created.
    state_dict : mapping of str to torch.Tensor
        The model's tensors (copied to CPU, made contiguous).
    metadata : mapping
        JSON-serialisable description; must hold ``kind``. ``format`` is added.

    Raises
    ------
    ConfigError
        ``metadata`` lacks ``kind`` or is not JSON-serialisable, or the file cannot be written.
    """
    path = Path(path)
    meta = dict(metadata)
    if not isinstance(meta.get("kind"), str):
        raise ConfigError("checkpoint metadata needs a 'kind' string")
    meta["format"] = FORMAT_VERSION
    try:
        text = json.dumps(meta, sort_keys=True)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"checkpoint metadata for {path} is not JSON-serialisable: {exc}") from None
    tensors = {k: v.detach().to("cpu").contiguous().clone() for k, v in state_dict.items()}
    # A temporary file beside the target (opened with the umask's permissions, unlike
    # mkstemp's 0600, so a shared cache stays readable), then an atomic rename.
    with atomic_path(path, what="checkpoint") as tmp, open(tmp, "xb") as fh:
        torch.save({"metadata": text, "state_dict": tensors}, fh)
    return path


def load_checkpoint(path, *, expected: Mapping[str, Any] | None = None) -> tuple[dict[str, torch.Tensor], dict]:
    """Read a checkpoint written by :func:`save_checkpoint`.

    Parameters
    ----------
    path : path-like
        The ``.pt`` file.
    expected : mapping, optional
        Metadata values the caller requires (e.g. ``{"kind": "ssdenet", "hrtf": ident,
        "grid": ident}``); checked with :func:`check_metadata`.

    Returns
    -------
    state_dict : dict of str to torch.Tensor
    metadata : dict

    Raises
    ------
    ConfigError
        The file is missing, unreadable or not a checkpoint of this project, or its metadata
        differ from ``expected`` (the message names both values).
    """
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"checkpoint {path} does not exist")
    try:
        blob = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # noqa: BLE001 (pickle, zip and torch errors all mean "not readable")
        raise ConfigError(f"cannot read checkpoint {path}: {type(exc).__name__}: {exc}") from None
    if not (isinstance(blob, dict) and isinstance(blob.get("metadata"), str)
            and isinstance(blob.get("state_dict"), dict)):
        raise ConfigError(f"{path} is not an acoustic-sim checkpoint (no metadata / state_dict)")
    try:
        meta = json.loads(blob["metadata"])
    except ValueError as exc:
        raise ConfigError(f"checkpoint {path} has corrupt metadata: {exc}") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT_VERSION:
        raise ConfigError(f"checkpoint {path} has format {meta.get('format') if isinstance(meta, dict) else None!r}, "
                          f"this version reads format {FORMAT_VERSION}; retrain it")
    if expected:
        check_metadata(meta, expected, path)
    return blob["state_dict"], meta


def read_metadata(path) -> dict:
    """The metadata of a checkpoint (the tensors are loaded too: files are small)."""
    return load_checkpoint(path)[1]


def check_metadata(metadata: Mapping[str, Any], expected: Mapping[str, Any], path=None) -> None:
    """Raise ConfigError when ``metadata`` differs from ``expected`` in any key of ``expected``.

    The message names the key in words, the checkpoint's value and the value in use, e.g.
    ``checkpoint x.pt was trained for HRTF 'ead8cbc807f2624b' (kemar) but is used with HRTF
    '1c0ffee...' (spherical)``. Keys ``<key>_name`` in either mapping, when present, are
    printed beside the ident.
    """
    where = f"checkpoint {path}" if path is not None else "checkpoint"
    for key, want in expected.items():
        if key.endswith("_name"):
            continue
        have = metadata.get(key)
        if _normalise(have) != _normalise(want):
            label = _LABELS.get(key, key)
            have_name = metadata.get(f"{key}_name")
            want_name = expected.get(f"{key}_name")
            have_s = f"{have!r}" + (f" ({have_name})" if have_name else "")
            want_s = f"{want!r}" + (f" ({want_name})" if want_name else "")
            raise ConfigError(f"{where} was trained for {label} {have_s} but is used with {label} {want_s}")


def _normalise(value):
    """Tuples and lists compare equal (JSON has only lists)."""
    if isinstance(value, (list, tuple)):
        return [_normalise(v) for v in value]
    return value
