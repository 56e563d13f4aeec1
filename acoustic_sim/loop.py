"""The hearing loop: one control step of the world heard through the ears, as one call.

One control step is one ear frame (16 ms, DESIGN.md section 1)::

    Coupling.advance()       8 physics steps of 2 ms, the world's sound events, poses to the renderer
    Soundscape.begin_block   the scheduled sounds that start in the block become renderer sources
    noise reference          the ambient noise measured at warm-up + the motors' ego-noise at this level
    Coupling.render()        the block of eardrum pressure (2, 705 | 706) Pa
    Soundscape.end_block     sounds over (reverberation included) leave the renderer
    Microphone               digital full scale, the ADC's 24 bits
    AuditoryPipeline         the head's pose (its world-frame tracker), then exactly one Percept
                             for the ear frame that ends with the block
    -> StepHearing           all of it, typed and frozen

:class:`HearingLoop` owns that chain and the listening warm-up before an episode; the task
envs (:class:`tasks.base.HearingTaskEnv`) call :meth:`HearingLoop.step` once per step and
act on its :class:`StepHearing`, so the order of the chain, the noise reference and the
sounds' renderer sources have one owner. Why: the chain used to be written out in the env's
``step`` and again in its warm-up, with the env building the pipeline's noise reference and
recomputing the front end's FFT itself, and task sounds reaching through the coupling into
the renderer.

The loop writes the world's controls nowhere: set them with
:func:`acoustic_sim.world.actuation.set_control` before :meth:`HearingLoop.step`. Its
randomness is that of its parts (the renderer's, the events', the microphone's generators),
so the same parts give the same steps bit for bit.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
from typing import TYPE_CHECKING

import numpy as np

from acoustic_sim.acoustics.microphone import FULL_SCALE_PA, Microphone
from acoustic_sim.auditory.frontend import N_BINS
from acoustic_sim.auditory.percept import Percept
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import FRAME_RATE
from acoustic_sim.world.soundscape import ScheduledSound, Soundscape

if TYPE_CHECKING:  # for the annotations only: importing this module imports no MuJoCo (its OpenGL backend)
    from acoustic_sim.world.coupling import Coupling
    from acoustic_sim.world.events import SoundEvent


@functools.cache
def microphone_floor() -> np.ndarray:
    """The microphone's self-noise power per bin (2, 1025), full-scale units: the floor of
    the noise reference (:func:`acoustic_sim.auditory.pipeline.microphone_noise_power`,
    computed once per process; do not modify the array)."""
    from acoustic_sim.auditory.pipeline import microphone_noise_power

    return microphone_noise_power()


@dataclasses.dataclass(frozen=True)
class StepHearing:
    """What one control step heard.

    Attributes
    ----------
    frame : int
        The ear frame that ends with the block (``coupling.frame_index`` after the step).
    time_s : float
        Project-clock time (s) of the block's end (``coupling.time_s`` after the step).
    world_events : tuple of SoundEvent
        What ``coupling.advance()`` returned: the world's events that start (or stop) in the block.
    events : tuple of dict
        Event records ``{kind, label, source, time_s, detail}``: the world's events, then the
        scheduled sounds that start in the block (:meth:`Soundscape.begin_block`).
    pressure : numpy.ndarray, shape (2, n), float64
        Eardrum pressure (Pa) of the block, n = 705 or 706.
    audio : numpy.ndarray, shape (2, n), float32
        The microphone's digital samples of the block (full scale 1.0).
    percept : Percept
        The pipeline's percept of the ear frame.
    frame_audio : numpy.ndarray, shape (2, n_fft), float64
        The digital samples the front end analysed for the frame (its last ``n_fft``).
    window : numpy.ndarray, shape (n_fft,)
        The front end's analysis window.
    """

    frame: int
    time_s: float
    world_events: tuple[SoundEvent, ...]
    events: tuple[dict, ...]
    pressure: np.ndarray
    audio: np.ndarray
    percept: Percept
    frame_audio: np.ndarray = dataclasses.field(repr=False)
    window: np.ndarray = dataclasses.field(repr=False)

    def frame_power(self) -> np.ndarray:
        """|X|^2 (2, 1025) of the ear frame, full-scale units: the windowed rFFT of
        :attr:`frame_audio` in float64, computed on demand (the front end's own spectra are
        complex64; the noise reference and the env's ``spectra`` observation are this one)."""
        return np.abs(np.fft.rfft(self.frame_audio * self.window, axis=-1)) ** 2


class HearingLoop:
    """The control step's chain, from the world to the percept, and the warm-up before it.

    Parameters
    ----------
    coupling : Coupling
        The world and its renderer (it must have one).
    microphone : Microphone
        The ear unit's microphones and ADC.
    pipeline : acoustic_sim.auditory.pipeline.AuditoryPipeline
        Reset here: its clock starts with the loop's first block.
    soundscape : Soundscape, optional
        The owner of the scheduled sounds; default a new one over ``coupling``.
    threads : context manager, optional
        Entered around every ``pipeline.process`` call (e.g. ``tasks.auditory.TorchThreads``);
        default none.

    Attributes
    ----------
    ambient_power : numpy.ndarray, shape (2, 1025)
        The room's steady noise at the ears, full-scale units, as :meth:`warm_up` measured it
        (the microphone's floor before).
    last : StepHearing or None
        The last step's hearing.
    """

    def __init__(self, coupling: Coupling, microphone: Microphone, pipeline, *, soundscape: Soundscape | None = None,
                 threads=None) -> None:
        if coupling.renderer is None:
            raise ConfigError("a HearingLoop needs a coupling with a renderer")
        if soundscape is not None and soundscape.coupling is not coupling:
            raise ConfigError("the soundscape of a HearingLoop must be over the loop's coupling")
        self.coupling = coupling
        self.microphone = microphone
        self.pipeline = pipeline
        self.soundscape = soundscape if soundscape is not None else Soundscape(coupling)
        self.threads = threads if threads is not None else contextlib.nullcontext()
        self.ambient_power = microphone_floor()
        self.last: StepHearing | None = None
        self._reference_of = None  # (ambient power, ego level) the pipeline's noise reference was made from
        self._ego_unit = None  # (ego noise, its unit_power_spectrum for the front end's window)
        pipeline.reset()

    # -- sounds -------------------------------------------------------------------------------
    def schedule_sound(self, name: str, label: str, signal, position, t: float, level_db: float, **kwargs) -> ScheduledSound:
        """Play ``signal`` from a fixed point from project-clock time ``t`` (s) on:
        :meth:`Soundscape.schedule_sound <acoustic_sim.world.soundscape.Soundscape.schedule_sound>`."""
        return self.soundscape.schedule_sound(name, label, signal, position, t, level_db, **kwargs)

    # -- the control step ---------------------------------------------------------------------
    def step(self) -> StepHearing:
        """One control step: the world advances one ear frame and the ears hear its block.

        Returns
        -------
        StepHearing

        Raises
        ------
        ConfigError
            If the pipeline does not give exactly one percept for the block.
        """
        c = self.coupling
        world = c.advance()
        records = self.soundscape.begin_block(world)
        self._set_noise_reference()
        pressure = c.render()
        self.soundscape.end_block()
        audio = self.microphone(pressure)
        # The head's pose in the block (the renderer holds it over the block), on the
        # pipeline's own clock, for its world-frame tracker.
        self.pipeline.note_pose(self.pipeline.frontend.sample / self.pipeline.frontend.sample_rate, c.head_rotation)
        with self.threads:
            percepts = self.pipeline.process(audio)
        if len(percepts) != 1:
            raise ConfigError(f"the pipeline returned {len(percepts)} percepts for one control block (expected exactly 1)")
        fe = self.pipeline.frontend
        self.last = StepHearing(frame=c.frame_index, time_s=c.time_s, world_events=tuple(world), events=tuple(records),
                                pressure=pressure, audio=audio, percept=percepts[0],
                                frame_audio=fe.buffer[:, -fe.n_fft:].copy(), window=fe.window)
        return self.last

    def warm_up(self, seconds: float) -> StepHearing | None:
        """Listen for ``seconds`` (the world as it is: hold the controls) before an episode.

        The ears' history (the 0.4 s log-mel window) fills with the room's own sound, so the
        first observation does not carry the onset of the background noise (which the
        detector takes for a sound event); the frames of the last two thirds (their 2048
        samples all audio) give :attr:`ambient_power`, at least the microphone's floor. The
        ground truth of what sounded is then forgotten.

        Parameters
        ----------
        seconds : float
            0 or more; rounded to whole control steps.

        Returns
        -------
        StepHearing or None
            The last step's (None for no step).
        """
        if not (np.isfinite(seconds) and seconds >= 0):
            raise ConfigError(f"warm_up: seconds must be a finite time >= 0, got {seconds!r}")
        n = round(seconds * FRAME_RATE)
        ambient, counted = np.zeros((2, N_BINS)), 0
        self.ambient_power = microphone_floor()
        self._reference_of = None
        last = None
        for k in range(n):
            last = self.step()
            if k >= n // 3:  # frames whose 2048 samples are all audio (the first are partly zeros)
                ambient += last.frame_power()
                counted += 1
        if counted:
            self.ambient_power = np.maximum(ambient / counted, microphone_floor())
        self.soundscape.forget()
        if getattr(self.pipeline, "tracker", None) is not None:
            self.pipeline.tracker.forget()  # what the warm-up heard is the room, not the episode's sounds
        return last

    def _set_noise_reference(self) -> None:
        """The pipeline's noise reference: the ambient noise measured while still (room
        background and microphone, :meth:`warm_up`) plus the motors' expected ego-noise at
        this block's level. The paper records the robot's driving noise in advance, in the
        room, so its reference holds the room's steady noise too: a bin counts only where a
        sound stands 10 times above both."""
        ego_noise = self.coupling.ego_noise
        level = ego_noise.pressure_rms if ego_noise is not None else 0.0
        last = self._reference_of
        if last is not None and last[0] is self.ambient_power and last[1] == level:
            return  # the same ambient and ego level as the last block: the same reference
        if ego_noise is None:
            ego = 0.0
        else:  # = expected_power_spectrum(window=...) at this level, without its checks each block
            unit = self._ego_unit
            if unit is None or unit[0] is not ego_noise:
                unit = self._ego_unit = (ego_noise, ego_noise.unit_power_spectrum(window=self.pipeline.frontend.window))
            ego = unit[1] * level**2
        self.pipeline.set_noise_power(self.ambient_power + np.asarray(ego) / FULL_SCALE_PA**2)
        self._reference_of = (self.ambient_power, level)


__all__ = ["HearingLoop", "StepHearing", "microphone_floor"]
