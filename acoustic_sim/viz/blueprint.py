"""Entity paths of a recording and the default layout that opens it readable.

Layout (left to right): the 3D scene with the sound overlay above the event log; the eye
camera, the two mel spectrograms, the class probabilities and the ear waveforms. Time series
show the last 10 s around the time cursor on the ``sim_time`` timeline.
"""

from __future__ import annotations

import rerun.blueprint as rrb

WORLD = "world"
HEARING = "world/hearing"  # the head frame (x forward, y left, z up), posed every frame
TRUE_DIRECTIONS = "world/hearing/true"
ESTIMATED_DIRECTIONS = "world/hearing/estimated"
TRACKED_DIRECTIONS = "world/hearing/tracked"  # the world-frame tracker's directions, seen from the head
EXISTENCE = "world/hearing/existence"
SOURCES = "world/sources"
EYE_FRUSTUM = "world/eye_camera"  # the eye camera's frustum in the scene, posed every frame
CAMERA = "camera/eye"
MEL_LEFT = "audio/mel/left"
MEL_RIGHT = "audio/mel/right"
WAVEFORM = "audio/waveform"
WAVEFORM_LEFT = "audio/waveform/left"
WAVEFORM_RIGHT = "audio/waveform/right"
PROBABILITIES = "percept/probabilities"
EVENTS = "events"

TIMELINE = "sim_time"
FRAME_TIMELINE = "frame"
EPISODE_TIMELINE = "episode"  # only in recordings of several episodes (Recorder.set_episode)


def default_blueprint(*, history_s: float = 10.0, look_target=None, eye_position=None,
                      play_state: str | None = "following") -> rrb.Blueprint:
    """The layout a recording opens with (scene, camera, spectrograms, probabilities, log).

    Parameters
    ----------
    history_s : float
        Seconds of history shown by the time-series views, ending at the time cursor.
    look_target, eye_position : (3,) world coordinates, optional
        Where the 3D view looks from and at (orbiting around the target); rerun frames the
        whole scene when they are not given.
    play_state : str or None
        ``following`` (default: open at the newest data, so a finished recording opens on its
        last frame with every view filled), ``paused``, ``playing``, or ``None`` for rerun's
        default.
    """
    recent = rrb.VisibleTimeRange(
        TIMELINE,
        start=rrb.TimeRangeBoundary.cursor_relative(seconds=-float(history_s)),
        end=rrb.TimeRangeBoundary.cursor_relative(seconds=0.0),
    )
    eye = None
    if look_target is not None and eye_position is not None:
        eye = rrb.EyeControls3D(kind=rrb.Eye3DKind.Orbital, position=[float(v) for v in eye_position],
                                look_target=[float(v) for v in look_target], eye_up=[0.0, 0.0, 1.0])
    kinds = rrb.encodings.TextLogColumnKind
    left = rrb.Vertical(
        rrb.Spatial3DView(origin=WORLD, name="Scene and hearing", eye_controls=eye),
        rrb.TextLogView(
            origin=EVENTS, name="Events",
            columns=rrb.TextLogColumns(
                timeline_columns=[rrb.encodings.TimelineColumn(TIMELINE), rrb.encodings.TimelineColumn(FRAME_TIMELINE, visible=False)],
                text_log_columns=[rrb.encodings.TextLogColumn(kinds.Body),
                                  rrb.encodings.TextLogColumn(kinds.EntityPath, visible=False),
                                  rrb.encodings.TextLogColumn(kinds.LogLevel, visible=False)],
            ),
        ),
        row_shares=[4, 1],
    )
    right = rrb.Vertical(
        rrb.Spatial2DView(origin=CAMERA, name="Eye camera"),
        rrb.Horizontal(
            rrb.Spatial2DView(origin=MEL_LEFT, name="Left ear: mel, last 2 s"),
            rrb.Spatial2DView(origin=MEL_RIGHT, name="Right ear: mel, last 2 s"),
        ),
        rrb.TimeSeriesView(origin=PROBABILITIES, name="Class probabilities", time_ranges=[recent],
                           plot_legend=rrb.PlotLegend(rrb.components.Corner2D.LeftTop)),
        rrb.TimeSeriesView(origin=WAVEFORM, name="Ear waveforms (min/max)", time_ranges=[recent],
                           plot_legend=rrb.PlotLegend(visible=False)),
        row_shares=[3, 2, 2, 2],
    )
    return rrb.Blueprint(
        rrb.Horizontal(left, right, column_shares=[3, 2]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed", timeline=TIMELINE, play_state=play_state),
    )
