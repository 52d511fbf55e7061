"""What the pointer is set up with (`PointerParams`) and what one step reports (`CameraView`,
`PointerState`); `vision.pointer` re-exports them."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from vision.detection import Detection, DetectorParams, Window
from vision.dwell import DwellParams, TaughtPoint
from vision.frame import Frame
from vision.geometry import PointEstimate
from vision.tracking2d import Tracking2DParams
from vision.tracking3d import Tracking3DParams


@dataclass(frozen=True)
class PointerParams:
    """Everything tunable about the pointer. `hold_s` applies to the 2-D and 3-D tracks."""

    ball_diameter: float = 0.025
    read_timeout_s: float = 0.25
    hold_s: float = 1.0
    min_distance: float = 0.2  # metres from a camera: bounds the apparent size
    max_distance: float = 4.0
    centre_sigma_px: float = 0.15  # per axis; measured on rendered frames: 0.1-0.13 px
    radius_sigma_px: float = 0.25  # measured: ~0.2 px
    reprojection_gate_px: float = 2.5
    size_ratio_range: tuple[float, float] = (0.65, 1.5)
    max_candidates_per_camera: int = 4
    mono_bridge_s: float = 0.3  # a stereo track may go on single views this long after stereo
    coast_s: float = 0.2  # an unmeasured track is shown (flagged "coasting") this long at most
    offer_after_hits: int = 2  # a new or re-acquired track is offered after this many fixes
    new_track_travel: float = 0.015  # metres a new track must move before it is offered: a
    # hand brings the pointer in, a still look-alike pair never moves
    reacquired_travel: float = 0.005  # the same for the pointer's track picked up again in
    # reach after a gap (an occlusion): it had been offered, remembered look-alikes are refused
    # and the fix is in the hand's reach, so a move of 10x a still fix's noise (~0.5 mm) shows
    # it is the hand
    offer_min_axis_ratio: float = 0.82  # a fix is taught only from whole, round views: a
    offer_min_fill: float = 0.76  # ball partly merged with a red thing has a biased centre
    offer_max_size_ratio: float = 1.17  # (and looks too big or small for its distance)
    clutter_scan_every: int = 5  # frames between whole-image looks for still look-alikes
    clutter_learn_hits: int = 5  # the track must be this well established to learn clutter
    clock_restart_s: float = 0.5  # a frame this much older than the last: the clock restarted
    search_window: bool = True
    detector: DetectorParams = field(default_factory=DetectorParams)
    tracking2d: Tracking2DParams = field(default_factory=Tracking2DParams)
    tracking3d: Tracking3DParams = field(default_factory=Tracking3DParams)
    dwell: DwellParams = field(default_factory=DwellParams)

    def __post_init__(self) -> None:
        if self.ball_diameter <= 0:
            raise ValueError("ball diameter must be positive")
        if self.read_timeout_s <= 0 or self.hold_s < 0:
            raise ValueError("read timeout must be positive and hold time non-negative")
        if not 0 < self.min_distance < self.max_distance:
            raise ValueError("need 0 < min_distance < max_distance")
        if self.coast_s < 0 or self.offer_after_hits < 1:
            raise ValueError("need coast_s >= 0 and offer_after_hits >= 1")

    @property
    def ball_radius(self) -> float:
        return 0.5 * self.ball_diameter

    def to_dict(self) -> dict:
        """Plain JSON-able dict (saved with the session next to profiles and camera models)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> PointerParams:
        nested = {"detector": DetectorParams, "tracking2d": Tracking2DParams,
                  "tracking3d": Tracking3DParams, "dwell": DwellParams}
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = set(data) - names
        if unknown:
            raise ValueError(f"unknown pointer parameters {sorted(unknown)}")
        kw = {k: (nested[k](**v) if k in nested else v) for k, v in data.items()}
        if "size_ratio_range" in kw:
            kw["size_ratio_range"] = tuple(kw["size_ratio_range"])
        return cls(**kw)


@dataclass
class CameraView:
    """What one camera contributed to a step (drawn as an overlay by the UI)."""

    camera_id: str
    status: str = "ok"  # ok | timeout | closed | bad_frame | stale | error
    message: str = ""
    timestamp: float | None = None
    detections: list[Detection] = field(default_factory=list)
    pointer: Detection | None = None  # the detection used for this step's 3-D position
    predicted_px: np.ndarray | None = None  # where the 3-D track expected the ball
    window: Window | None = None  # the search window used (None: whole image)
    frame: Frame | None = None


@dataclass
class PointerState:
    """Result of one `PointerSystem.step()`.

    `position_world` is the 3-D track's estimate, kept (predicted) for up to `hold_s` without a
    measurement so the track can pick the ball up again after an occlusion. It is not what to
    teach or draw: `offered_position` is set only when a camera measured the ball in this very
    frame, in stereo when several cameras run, on an established track (teach from that);
    `drawn_position` adds fixes not fit to teach and at most `coast_s` of coasting, each named
    by `status` (draw coasting as "coasting", never as the pointer).
    """

    timestamp: float
    position_world: np.ndarray | None
    covariance: np.ndarray  # 3x3 of `position_world` (NaN when lost)
    mode: str  # "stereo", "mono" (less accurate) or "lost"
    measured: bool  # a camera measured the ball in this frame (False: predicted only)
    track_id: int | None
    velocity_world: np.ndarray | None = None
    measurement: PointEstimate | None = None  # this frame's raw 3-D point, if any
    cameras: dict[str, CameraView] = field(default_factory=dict)
    taught: TaughtPoint | None = None
    dwell_progress: float = 0.0
    skew_s: float = 0.0  # spread of the frame timestamps used (unsynchronised cameras)
    offered: bool = False  # measured now, on a track confirmed by `offer_after_hits` fixes
    since_measured_s: float = float("inf")  # since the track's last fix fit to teach
    coast_limit_s: float = 0.2

    @property
    def offered_position(self) -> np.ndarray | None:
        """The position that may be taught: this frame's measurement itself (not the filter,
        which single-view fixes or a coast may have pulled), else None."""
        if not self.offered or self.measurement is None:
            return None
        return self.measurement.position_world

    @property
    def coasting(self) -> bool:
        """No fix now, but one fit to teach less than `coast_limit_s` ago: a prediction."""
        return (self.position_world is not None and not self.measured
                and self.since_measured_s <= self.coast_limit_s)

    @property
    def drawn_position(self) -> np.ndarray | None:
        """What the UI may show: a position measured now (offered, or flagged by `status` as
        single view / unconfirmed), or a flagged coasting prediction."""
        if self.offered:
            return self.offered_position
        return self.position_world if (self.measured or self.coasting) else None

    @property
    def status(self) -> str:
        """For the UI: measured, single view (seen by one camera of several: shown, not
        taught), unconfirmed (a new track's first fix), coasting, not measured, or lost."""
        if self.position_world is None:
            return "lost"
        if self.offered:
            return "measured"
        if self.measured:
            return "single view" if self.mode == "mono" else "unconfirmed"
        return "coasting" if self.coasting else "not measured"

    @property
    def detections(self) -> dict[str, list[Detection]]:
        return {cid: v.detections for cid, v in self.cameras.items()}

    @property
    def less_accurate(self) -> bool:
        """True in single-camera mode: the UI must say the depth is a size estimate."""
        return self.mode == "mono"
