"""`PointerSystem`: the facade the Session uses. One `step()` reads a frame from every camera,
finds the ball in each, tracks it per camera, turns the views into one 3-D position (stereo
triangulation, or the single-camera size estimate), filters it in 3-D and watches for a dwell.

Failure is reported, never fatal: a camera that times out, has stopped or delivers a frame of
the wrong size is marked in that frame's `CameraView`, and the tracks carry on with the other
cameras (or coast, for up to `hold_s`).

What may be taught is only what a camera measured in the frame at hand (`offered`): coasting
is shown for at most `coast_s` and flagged, a new or re-acquired track is offered only after
`offer_after_hits` fixes, a fix is associated with the track only inside a gate in 3-D (the
Kalman gate, capped by how far a hand can move the ball) and in every image (the search
window), and still look-alikes seen next to the measured ball are remembered and refused.

A ball merged in one view with a background region of its colour is not a blob any more; while
the track is followed it is looked for by its last clean look (`vision.appearance`) inside the
window the track predicts, and such a view is offered only under stricter rules.
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from collections.abc import Mapping, Sequence

import numpy as np

from vision.appearance import AppearanceMemory, AppearanceParams
from vision.camera_model import CameraModel
from vision.clutter import ClutterMemory
from vision.color import DEFAULT_POINTER_RED, ColorProfile
from vision.detection import BlobDetector, Detection, Window, window_around
from vision.dwell import DwellDetector
from vision.errors import CameraClosed, CameraError, CameraTimeout, FrameError
from vision.frame import Frame, validate_image
from vision.geometry import (
    expected_radius_px,
    mono_from_size,
    project_covariance,
    sphere_ray,
)
from vision.pointer_hypotheses import Hypothesis, size_ok, stereo_hypotheses
from vision.pointer_types import CameraView, PointerParams, PointerState
from vision.scene import PointerScene
from vision.sources import FrameSource, synthetic_cameras
from vision.tracking2d import Tracker2D
from vision.tracking3d import Track3D

__all__ = ["CameraView", "PointerParams", "PointerState", "PointerSystem"]


class PointerSystem:
    """Cameras + their calibrations + a colour profile -> pointer positions and taught points."""

    def __init__(self, sources: Sequence[FrameSource],
                 models: Sequence[CameraModel] | Mapping[str, CameraModel],
                 profile: ColorProfile = DEFAULT_POINTER_RED,
                 params: PointerParams | None = None,
                 appearance: AppearanceParams | None = None) -> None:
        if not sources:
            raise CameraError("no camera: connect a camera, pick a video/folder, or use the "
                              "synthetic camera")
        ids = [s.camera_id for s in sources]
        if len(set(ids)) != len(ids):
            raise ValueError(f"camera ids must be unique, got {ids}; give each source an id")
        if isinstance(models, Mapping):
            missing = [i for i in ids if i not in models]
            if missing:
                raise ValueError(f"no camera model (calibration) for {missing}")
            models = [models[i] for i in ids]
        if len(models) != len(sources):
            raise ValueError(f"{len(sources)} cameras but {len(models)} camera models")
        self.sources = list(sources)
        self.models = list(models)
        self.params = params or PointerParams()
        p = self.params
        self._t2 = dataclasses.replace(p.tracking2d, hold_s=p.hold_s)
        self._t3 = dataclasses.replace(p.tracking3d, hold_s=p.hold_s)
        self.profile = profile
        self.trackers2d = [Tracker2D(self._t2) for _ in self.sources]
        self.track = Track3D(self._t3)
        self.dwell = DwellDetector(p.dwell)
        self._radius_ranges = [
            (m.focal_px * p.ball_radius / p.max_distance, m.focal_px * p.ball_radius
             / p.min_distance) for m in self.models]
        self._last_stamp: list[float | None] = [None] * len(self.sources)
        self._pointer_track2d: list[int | None] = [None] * len(self.sources)
        self.clutter = ClutterMemory(len(self.sources))
        self.appearance = AppearanceMemory(len(self.sources), appearance)
        self._gate_px: list[tuple[np.ndarray, float] | None] = [None] * len(self.sources)
        self._steps = 0
        self._measured_last = True
        self._last_stereo_t: float | None = None
        self._last_offered: tuple[int | None, float] = (None, 0.0)
        self._time: float | None = None
        self._wall_at_time = 0.0
        self.last_state: PointerState | None = None

    # -- configuration ------------------------------------------------------------------------
    @property
    def profile(self) -> ColorProfile:
        return self._profile

    @profile.setter
    def profile(self, profile: ColorProfile) -> None:
        """Switch or recalibrate the colour profile; tracks are kept."""
        self._profile = profile
        self.detector = BlobDetector(profile, self.params.detector)

    @property
    def camera_ids(self) -> list[str]:
        return [s.camera_id for s in self.sources]

    def reset(self) -> None:
        """Forget all tracks and any dwell in progress (cameras stay open)."""
        for tr in self.trackers2d:
            tr.reset()
        self.track.reset()
        self.dwell.reset()
        self.clutter.reset()
        self.appearance.reset()
        self._last_stereo_t = None
        self._last_offered = (None, 0.0)
        self._pointer_track2d = [None] * len(self.sources)
        self._last_stamp = [None] * len(self.sources)
        self._time = None
        self.last_state = None

    def close(self) -> None:
        for s in self.sources:
            with contextlib.suppress(Exception):  # closing must not fail: the camera is gone
                s.close()

    # -- one step -----------------------------------------------------------------------------
    def _read(self) -> tuple[dict[int, Frame], list[CameraView]]:
        frames: dict[int, Frame] = {}
        views: list[CameraView] = []
        for i, (src, model) in enumerate(zip(self.sources, self.models, strict=True)):
            view = CameraView(src.camera_id)
            views.append(view)
            try:
                fr = src.read(self.params.read_timeout_s)
                validate_image(fr.image, model.width, model.height, src.camera_id)
            except CameraTimeout as exc:
                view.status, view.message = "timeout", str(exc)
                continue
            except CameraClosed as exc:
                view.status, view.message = "closed", str(exc)
                continue
            except FrameError as exc:
                view.status, view.message = "bad_frame", str(exc)
                continue
            except Exception as exc:  # a broken driver is reported, never fatal
                view.status, view.message = "error", f"camera {src.camera_id!r}: {exc}"
                continue
            view.timestamp = fr.timestamp
            view.frame = fr
            last = self._last_stamp[i]
            if last is not None and last - self.params.clock_restart_s < fr.timestamp <= last:
                view.status = "stale"
                view.message = f"camera {src.camera_id!r} repeated an old frame"
                continue
            self._last_stamp[i] = fr.timestamp
            frames[i] = fr
        return frames, views

    def _clock(self, frames: dict[int, Frame]) -> float:
        now = time.monotonic()
        if frames:
            t = max(f.timestamp for f in frames.values())
        elif self._time is None:
            t = 0.0
        else:  # no camera delivered: let time pass so a held track expires
            t = self._time + (now - self._wall_at_time)
        if self._time is not None and t < self._time:
            # a source restarted its clock (looped file, reconnected camera): start afresh
            for tr in self.trackers2d:
                tr.reset()
            self.track.reset()
            self.dwell.reset()
        self._time = t
        self._wall_at_time = now
        return t

    def _search(self, i: int, frame: Frame, view: CameraView) -> list[Detection]:
        p = self.params
        model = self.models[i]
        window: Window | None = None
        radius_range = self._radius_ranges[i]
        self._gate_px[i] = None
        if self.track.active:
            X = self.track.filter.position
            uv = model.project(X)
            r_exp = expected_radius_px(model, X, p.ball_radius)
            if np.all(np.isfinite(uv)) and np.isfinite(r_exp):
                cov_px = project_covariance(model, X, self.track.filter.position_cov)
                sd = float(np.sqrt(max(np.linalg.eigvalsh(cov_px).max(), 0.0)))
                self._gate_px[i] = (uv, min(4.0 * sd + 2.5 * r_exp + 8.0,
                                            0.5 * min(model.width, model.height)))
        if p.search_window and self.track.active:
            X = self.track.filter.position
            uv = model.project(X)
            r_exp = expected_radius_px(model, X, p.ball_radius)
            if np.all(np.isfinite(uv)) and np.isfinite(r_exp):
                view.predicted_px = uv
                cov_px = project_covariance(model, X, self.track.filter.position_cov)
                sd = float(np.sqrt(max(np.linalg.eigvalsh(cov_px).max(), 0.0)))
                half = min(4.0 * sd + 2.5 * r_exp + 8.0, 0.5 * min(model.width, model.height))
                window = window_around(uv, half, model.width, model.height)
                radius_range = (0.6 * r_exp, 1.6 * r_exp + 1.0)
        elif p.search_window and self._pointer_track2d[i] is not None:
            pred = self.trackers2d[i].predicted(self._pointer_track2d[i], self._time)
            tr = self.trackers2d[i].track(self._pointer_track2d[i])
            if pred is not None and tr is not None:
                sd = float(np.sqrt(max(np.linalg.eigvalsh(pred[1]).max(), 0.0)))
                half = min(4.0 * sd + 2.5 * tr.radius_px + 8.0,
                           0.5 * min(model.width, model.height))
                window = window_around(pred[0], half, model.width, model.height)
                radius_range = (0.6 * tr.radius_px, 1.6 * tr.radius_px + 1.0)
        dets: list[Detection] = []
        if window is not None and window[2] > window[0] and window[3] > window[1]:
            dets = self.detector.detect(frame.image, window, radius_range)
        if not dets:
            window = None
            dets = self.detector.detect(frame.image, None, self._radius_ranges[i])
        elif not self._measured_last:
            # the window holds blobs, yet the last frame found no ball there: the ball may be
            # back elsewhere (after an occlusion), so look at the whole image as well
            more = self.detector.detect(frame.image, None, self._radius_ranges[i])
            dets = dets + [d for d in more if min(np.linalg.norm(d.center_px - e.center_px)
                                                  for e in dets) > 2.0]
            window = None
        view.window = window
        if self._gate_px[i] is not None:
            dets = self._look_for_merged(i, frame, dets)
        return dets

    def _look_for_merged(self, i: int, frame: Frame, dets: list[Detection]) -> list[Detection]:
        """Where the track predicts the ball: do whole blobs there stand alone, and if none
        does, is the ball's look there (`AppearanceMemory.look_near`)? Looked for while the
        track is held, near the prediction only (a bounded cost: a masked match over a 90 px
        square is ~1 ms; a ball farther off is found as a blob or not at all)."""
        p = self.params
        t = self._time if self._time is not None else frame.timestamp
        model, X = self.models[i], self.track.filter.position
        uv, r_exp = model.project(X), expected_radius_px(model, X, p.ball_radius)
        if not (np.all(np.isfinite(uv)) and np.isfinite(r_exp)):
            return dets
        cov_px = project_covariance(model, X, self.track.filter.position_cov)
        sd = float(np.sqrt(max(np.linalg.eigvalsh(cov_px).max(), 0.0)))
        near = min(4.0 * sd + r_exp + 4.0, self._gate_px[i][1], 4.0 * r_exp + 12.0)
        last = self.track.last_measurement_time
        return self.appearance.look_near(
            i, t, frame.image, self.profile, dets, uv, X, near, r_exp,
            last is not None and t - last <= p.hold_s, lambda d: self._whole(d, r_exp))

    def _mono(self, i: int, j: int, d: Detection) -> Hypothesis:
        p = self.params
        model = self.models[i]
        est = mono_from_size(model, sphere_ray(model, d.center_px, d.radius_px), p.ball_radius,
                             p.centre_sigma_px, p.radius_sigma_px)
        return Hypothesis(dataclasses.replace(est, cameras=(i,)), {i: j})

    def _clutter_in(self, h: Hypothesis, dets: dict[int, list[Detection]]) -> bool:
        return any(self.clutter.is_clutter(i, dets[i][j]) for i, j in h.used.items())

    def _in_image_gate(self, h: Hypothesis, dets: dict[int, list[Detection]]) -> bool:
        """Every view of the fix lies within that camera's gate around the track's projection."""
        for i, j in h.used.items():
            g = self._gate_px[i]
            if g is not None and np.linalg.norm(dets[i][j].center_px - g[0]) > g[1]:
                return False
        return True

    def _choose(self, t: float, dets: dict[int, list[Detection]],
                ids2d: dict[int, list[int]], n_delivering: int) -> Hypothesis | None:
        """Pick this frame's measurement (or none) and feed the 3-D track.

        With a track: the stereo candidate nearest in the Mahalanobis sense inside the gate
        (3-D, capped by the hand's speed, and in every image); failing that a single view
        inside the gate, as a brief stand-in (one camera lost the ball for up to
        `mono_bridge_s`) or because that view's blob has been tracked for a few frames (the
        ball is in front of a same-coloured thing in the other view). A fix outside the gate
        is a new candidate, not a jump: it starts a new track only once it has stayed at a
        consistent place for `reinit_after_s`. Remembered still look-alikes are refused
        except while the track is followed frame to frame (the ball may pass over one).
        Without a track: stereo, else a confirmed single-view blob that has moved.
        """
        stereo = stereo_hypotheses(self.models, self.params, dets)
        k = self.params.max_candidates_per_camera
        gate = self._t3.gate_chi2
        fresh_stereo = [h for h in stereo if not self._clutter_in(h, dets)]
        if not self.track.active:
            h = self._best_new(fresh_stereo, dets) if fresh_stereo else \
                self._confirmed_mono(dets, ids2d, n_delivering)
            if h is not None:
                self.track.start(t, h.est)
            return h
        since = t - (self.track.last_measurement_time or t)
        followed = since <= self.params.coast_s

        def ok(h: Hypothesis) -> bool:
            return self._in_image_gate(h, dets) and (followed or not self._clutter_in(h, dets))

        gated = [(d, h) for h in stereo
                 if ok(h) and (d := self.track.gate_distance(h.est)) <= gate]
        if gated:
            h = min(gated, key=lambda g: g[0])[1]
            self.track.update(t, h.est)
            return h
        since_stereo = t - (self._last_stereo_t if self._last_stereo_t is not None else -1e9)
        bridge = n_delivering == 1 or since_stereo <= self.params.mono_bridge_s
        monos = [self._mono(i, j, d) for i, ds in dets.items() for j, d in enumerate(ds[:k])
                 if not self.clutter.is_clutter(i, d)
                 and (bridge or (self.trackers2d[i].is_confirmed(ids2d[i][j])
                                 and (n_delivering <= 1
                                      or self.trackers2d[i].has_moved(ids2d[i][j]))))]
        gated = [(d, h) for h in monos
                 if ok(h) and (d := self.track.gate_distance(h.est)) <= gate]
        fresh = self._best_new(fresh_stereo, dets) if fresh_stereo else \
            (None if gated else self._confirmed_mono(dets, ids2d, n_delivering))
        # a track never confirmed may be a chance fix: a stereo fix elsewhere replaces it at once
        replace = fresh is not None and fresh_stereo and not self.track.confirmed
        if fresh is not None and (replace or self.track.disagreement(t, fresh.est.position_world)):
            self.track.start(t, fresh.est)
            return fresh
        if gated:
            h = min(gated, key=lambda g: g[0])[1]
            self.track.update(t, h.est, keep_disagreement=True)
            return h
        return None

    def _confirmed_mono(self, dets: dict[int, list[Detection]], ids2d: dict[int, list[int]],
                        n_delivering: int = 1) -> Hypothesis | None:
        """The roundest blob seen for `confirm_hits` frames in a row that is no remembered
        look-alike; with other cameras delivering (which do not see it), it must also have
        moved: a still red thing seen by one camera is not taken for the pointer."""
        k = self.params.max_candidates_per_camera
        confirmed = [(d.score, i, j) for i, ds in dets.items() for j, d in enumerate(ds[:k])
                     if self.trackers2d[i].is_confirmed(ids2d[i][j])
                     and not self.clutter.is_clutter(i, d)
                     and (n_delivering <= 1 or self.trackers2d[i].has_moved(ids2d[i][j]))]
        if not confirmed:
            return None
        _, i, j = max(confirmed)
        return self._mono(i, j, dets[i][j])

    def _best_new(self, stereo: list[Hypothesis],
                  dets: dict[int, list[Detection]]) -> Hypothesis:
        """Without a track, prefer more views, then views that agree, then the right size."""
        def cost(h: Hypothesis) -> tuple[float, float]:
            size = size_ok(self.models, self.params, h.est.position_world, h.used, dets) or 0.0
            return (-len(h.used), h.est.reprojection_px / self.params.centre_sigma_px
                    + 10.0 * size)
        return min(stereo, key=cost)

    def step(self) -> PointerState:
        """Process one synchronised frame set; never raises for camera trouble."""
        frames, views = self._read()
        t = self._clock(frames)
        self.track.predict_to(t)
        dets: dict[int, list[Detection]] = {}
        ids2d: dict[int, list[int]] = {}
        for i, fr in frames.items():
            dets[i] = self._search(i, fr, views[i])
            ids2d[i] = self.trackers2d[i].update(t, dets[i])
            views[i].detections = dets[i]
        chosen = self._choose(t, dets, ids2d, len(frames))
        # with several cameras, anything short of stereo means: look at the whole image too
        self._measured_last = chosen is not None and (chosen.est.mode == "stereo"
                                                      or len(frames) < 2)
        if chosen is not None and chosen.est.mode == "stereo":
            self._last_stereo_t = t
        if chosen is not None:
            for i, j in chosen.used.items():
                views[i].pointer = dets[i][j]
                self._pointer_track2d[i] = ids2d[i][j]
        taught = None
        p = self.params
        self._steps += 1
        if self.track.active:
            pos = self.track.filter.position
            meas = chosen.est if chosen is not None else None
            # teach only from fixes of teaching accuracy: with several cameras, stereo ones (a
            # single view's depth, from the ball's size, is good to a few per cent only)
            # a new track must show it moves (a still look-alike never does); the pointer's
            # track picked up again after a gap needs less (`reacquired_travel`)
            travel = p.reacquired_travel if self.track.was_confirmed else p.new_track_travel
            offered = meas is not None and self.track.hits >= p.offer_after_hits and \
                (meas.mode == "stereo" or len(self.sources) == 1) and \
                (self.track.confirmed or self.track.travel >= travel) and \
                self._clean_views(chosen, dets)
            self.track.confirmed |= offered
            if offered:
                self._last_offered = (self.track.track_id, t)
            # coasting counts from the last fix fit to teach, on this same track
            tid, t_off = self._last_offered
            since = t - t_off if tid == self.track.track_id else float("inf")
            if offered:  # a dwell is made of measured frames only
                taught = self.dwell.update(t, pos, meas.position_world, meas.covariance,
                                           self.track.last_mode)
                if meas.mode == "stereo" and self.track.hits >= p.clutter_learn_hits:
                    self._learn_clutter(t, frames, chosen, dets)
                if meas.mode == "stereo":
                    self._learn_looks(t, frames, chosen, dets)
            elif since > p.coast_s:
                self.dwell.update(t, None)  # a gap longer than coasting ends any dwell
            state = PointerState(
                timestamp=t, position_world=pos, covariance=self.track.filter.position_cov,
                mode=self.track.last_mode, measured=meas is not None,
                track_id=self.track.track_id, velocity_world=self.track.filter.velocity,
                measurement=meas, taught=taught, dwell_progress=self.dwell.progress(),
                offered=offered, since_measured_s=since, coast_limit_s=p.coast_s)
        else:
            self.dwell.update(t, None)
            self._pointer_track2d = [
                tid if self.trackers2d[i].track(tid) is not None else None
                for i, tid in enumerate(self._pointer_track2d)]
            state = PointerState(timestamp=t, position_world=None,
                                 covariance=np.full((3, 3), np.nan), mode="lost",
                                 measured=False, track_id=None, coast_limit_s=p.coast_s)
        state.cameras = {v.camera_id: v for v in views}
        if frames:
            stamps = [f.timestamp for f in frames.values()]
            state.skew_s = float(max(stamps) - min(stamps))
        self.last_state = state
        return state

    def _clean_views(self, h: Hypothesis, dets: dict[int, list[Detection]]) -> bool:
        """Every view of the fix is a whole ball: round, filled, and of the size its distance
        implies. A ball partly merged with (or cut by) a thing of its colour still triangulates,
        but a pixel or two off along the epipolar line, which is millimetres in depth."""
        p = self.params
        ap = self.appearance.params
        matched = any(dets[i][j].method != "blob" for i, j in h.used.items())
        for i, j in h.used.items():
            d = dets[i][j]
            r_exp = expected_radius_px(self.models[i], h.est.position_world, p.ball_radius)
            if not self._whole(d, r_exp):
                return False
            if d.method == "appearance" and not d.match >= ap.min_ncc:
                return False
            if d.method != "blob" and h.est.reprojection_px > ap.offer_max_reprojection_px:
                return False  # a look match or an outline: its views must agree closely
            if matched and d.method == "blob" and not d.ring_fraction <= ap.max_ring:
                return False  # next to a match, a blob touching its colour is not trusted
        return True

    def _whole(self, d: Detection, r_exp: float) -> bool:
        """Round, filled and of the size its distance implies (appearance matches are sized by
        the track, their shape is that of the clean look they were matched to)."""
        p = self.params
        ratio = d.radius_px / r_exp if np.isfinite(r_exp) and r_exp > 0 else 0.0
        return d.axis_ratio >= p.offer_min_axis_ratio and d.fill >= p.offer_min_fill and \
            1.0 / p.offer_max_size_ratio <= ratio <= p.offer_max_size_ratio

    def _learn_looks(self, t: float, frames: dict[int, Frame], chosen: Hypothesis,
                     dets: dict[int, list[Detection]]) -> None:
        """Keep each view's look of the ball from a clean stereo fix (`vision.appearance`)."""
        X = chosen.est.position_world
        for i, j in chosen.used.items():
            r_exp = expected_radius_px(self.models[i], X, self.params.ball_radius)
            self.appearance.learn(i, t, frames[i].image, dets[i][j], X, r_exp,
                                  chosen.est.reprojection_px)

    def _learn_clutter(self, t: float, frames: dict[int, Frame], chosen: Hypothesis,
                       dets: dict[int, list[Detection]]) -> None:
        """Remember the other blobs each camera sees next to the well-measured ball; every
        `clutter_scan_every` frames one camera also looks at its whole image for them."""
        every = self.params.clutter_scan_every
        n = len(self.sources)
        scan = (self._steps // every) % n if every > 0 and self._steps % every == 0 else None
        for i, j in chosen.used.items():
            seen = list(dets[i])
            if i == scan and i in frames:
                seen += self.detector.detect(frames[i].image, None, self._radius_ranges[i])
            self.clutter.learn(i, t, seen, dets[i][j])

    # -- convenience --------------------------------------------------------------------------
    @classmethod
    def synthetic(cls, models: Sequence[CameraModel], scene: PointerScene, *, seed: int = 0,
                  fps: float = 60.0, profile: ColorProfile = DEFAULT_POINTER_RED,
                  params: PointerParams | None = None) -> PointerSystem:
        """A system watching a `PointerScene` through synthetic cameras (sample cells, tests)."""
        return cls(synthetic_cameras(models, scene, seed=seed, fps=fps), models, profile, params)
