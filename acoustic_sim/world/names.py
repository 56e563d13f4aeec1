"""Names of the MuJoCo elements that the rest of the project relies on.

The composed scenes (``scenes.py``) attach each asset under a prefix; the view (``view.py``)
looks elements up by these full names and by nothing else, so an asset can be rebuilt
without touching the code that reads it. World frame: MuJoCo's, z up. The robot faces +x.
"""

from __future__ import annotations

# Prefixes used by scenes.py when attaching assets with MjSpec.attach(..., prefix=...).
ROBOT = "robot/"
CAR = "car/"
WHEELCHAIR = "wheelchair/"
PERSON = "person/"
BYSTANDERS = ("bystander1/", "bystander2/")  # the room's other people (the same asset as the person)
SPEAKER = "speaker/"

# -- robot (assets/musashi_head + upper body) --------------------------------------------
HEAD_BODY = ROBOT + "head"
EAR_LEFT_SITE = ROBOT + "ear_left"  # ear-canal entrance, left (+y in the head frame)
EAR_RIGHT_SITE = ROBOT + "ear_right"
EYE_CAMERAS = (ROBOT + "eye_left", ROBOT + "eye_right")  # cameras, looking along the head's +x
NECK_JOINTS = (ROBOT + "neck_yaw", ROBOT + "neck_pitch")  # yaw +-90 deg (+ = left), pitch +-45 deg (+ = nose down)
EYE_JOINTS = (ROBOT + "eye_yaw", ROBOT + "eye_pitch")  # both eyes move together (one pair of joints drives both)
ARM_SIDES = ("left", "right")
ARM_JOINT_SUFFIXES = ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow", "wrist")


def arm_joints(side: str) -> tuple[str, ...]:
    """Joint (and position-actuator) names of one arm, shoulder to wrist."""
    return tuple(f"{ROBOT}{side}_{s}" for s in ARM_JOINT_SUFFIXES)


def hand_body(side: str) -> str:
    return f"{ROBOT}{side}_hand"


def grasp_site(side: str) -> str:
    """Site at the palm centre; a grasp attaches the lever handle here."""
    return f"{ROBOT}{side}_palm"


ROBOT_ROOT_BODY = ROBOT + "torso"  # origin at the seated robot's hip point (H-point)
EAR_SPACING_M = 0.152
"""Distance (m) between the ear-canal entrances: the KEMAR head breadth (Burkhard & Sachs 1975),
the head of the bundled MIT KEMAR HRTF (assets/musashi_head/README.md)."""
GRASP_TARGET_BODIES = {"left": CAR + "gearshift_lever", "right": CAR + "brake_lever"}
"""Lever body each hand grasps in the cabin: the gearshift on the left, the brake on the right."""
GRASP_TARGET_SITES = {"left": CAR + "gearshift_knob", "right": CAR + "brake_handle"}
"""Handle site of each hand's lever; the palm must be this close to grasp (scene.grasp)."""


def grasp_equality(side: str) -> str:
    """Equality (cabin scene; a ball-joint ``connect``) that holds this hand on its lever while active."""
    return f"{ROBOT}{side}_grasp"


# -- car cabin (assets/car_cabin) ----------------------------------------------------------
CABIN_INTERIOR_SITE = CAR + "interior"  # box-typed site: the cabin's interior air volume (the acoustic room)
ALARM_SPEAKER_SITE = CAR + "alarm_speaker"  # dashboard, about 0.8 m in front of the head
GEARSHIFT_JOINT = CAR + "gearshift"  # hinge; positions P, R, N, D in this order, + = toward D
GEARSHIFT_KNOB_SITE = CAR + "gearshift_knob"
GEARSHIFT_HANDLE_BODY = CAR + "gearshift_lever"
BRAKE_JOINT = CAR + "brake"  # hinge; + = pulled up
BRAKE_HANDLE_SITE = CAR + "brake_handle"
BRAKE_HANDLE_BODY = CAR + "brake_lever"
BRAKE_PAWL_SITE = CAR + "brake_pawl"  # where the ratchet clicks come from
IGNITION_SITE = CAR + "ignition"
HORN_SITE = CAR + "horn"  # front grille (distractor "outside the cabin")
GEAR_NAMES = ("P", "R", "N", "D")
# Mechanism geometry, declared by the cabin asset as MuJoCo custom numerics (<custom><numeric>)
# and read by view.py; the asset's detent bumps and ratchet pins sit at these angles.
GEAR_DETENTS_NUMERIC = CAR + "gear_detents"  # joint angle (rad) of each detent, in GEAR_NAMES order
BRAKE_TEETH_NUMERIC = CAR + "brake_teeth"  # lever angle (rad) at which it rests on tooth k, k = 1..n
BRAKE_PAWL_JOINT = CAR + "pawl"  # hinge of the ratchet pawl; a pin passing lifts it, its snap back is the click
BRAKE_RELEASE_ACTUATOR = CAR + "brake_release"  # motor on the pawl, ctrl 0..1: the release button (1 lifts the pawl)
GEAR_DETENT_JOINT = CAR + "gear_detent"  # slide joint of the spring-loaded detent roller under the gearshift
CABIN_SEAT_SITE = CAR + "driver_seat"  # the driver's hip point; the robot's torso is attached here
GEAR_DETENT_ANGLES_DEG = (0.0, 15.0, 30.0, 45.0)  # the asset's GEAR_DETENTS_NUMERIC, in degrees
BRAKE_TOOTH_ANGLES_DEG = (8.0, 15.0, 22.0, 29.0, 36.0, 43.0, 50.0)  # the asset's BRAKE_TEETH_NUMERIC, in degrees

# -- wheelchair room (assets/wheelchair) ---------------------------------------------------
WHEELCHAIR_ROOT_JOINT = WHEELCHAIR + "root"  # free joint of the chassis
WHEEL_JOINTS = (WHEELCHAIR + "left_wheel", WHEELCHAIR + "right_wheel")  # velocity actuators of the same names
ROOM_INTERIOR_SITE = "room_interior"  # box-typed site: the room's air volume
PERSON_ROOT_BODY = PERSON + "body"  # mocap body: place the person anywhere
PERSON_HEAD_BODY = PERSON + "head"
PERSON_MOUTH_SITE = PERSON + "mouth"
BYSTANDER_HEAD_BODIES = tuple(b + "head" for b in BYSTANDERS)
LOUDSPEAKER_SITE = SPEAKER + "cone"  # distractor loudspeaker (mocap)
WHEELCHAIR_CHASSIS_BODY = WHEELCHAIR + "chassis"  # carries the free joint; origin on the floor between the wheels
WHEELCHAIR_SEAT_SITE = WHEELCHAIR + "seat"  # the robot's hip point on the wheelchair
LOUDSPEAKER_BODY = SPEAKER + "body"  # mocap body of the loudspeaker: place it anywhere
