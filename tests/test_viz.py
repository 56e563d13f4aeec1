"""Rerun recordings: what a recording holds (read back with rerun's own reader), that logging
leaves the simulation alone, the scene conversion, and every error a user can provoke."""

from __future__ import annotations

import dataclasses

from acoustic_sim.world.snapshot import choose_gl_backend

choose_gl_backend()  # before MuJoCo is imported (when this module is the first to import it)

import mujoco
import numpy as np
import pytest
import rerun as rr

from acoustic_sim.acoustics.hrtf import HRTF
from acoustic_sim.acoustics.sounds import SOUND_CLASSES
from acoustic_sim.auditory.percept import Percept
from acoustic_sim.directions import DirectionGrid
from acoustic_sim.errors import ConfigError
from acoustic_sim.frames import FRAME_RATE
from acoustic_sim.viz import Recorder, RecorderConfig, RecordingError, SceneGeometry, play
from acoustic_sim.viz import blueprint as bp
from acoustic_sim.viz.play import check_recording, how_to_view
from acoustic_sim.viz.sample import SyntheticEpisode, scene_model
from acoustic_sim.world.view import WorldView

N_FRAMES = 40


@pytest.fixture(scope="module")
def grid() -> np.ndarray:
    return DirectionGrid.paper(HRTF.load("kemar")).vectors


@pytest.fixture(scope="module")
def cabin() -> mujoco.MjModel:
    return scene_model("cabin")[0]


def _read(path):
    """Chunks of the recording, and its store entries, with rerun's reader."""
    reader = rr.chunk.RrdReader(path)
    return list(reader.stream()), reader.recordings(), reader.blueprints()


def _frames(chunks, entity=None) -> set[int]:
    out: set[int] = set()
    for c in chunks:
        if c.is_static or (entity is not None and c.entity_path != entity):
            continue
        out.update(c.to_record_batch().column("frame").to_pylist())
    return out


def _column(chunks, entity: str, name: str) -> list:
    values = []
    for c in chunks:
        if c.entity_path == entity and not c.is_static:
            rb = c.to_record_batch()
            if name in rb.schema.names:
                values.extend(rb.column(name).to_pylist())
    return values


@pytest.fixture(scope="module")
def recording(tmp_path_factory, cabin, grid):
    path = tmp_path_factory.mktemp("viz") / "episode.rrd"
    episode = SyntheticEpisode(cabin, grid, seed=3, camera=False)
    cfg = RecorderConfig(application_id="acoustic_sim_test", flush_every=16, camera_every=2)
    with Recorder.open(path, cabin, grid, config=cfg) as rec:
        for k in range(N_FRAMES):
            kw = episode.frame(k)
            kw["camera_image"] = np.full((24, 32, 3), k, np.uint8)
            rec.log_frame((k + 1) / FRAME_RATE, k, **kw)
    assert rec.closed
    return path


def test_recording_reads_back_with_rerun(recording, cabin):
    chunks, recordings, blueprints = _read(recording)
    assert [r.application_id for r in recordings] == ["acoustic_sim_test"]
    assert len(blueprints) == 1  # the default layout travels with the file
    paths = {c.entity_path for c in chunks}
    for entity in (bp.ESTIMATED_DIRECTIONS, bp.TRUE_DIRECTIONS, bp.EXISTENCE, bp.SOURCES, bp.HEARING, bp.CAMERA,
                   bp.MEL_LEFT, bp.MEL_RIGHT, bp.PROBABILITIES, bp.WAVEFORM_LEFT, bp.WAVEFORM_RIGHT, bp.EVENTS):
        assert "/" + entity in paths, entity
    # the scene mirrors the model's names: world/<prefix>/<body>/<geom>
    geometry = SceneGeometry(cabin)
    shapes = geometry.shapes()
    assert shapes and {"/" + s.entity for s in shapes} <= paths
    assert any(p.startswith("/world/car/") for p in paths) and any(p.startswith("/world/robot/") for p in paths)
    assert {p for p in paths if p.startswith("/world/robot/head")}
    # one row per ear frame on the frame timeline, and sim_time in seconds
    assert _frames(chunks) == set(range(N_FRAMES))
    assert _frames(chunks, "/" + bp.PROBABILITIES) == set(range(N_FRAMES))
    sim = sorted(t.total_seconds() for t in _column(chunks, "/" + bp.PROBABILITIES, "sim_time"))
    assert sim[0] == pytest.approx(1 / FRAME_RATE) and sim[-1] == pytest.approx(N_FRAMES / FRAME_RATE)


def test_estimated_directions_were_logged(recording):
    chunks, _, _ = _read(recording)
    vectors = _column(chunks, "/" + bp.ESTIMATED_DIRECTIONS, "Arrows3D:vectors")
    labels = _column(chunks, "/" + bp.ESTIMATED_DIRECTIONS, "Arrows3D:labels")
    estimated = [np.asarray(v) for v in vectors if v]
    assert estimated, "no estimated direction arrows in the recording"
    assert all(np.linalg.norm(v, axis=1).min() > 0.1 for v in estimated)
    assert any(any(str(lbl).startswith("reverse_alarm") for lbl in row) for row in labels if row)
    # the existence map: one class id per grid direction in each logged row
    ids = [row for row in _column(chunks, "/" + bp.EXISTENCE, "Points3D:class_ids") if row]
    assert ids and all(len(row) == 327 for row in ids)
    # probabilities: six per frame
    probs = _column(chunks, "/" + bp.PROBABILITIES, "Scalars:scalars")
    assert len(probs) == N_FRAMES and all(len(p) == len(SOUND_CLASSES) for p in probs)


def test_camera_and_events(recording):
    chunks, _, _ = _read(recording)
    assert _frames(chunks, "/" + bp.CAMERA) == set(range(0, N_FRAMES, 2))  # camera_every=2
    media = _column(chunks, "/" + bp.CAMERA, "EncodedImage:media_type")
    assert media and all(m == ["image/jpeg"] for m in media)
    texts = [t for row in _column(chunks, "/" + bp.EVENTS, "TextLog:text") for t in (row if isinstance(row, list) else [row])]
    assert any("alarm started" in t for t in texts)


def test_room_scene_records(tmp_path, grid):
    room, source = scene_model("room")
    episode = SyntheticEpisode(room, grid, seed=0, camera=False)
    path = tmp_path / "room.rrd"
    with Recorder.open(path, room, grid) as rec:
        for k in range(5):
            rec.log_frame((k + 1) / FRAME_RATE, k, **episode.frame(k))
    chunks, _, _ = _read(path)
    paths = {c.entity_path for c in chunks}
    for prefix in ("/world/wheelchair/", "/world/person/", "/world/robot/"):
        assert any(p.startswith(prefix) for p in paths), (prefix, source)
    assert _frames(chunks) == set(range(5))


def test_sound_events_are_spelled_out(tmp_path):
    from acoustic_sim.world.events import SoundEvent

    ev = SoundEvent(kind="ratchet_click", label="ratchet", source="brake_pawl", sample=705, level_db=70.0, detail="3")
    path = tmp_path / "ev.rrd"
    with Recorder.open(path) as rec:
        rec.log_frame(0.016, 0, events=[ev, "hand released"])
    chunks, _, _ = _read(path)
    texts = _column(chunks, "/" + bp.EVENTS, "TextLog:text")
    flat = [t for row in texts for t in (row if isinstance(row, list) else [row])]
    assert flat == ["ratchet_click: ratchet from brake_pawl (3)", "hand released"]


def _copy(value):
    if isinstance(value, np.ndarray):
        return value.copy()
    if isinstance(value, (list, tuple)):
        return type(value)(_copy(v) for v in value)
    if isinstance(value, dict):
        return {k: _copy(v) for k, v in value.items()}
    if dataclasses.is_dataclass(value):
        return dataclasses.replace(value, **{f.name: _copy(getattr(value, f.name)) for f in dataclasses.fields(value)
                                             if not f.name.startswith("_")})
    return value


def _equal(a, b) -> bool:
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if dataclasses.is_dataclass(a):
        return all(_equal(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    return a == b


def test_logging_does_not_mutate_inputs(tmp_path, cabin, grid):
    episode = SyntheticEpisode(cabin, grid, seed=1, camera=False)
    np.random.seed(1234)
    global_state = np.random.get_state()[1].copy()
    with Recorder.open(tmp_path / "m.rrd", cabin, grid, config=RecorderConfig(flush_every=3)) as rec:
        for k in range(8):
            kw = episode.frame(k)
            kw["camera_image"] = np.arange(24 * 32 * 3, dtype=np.uint8).reshape(24, 32, 3)
            view = kw.pop("view")
            data = episode.data
            before = _copy(kw)
            state = {f: getattr(data, f).copy() for f in ("qpos", "qvel", "xpos", "xquat", "xmat", "ctrl", "act")}
            t_before = data.time
            rec.log_frame((k + 1) / FRAME_RATE, k, view=view, **kw)
            assert _equal(kw, before)
            assert all(np.array_equal(getattr(data, f), v) for f, v in state.items()) and data.time == t_before
    assert np.array_equal(np.random.get_state()[1], global_state)  # no use of numpy's global RNG


def test_recording_does_not_change_the_simulation(tmp_path, cabin, grid):
    """Same seed, same trajectory, with and without a recorder in the loop."""

    def rollout(recorder):
        rng = np.random.default_rng(7)
        data = mujoco.MjData(cabin)
        view = WorldView(cabin, data)
        lo, hi = cabin.actuator_ctrlrange.T if cabin.nu else (np.zeros(0), np.zeros(0))
        for k in range(12):
            if cabin.nu:
                data.ctrl[:] = rng.uniform(lo, hi)
            for _ in range(8):
                mujoco.mj_step(cabin, data)
            if recorder is not None:
                recorder.log_frame(data.time, k, view=view, audio_block=rng.standard_normal((2, 705)) * 0 + 0.1,
                                   head_pose=(np.zeros(3), np.eye(3)))
            else:
                rng.standard_normal((2, 705))
        return data.qpos.copy(), data.qvel.copy()

    plain = rollout(None)
    with Recorder.open(tmp_path / "s.rrd", cabin, grid) as rec:
        recorded = rollout(rec)
    assert all(np.array_equal(a, b) for a, b in zip(plain, recorded))


# -- the scene ------------------------------------------------------------------------------------


def _toy_model() -> mujoco.MjModel:
    spec = mujoco.MjSpec()
    w = spec.worldbody
    g = mujoco.mjtGeom
    w.add_geom(name="floor", type=g.mjGEOM_PLANE, size=[0, 0, 0.1], rgba=[0.8, 0.8, 0.8, 1])
    spec.add_hfield(name="terrain", nrow=3, ncol=4, size=[1, 1, 0.2, 0.1], userdata=list(np.linspace(0, 1, 12)))
    w.add_geom(name="bumps", type=g.mjGEOM_HFIELD, hfieldname="terrain", pos=[3, 0, 0])
    spec.add_mesh(name="tet", uservert=[0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1])
    b = w.add_body(name="car/lever", pos=[0.2, 0.1, 1.0], quat=[0.9238795, 0, 0.3826834, 0])
    b.add_joint(name="car/hinge", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0])
    b.add_geom(name="car/knob", type=g.mjGEOM_SPHERE, size=[0.05, 0, 0], pos=[0, 0, 0.2], rgba=[1, 0, 0, 1])
    b.add_geom(name="car/stick", type=g.mjGEOM_CAPSULE, size=[0.01, 0.1, 0])
    b.add_geom(name="car/egg", type=g.mjGEOM_ELLIPSOID, size=[0.01, 0.02, 0.03])
    b.add_geom(name="car/can", type=g.mjGEOM_CYLINDER, size=[0.02, 0.05, 0])
    b.add_geom(name="car/block", type=g.mjGEOM_BOX, size=[0.02, 0.03, 0.04])
    b.add_geom(name="car/tet", type=g.mjGEOM_MESH, meshname="tet")
    b.add_geom(name="car/hidden", type=g.mjGEOM_BOX, size=[0.1, 0.1, 0.1], group=3)
    b.add_geom(name="car/clear", type=g.mjGEOM_BOX, size=[0.1, 0.1, 0.1], rgba=[1, 1, 1, 0])
    tip = b.add_body(name="car/lever/tip", pos=[0, 0, 0.3])
    tip.add_joint(name="car/tip_hinge", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[1, 0, 0])
    tip.add_geom(type=g.mjGEOM_BOX, size=[0.02, 0.02, 0.02])
    return spec.compile()


def test_scene_geometry_paths_shapes_and_poses():
    model = _toy_model()
    geo = SceneGeometry(model)
    assert geo.body_paths == ["world", "world/car/lever", "world/car/lever/tip"]
    shapes = {s.entity: s.kind for s in geo.shapes()}
    assert shapes == {
        "world/floor": "mjGEOM_PLANE", "world/bumps": "mjGEOM_HFIELD", "world/car/lever/knob": "mjGEOM_SPHERE",
        "world/car/lever/stick": "mjGEOM_CAPSULE", "world/car/lever/egg": "mjGEOM_ELLIPSOID",
        "world/car/lever/can": "mjGEOM_CYLINDER", "world/car/lever/block": "mjGEOM_BOX",
        "world/car/lever/tet": "mjGEOM_MESH", "world/car/lever/tip/geom_10": "mjGEOM_BOX",
    }  # group 3 and fully transparent geoms are left out
    data = mujoco.MjData(model)
    data.qpos[:] = [0.4, -0.7]
    mujoco.mj_kinematics(model, data)
    t, q = geo.body_poses(data.xpos, data.xquat)
    # the tip's entity sits under the lever's: its pose is relative, and composes back to xpos/xquat
    r_lever = data.xmat[1].reshape(3, 3)
    np.testing.assert_allclose(t[1], data.xpos[1], atol=1e-6)
    np.testing.assert_allclose(r_lever @ t[2] + data.xpos[1], data.xpos[2], atol=1e-6)
    rel = np.zeros(9)
    mujoco.mju_quat2Mat(rel, np.r_[q[2, 3], q[2, :3]].astype(np.float64))
    np.testing.assert_allclose(r_lever @ rel.reshape(3, 3), data.xmat[2].reshape(3, 3), atol=1e-6)


class _PoseView:
    """The part of ``WorldView`` the recorder reads, for a model without the robot (no ears)."""

    def __init__(self, data: mujoco.MjData) -> None:
        self._data = data

    def body_poses(self):
        return self._data.xpos.copy(), self._data.xquat.copy()


def test_unchanged_bodies_are_not_logged_again(tmp_path):
    model = _toy_model()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    path = tmp_path / "still.rrd"
    with Recorder.open(path, model) as rec:
        for k in range(10):
            if k >= 5:
                data.qpos[0] = 0.1 * k
                mujoco.mj_kinematics(model, data)
            rec.log_frame(k / FRAME_RATE, k, view=_PoseView(data))
    chunks, _, _ = _read(path)
    assert _frames(chunks, "/world/car/lever") == {0, 5, 6, 7, 8, 9}
    assert _frames(chunks, "/world/car/lever/tip") == {0}  # relative to the lever, it never moved


# -- errors ------------------------------------------------------------------------------------------


def test_bad_recording_paths(tmp_path):
    with pytest.raises(RecordingError, match=r"\.rrd"):
        Recorder.open(tmp_path / "episode.txt")
    (tmp_path / "folder.rrd").mkdir()
    with pytest.raises(RecordingError, match="folder"):
        Recorder.open(tmp_path / "folder.rrd")
    (tmp_path / "afile").write_text("x")
    with pytest.raises(RecordingError, match="cannot write"):
        Recorder.open(tmp_path / "afile" / "episode.rrd")


def test_config_errors():
    for bad in ({"flush_every": 0}, {"camera_every": -1}, {"jpeg_quality": 0}, {"existence_levels": 1},
                {"mel_range": (0.0, -1.0)}, {"arrow_length_m": 0.0}, {"application_id": ""},
                {"play_state": "rewinding"}, {"pose_tolerance": -1.0}):
        with pytest.raises(ConfigError):
            RecorderConfig(**bad)
    with pytest.raises(ConfigError, match="grid_vectors"):
        Recorder(rr.RecordingStream("t"), grid_vectors=np.zeros((5, 2)))


def test_tracked_directions_are_drawn_from_the_head(tmp_path, grid):
    """The percept's world-frame tracks are logged as arrows in the head frame, labelled with
    their front-back decision."""
    from acoustic_sim.auditory.tracker import TrackedDirection

    probs = np.zeros(len(SOUND_CLASSES), np.float32)
    track = TrackedDirection(world_vector=np.array([0.0, 1.0, 0.0]), azimuth_deg=90.0, elevation_deg=0.0,
                             head_vector=np.array([-1.0, 0.0, 0.0]), head_azimuth_deg=180.0, head_elevation_deg=0.0,
                             front=False, decided=True, margin_nats=5.0, confidence=0.9, frames=12)
    p = Percept(frame=0, time_s=0.016, classes=SOUND_CLASSES, probabilities=probs, detected=(),
                tracked={"human_voice": track})
    path = tmp_path / "t.rrd"
    with Recorder.open(path, None, grid) as rec:
        rec.log_frame(0.016, 0, percept=p, head_pose=(np.zeros(3), np.eye(3)))
    chunks, _, _ = _read(path)
    labels = [row for row in _column(chunks, "/" + bp.TRACKED_DIRECTIONS, "Arrows3D:labels") if row]
    vectors = [np.asarray(v) for v in _column(chunks, "/" + bp.TRACKED_DIRECTIONS, "Arrows3D:vectors") if v]
    assert labels == [["human_voice decided"]]
    assert vectors[0][0][0] < 0 and abs(vectors[0][0][1]) < 1e-6  # behind the head, as the track says


def test_log_frame_errors(tmp_path, grid):
    rec = Recorder.open(tmp_path / "e.rrd", None, grid)
    with pytest.raises(RecordingError, match="audio_block"):
        rec.log_frame(0.0, 0, audio_block=np.zeros(705))
    with pytest.raises(RecordingError, match="camera_image"):
        rec.log_frame(0.0, 0, camera_image=np.zeros((4, 4, 3), np.float32))
    with pytest.raises(RecordingError, match="frame"):
        rec.log_frame(0.0, -1)
    with pytest.raises(RecordingError, match="time_s"):
        rec.log_frame(float("nan"), 0)
    other = Percept(frame=0, time_s=0.0, classes=("a", "b"), probabilities=np.zeros(2, np.float32), detected=())
    with pytest.raises(RecordingError, match="classes"):
        rec.log_frame(0.0, 0, percept=other)
    rec.close()
    rec.close()  # twice is fine
    with pytest.raises(RecordingError, match="closed"):
        rec.log_frame(0.0, 1)


# -- play ---------------------------------------------------------------------------------------------


def test_play_errors(tmp_path):
    with pytest.raises(RecordingError, match="does not exist"):
        play(tmp_path / "missing.rrd")
    (tmp_path / "notes.txt").write_text("hello")
    with pytest.raises(RecordingError, match=r"\.rrd"):
        play(tmp_path / "notes.txt")
    (tmp_path / "junk.rrd").write_bytes(b"this is not a recording")
    with pytest.raises(RecordingError, match="not a rerun recording"):
        play(tmp_path / "junk.rrd")
    (tmp_path / "dir.rrd").mkdir()
    with pytest.raises(RecordingError, match="not a file"):
        play(tmp_path / "dir.rrd")


def test_play_without_display_says_how_to_view(recording, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    assert check_recording(recording) == recording
    assert play(recording) == 0
    out = capsys.readouterr().out
    assert "No display" in out and f"rerun {recording}" in out and "--web-viewer" in out
    assert out == how_to_view(recording)


# -- task episodes through the runner's hook (fast auditory models) --------------------------------


def _rows(chunks, entity: str, column: str) -> list[tuple[int, object]]:
    """(frame, value) of every row of ``entity`` that has ``column``, in frame order."""
    out = []
    for c in chunks:
        if c.entity_path == entity and not c.is_static:
            rb = c.to_record_batch()
            if column in rb.schema.names:
                out += zip(rb.column("frame").to_pylist(), rb.column(column).to_pylist())
    return sorted(out, key=lambda r: r[0])


def _seconds(chunks, entity: str) -> list[float]:
    import pyarrow as pa

    out = []
    for c in chunks:
        if c.entity_path == entity and not c.is_static:
            out += [ns / 1e9 for ns in c.to_record_batch().column("sim_time").cast(pa.int64()).to_pylist()]
    return sorted(out)


_SAME_EPISODE = r"""
import json, sys
import numpy as np
from apps.runner import make_env, run_episode
from acoustic_sim.viz.episode import EpisodeRecorder
from acoustic_sim.viz.recorder import RecorderConfig
from policies import make_policy

def collect(trace):
    def hook(env, episode, step, obs, reward, terminated, truncated, info):
        audio = None if step == 0 else env.unwrapped.last_audio.copy()
        trace.append((step, {k: v.copy() for k, v in obs.items()}, reward, terminated, truncated,
                      [dict(e) for e in info["events"]], audio))
    return hook

env = make_env("reverse-alarm", profile="fast", max_episode_s=1.0)
plain, recorded = [], []
record_plain = run_episode(env, make_policy("scripted", env), 4, step_callback=collect(plain))
rec = EpisodeRecorder(sys.argv[1], config=RecorderConfig(camera_every=1, flush_every=7))
hook = collect(recorded)
def both(*args):
    rec(*args)
    hook(*args)
with rec:
    record_recorded = run_episode(env, make_policy("scripted", env), 4, step_callback=both)
mismatch = None
for a, b in zip(plain, recorded):
    if a[0] != b[0] or a[2:6] != b[2:6]:
        mismatch = [a[0], "step, reward, end or events"]
    elif a[1].keys() != b[1].keys():
        mismatch = [a[0], "observation keys"]
    else:
        bad = [k for k in a[1] if a[1][k].dtype != b[1][k].dtype or not np.array_equal(a[1][k], b[1][k])]
        if bad:
            mismatch = [a[0], bad[0]]
        elif not ((a[6] is None and b[6] is None) or np.array_equal(a[6], b[6])):
            mismatch = [a[0], "audio"]
    if mismatch:
        break
keys = ("outcome", "events", "steps", "release_s", "gear")
print(json.dumps({"steps": [len(plain), len(recorded)], "mismatch": mismatch, "camera": rec.camera,
                  "records": [record_plain.get(k) == record_recorded.get(k) for k in keys],
                  "classes_heard": int(sum(bool(np.any(t[1]["class_conf"] > 0)) for t in plain))}))
"""


def _python(code: str, *args: str) -> dict:
    """Run ``code`` in a fresh interpreter (which picks its own offscreen OpenGL backend before
    MuJoCo is imported, whatever this process imported) and return the JSON it prints last."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    root = str(Path(__file__).resolve().parents[1])
    out = subprocess.run([sys.executable, "-c", code, *args], cwd=root, capture_output=True, text=True, timeout=900,
                         check=False)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_recording_through_the_runner_hook_does_not_change_the_episode(tmp_path):
    """Same seed: bit-identical observations, rewards, events and ear blocks over 62 steps of
    ReverseAlarm (fast models; seed 4 has the radio, heard with directions) with and
    without a recording, eye camera rendered every step, attached through the runner's hook."""
    r = _python(_SAME_EPISODE, str(tmp_path / "same.rrd"))
    assert r["steps"] == [63, 63]  # the reset and 62 steps, both times
    assert r["mismatch"] is None, r["mismatch"]
    assert all(r["records"])
    assert r["classes_heard"] > 5  # the percepts had directions: there was something to disturb
    assert r["camera"]  # the eye camera did render, every step
    chunks, _, _ = _read(tmp_path / "same.rrd")
    assert len(_rows(chunks, "/" + bp.CAMERA, "EncodedImage:blob")) == 63


def test_run_rrd_records_an_episode_that_reads_back(tmp_path):
    """``acoustic-sim run ... --rrd FILE``: one episode, read back with rerun's own reader."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    rrd = tmp_path / "ep.rrd"
    out = subprocess.run([sys.executable, "-m", "acoustic_sim.cli", "run", "reverse-alarm", "--policy", "scripted",
                          "--episodes", "1", "--seed", "0", "--profile", "fast", "--out", str(tmp_path), "--rrd", str(rrd)],
                         cwd=Path(__file__).resolve().parents[1], capture_output=True, text=True, timeout=900, check=False)
    assert out.returncode == 0, out.stderr[-3000:]
    assert f"acoustic-sim play {rrd}" in out.stdout and "warning" not in out.stderr
    record = json.loads((tmp_path / "episodes.json").read_text())["records"][0]
    assert check_recording(rrd) == rrd
    chunks, recordings, blueprints = _read(rrd)
    assert len(recordings) == 1 and len(blueprints) == 1
    paths = {c.entity_path for c in chunks}
    for entity in (bp.ESTIMATED_DIRECTIONS, bp.TRUE_DIRECTIONS, bp.EXISTENCE, bp.SOURCES, bp.HEARING, bp.EYE_FRUSTUM,
                   bp.CAMERA, bp.MEL_LEFT, bp.MEL_RIGHT, bp.PROBABILITIES, bp.WAVEFORM_LEFT, bp.WAVEFORM_RIGHT, bp.EVENTS):
        assert "/" + entity in paths, entity
    assert {"/world/car/gearshift_lever", "/world/robot/head"} <= paths
    # one frame per step plus the reset, on all three timelines
    n = record["steps"] + 1
    assert _frames(chunks) == set(range(n))
    assert [f for f, _ in _rows(chunks, "/" + bp.PROBABILITIES, "Scalars:scalars")] == list(range(n))
    sim = _seconds(chunks, "/" + bp.PROBABILITIES)
    assert sim[0] == 0.0 and sim[-1] == pytest.approx(record["steps"] / FRAME_RATE, abs=1e-3)
    episodes = {e for c in chunks if not c.is_static for e in c.to_record_batch().column("episode").to_pylist()}
    assert episodes == {0}
    camera = [f for f, _ in _rows(chunks, "/" + bp.CAMERA, "EncodedImage:blob")]
    assert camera == list(range(0, n, 4))  # every 4th step
    # the estimated directions: unit arrows (0.5 m long) of the detected classes, the alarm among them
    est = [(f, v) for f, v in _rows(chunks, "/" + bp.ESTIMATED_DIRECTIONS, "Arrows3D:labels") if v]
    assert est and any(str(label).startswith("reverse_alarm") for _, row in est for label in row)
    vectors = [np.asarray(v) for _, v in _rows(chunks, "/" + bp.ESTIMATED_DIRECTIONS, "Arrows3D:vectors") if v]
    assert vectors and all(np.allclose(np.linalg.norm(v, axis=1), 0.5, atol=1e-4) for v in vectors)
    # the car's alarm is drawn where it is: a true arrow labelled with its source
    true = [row for _, row in _rows(chunks, "/" + bp.TRUE_DIRECTIONS, "Arrows3D:labels") if row]
    assert any("alarm" in row for row in true) == (record["target_onset_s"] is not None)
    text = [t for _, row in _rows(chunks, "/" + bp.EVENTS, "TextLog:text") for t in row]
    assert text[0] == "episode 0, seed 0: reverse-alarm starts"
    assert text[-1].startswith("episode 0 ends: ")
    if record["release_s"] is not None:
        assert any(t.startswith("the hand lets go") for t in text)


def test_several_episodes_follow_each_other_in_one_recording(tmp_path):
    from apps.runner import run_episodes

    rrd = tmp_path / "two.rrd"
    result = run_episodes("reverse-alarm", "blind", 2, 5, tmp_path, profile="fast", progress=False, rrd=rrd, camera=False)
    steps = [r["steps"] for r in result["records"]]
    chunks, recordings, _ = _read(rrd)
    assert len(recordings) == 1
    assert _frames(chunks) == set(range(steps[0] + steps[1] + 2))
    by_episode: dict[int, list[int]] = {}
    for c in chunks:
        if c.entity_path == "/" + bp.PROBABILITIES and not c.is_static:
            rb = c.to_record_batch()
            for f, e in zip(rb.column("frame").to_pylist(), rb.column("episode").to_pylist()):
                by_episode.setdefault(e, []).append(f)
    assert sorted(by_episode[0]) == list(range(steps[0] + 1))
    assert sorted(by_episode[1]) == list(range(steps[0] + 1, steps[0] + steps[1] + 2))
    sim = _seconds(chunks, "/" + bp.PROBABILITIES)
    end0, start1 = sim[steps[0]], sim[steps[0] + 1]
    assert end0 == pytest.approx(steps[0] / FRAME_RATE, abs=1e-3)
    assert start1 == pytest.approx(end0 + 1.0)  # the 1 s gap
    assert not _rows(chunks, "/" + bp.CAMERA, "EncodedImage:blob")  # camera=False
    text = [t for _, row in _rows(chunks, "/" + bp.EVENTS, "TextLog:text") for t in row]
    assert "episode 1, seed 6: reverse-alarm starts" in text


def test_episode_recording_errors(tmp_path, cabin):
    from acoustic_sim.cli import main
    from acoustic_sim.viz.episode import EpisodeRecorder

    with pytest.raises(RecordingError, match=r"\.rrd"):
        EpisodeRecorder(tmp_path / "episode.txt")
    with pytest.raises(ConfigError, match="gap_s"):
        EpisodeRecorder(tmp_path / "x.rrd", gap_s=-1.0)
    unused = EpisodeRecorder(tmp_path / "unused.rrd")
    assert (tmp_path / "unused.rrd").is_file()
    unused.close()
    assert not (tmp_path / "unused.rrd").exists()  # nothing recorded, nothing left behind
    # the command line checks the file before it loads any model or runs anything
    assert main(["run", "reverse-alarm", "--episodes", "1", "--out", str(tmp_path / "o"), "--rrd",
                 str(tmp_path / "episode.txt")]) == 2
    assert main(["run", "reverse-alarm", "--episodes", "1", "--out", str(tmp_path / "o"), "--no-camera"]) == 2
    assert not (tmp_path / "o" / "episodes.json").exists()
    with pytest.raises(ConfigError, match="not a camera"):
        Recorder(rr.RecordingStream("t"), model=cabin, eye_camera="robot/nose")
    with pytest.raises(ConfigError, match="model"):
        Recorder(rr.RecordingStream("t"), eye_camera="robot/eye_right")
    rec = Recorder.open(tmp_path / "e.rrd", cabin)
    with pytest.raises(RecordingError, match="episode"):
        rec.set_episode(-1)
    with pytest.raises(RecordingError, match="body_poses"):
        rec.log_frame(0.0, 0, view=_PoseView(mujoco.MjData(_toy_model())))
    rec.close()
    with pytest.raises(RecordingError, match="closed"):
        rec.set_episode(1)
