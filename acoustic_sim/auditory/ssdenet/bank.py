"""The trained SSDENet bank: the networks of one HRTF and one grid, their checkpoints and cache.

:class:`SSDENetBank` is the stack of networks (:class:`~acoustic_sim.auditory.ssdenet.stack.SSDENetStack`)
together with what it was trained for (HRTF ident, profile, seed). A checkpoint is its
``state_dict`` plus JSON metadata (:mod:`acoustic_sim.auditory.checkpoint`); trained banks
are cached per (HRTF ident, grid ident, profile) by :meth:`SSDENetBank.load_or_train`.
:func:`train_bank` makes a bank of the weights that
:func:`~acoustic_sim.auditory.ssdenet.training.train_weights` trains, and
:func:`train_command` is ``acoustic-sim train ssdenet``.
"""

from __future__ import annotations

from pathlib import Path

import torch

from acoustic_sim.auditory import checkpoint as ckpt
from acoustic_sim.auditory.frontend import N_FFT
from acoustic_sim.auditory.ssdenet.training import train_weights
from acoustic_sim.auditory.ssdenet.recipes import SSDENetProfile, get_profile
from acoustic_sim.auditory.ssdenet.stack import SSDENetStack
from acoustic_sim.directions import DirectionGrid
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import SAMPLE_RATE

KIND = "ssdenet"
"""Checkpoint kind."""

VERSION = 1
"""Version of the training recipe; a cached bank of another version is retrained."""


class SSDENetBank(SSDENetStack):
    """SSDENets for a set of frequency bins, trained for one HRTF and one direction grid.

    Parameters
    ----------
    grid, bins, hidden, generator, output_prior, weights
        The networks (:class:`SSDENetStack`): D output directions, increasing rFFT bins,
        hidden units H, and initial or trained weights.
    hrtf_ident : str
        Ident of the HRTF the bank is (to be) trained on; checked on load.
    hrtf_name : str
        Human-readable HRTF name (messages only).
    profile : SSDENetProfile, optional
        The profile it was built from (stored in checkpoints).
    seed : int, optional
        The seed it was trained with (recorded in checkpoints).

    Notes
    -----
    Use :meth:`load_or_train` rather than the constructor.
    """

    def __init__(self, grid: DirectionGrid, bins, hidden: int, *, hrtf_ident: str, hrtf_name: str = "",
                 profile: SSDENetProfile | None = None, generator: torch.Generator | None = None,
                 output_prior: float = 0.5, seed: int | None = None,
                 weights: dict[str, torch.Tensor] | None = None) -> None:
        super().__init__(grid, bins, hidden, generator=generator, output_prior=output_prior, weights=weights)
        self.hrtf_ident = str(hrtf_ident)
        self.hrtf_name = str(hrtf_name)
        self.profile = profile
        self.seed = seed

    # -- checkpoints ------------------------------------------------------------------------

    def metadata(self) -> dict:
        """The checkpoint metadata of this bank (JSON-ready)."""
        prof = self.profile
        return {
            "kind": KIND, "version": VERSION, "profile": prof.name if prof else "custom",
            "profile_config": prof.to_dict() if prof else None, "seed": self.seed,
            "hrtf": self.hrtf_ident, "hrtf_name": self.hrtf_name,
            "grid": self.grid.ident, "grid_name": self.grid.name, "n_directions": self.n_directions,
            "bins": self.bins.tolist(), "hidden": self.hidden, "sample_rate": SAMPLE_RATE, "n_fft": N_FFT,
        }

    def save(self, path) -> Path:
        """Write the bank as a checkpoint (atomically); returns the path."""
        return ckpt.save_checkpoint(path, self.state_dict(), self.metadata())

    @classmethod
    def load(cls, path, hrtf, grid: DirectionGrid) -> SSDENetBank:
        """Load a bank and check that it was trained for this HRTF and grid.

        Parameters
        ----------
        path : path-like
            Checkpoint written by :meth:`save`.
        hrtf : HRTF
            The ears it will be used with.
        grid : DirectionGrid
            The output grid it will be used with.

        Raises
        ------
        ConfigError
            Unreadable file, not an SSDENet checkpoint, or trained for another HRTF or grid
            (the message names both idents).
        """
        expected = {"kind": KIND, "hrtf": hrtf.ident, "hrtf_name": hrtf.name, "grid": grid.ident,
                    "grid_name": grid.name}
        state, meta = ckpt.load_checkpoint(path, expected=expected)
        prof = None
        if isinstance(meta.get("profile_config"), dict):
            try:
                cfg = dict(meta["profile_config"])
                cfg["bins"] = tuple(cfg["bins"])
                cfg["snr_db"] = tuple(cfg["snr_db"])
                prof = SSDENetProfile(**cfg)
            except (TypeError, KeyError, ConfigError) as exc:
                raise ConfigError(f"checkpoint {path} has a malformed profile: {exc}") from None
        try:
            bank = cls(grid, meta["bins"], int(meta["hidden"]), hrtf_ident=hrtf.ident, hrtf_name=hrtf.name,
                       profile=prof, seed=meta.get("seed"))
            bank.load_state_dict(state)
        except (KeyError, RuntimeError, TypeError) as exc:
            raise ConfigError(f"checkpoint {path} does not fit an SSDENet bank: {exc}") from None
        bank.eval()
        return bank

    @staticmethod
    def cache_path(hrtf, grid: DirectionGrid, profile) -> Path:
        """Where :meth:`load_or_train` keeps the bank of (HRTF, grid, profile)."""
        return ckpt.cache_path(KIND, get_profile(profile).name, hrtf.ident, grid.ident)

    @classmethod
    def rebuild(cls, hrtf, grid: DirectionGrid, profile, *, seed: int | None = None, progress: bool = True,
                path=None) -> SSDENetBank:
        """Train a bank from scratch and save it (``acoustic-sim train ssdenet``).

        (Not called ``train``: that name is ``torch.nn.Module.train(mode)``.)

        Parameters
        ----------
        hrtf : HRTF
        grid : DirectionGrid
        profile : SSDENetProfile or str
        seed : int, optional
            Default: the profile's seed. Same seed, same weights, bit for bit (on the same
            machine and torch thread count).
        progress : bool
            Show a tqdm progress bar on stderr.
        path : path-like, optional
            Where to save; default :meth:`cache_path`. ``False`` saves nothing.
        """
        bank = train_bank(hrtf, grid, profile, seed=seed, progress=progress)
        if path is not False:
            bank.save(cls.cache_path(hrtf, grid, profile) if path is None else path)
        return bank

    @classmethod
    def load_or_train(cls, hrtf, grid: DirectionGrid, profile, *, progress: bool = True) -> SSDENetBank:
        """The cached bank of (HRTF, grid, profile); trained and cached on first use.

        A cached file of another recipe version, profile definition or seed is retrained
        (and overwritten); an unreadable one is an error that says how to rebuild it.
        """
        prof = get_profile(profile)
        path = cls.cache_path(hrtf, grid, prof)
        if path.is_file():
            try:
                meta = ckpt.read_metadata(path)
            except ConfigError as exc:
                raise ConfigError(f"{exc}; delete it or rebuild it with `acoustic-sim train ssdenet "
                                  f"--hrtf {hrtf.name} --profile {prof.name}`") from None
            if (meta.get("version") == VERSION and meta.get("profile_config") == prof.to_dict()
                    and meta.get("seed") == prof.seed):
                return cls.load(path, hrtf, grid)
        return cls.rebuild(hrtf, grid, prof, progress=progress, path=path)


def train_bank(hrtf, grid: DirectionGrid, profile, *, seed: int | None = None, progress: bool = True,
               stats: dict | None = None) -> SSDENetBank:
    """Train an SSDENet bank on the paper's virtual-source data
    (:mod:`~acoustic_sim.auditory.ssdenet.training`).

    The parameters are those of :func:`~acoustic_sim.auditory.ssdenet.training.train_weights`
    (``seed`` defaults to the profile's; ``stats`` is filled with the training times, the
    final loss and the number of steps).

    Returns
    -------
    SSDENetBank
        In eval mode.
    """
    prof = get_profile(profile)
    weights = train_weights(hrtf, grid, prof, seed=seed, progress=progress, stats=stats)
    bank = SSDENetBank(grid, prof.bins, prof.hidden, hrtf_ident=hrtf.ident, hrtf_name=hrtf.name, profile=prof,
                       seed=prof.seed if seed is None else int(seed), weights=weights)
    bank.eval()
    return bank


def train_command(hrtf: str, profile: str, out=None, *, seed: int | None = None, progress: bool = True) -> dict:
    """``acoustic-sim train ssdenet``: train a bank on the paper grid of an HRTF and save it.

    Parameters
    ----------
    hrtf : str
        ``"kemar"``, ``"spherical"`` or a SOFA path
        (:meth:`acoustic_sim.acoustics.hrtf.HRTF.load`).
    profile : str
        ``"paper"`` or ``"fast"``.
    out : path-like, optional
        Checkpoint file; default the cache file that
        :meth:`~acoustic_sim.auditory.ssdenet.SSDENetBank.load_or_train` reads.
    seed : int, optional
        Default: the profile's seed.
    progress : bool
        Progress bar on stderr.

    Returns
    -------
    dict
        JSON-ready summary: ``path``, ``hrtf``, ``hrtf_ident``, ``grid_ident``,
        ``n_directions``, ``profile``, ``bins``, ``frequencies_hz``, ``hidden``,
        ``n_parameters``, ``data_s``, ``train_s``, ``final_loss``, ``seed``.
    """
    from acoustic_sim.acoustics.hrtf import HRTF

    h = HRTF.load(hrtf)
    grid = DirectionGrid.paper(h)
    prof = get_profile(profile)
    stats: dict = {}
    bank = train_bank(h, grid, prof, seed=seed, progress=progress, stats=stats)
    path = bank.save(SSDENetBank.cache_path(h, grid, prof) if out is None else out)
    return {
        "path": str(path), "hrtf": h.name, "hrtf_ident": h.ident, "grid_ident": grid.ident,
        "n_directions": len(grid), "profile": prof.name, "bins": list(prof.bins),
        "frequencies_hz": [round(float(f), 1) for f in prof.frequencies_hz], "hidden": prof.hidden,
        "n_parameters": bank.n_parameters(), "data_s": round(stats["data_s"], 2), "train_s": round(stats["train_s"], 2),
        "final_loss": stats["final_loss"], "seed": prof.seed if seed is None else int(seed),
    }
