"""The hearing tasks' Gymnasium ids, registered on ``import acoustic_sim``.

The entry points are strings, so registering imports neither the task modules nor MuJoCo or
torch (``gymnasium.make`` loads them on first use; the library stays below the apps). Each id
carries a TimeLimit (``max_episode_steps``) equal to the env's own default limit, so
``gymnasium.make(id, max_episode_s=...)`` with a longer episode also needs
``max_episode_steps=``.
"""

from __future__ import annotations

from acoustic_sim.frames import FRAME_RATE

TASK_IDS = {
    "reverse-alarm": ("acoustic_sim/ReverseAlarm-v0", "tasks.reverse_alarm:ReverseAlarmEnv", 12.0),
    "parking-brake": ("acoustic_sim/ParkingBrake-v0", "tasks.parking_brake:ParkingBrakeEnv", 10.0),
    "call-response": ("acoustic_sim/CallResponse-v0", "tasks.call_response:CallResponseEnv", 30.0),
}
"""Command-line task name -> (Gymnasium id, entry point, default episode limit in s: the
class's ``default_max_episode_s``, which a test checks)."""


def max_episode_steps(task: str) -> int:
    """The TimeLimit of ``task``'s id, in control steps."""
    return round(TASK_IDS[task][2] * FRAME_RATE)  # the control step is one audio frame


def register_envs() -> None:
    """Register every task id not yet registered (idempotent)."""
    from gymnasium.envs.registration import register, registry

    for task, (env_id, entry, _) in TASK_IDS.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry, max_episode_steps=max_episode_steps(task))


__all__ = ["TASK_IDS", "max_episode_steps", "register_envs"]
