"""Task-env episodes into a rerun recording: the episode runner's ``step_callback``.

:class:`EpisodeRecorder` is called by :func:`apps.runner.run_episode` after every
reset and every step, as ``recorder(env, episode, step, obs, reward, terminated, truncated,
info)``, and logs what the env exposes: the scene's body poses and the eye camera's pose
(through the env's :class:`~acoustic_sim.world.view.WorldView`), the head pose, the sounds
playing (ground truth from ``info["sounding"]``: labelled points and true-direction arrows),
the percept of the step (``env.last_percept``: probabilities, estimated directions, the
existence map, the mel frame), the ears' block (``env.last_audio``), the events in words
and the eye camera image.

Several episodes, one file. A run of N episodes is *one* recording. Episodes follow each
other on the timelines: ``frame`` counts every logged step of the run (a reset is a frame
too), ``sim_time`` is each episode's own time (0 at its first observation) plus an offset
that puts it :attr:`EpisodeRecorder.gap_s` after the end of the previous one, and an
``episode`` sequence timeline holds the episode number. The event log opens every episode
with its number and seed and closes it with its outcome.

Recording never changes the episode: it reads copies (``WorldView`` hands out copies, the
percept and audio are only read) and uses no random number generator; the eye image is
rendered from the current state without stepping anything (a test checks the observations
bit for bit with and without a recording).
"""

from __future__ import annotations

import dataclasses
import math
import sys
from typing import Self

import numpy as np

from acoustic_sim.errors import AcousticSimError, ConfigError
from acoustic_sim.viz.recorder import Recorder, RecorderConfig, RecordingError, prepare_path
from acoustic_sim.world.names import EYE_CAMERAS

EYE_CAMERA = EYE_CAMERAS[1]
"""The camera whose frustum is drawn: the right eye, which ``HearingTaskEnv.eye_image`` renders."""

_OUTCOME_WORDS = {
    "success": "success",
    "early": "failure: let go before the target sound (a false release)",
    "late": "failure: let go too late",
    "not_in_reverse": "failure: let go with the lever not in R",
    "past_reverse": "failure: pushed the lever past R",
    "no_release": "failure: never let go",
    "timeout": "time limit reached",
}
"""Outcomes of the tasks' ``info["outcome"]`` in words (others are shown as they are)."""


def outcome_words(outcome: str) -> str:
    """A task outcome (``info["outcome"]``) in plain words."""
    return _OUTCOME_WORDS.get(outcome, outcome.replace("_", " "))


def event_words(event: dict) -> str:
    """One event of ``info["events"]`` (``kind``, ``label``, ``source``, ``detail``) in plain words."""
    kind, label = event.get("kind", ""), event.get("label", "")
    source, detail = event.get("source", ""), event.get("detail", "")
    if kind == "alarm_start":
        return f"reverse alarm starts ({source}; the lever entered {detail})" if detail else f"reverse alarm starts ({source})"
    if kind == "alarm_stop":
        return f"reverse alarm stops ({source})"
    if kind == "gear_change":
        return f"gearshift clicks into {detail}"
    if kind == "ratchet_click":
        return f"ratchet clicks (tooth {detail})"
    if kind == "key_turn":
        return "key turns"
    if kind == "voice_call":
        return f"the person calls ({source})"
    if kind == "distractor":
        what = label.replace("_", " ")
        return f"distractor: {what} ({detail})" if detail else f"distractor: {what} from {source}"
    text = f"{kind}: {label} from {source}"
    return f"{text} ({detail})" if detail else text


class EpisodeRecorder:
    """Record the episodes of a run into one ``.rrd`` file (a runner ``step_callback``).

    Parameters
    ----------
    path : str or pathlib.Path
        The recording, ending in ``.rrd``; checked and created at once (before any episode runs).
    camera : bool
        Log the right eye camera's image every ``config.camera_every``-th step, rendered by
        MuJoCo's offscreen renderer: fast on a GPU, but tens of milliseconds a picture with
        software OpenGL on a CPU (``acoustic-sim bench viz`` measures it as
        ``episode.eye_render_ms``). If offscreen rendering fails, a warning is printed, the
        event log says so, and the recording goes on without images.
    config : RecorderConfig or None
        Recorder options (``camera_every`` is the step interval of the eye images).
    first_seed : int or None
        Seed of episode 0 (episode ``i`` uses ``first_seed + i``, the runner's rule), for the
        event log; ``None``: seeds are not shown.
    gap_s : float
        Seconds of ``sim_time`` between the end of an episode and the start of the next, >= 0.
    name : str or None
        The recording's name in the viewer; default the file's stem.

    Raises
    ------
    RecordingError
        If ``path`` cannot take a recording.
    ConfigError
        If ``gap_s`` is negative or not finite.
    """

    def __init__(self, path, *, camera: bool = True, config: RecorderConfig | None = None,
                 first_seed: int | None = None, gap_s: float = 1.0, name: str | None = None) -> None:
        if not (isinstance(gap_s, (int, float)) and math.isfinite(gap_s) and gap_s >= 0):
            raise ConfigError(f"gap_s must be a number of seconds >= 0, got {gap_s!r}")
        self.path = prepare_path(path)
        self.camera = bool(camera)
        self.config = config if config is not None else RecorderConfig()
        self.first_seed = first_seed
        self.gap_s = float(gap_s)
        self.name = name
        self.recorder: Recorder | None = None
        """The underlying :class:`Recorder` (opened at the first call)."""
        self.frames = 0
        """Frames logged so far (resets included)."""
        self.episodes = 0
        """Episodes begun so far."""
        self._episode: int | None = None
        self._offset = 0.0
        self._last_t = 0.0
        self._released = False
        self._found = False

    # -- the hook ----------------------------------------------------------------------------------

    def __call__(self, env, episode: int, step: int, obs, reward: float, terminated: bool, truncated: bool,
                 info: dict) -> None:
        """Log one step of an episode (the runner's ``step_callback`` signature).

        Parameters
        ----------
        env : gymnasium.Env
            The task env (wrapped or not): its view, coupling, last percept and ear block
            are read, and its eye camera rendered.
        episode : int
            Episode number in the run (a new number starts a new episode in the recording).
        step : int
            Step in the episode; 0 is the observation of ``reset``.
        obs, reward, terminated, truncated, info
            What ``reset`` or ``step`` returned; ``info`` supplies the sounds playing (ground
            truth), the events, the release and the outcome.

        Raises
        ------
        RecordingError
            If the env's scene has other bodies than the one the recording started with
            (one file holds the episodes of one task).
        """
        env = env.unwrapped
        if self.recorder is None:
            self._open(env)
        rec = self.recorder
        if episode != self._episode:
            self._start_episode(episode)
        t = self._offset + (float(env.time_s) - float(env.start_s))
        self._last_t = t
        view = env.view
        events = self._events(env, episode, step, info, terminated, truncated)
        image = None
        if self.camera and step % self.config.camera_every == 0:
            image = self._eye_image(env, events)
        rec.log_frame(t, self.frames, view=view, head_pose=view.head_pose(), sources=self._sources(env, info),
                      percept=env.last_percept, audio_block=env.last_audio if step > 0 else None, events=events,
                      camera_image=image)
        self.frames += 1

    def _open(self, env) -> None:
        model = env.model
        has_eye = _has_camera(model, EYE_CAMERA)
        h, w = env.image_size
        # camera_every=1: the steps whose image is rendered are chosen here, before rendering.
        cfg = dataclasses.replace(self.config, camera_every=1, eye_aspect=w / h)
        self.recorder = Recorder.open(self.path, model, env.pipeline.grid.vectors, env.pipeline.classes, config=cfg,
                                      eye_camera=EYE_CAMERA if has_eye else None, name=self.name)

    def _start_episode(self, episode: int) -> None:
        if self._episode is not None:
            self._offset = self._last_t + self.gap_s
        self._episode = episode
        self.episodes += 1
        self._released = self._found = False
        self.recorder.set_episode(episode)

    def _events(self, env, episode: int, step: int, info: dict, terminated: bool, truncated: bool) -> list[str]:
        start_s = float(env.start_s)
        lines = []
        if step == 0:
            seed = "" if self.first_seed is None else f", seed {self.first_seed + episode}"
            lines.append(f"episode {episode}{seed}: {getattr(env, 'task', type(env).__name__)} starts")
        for e in info.get("events", ()):
            at = float(e.get("time_s", env.time_s)) - start_s
            lines.append(f"{event_words(e)} [at {at:.3f} s]")
        if not self._released and info.get("release_s") is not None:
            self._released = True
            gear = f" (gear {info['gear']})" if info.get("gear") else ""
            lines.append(f"the hand lets go{gear} [at {float(info['release_s']) - start_s:.3f} s]")
        if not self._found and info.get("found_s") is not None:
            self._found = True
            lines.append(f"the person is in view [at {float(info['found_s']) - start_s:.3f} s]")
        if terminated or truncated:
            outcome = info.get("outcome", "")
            reaction = info.get("reaction_s")
            more = f", reaction {reaction:.2f} s" if isinstance(reaction, (int, float)) and math.isfinite(reaction) else ""
            lines.append(f"episode {episode} ends: {outcome_words(outcome)}{more}")
        return lines

    def _sources(self, env, info: dict) -> list[tuple[str, str, np.ndarray]]:
        """The sounds playing, as (name, class, world position)."""
        c = env.coupling
        task_sounds = {s.name: s for s in getattr(env, "task_sounds", ())}
        out = []
        for snd in info.get("sounding", ()):
            name = snd["source"]
            if name in task_sounds:
                room = task_sounds[name].position
            else:
                try:
                    room = c.emitter_position(name)
                except ConfigError:
                    continue  # a sound with no place in the scene: its true arrow is not drawn
            label = name.split("/", 1)[1] if name.startswith("task/") else name
            out.append((label, snd["label"], c.frame.to_world(room)))
        return out

    def _eye_image(self, env, events: list[str]):
        try:
            return env.eye_image()
        except AcousticSimError as err:
            self.camera = False
            msg = f"eye camera images are off: {err}"
            print(f"acoustic-sim: warning: {msg}", file=sys.stderr)
            events.append(msg)
            return None

    # -- end ---------------------------------------------------------------------------------------

    def close(self) -> None:
        """Finish the file (safe to call twice). If no step was ever logged (the run failed
        before its first reset), the empty file created by the constructor is removed."""
        if self.recorder is not None:
            self.recorder.close()
        elif self.path.is_file() and self.path.stat().st_size == 0:
            self.path.unlink()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _has_camera(model, name: str) -> bool:
    import mujoco

    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, name) >= 0


__all__ = ["EYE_CAMERA", "EpisodeRecorder", "RecordingError", "event_words", "outcome_words"]
