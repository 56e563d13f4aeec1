"""The paper's behaviours, from the observation only (never ``info``).

ReverseAlarm
    Push the gearshift along the taught motion (toward D, through R) until the reverse alarm
    is heard *from the front*, then let go.
ParkingBrake
    Pull the brake lever along the taught motion until the ratchet is heard *from the right*,
    then let go.
CallResponse
    When a voice is heard, turn the head and eyes toward it, and the wheelchair when it is
    beyond the neck's reach, until the person is in view. A direction that turned out to hold
    no person (the loudspeaker, a front-back confusion) is remembered and not checked again;
    a voice from there is tried at its front-back mirror image instead.

While the target sound is heard and not yet placed elsewhere, the lever stops and the robot
listens (the motion resumes when the evidence puts the sound outside the accepted region,
or it stops). The lever makes the sound the robot must hear (the alarm on entering R, a
click at each of the brake's teeth), so the robot also chooses when: it waits for quiet
before moving the lever on, and credits the target only to a lever that has just moved
(:class:`ScriptedReverseAlarm`, "Waiting for quiet").

"Heard from a direction" is a vote over the last frames: a frame votes for the class when
its probability is at least ``threshold`` and the estimated direction lies in the accepted
region (with some confidence), against it when the class is heard from elsewhere. The robot
acts when at least ``votes`` of the last ``window`` frames voted for and more voted for than
against: one stray frame (a mislocalized distractor, a front-back flip) does not decide.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from acoustic_sim.frames import head_to_body_azimuth, in_lateral_region, lateral_deg
from tasks.base import CLASSES, CONTROL_DT, lever_arm_angles


class TaskPolicy:
    """Base of the policies: the env's static action layout, a step counter.

    Parameters
    ----------
    env : gymnasium.Env
        A task env (wrapped or not); only its static ``layout`` and ``task`` are read.
    """

    def __init__(self, env) -> None:
        self.env = env.unwrapped
        self.layout = self.env.layout
        self.steps = 0

    def reset(self, obs, info) -> None:
        """Start of an episode (the observation and info of ``env.reset``)."""
        self.steps = 0

    def act(self, obs, info) -> np.ndarray:
        """The action (normalized, float32) for the observation (and, for the oracle, info)."""
        raise NotImplementedError

    @property
    def time_s(self) -> float:
        """Seconds since the episode's start, at the step about to be taken."""
        return self.steps * CONTROL_DT


class Votes:
    """Frame votes over a sliding window: for (the class from the accepted region) or against."""

    def __init__(self, window: int, votes: int) -> None:
        self.window, self.votes = int(window), int(votes)
        self.frames: deque = deque(maxlen=self.window)

    def reset(self) -> None:
        self.frames.clear()

    def push(self, pro: bool, con: bool) -> bool:
        """Add one frame's vote; True when the evidence decides."""
        self.frames.append((bool(pro), bool(con)))
        pros = sum(p for p, _ in self.frames)
        cons = sum(c for _, c in self.frames)
        return pros >= self.votes and pros > cons


def azimuth_deg(v) -> float:
    """Azimuth (deg, + left) of a head-frame vector."""
    return math.degrees(math.atan2(float(v[1]), float(v[0])))


def heard(obs, label: str, threshold: float, min_conf: float) -> tuple[bool, np.ndarray | None]:
    """Whether ``label`` is heard in this frame, and its direction when it has a confident estimate."""
    i = CLASSES.index(label)
    on = float(obs["class_prob"][i]) >= threshold
    has = float(obs["class_conf"][i]) > min_conf and float(np.linalg.norm(obs["class_dir"][i])) > 0.5
    return on, (np.asarray(obs["class_dir"][i], float) if on and has else None)


# -- the cabin: a hand on a lever -------------------------------------------------------------------


class LeverPolicy(TaskPolicy):
    """Move a lever along the taught motion until :meth:`should_release`, then open the hand.

    Attributes (class level)
    ------------------------
    side : str
        The hand on the lever.
    delay_s, rate_deg_s, max_deg : float
        The taught motion: still for ``delay_s``, then ``rate_deg_s`` up to ``max_deg``.
    head_yaw_deg : float
        The neck's yaw (deg, + left) held during the episode: the listening pose.
    """

    side = "left"
    delay_s = 0.2
    rate_deg_s = 8.0
    max_deg = 30.0
    head_yaw_deg = 0.0

    def reset(self, obs, info) -> None:
        super().reset(obs, info)
        self.released = False
        self.hold = False
        self.motion_s = 0.0
        self._arm = lever_arm_angles(self.side, 0.0)

    def lever_target_deg(self) -> float:
        return float(np.clip(self.rate_deg_s * (self.motion_s - self.delay_s), 0.0, self.max_deg))

    def should_release(self, obs, info) -> bool:
        """Decide from this observation; may set ``self.hold`` to pause the motion."""
        raise NotImplementedError

    def act(self, obs, info) -> np.ndarray:
        if not self.released and self.should_release(obs, info):
            self.released = True
        if not self.released:
            if not self.hold:
                self.motion_s += CONTROL_DT
            self._arm = lever_arm_angles(self.side, self.lever_target_deg())
        values = self.layout.arm(self.side, self._arm)
        values["neck_yaw"] = math.radians(self.head_yaw_deg)
        values[f"grasp_{self.side}"] = -1.0 if self.released else 1.0
        self.steps += 1
        return self.layout.action(values)


class ScriptedReverseAlarm(LeverPolicy):
    """Push the gearshift until the reverse alarm is heard from the front, then let go.

    Parameters (class level): ``threshold`` (class probability), ``min_conf`` (direction
    confidence), ``head_yaw_deg`` (the neck's yaw while listening, deg, + left),
    ``lateral_range_deg`` (the lateral angles from the turned head accepted as the alarm's,
    deg, + left), ``elevation_deg`` (their elevations in the car's frame, deg), ``window``
    and ``votes`` (see :class:`Votes`); ``credit_s``, ``masker_level``, ``masker_quiet_s``,
    ``settle_s`` and ``own_classes`` (waiting for quiet, below).

    Front and back. Interaural features give a sound's lateral angle (its angle to the
    head's median plane), not where it lies on the cone of confusion around the interaural
    axis: a source and its mirror image through that axis give the same features (with
    KEMAR's mirror-symmetric ears, ILD and IPD are exactly 0 at every frequency on the whole
    median plane, so the dashboard alarm and a beeper behind the car sound the same).
    Looking straight ahead, the alarm's mirror image is behind the car, where half of the
    other vehicles' beepers are. The robot therefore listens with its head turned 22 deg to
    the right (``head_yaw_deg``): the dashboard speaker is then 22 deg left of the head's
    median plane (10 deg below the ears), and the policy accepts what the ears can tell, a
    lateral angle of 5-36 deg to the left (``lateral_range_deg``), not above 20 deg
    (``elevation_deg``). That is the front of the car and its mirror image behind on the
    left (about 136 deg in the car's frame). A beeper straight behind the car is then at
    lateral -22 deg (to the right), and those beside the car on the left, whose sound comes
    through the body from their own direction (:func:`tasks.soundscape.outside_placement`),
    at 70-90 deg; one behind on the left, near 136 deg, cannot be told from the alarm.

    The lateral rule (since 2026-12-04, session 21, with that line-of-sight law for sounds
    from outside the cabin). Before, the head was turned 45 deg right and the policy
    accepted a sector of azimuths in the car's frame (+-20 deg) and its mirror image through
    the door (90 deg left), and outside sounds played from the point inside the walls nearest
    to them, which brought a beeper beside the car and 0.5-1 m ahead of the head in through
    the window next to the head, 19-35 deg from straight ahead. Played from their own
    direction, those beepers (68-86 deg) fell onto that mirror sector: pose and rule had to
    change with the law. Paper models (seeds 100-199, 200-299, 1000-1099, 2000-2099; the
    ``/tmp`` scripts of the session): under the new law the old policy 94 with 4 false
    releases on 1000-1099; head 25-30 deg right with the sectors 83 with none; lateral
    windows 10-38 deg at 25 deg right 90 with none, 15-40 deg at 30 deg right 87 with none;
    5-36 deg at 22 deg right, no elevation bound: 95 (2 false releases: 134, 157), 89 (3:
    214, 236, 285), 98 (0), 95 (0) on the four ranges; with the bound at 20 deg up (this
    policy): **96 (0), 88 (1: 236), 97 (0), 93 (0)**, 374 of 400 with one false release
    (214, traced: a beeper on the right placed 60 deg up on the left; the bound drops it),
    against 382 with 4 for the old policy under the old law. Of the failures left, one
    traced (208, never let go): the first beep came with the gear lever's clunk, 58 deg to
    the left and 40 deg down, and was placed there; the next beeps, inside the region, came
    more than ``credit_s`` after the hand stopped. Fast models (the tests';
    :data:`~acoustic_sim.auditory.ssdenet_profiles.FAST`), test seeds 100-119, training
    seeds 0, 1 and 2: 19, 20 and 18 of 20, no false release; seeds 1000-1099, training seed
    0: 95 with none (the old policy under the old law with the then 16-bin bank: 18, 15 and
    14 of 20 with one false release each; 89 with none).

    Measurements below dated before session 21 are of the 45-deg pose with its sectors under
    the nearest-point law; they explain the rules kept (waiting for quiet, ``credit_s``, the
    elevation bound).

    Waiting for quiet (since 2026-12-04). The lever makes the sound the robot must hear (the
    alarm once it enters R; the ratchet's click at each tooth), so the robot also chooses
    *when*. It does not move the lever on while another class is heard (probability at least
    ``masker_level``: the radio's speech, a horn, the key turning, another class's false
    alarm; not ``own_classes``, the gear lever's own clunks), nor for ``masker_quiet_s``
    after; nor for ``settle_s`` after its own class was last heard, from anywhere (another
    vehicle's beeper and the turn-signal relay repeat: the next beep or tick should not come
    while the real sound is being placed; while the real alarm sounds this keeps the lever in
    R). And a frame votes for the target only within ``credit_s`` of the lever's last
    commanded motion: what is heard long after the hand stopped is not the hand's doing (a
    beeper's beep while the lever waits, the key's lock click placed on the right). The
    waits follow only what is heard; a cabin that never fell quiet would keep the lever still
    until the episode's end (``timeout``). Paper models, the same episodes before and after:
    ReverseAlarm 100-199 89/100 -> 99/100, 200-299 90 -> 96, 1000-1099 86 with 3 false
    releases -> 96 with 3; ParkingBrake 100-199 89 -> 98, 200-299 78 with 6 -> 94 with none,
    1000-1099 69 with 5 -> 99 with none. Fast models: on the test seeds 100-119 ReverseAlarm
    18/20 with 1 (unchanged), ParkingBrake 17 -> 18 of 20, none; on 1000-1099 ReverseAlarm 79
    with 4 -> 88 with 2, ParkingBrake 62 with 8 -> 89 with 1. Variants compared on those
    seeds (a ``/tmp`` script, which also waited 0.1 s at the start: counts within about 2
    of these): without ``credit_s`` ReverseAlarm 1000-1099 91 with 7 false releases (the
    beeper's later beeps placed at the alarm's mirror image while the lever waited);
    ``credit_s`` 0.5 s for the ratchet 93 with 6 (the key's lock click and the radio's onsets
    7-34 frames after the lever stopped; decisions on a real click come 1-2 frames after it
    stops), 0.13 s 98 with 1 (these two without ``settle_s``); waiting after the target's class only when it was placed
    elsewhere, not ``settle_s`` after any hearing: ReverseAlarm 92 with 6 on 1000-1099;
    counting the lever as moving while the arm's joints still turn (proprioception, at least
    2 deg/s, about 0.2 s after the command stops): ParkingBrake 96/100 none on 200-299, 98
    with 1 on 1000-1099 (not taken); the alarm credited only after the gear lever's clunk was
    heard (the lever entering R; the alarm's frames before it neither for nor against, 1.5 s
    after it for): ReverseAlarm 40/100 on both 200-299 and 1000-1099, no false release,
    median reaction 0.91 s (MelCNN hears the clunk 0.2-0.3 s after the alarm starts, when the
    first beep has been placed already; the second comes 0.9 s after the first). Letting go on
    the votes only once the clunk has been heard within 0.5 s before or after them (the
    decision waits up to 0.5 s): paper models 97, 94 and 98 of 100 on 100-199, 200-299 and
    1000-1099, no false release (against 99, 96 and 96 with 3), median reaction 0.23-0.25 s;
    but the fast MelCNN often misses the clunk: 10/20 on the test seeds (18/20 now). Not
    taken: the rule would rest on a class that the small models do not hear.

    In front, not above (since 2026-12-04, session 19). The sector is bounded in elevation
    too (``elevation_deg``: at most 20 deg up; the dashboard speaker is 10 deg below the
    ears): two of the three false releases on the then held-out seeds 2000-2099 were another
    vehicle's beeper placed 30-40 deg up (2048, 2079); another one 60 deg up, in front, let
    go with the head turned 70 deg (1004). Paper models, the same episodes before -> after:
    100-199 99 -> 99, 200-299 96 -> 96, 1000-1099 96 with 3 false releases -> 96 with 3,
    2000-2099 92 with 3 -> 91 with 1 (2007, 2024 and 2065 now never let go: their alarm's
    beeps were placed 30-50 deg up, the up-down confusion of the cone); fast models 100-119
    18/20 with 1 -> the same, 1000-1099 88 with 2 -> 89 with none. A lower bound as well (-40
    deg): 94 with 3 and 89 with 1 on 1000-1099 and 2000-2099 (beeps placed lower): none.
    The false releases left (1012, 1034, 1084, 2064; fast 100) are beepers on the left whose
    placements are those of the alarm's beeps (azimuth 77-80 deg, elevation -30 or -20 deg
    from the car: the alarm's mirror image). A beeper outside plays from the nearest point
    inside the walls (:func:`tasks.soundscape.outside_placement`), and the cabin's left wall
    is 0.45 m from the head, so beepers beside the car up to 1 m ahead of the head are heard
    through the window 21-37 deg from the alarm (1034, 1084, 2048, 2064, 2079): close enough
    for the estimates of one to be those of the other. The mirror image keeps angles, so no
    listening pose separates them; measured (no elevation bound): the head turned 70 deg
    right, 90/100 with 7 false releases on 1000-1099 (95 with 2 on 200-299); 85 deg right, 85
    with 6; 80 deg left (the alarm's mirror image 20 deg right of the front), 85 with 5.
    With the line of sight through the body instead of the nearest point (what the first
    wavefront would do; measured with a ``/tmp`` patch, not the world's law) the beepers on
    the left come from 68-112 deg, onto the mirror sector: the pose and the rule would have
    to change with it (:func:`tasks.soundscape.outside_placement` has the figures).

    Held out (seeds 3000-3099, which no choice looked at; ``acoustic-sim eval tasks``,
    ``results/tasks``): with the lateral rule under the line-of-sight law 0.92 (95 % interval
    0.85-0.96), no false release, 7 that never let go (3009, 3013, 3019, 3027, 3073, 3092,
    3097) and one late (3056), median reaction 0.11 s (not looked at); with the 45-deg pose
    and its sectors under the nearest-point law it was 0.96 (0.90-0.98), no false release, 4
    that never let go (3013, 3015, 3034, 3087). With the product fusion of bins
    (:data:`acoustic_sim.auditory.ssdenet.DEFAULT_FUSION`, chosen on the design seeds; the
    models retrained on another machine, 2026-12-05): 0.96 (0.90-0.98), no false release, 4
    that never let go (3013, 3019, 3090, 3093), median reaction 0.11 s.

    Held out before the elevation bound (seeds 2000-2099): 0.92 with 3 false releases, each
    another vehicle's beeper on the left placed at the alarm's front-back mirror image or high
    up (2048, 2064, 2079: the ambiguity described above), and 5 that never let go. In the two
    looked at, no beep was placed in front within ``credit_s`` of the lever's stop: in 2019 a
    car horn stopped the lever (0.1 s after the horn began: MelCNN's delay), the lever still
    slid into R and the alarm sounded under the horn, its first placed beep 1.2 s after the
    stop; in 2088 the first beep was placed outside the region and the next ones not at all
    (then under the radio). Before waiting for quiet, on the held-out seeds of then
    (1000-1099): 0.86 with 3.

    Where it failed before waiting for quiet (paper models, seeds 100-199): 0.89 (95 %
    interval 0.81-0.94), no false release, 11 late, each a first beep that gave no accepted
    direction, so the release waited for the next beep, 0.8-1.1 s later. In eight (115, 116,
    143, 147, 168, 171, 173, 198) the first beep made no onset at all: it started under a
    car horn, the radio's speech or another vehicle's beeper, and the high-passed broadband
    energy did not rise 8 times (:class:`~acoustic_sim.auditory.precedence.FirstWavefront`);
    in three (152, 157, 158) it was placed outside the accepted region. Onsets detected per
    octave band as well (1-16 kHz, a rise in any band counts; a ``/tmp`` patch of
    ``FirstWavefront.push``), measured and not taken: paper models, seeds 100-299, 186/200
    on time against 179/200, but one false release against none (102: another vehicle's
    beeper on the left, accepted at its front-back mirror image once it gets more onsets);
    fast models, 100-199, 86/100 with 3 false releases against 84 with 2; ParkingBrake (paper,
    100-199) 86/100 with 2 false releases against 89 with none (the relay's and the key's
    clicks get more onsets too). It would also cost four more filters per block (about 0.1 ms
    each here, against the fast env's 3.2 ms step). On seeds 100-129
    alone the same models give 0.93 (115, 116 late). Models trained where espeak-ng was
    missing (formant voices) gave 0.90 with a false release: 118 let go on another
    vehicle's beeper on the left (114 deg azimuth from the turned head), placed at its
    front-back mirror image (64 deg: 19 deg from the car's front, inside the front sector).
    The turned head trades the beepers behind the car (whose mirror images then lie to the
    right) for those on the left, whose mirror images lie in front: the ears cannot tell
    them from the alarm. With one first-wavefront window per
    onset (before :attr:`tasks.cabin.CabinLeverTask.onset_windows`) it was 0.80 with 6 late:
    in 103, 114, 115 and 120 a beep was placed at 87 deg azimuth, -10 deg elevation (lateral
    80 deg; the alarm is at 45 deg from the turned head), and the next beep, 0.8-1.1 s
    later, came after the task's 1.0 s. That placement is an onset effect: a beep ramps up
    over 2-8 ms, and in the window the far ear, up to 0.7 ms behind on the ramp, is quieter
    than the head makes it (seed 103: ILD 1.47 and 2.10 at 1184 and 3510 Hz; 0.92 and 1.19
    with the ears aligned on their lag). Measured against one window (paper models, seeds
    100-189: 74/90, no false release; fast, 100-119: 18/20): three windows 80/90, none,
    fast 16/20 with one (another vehicle's beeper on the left, placed at the alarm's mirror
    image, which this rule accepts: the ears cannot tell them apart); aligning the ears on
    their lag (``FirstWavefront(align_lag_ms=)``) 25/30 on seeds 100-129, fast 17/20; the
    head turned 85 deg right (the alarm at lateral 78 deg, near the interaural axis, where
    the cone of confusion shrinks) with a lateral rule (at least 45 deg): 79/90 with one
    false release, fast 16/20 with one; the alarm's direction without its third harmonic's
    bank bin (3510 Hz): 80/90, fast 18/20, but that rule follows from these episodes, not
    from the ears.
    """

    side = "left"
    rate_deg_s = 8.0
    max_deg = 30.0
    label = "reverse_alarm"
    threshold = 0.5
    min_conf = 0.0
    window = 8
    votes = 3
    head_yaw_deg = -22.0
    lateral_range_deg = (5.0, 36.0)
    """The lateral angles (deg, + left, from the turned head) accepted as the alarm's: the
    dashboard speaker is 22 deg left of the head turned 22 deg right."""
    elevation_deg = (-90.0, 20.0)
    """The region's elevations (deg, + up, car frame): the dashboard speaker is 10 deg below
    the ears; an estimate more than 30 deg above that is not the alarm; below, no bound (its
    beeps are placed down to -50 deg; see "In front, not above" in
    :class:`ScriptedReverseAlarm`)."""

    credit_s = 1.0
    """How long after the hand stopped the target sound can still be its doing (see
    :class:`ScriptedReverseAlarm`'s "Waiting for quiet"): the alarm sounds as long as the
    lever stays in R, one beep every 0.8-1.1 s, so a beep in the second after the hand
    stopped may be the first one the ears place."""
    masker_level = 0.5
    """Probability from which another class counts as masking (the lever waits)."""
    masker_quiet_s = 0.1
    """Quiet time (s) after the last masking frame before the lever moves again."""
    settle_s = 1.5
    """Quiet time (s) after the target class was last heard before the lever moves again: a
    sound of the target's class from elsewhere (another vehicle's beeper, the turn-signal
    relay) repeats, and the next one should not come while the lever makes the real one."""
    own_classes = ("gearshift",)
    """Classes the robot's own hands make (the gear lever's clunks): never a masker."""

    def reset(self, obs, info) -> None:
        super().reset(obs, info)
        self.evidence = Votes(self.window, self.votes)
        self._maskers = [i for i, c in enumerate(CLASSES) if c != self.label and c not in self.own_classes]
        self._last_move = 0
        self._masker_quiet = self._target_quiet = 10**9
        self.waiting: str | None = None  # why the lever stands: "listening", "masked", "settling"
        self.maskers: tuple = ()  # the classes masking in the last frame

    def accept(self, direction: np.ndarray, obs) -> bool:
        """The alarm's region: the estimate's lateral angle from the turned head (its angle to
        the head's median plane, + left; :func:`lateral_deg`) within ``lateral_range_deg``,
        and its elevation in the car's frame within ``elevation_deg``; ``obs`` gives the
        neck's pitch (:func:`~acoustic_sim.frames.in_lateral_region`)."""
        return in_lateral_region(direction, head_pose(obs)[1], lateral_range_deg=self.lateral_range_deg,
                                 elevation_deg=self.elevation_deg)

    def should_release(self, obs, info) -> bool:
        if not self.hold:  # the lever moved in the last step
            self._last_move = self.steps
        on, d = heard(obs, self.label, self.threshold, self.min_conf)
        accepted = d is not None and self.accept(d, obs)
        credited = self.steps - self._last_move <= round(self.credit_s / CONTROL_DT)
        pro = on and accepted and credited
        con = on and d is not None and not accepted
        decided = self.evidence.push(pro, con)
        # Hearing the sound, stop moving and listen, unless most of the recent frames place
        # it outside the accepted region (another source's: carry on). Moving on while the
        # direction is still being settled would push the lever past the position that
        # made the sound.
        pros = sum(p for p, _ in self.evidence.frames)
        cons = sum(c for _, c in self.evidence.frames)
        self.hold = on and pros >= cons
        # Waiting for quiet: the lever does not move (so makes no sound) while another class
        # masks, nor soon after the target's class was heard from anywhere.
        maskers = tuple(CLASSES[i] for i in self._maskers if float(obs["class_prob"][i]) >= self.masker_level)
        self._masker_quiet = 0 if maskers else self._masker_quiet + 1
        self._target_quiet = 0 if on else self._target_quiet + 1
        self.maskers = maskers
        self.waiting = "listening" if self.hold else None
        if not self.hold and self._masker_quiet < round(self.masker_quiet_s / CONTROL_DT):
            self.hold, self.waiting = True, "masked"
        elif not self.hold and self._target_quiet < round(self.settle_s / CONTROL_DT):
            self.hold, self.waiting = True, "settling"
        return decided


POLICY_CLASSES = {"reverse-alarm": ScriptedReverseAlarm}
"""Task name -> scripted policy class (filled in below for every task)."""


class ScriptedParkingBrake(ScriptedReverseAlarm):
    """Pull the brake lever until the ratchet is heard from the right, then let go.

    "From the right" is a lateral angle (the angle between the direction and the median
    plane, toward the right ear) of at least ``lateral_deg``: the ratchet's pawl is at -108 deg
    azimuth, -63 deg elevation from the head, a lateral angle of 26 deg (the estimates of
    its clicks: 40-55 deg). The lateral angle is what the interaural cues fix; the position
    on the cone of confusion (front, back, up, down) is what they get wrong. An azimuth
    sector (-165 to -35 deg, the previous rule) took the radio's speech in front at -17 deg,
    placed at its front-back mirror image -164 deg (lateral 16 deg), for the ratchet (fast
    models, seed 115: an early release). Fast models, seeds 100-119 (one onset window): 0.65 -> 0.70,
    false releases 0.15 -> 0.05 (the same with 20, 30 or 40 deg).

    Held out (seeds 3000-3099; ``acoustic-sim eval tasks``, ``results/tasks``; the policy as
    on 2000-2099, its elevation bound is ReverseAlarm's only): 0.94 (0.88-0.97), no false
    release, 4 late (2.4-2.6 s after the first click: 3003, 3051, 3088, 3095) and 2 that
    never let go (3009, 3069); not looked at. Rerun with the models retrained on another
    machine (2026-12-05; this task keeps the sum fusion,
    :attr:`tasks.parking_brake.ParkingBrakeEnv.fusion`): 0.95 (0.89-0.98), no false release,
    the same 4 late (3003 now 1.6 s) and 1 that never let go (3009).

    Held out on seeds 2000-2099 (now design seeds), waiting for
    quiet (:class:`ScriptedReverseAlarm`): 0.96, no false release, 3 that never let go and 1
    late. In 2078 (looked at) the turn-signal relay stopped the lever, which still slid over
    the first tooth 0.1 s later; that click was not placed on the right within ``credit_s``,
    and the relay's ticks kept the ratchet class on, so the lever stayed (crediting the arm's
    sensed motion instead, measured on the design seeds, was not better).
    Everything below this paragraph was measured before waiting for quiet.

    Held out then (seeds 1000-1099): 0.69 with 5 false releases; on seeds 200-299 0.78 with 6. Looked at
    afterwards (not used to choose anything): most late episodes there are a first click under
    the ignition key's jingle (3-10 kHz, over the pawl's 2-8 kHz modes) or the radio's speech
    that MelCNN does not detect (ratchet at most 0.1-0.5 in the 0.3 s after the click: 1003,
    1010, 1011, 1013); the false releases are the key's lock clicks (the ignition is right
    of the steering column) or the radio's speech onsets (front right, placed further right),
    heard while the relay's ticks keep the ratchet class on (222, 235, 1021, 1055). A
    MelCNN trained with slow pulls as well (single clicks 0.2-0.8 s apart, 40 % of the
    ratchet examples, as this pull makes them; a ``/tmp`` patch of ``sounds._ratchet``):
    paper models 73/100 with 7 false releases on 1000-1099 (ReverseAlarm 85 with 4), fast
    57 with 6 (against 62 with 8): not taken (the one decision those seeds informed, and it
    kept what the report measures). Letting the con votes not veto (release on
    ``votes`` pro votes alone): the same 11 late on 100-199. Directions for classes from
    probability 0.3 on, the policy acting from 0.4 (the 141 case below): 91/100 on 100-199,
    80/100 with 6 false releases on 200-299 (78 with 6), ReverseAlarm 87 with 1 (89 with
    none): not taken. ``direction_frames`` 18 and 24 (the pipeline's 12): 84 and 74 on
    100-199. An onset counting only for the detected classes whose characteristic bins are
    most enriched in the energy it added (its share there over the bins' share of the band;
    at least half the largest: a ``/tmp`` patch of the pipeline's ``_directions``, the
    ``specificity`` machinery on): 80/100 with 4 false releases on 200-299, 87 with none on
    100-199 (only the largest: 70 with 2 on 200-299): not taken.

    Paper models, seeds 100-199 (design seeds), before waiting for quiet: 0.89 (95 % interval 0.81-0.94), no false release,
    11 late, each a first click that gave no accepted direction (the next tooth comes 0.58 s
    later, see ``rate_deg_s``). Its onset was heard in all but three (183, 197, 198); it was
    not detected by MelCNN under the radio's speech (115, also under the key turn, and 133:
    ratchet at most 0.26), placed elsewhere (118, 122, 165, 197: up, near the zenith or to
    the left), or the turn-signal relay's clicks, ticking at the same time, were taken for
    the ratchet and placed on the left (141, 178, 183, 196, 198; in 141 the click's onset
    was found and placed, but MelCNN's ratchet probability stayed at 0.41-0.49 under the
    key turn for 14 frames, and when it rose the click had left the 12 frames that a
    direction sums, which then held only the relay's ticks). Seeds 100-129 alone: 0.90
    (115, 118 and 122 late). The models of an
    earlier machine gave 0.87 (also 121 late); models trained without espeak-ng 0.83 (103,
    104, 112, 115 and 118 late: clicks not detected under the key turn, the relay or the
    radio, or placed where the relay ticked at the same time). With one onset window (before
    :attr:`tasks.cabin.CabinLeverTask.onset_windows`) the earlier machine's models gave the
    same count. The two rules side by side (one onset window; the same episodes, only
    ``accept`` changed): paper models, seeds 100-159: lateral 20 deg 54/60, sector 56/60, no
    false release with either; fast models, seeds 100-129: lateral 0.70 with 2 false
    releases, sector 0.60 with 6. Lateral 10 deg (paper, 100-129): 0.87 with 2 false
    releases.
    """

    side = "right"
    delay_s = 0.2
    rate_deg_s = 12.0
    """The pull's speed. The brake's teeth are 7 deg apart
    (:data:`acoustic_sim.world.names.BRAKE_TOOTH_ANGLES_DEG`): at 12 deg/s a first click
    that the ears miss or misplace is followed by the next 0.58 s later, after the task's
    0.5 s. A pull at 24 deg/s (the next click 0.29 s later) was measured and not taken:
    paper models (trained without espeak-ng), seeds 100-189, 82/90 -> 88/90 with the task's
    distractors, but most of that came from letting go before the relay and the key turn had
    started (the first tooth clicks 0.33 s sooner; blind false releases 0.73 -> 0.27 on
    seeds 100-129). With both starting in the first 0.6 s, 83/90 at 12 deg/s and 84/90 at 24
    (none false): the faster arm's motors are louder (twice every speed: 6 dB,
    :mod:`acoustic_sim.world.egonoise`) and mask more clicks (at 24 deg/s, with the task's
    distractors, 15 releases came after the second tooth, 0.24-0.44 s after the first click,
    and 2 were late; at 12, 8 late). 18, 21 and 30 deg/s with the task's distractors: 83, 85
    and 87 of 90."""
    max_deg = 45.0
    label = "ratchet"
    head_yaw_deg = 0.0  # the ratchet is far off the median plane: no front-back question
    mirror = False
    lateral_deg = 20.0
    window = 6
    votes = 2
    credit_s = 0.064
    """A click is the pawl passing a tooth, which only a moving lever does: one heard more
    than four frames after the pull's command stopped is not the brake's (the ears' decision
    comes one or two frames after the lever stops on a click: it stops when the class is
    heard). The lever itself follows the command up to about 0.2 s late, so a tooth it slides
    over after a stop for another sound goes uncredited (2078 in the held-out run); crediting
    the arm's sensed motion instead was measured and not taken (see above)."""

    def accept(self, direction: np.ndarray, obs) -> bool:
        return lateral_deg(direction) <= -self.lateral_deg


POLICY_CLASSES["parking-brake"] = ScriptedParkingBrake


# -- the room: turn toward a voice ------------------------------------------------------------------


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def head_pose(obs) -> tuple[float, float, float]:
    """The head's turn on the frame fixed at the episode's start, from the observation: the
    neck's yaw and pitch (rad, proprioception) and the wheelchair's odometry heading (rad; 0
    without a wheelchair, no ``base`` in the observation: the car seat), so that
    ``v = Rz(heading) Rz(neck_yaw) Ry(neck_pitch) v_head``."""
    heading = float(obs["base"][0]) if "base" in obs else 0.0
    return float(obs["joint_pos"][0]), float(obs["joint_pos"][1]), heading


def fixed_azimuth(obs, v_head, *, mirror: bool = False) -> float:
    """Azimuth (rad, + left) in the frame fixed at the episode's start, from a head-frame vector
    (``mirror``: of its front-back mirror image, see :func:`~acoustic_sim.frames.head_to_body_azimuth`),
    the head turned by :func:`head_pose`."""
    yaw, pitch, heading = head_pose(obs)
    return head_to_body_azimuth(v_head, yaw, pitch, heading=heading, mirror=mirror)


class TurnPolicy(TaskPolicy):
    """Gaze at a direction fixed in the room: neck and eyes, and the wheelchair beyond them.

    ``target`` (rad, fixed frame) is set by subclasses; the gaze moves the neck up to
    ``neck_max_deg`` and the eyes up to ``eye_max_deg``; a target beyond ``turn_body_deg``
    of the wheelchair's heading turns the chair on the spot at ``wheel_speed`` (rad/s)
    until it is within ``stop_body_deg``.
    """

    neck_max_deg = 85.0
    eye_max_deg = 28.0
    turn_body_deg = 100.0
    stop_body_deg = 50.0
    wheel_speed = 1.5

    def reset(self, obs, info) -> None:
        super().reset(obs, info)
        self.target: float | None = None
        self.turning_body = False

    def gaze_action(self, obs) -> np.ndarray:
        values = {"left_wheel": 0.0, "right_wheel": 0.0}
        if self.target is not None:
            rel = _wrap(self.target - float(obs["base"][0]))
            if abs(rel) > math.radians(self.turn_body_deg):
                self.turning_body = True
            elif abs(rel) < math.radians(self.stop_body_deg):
                self.turning_body = False
            if self.turning_body:
                w = self.wheel_speed * (1.0 if rel > 0 else -1.0)
                values.update(left_wheel=-w, right_wheel=w)
            neck = float(np.clip(rel, -math.radians(self.neck_max_deg), math.radians(self.neck_max_deg)))
            eye = float(np.clip(rel - neck, -math.radians(self.eye_max_deg), math.radians(self.eye_max_deg)))
            values.update(neck_yaw=neck, eye_yaw=eye)
        return self.layout.action(values)

    def gaze_settled(self, obs) -> bool:
        """The gaze is at the target and the body still."""
        if self.target is None or self.turning_body:
            return False
        rel = _wrap(self.target - float(obs["base"][0]))
        gaze = float(obs["joint_pos"][0]) + float(obs["joint_pos"][2])
        still = abs(float(obs["base"][2])) < 0.05 and float(np.max(np.abs(obs["joint_vel"][:4]))) < 0.1
        return abs(_wrap(rel - gaze)) < math.radians(4.0) and still


class ScriptedCallResponse(TurnPolicy):
    """Turn toward the voice; if nobody is there, remember the direction and wait for the next
    call (a voice from a remembered direction is tried at its front-back mirror image).

    A direction is decided from ``decide_frames`` frames in which the voice was heard with
    a direction (or fewer, at least ``min_frames``, when the voice stops for ``gap_frames``):
    the confidence-weighted circular mean of their azimuths in the fixed frame.
    """

    threshold = 0.5
    min_conf = 0.0
    decide_frames = 8
    min_frames = 3
    gap_frames = 10
    look_s = 0.4
    same_deg = 30.0

    def reset(self, obs, info) -> None:
        super().reset(obs, info)
        self.frames: list[tuple[float, float, float]] = []  # (azimuth, mirrored azimuth, weight)
        self.gap = 0
        self.checked: list[float] = []
        self.settled_steps = 0

    def _mean(self, k: int) -> float:
        w = np.array([f[2] for f in self.frames])
        a = np.array([f[k] for f in self.frames])
        return math.atan2(float(np.sum(w * np.sin(a))), float(np.sum(w * np.cos(a))))

    def _is_checked(self, az: float) -> bool:
        return any(abs(_wrap(az - c)) < math.radians(self.same_deg) for c in self.checked)

    def _decide(self) -> None:
        direct, mirror = self._mean(0), self._mean(1)
        self.frames.clear()
        for candidate in (direct, mirror):
            if not self._is_checked(candidate):
                if self.target is None or abs(_wrap(candidate - self.target)) > math.radians(self.same_deg):
                    self.target = candidate
                    self.settled_steps = 0
                return

    def act(self, obs, info) -> np.ndarray:
        on, d = heard(obs, "human_voice", self.threshold, self.min_conf)
        if on and d is not None:
            w = 0.1 + float(obs["class_conf"][CLASSES.index("human_voice")])
            self.frames.append((fixed_azimuth(obs, d), fixed_azimuth(obs, d, mirror=True), w))
            self.gap = 0
        else:
            self.gap += 1
        if len(self.frames) >= self.decide_frames or (self.gap >= self.gap_frames and len(self.frames) >= self.min_frames):
            self._decide()
        elif self.gap >= self.gap_frames:
            self.frames.clear()
        if self.gaze_settled(obs):
            self.settled_steps += 1
            if self.settled_steps * CONTROL_DT >= self.look_s:  # looked, nobody there
                self.checked.append(self.target)
                if len(self.checked) > 4:
                    self.checked = self.checked[-2:]
                self.settled_steps = -10**9  # until a new target
        action = self.gaze_action(obs)
        self.steps += 1
        return action


POLICY_CLASSES["call-response"] = ScriptedCallResponse
