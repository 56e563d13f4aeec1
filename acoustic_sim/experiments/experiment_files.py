"""The files the HRTF experiments write: their output folder, compact JSON and PNG figures
(made without pyplot, so no GUI backend and no global figure state)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from acoustic_sim.errors import ConfigError
from acoustic_sim.files import atomic_path, write_text


def output_folder(out_dir) -> Path:
    """``out_dir`` as a Path, created if missing."""
    path = Path(out_dir)
    if path.exists() and not path.is_dir():
        raise ConfigError(f"output folder {path} exists and is not a folder")
    path.mkdir(parents=True, exist_ok=True)
    return path


def compact_json(obj, indent: int = 0) -> str:
    """JSON with dicts and lists of containers indented, lists of scalars on one line (the
    long numeric arrays stay compact and diffs stay readable)."""
    pad, inner = " " * indent, " " * (indent + 1)
    if isinstance(obj, dict):
        if not obj:
            return "{}"
        items = [f"{inner}{json.dumps(str(k))}: {compact_json(v, indent + 1)}" for k, v in obj.items()]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    if isinstance(obj, list) and any(isinstance(v, (dict, list)) for v in obj):
        return "[\n" + ",\n".join(inner + compact_json(v, indent + 1) for v in obj) + "\n" + pad + "]"
    return json.dumps(obj, allow_nan=False)


def write_compact_json(path: Path, data: dict) -> None:
    """Write ``data`` as :func:`compact_json` (no NaN) through a temporary file."""
    write_text(path, compact_json(data) + "\n")


def save_figure(fig: Figure, path: Path) -> None:
    """Save ``fig`` as a PNG at 110 dpi through a temporary file."""
    FigureCanvasAgg(fig)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110)


def rounded(a, digits: int) -> list:
    """``a`` rounded to ``digits`` decimals, as nested lists (for JSON)."""
    return np.round(np.asarray(a, dtype=float), digits).tolist()
