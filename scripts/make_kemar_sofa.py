#!/usr/bin/env python
"""Build ``assets/hrtf/mit_kemar_normal_pinna.sofa`` from the copy of the MIT KEMAR data in slab.

The MIT KEMAR "normal pinna" head-related impulse responses (Gardner & Martin 1994, MIT Media
Lab; 710 directions, elevation -40..90 deg, 512 taps at 44.1 kHz) ship inside the PyPI package
``slab`` as ``slab/data/mit_kemar_normal_pinna.bz2``: a bz2-compressed pickle of a
``slab.hrtf.HRTF`` object holding 710 ``slab.filter.Filter`` objects. ``import slab`` needs
PortAudio, so this script never imports it: it downloads the slab wheel with
``pip download`` (or takes a local wheel), reads the member with :mod:`zipfile`, and unpickles it
with a restricted unpickler that maps the two slab classes to inert stubs and refuses every
other global except the numpy array reconstructors.

The data are written unchanged (no resampling, scaling or trimming) as a SimpleFreeFieldHRIR
SOFA file with sofar: ``Data.IR`` (710, 2, 512) with receiver 0 = left ear, ``SourcePosition``
in spherical coordinates (azimuth deg counter-clockwise from the front, elevation deg, distance
m). Before writing, the script checks against physics that a source at azimuth +90 deg
(left) is louder and earlier in receiver 0, and that the right channel is the mirror image of
the left one (the "normal pinna" set is the left ear measured with the DB-061 pinna, mirrored).

Run it (it only needs the network to fetch the wheel; pass ``--wheel`` to work offline)::

    .venv/bin/python scripts/make_kemar_sofa.py --out assets/hrtf/mit_kemar_normal_pinna.sofa
"""

from __future__ import annotations

import argparse
import bz2
import hashlib
import io
import pickle
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path
from typing import ClassVar

import numpy as np

SLAB_VERSION = "1.8.2"
MEMBER = "slab/data/mit_kemar_normal_pinna.bz2"
# sha256 of the bz2 member in slab 1.8.2; a different payload is refused unless --no-pin.
MEMBER_SHA256 = "61f562a68284ba40899fd66b9d9e976351a41def04e3e826ae4cb3d5c3a7d975"

ORIGINAL_URL = "https://sound.media.mit.edu/resources/KEMAR.html"
LICENSE = (
    "This data is Copyright 1994 by the MIT Media Laboratory. It is provided free with no "
    "restrictions on use, provided the authors are cited when the data is used in any research "
    "or commercial application. (Gardner & Martin, README of the MIT KEMAR archive, "
    f"{ORIGINAL_URL})"
)
REFERENCES = (
    "Gardner, W. G. and Martin, K. D. (1994). HRTF measurements of a KEMAR dummy-head "
    "microphone. MIT Media Lab Perceptual Computing Technical Report #280. "
    f"{ORIGINAL_URL}; Gardner, W. G. and Martin, K. D. (1995). HRTF measurements of a KEMAR. "
    "J. Acoust. Soc. Am. 97(6), 3907-3908."
)


class _Stub:
    """Inert stand-in for a pickled slab class: keeps the instance dict, nothing else."""

    def __setstate__(self, state):
        if not isinstance(state, dict):
            raise pickle.UnpicklingError(f"unexpected state of type {type(state).__name__}")
        self.__dict__.update(state)


class _SlabHRTF(_Stub):
    pass


class _SlabFilter(_Stub):
    pass


class _RestrictedUnpickler(pickle.Unpickler):
    """Unpickler that maps slab's classes to stubs and allows only numpy's reconstructors."""

    _STUBS: ClassVar[dict] = {("slab.hrtf", "HRTF"): _SlabHRTF, ("slab.filter", "Filter"): _SlabFilter}
    _NUMPY: ClassVar[frozenset] = frozenset({
        ("numpy.core.multiarray", "_reconstruct"),
        ("numpy._core.multiarray", "_reconstruct"),
        ("numpy.core.multiarray", "scalar"),
        ("numpy._core.multiarray", "scalar"),
        ("numpy", "ndarray"),
        ("numpy", "dtype"),
    })

    def find_class(self, module, name):
        if (module, name) in self._STUBS:
            return self._STUBS[(module, name)]
        if (module, name) in self._NUMPY:
            # numpy 2 moved numpy.core to numpy._core; both names resolve to the same objects.
            from numpy._core import multiarray

            if name in ("_reconstruct", "scalar"):
                return getattr(multiarray, name)
            return getattr(np, name)
        raise pickle.UnpicklingError(f"refusing to unpickle global {module}.{name}")


def fetch_wheel(version: str, workdir: Path) -> Path:
    """Download the slab wheel (no dependencies) with pip into ``workdir``; return its path."""
    cmd = [sys.executable, "-m", "pip", "download", f"slab=={version}", "--no-deps",
           "--only-binary=:all:", "--quiet", "-d", str(workdir)]
    print("running:", " ".join(cmd))
    subprocess.run(cmd, check=True)
    wheels = sorted(workdir.glob("slab-*.whl"))
    if not wheels:
        raise SystemExit(f"pip download produced no slab wheel in {workdir}")
    return wheels[0]


def read_member(wheel: Path) -> bytes:
    """The raw bz2 member bytes from the wheel."""
    with zipfile.ZipFile(wheel) as zf:
        try:
            return zf.read(MEMBER)
        except KeyError:
            raise SystemExit(f"{wheel} has no member {MEMBER}") from None


def load_kemar(payload: bytes) -> tuple[np.ndarray, np.ndarray, float]:
    """Decode the bz2 pickle: (hrir (710, 2, 512) float64, sources (710, 3) az/el/dist, fs)."""
    obj = _RestrictedUnpickler(io.BytesIO(bz2.decompress(payload))).load()
    if not isinstance(obj, _SlabHRTF):
        raise SystemExit(f"unexpected pickle content: {type(obj).__name__}")
    fs = float(obj.samplerate)
    sources = np.asarray(obj.sources, dtype=float)
    filters = obj.data
    if any(float(f.samplerate) != fs or not f.fir for f in filters):
        raise SystemExit("the filters do not all share the HRTF's sample rate / FIR type")
    # slab stores each filter as (n_taps, n_channels); SOFA wants (M, R, N).
    hrir = np.stack([np.asarray(f.data, dtype=float).T for f in filters])
    if hrir.shape != (710, 2, 512) or sources.shape != (710, 3) or fs != 44100.0:
        raise SystemExit(f"unexpected shapes {hrir.shape}, {sources.shape} or rate {fs}")
    return hrir, sources, fs


def check_physics(hrir: np.ndarray, sources: np.ndarray) -> str:
    """Check channel order / azimuth sense and the mirror symmetry; return a summary line."""
    az, el = sources[:, 0], sources[:, 1]

    def idx(a, e):
        return int(np.argmin(np.abs((az - a + 180) % 360 - 180) + np.abs(el - e)))

    def onset(x):
        return int(np.argmax(np.abs(x) >= 0.1 * np.abs(x).max()))

    i = idx(90.0, 0.0)
    h = hrir[i]
    level = 10 * np.log10(np.sum(h**2, axis=-1))
    on = [onset(h[0]), onset(h[1])]
    if not (level[0] > level[1] + 6 and on[0] < on[1]):
        raise SystemExit(f"az +90: receiver 0 is not the louder/earlier ear: {level}, {on}")
    # Mirror check: the right ear at azimuth a equals the left ear at -a.
    key = {(round(a % 360, 4), e): k for k, (a, e) in enumerate(zip(az, el))}
    mirror = max(
        float(np.max(np.abs(hrir[k, 1] - hrir[key[(round((-a) % 360, 4), e)], 0])))
        for k, (a, e) in enumerate(zip(az, el))
    )
    return (f"az +90 el 0: receiver 0 is {level[0] - level[1]:.1f} dB louder and "
            f"{on[1] - on[0]} samples earlier (10% onset) than receiver 1 -> receiver 0 = left, "
            f"azimuth counter-clockwise; max |right(az) - left(-az)| = {mirror:g}")


def build_sofa(hrir, sources, fs, provenance: str):
    import sofar

    sofa = sofar.Sofa("SimpleFreeFieldHRIR")
    sofa.Data_IR = hrir
    sofa.Data_SamplingRate = fs
    sofa.Data_Delay = np.zeros((1, 2))
    sofa.SourcePosition = sources
    sofa.SourcePosition_Type = "spherical"
    sofa.SourcePosition_Units = "degree, degree, metre"
    # Receiver 0 is the left ear (+y); only the sign of y is meaningful here.
    sofa.ReceiverPosition = np.array([[0.0, 0.09, 0.0], [0.0, -0.09, 0.0]])
    sofa.GLOBAL_Title = "MIT KEMAR HRIRs, normal pinna (Gardner & Martin 1994)"
    sofa.GLOBAL_DatabaseName = "MIT KEMAR"
    sofa.GLOBAL_ListenerShortName = "KEMAR, normal pinna (DB-061)"
    sofa.GLOBAL_AuthorContact = ("Bill Gardner <billg@media.mit.edu>, Keith Martin "
                                 "<kdm@media.mit.edu> (MIT Media Lab, original data)")
    sofa.GLOBAL_Organization = "MIT Media Lab, Machine Listening Group"
    sofa.GLOBAL_License = LICENSE
    sofa.GLOBAL_References = REFERENCES
    sofa.GLOBAL_Origin = ORIGINAL_URL
    sofa.GLOBAL_History = provenance
    sofa.GLOBAL_Comment = (
        "Converted by acoustic-sim scripts/make_kemar_sofa.py without resampling, scaling or "
        "trimming. Measured in MIT's anechoic chamber with the loudspeaker at 1.4 m; the left "
        "ear (normal pinna) responses are used for both ears, the right ear being the mirror "
        "image (right at azimuth a = left at -a). The responses include the loudspeaker and "
        "microphone responses (not equalized); each starts 200 samples after the excitation.")
    # Fixed dates keep the output reproducible across reruns.
    sofa.GLOBAL_DateCreated = "1994-05-18 00:00:00"
    sofa.GLOBAL_DateModified = "2026-01-01 00:00:00"
    return sofa


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=(
            "Convert the MIT KEMAR normal-pinna HRIRs bundled in the PyPI package slab "
            "(without importing slab) to a SimpleFreeFieldHRIR SOFA file."),
        epilog="Example: .venv/bin/python scripts/make_kemar_sofa.py "
               "--out assets/hrtf/mit_kemar_normal_pinna.sofa")
    parser.add_argument("--out", type=Path, default=Path("assets/hrtf/mit_kemar_normal_pinna.sofa"),
                        help="output SOFA path (default: %(default)s)")
    parser.add_argument("--wheel", type=Path, default=None,
                        help="use this local slab wheel instead of downloading one from PyPI")
    parser.add_argument("--slab-version", default=SLAB_VERSION,
                        help="slab version to download (default: %(default)s)")
    parser.add_argument("--no-pin", action="store_true",
                        help="accept a data member whose sha256 differs from the pinned one")
    parser.add_argument("--compression", type=int, default=9, choices=range(10), metavar="0-9",
                        help="netCDF zlib level (default: %(default)s)")
    args = parser.parse_args(argv)

    with tempfile.TemporaryDirectory() as tmp:
        wheel = args.wheel if args.wheel is not None else fetch_wheel(args.slab_version, Path(tmp))
        payload = read_member(wheel)
    digest = hashlib.sha256(payload).hexdigest()
    print(f"{MEMBER} from {wheel.name}: sha256 {digest}")
    if digest != MEMBER_SHA256 and not args.no_pin:
        raise SystemExit(f"sha256 mismatch (expected {MEMBER_SHA256}); rerun with --no-pin to "
                         "accept a different payload")

    hrir, sources, fs = load_kemar(payload)
    print(check_physics(hrir, sources))

    import sofar

    provenance = (f"{MEMBER} (sha256 {digest}) from {wheel.name} (PyPI), itself derived from the "
                  f"MIT KEMAR archive {ORIGINAL_URL}")
    sofa = build_sofa(hrir, sources, fs, provenance)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    sofar.write_sofa(str(args.out), sofa, compression=args.compression)
    data = args.out.read_bytes()
    print(f"wrote {args.out} ({len(data) / 1e6:.2f} MB), sha256 {hashlib.sha256(data).hexdigest()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
