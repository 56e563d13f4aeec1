"""Writing an HRTF set as a SimpleFreeFieldHRIR SOFA file that
:func:`~acoustic_sim.acoustics.hrtf.sofa_read.load_sofa` reads back unchanged.

Beside the standard variables, three global attributes record what the loader would otherwise
re-derive: the set's ident, its onset, and that the data already follow the amplitude
convention (so they are not normalized twice). The loader trusts them only when the ident
matches the data it read.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from acoustic_sim.errors import HRTFError
from acoustic_sim.files import atomic_path

SAVED_IDENT_ATTR = "GLOBAL_AcousticSimIdent"
"""Global attribute holding the writer's :attr:`~acoustic_sim.acoustics.hrtf.HRTF.ident`."""

SAVED_ONSET_ATTR = "GLOBAL_AcousticSimOnsetSamples"
"""Global attribute holding ``repr(onset_samples)``."""

SAVED_SCALED_ATTR = "GLOBAL_AcousticSimAmplitude"
"""Global attribute saying the data follow the amplitude convention (value
:data:`SAVED_SCALED_VALUE`)."""

SAVED_SCALED_VALUE = "free-field pressure at head centre to ear pressure"


def write_sofa(hrtf, path) -> Path:
    """The file :meth:`~acoustic_sim.acoustics.hrtf.HRTF.save_sofa` writes (see there).

    Receivers at y = +-0.09 m (left first), sources at the set's distance, ``Data.Delay``
    zero, netCDF-4 compression level 4, the three attributes above; written atomically
    (:func:`acoustic_sim.files.atomic_path`).

    Parameters
    ----------
    hrtf : acoustic_sim.acoustics.hrtf.HRTF
        The set.
    path : str or os.PathLike
        As for ``save_sofa``: a ``.sofa`` file.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    import sofar

    path = Path(path)
    sofa = sofar.Sofa("SimpleFreeFieldHRIR")
    sofa.Data_IR = hrtf.hrir
    sofa.Data_SamplingRate = float(hrtf.sample_rate)
    sofa.Data_Delay = np.zeros((1, 2))
    sofa.SourcePosition = np.column_stack(
        [hrtf.azimuth_deg % 360.0, hrtf.elevation_deg, np.full(hrtf.n_directions, hrtf.distance_m)])
    sofa.SourcePosition_Type = "spherical"
    sofa.SourcePosition_Units = "degree, degree, metre"
    sofa.ReceiverPosition = np.array([[0.0, 0.09, 0.0], [0.0, -0.09, 0.0]])
    sofa.GLOBAL_Title = f"acoustic-sim HRTF {hrtf.name}"
    # The module the file names as its writer stays acoustic_sim.acoustics.hrtf (the package).
    sofa.GLOBAL_Comment = (f"Written by acoustic_sim.acoustics.hrtf (ident {hrtf.ident}); "
                           f"source: {hrtf.source}")
    sofa.add_attribute(SAVED_IDENT_ATTR, hrtf.ident)
    sofa.add_attribute(SAVED_ONSET_ATTR, repr(hrtf.onset_samples))
    sofa.add_attribute(SAVED_SCALED_ATTR, SAVED_SCALED_VALUE)
    with atomic_path(path) as tmp:
        try:
            sofar.write_sofa(str(tmp), sofa, compression=4)
        except Exception as exc:
            raise HRTFError(f"cannot write SOFA file {path}: {exc}") from exc
    return path
