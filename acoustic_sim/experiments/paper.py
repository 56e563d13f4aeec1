"""``acoustic-sim eval paper``: every experiment of Omura et al. 2022 in one run.

Writes into the output folder: ``pinna.json``, ``hrtf_ild_ipd.json`` (with their
figures), ``localization.json`` (keys ``simulation`` and ``room``), ``detection.json``,
``summary.json`` (timings, and each target with its result and verdict:
:func:`~acoustic_sim.experiments.report.targets`), the figures
``localization_simulation.png`` and ``localization_room.png``, the measured HRTF
``measured_hrtf.sofa`` and ``REPORT.md`` (the tables, generated from the JSON).

``--quick`` uses the small models (SSDENet's ``quick`` profile, MelCNN's ``fast``), 24 simulated directions, a 60-direction
HRTF measurement, the quick room directions and 300 detection windows: every file with
every key, in a few minutes, for the tests. Numbers from a quick run are not the paper's.
"""

from __future__ import annotations

import time

import numpy as np

from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.acoustics.measure import measure_hrtf
from acoustic_sim.auditory.baselines import GccPhat, Music
from acoustic_sim.auditory.melcnn import MelCNN, evaluate, report_rng
from acoustic_sim.auditory.ssdenet import DEFAULT_FUSION, LEAKAGE, SSDENetBank, valid_bins
from acoustic_sim.directions import DirectionGrid
from acoustic_sim.errors import ConfigError
from acoustic_sim.experiments import hrtf_figures, localization
from acoustic_sim.files import check_writable_folder
from acoustic_sim.experiments.report import targets as report_targets, write_json, write_report

PAPER_CLAIMS = {
    "simulation": "SSDENet's mean error is below MUSIC's for every signal; MUSIC is near chance (about 90 deg) for sines and triangles.",
    "detection_f1": 0.87,
}


MEASURED_TAPS = 128
"""Length of the responses measured in the conference room (samples): 2.2 ms after the sound
reaches the head centre, a gate before the room's first reflection (the floor's, 3.9 ms
after the direct sound for a source at ear height 1.5 m away), as HRTFs measured in ordinary
rooms are cut. The paper does not give its response length. On the lab room's median plane
(the same 25 elevations x 4 trials, first-wavefront estimator), a bank from responses of 512
taps (the conference room's reflections of the first 11.6 ms in them; the first estimator's
Welch segments) gave top-bottom 0.77 and front-back confusion 0.32, one from 128 taps 0.84
and 0.23 (SSDENet on the frames: 0.60-0.66 and 0.64). The full run with 128 taps and the
paper's sum of bins: top-bottom 0.84 on the first wavefront (one window; 0.87 with the three
of :data:`~acoustic_sim.experiments.localization.ROOM_ONSET_WINDOWS`), 0.72 on the frames
(0.64 with the 512-tap bank), MUSIC 0.80 (0.68); with the product fusion of bins
(``results/paper``) 0.90 on the first wavefront and 0.79 on the frames."""


def _estimators(hrtf: HRTF, grid: DirectionGrid, bank: SSDENetBank) -> dict:
    """The methods as ``(spectra, noise_power) -> unit vector``: SSDENet with the default
    fusion of bins (``ssdenet``, the product) and with the paper's sum (``ssdenet-sum``),
    MUSIC and GCC-PHAT."""
    music = Music(hrtf, grid)
    gcc = GccPhat(hrtf)
    ahead = localization.straight_ahead(grid)

    def ssdenet(fusion):
        def estimate(spectra, noise):
            est = bank.estimate(spectra, valid_bins(spectra, noise, class_bins=bank.bins, leakage=LEAKAGE), fusion)
            # No valid bin (the source is below the noise everywhere): no information, so the
            # estimate is straight ahead, as for the baselines on silence.
            return ahead if est is None else est.vector

        return estimate

    return {
        "ssdenet": ssdenet(DEFAULT_FUSION),
        "ssdenet-sum": ssdenet("sum"),
        "music": lambda spectra, noise: music.estimate(spectra)[0],
        "gcc-phat": lambda spectra, noise: gcc.estimate(spectra)[0],
    }


def run_paper(*, out, hrtf="kemar", quick: bool = False, seed: int = 0, progress: bool = True) -> dict:
    """Run all experiments; returns a summary (also in ``summary.json``).

    Parameters
    ----------
    out : path-like
        Output folder (created).
    hrtf : str or HRTF
        The robot's ears (the world): ``kemar``, ``spherical`` or a SOFA path.
    quick : bool
        Small models and fewer directions and sounds (see the module docstring).
    seed : int
        Seed of every random choice (sources, noise, measurement), >= 0.
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError(f"seed must be an integer >= 0, got {seed!r}")
    out = check_writable_folder(out, what="--out")
    ears = hrtf if isinstance(hrtf, HRTF) else HRTF.load(hrtf)  # a bad file fails before the folder is made
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    profile = "fast" if quick else "paper"  # MelCNN's
    ssdenet_profile = "quick" if quick else "paper"  # two banks to train: the smallest one
    t0 = time.perf_counter()
    timings = {}

    hrtf_figures.pinna(out, hrtf_with=ears)
    hrtf_figures.hrtf_ild_ipd(out, hrtf=ears)
    timings["hrtf_s"] = time.perf_counter() - t0

    # 3. Simulation: networks trained on the world's own HRTF, sources through that HRTF.
    t = time.perf_counter()
    grid = DirectionGrid.paper(ears)
    bank = SSDENetBank.load_or_train(ears, grid, ssdenet_profile, progress=progress)
    directions = None
    if quick:
        directions = grid.vectors[np.linspace(0, len(grid) - 1, 24).astype(int)]
    simulation = localization.simulation(ears, grid, _estimators(ears, grid, bank), rng=rng, directions=directions,
                                         progress=progress)
    timings["simulation_s"] = time.perf_counter() - t

    # 4. Room: the HRTF measured in the conference room trains the networks (the paper's
    # setting); the world's ears render the lab room.
    t = time.perf_counter()
    sofa = out / "measured_hrtf.sofa"
    measure_hrtf(hrtf=ears, room="conference", seconds=0.3 if quick else 1.0, taps=MEASURED_TAPS,
                 max_directions=60 if quick else None, seed=seed, out=sofa, progress=progress)
    measured = HRTF.load(sofa)
    mgrid = DirectionGrid.paper(measured)
    mbank = SSDENetBank.load_or_train(measured, mgrid, ssdenet_profile, progress=progress)
    # Beside the paper's methods on the frames: the streaming pipeline's precedence
    # rule (SSDENet on the loudspeaker's first wavefront), with the same bank.
    wavefront = localization.first_wavefront(mbank, windows=localization.ROOM_ONSET_WINDOWS)
    room = localization.room(ears, _estimators(measured, mgrid, mbank), rng=rng, quick=quick, progress=progress,
                             audio_estimators={"ssdenet-wavefront": wavefront})
    room.update(level_db_spl=[73.0, 76.0], distance_m=1.5, room="lab", trained_on=f"{measured.name} ({measured.ident})",
                measured_taps=MEASURED_TAPS, measured_in="conference",
                wavefront_windows=localization.ROOM_ONSET_WINDOWS)
    timings["room_s"] = time.perf_counter() - t
    loc = {"simulation": simulation, "room": room, "hrtf": ears.name, "profile": ssdenet_profile, "quick": quick,
           "directions": len(grid) if directions is None else len(directions), "paper_claim": PAPER_CLAIMS["simulation"]}
    write_json(out / "localization.json", loc)

    # 5. Detection.
    t = time.perf_counter()
    cnn = MelCNN.load_or_train(profile, progress=progress)
    det = evaluate(cnn, report_rng(profile), 300 if quick else 3000, progress=progress)
    det.update(profile=profile, paper_f1=PAPER_CLAIMS["detection_f1"])
    write_json(out / "detection.json", det)
    timings["detection_s"] = time.perf_counter() - t

    timings = {k: round(v, 1) for k, v in timings.items()}
    timings["total_s"] = round(time.perf_counter() - t0, 1)
    summary = {"out": str(out), "profile": profile, "quick": quick, "seed": seed, "hrtf": ears.name, "timings": timings,
               "targets": report_targets(loc, det)}
    write_json(out / "summary.json", summary)
    write_report(out)
    return summary
