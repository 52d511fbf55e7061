"""Scripted pointer use for sample cells and tests: animate the synthetic pointer ball moving
in to a target and holding still, run the real pipeline on the rendered frames, return the
taught point. Nothing is short-cut: the position comes out of detection, triangulation,
tracking and the dwell detector exactly as with a real camera."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from vision.camera_model import CameraModel
from vision.dwell import TaughtPoint
from vision.errors import VisionError
from vision.pointer import PointerParams, PointerSystem
from vision.scene import BackgroundSpec, PointerScene
from vision.trajectories import waypoints

SystemFactory = Callable[[PointerScene], PointerSystem]


def dwell_scene(target_world: np.ndarray, *, seed: int, approach_from: np.ndarray | None = None,
                hold_s: float = 3.0, move_s: float = 0.8, tremor: float = 0.0003,
                background: BackgroundSpec | None = None) -> PointerScene:
    """The pointer starts 15 cm from the target (seeded direction), moves in, holds."""
    target = np.asarray(target_world, dtype=float)
    if target.shape != (3,) or not np.all(np.isfinite(target)):
        raise ValueError(f"target must be a finite (x, y, z), got {target_world!r}")
    if approach_from is None:
        rng = np.random.default_rng(seed)
        d = rng.normal(size=3)
        approach_from = target + 0.15 * d / np.linalg.norm(d)
    path = waypoints([np.asarray(approach_from, float), target], move_s, [0.3, hold_s],
                     tremor=tremor, seed=seed)
    return PointerScene(path, background=background or BackgroundSpec())


def simulate_dwell(system_factory_or_cameras: SystemFactory | Sequence[CameraModel],
                   target_world: np.ndarray, *, seed: int,
                   approach_from: np.ndarray | None = None, hold_s: float = 3.0,
                   params: PointerParams | None = None,
                   background: BackgroundSpec | None = None) -> TaughtPoint:
    """Run the pointer pipeline until the dwell at `target_world` fires; return the point.

    `system_factory_or_cameras` is either the camera models (a `PointerSystem` with synthetic
    cameras and the default red profile is built) or `factory(scene) -> PointerSystem`.
    Raises `VisionError` (saying what the tracker saw) if no dwell fires while holding.
    """
    scene = dwell_scene(target_world, seed=seed, approach_from=approach_from, hold_s=hold_s,
                        background=background)
    if callable(system_factory_or_cameras):
        system = system_factory_or_cameras(scene)
    else:
        models = list(system_factory_or_cameras)
        if not models or not all(isinstance(m, CameraModel) for m in models):
            raise ValueError("pass camera models or a factory(scene) -> PointerSystem")
        system = PointerSystem.synthetic(models, scene, seed=seed, params=params)
    dwell_s = system.params.dwell.dwell_s
    if hold_s < dwell_s:
        raise ValueError(f"hold_s {hold_s} s is shorter than the dwell time {dwell_s} s")
    modes: dict[str, int] = {}
    try:
        t_end = 0.3 + 0.8 + hold_s + 0.2
        while True:
            state = system.step()
            modes[state.mode] = modes.get(state.mode, 0) + 1
            if state.taught is not None:
                return state.taught
            if state.timestamp > t_end:
                break
    finally:
        system.close()
    raise VisionError(f"no dwell fired at {np.round(target_world, 3).tolist()} within "
                      f"{hold_s:.1f} s of holding; tracker modes seen: {modes}")


def board_poses(model: CameraModel, width_m: float, height_m: float, n: int, *, seed: int,
                distance: tuple[float, float] = (0.35, 0.6), max_tilt_deg: float = 40.0,
                min_tilt_deg: float = 15.0) -> list[np.ndarray]:
    """`n` poses T_world_board of a board held in front of `model`, tilted 15-40 degrees in
    varied directions and spread over the image, as a careful operator would hold it."""
    rng = np.random.default_rng(seed)
    T_wc = model.T_world_camera
    poses = []
    f = model.focal_px
    for k in range(n):
        d = rng.uniform(*distance)
        # board centre spread over the middle 70 % of the image
        u = model.K[0, 2] + rng.uniform(-0.35, 0.35) * model.width
        v = model.K[1, 2] + rng.uniform(-0.35, 0.35) * model.height
        centre_cam = np.array([(u - model.K[0, 2]) / f * d, (v - model.K[1, 2]) / f * d, d])
        tilt = np.radians(rng.uniform(min_tilt_deg, max_tilt_deg))
        axis_angle = 2 * np.pi * (k / n) + rng.uniform(-0.3, 0.3)
        axis = np.array([np.cos(axis_angle), np.sin(axis_angle), 0.0])
        spin = np.radians(rng.uniform(-20, 20))
        R = _axis_angle(axis, tilt) @ _axis_angle(np.array([0.0, 0.0, 1.0]), spin)
        T_cb = np.eye(4)
        T_cb[:3, :3] = R  # board z along the camera's z: printed side faces the camera
        T_cb[:3, 3] = centre_cam - R @ np.array([width_m / 2, height_m / 2, 0.0])
        poses.append(T_wc @ T_cb)
    return poses


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    a = axis / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def render_board_views(model: CameraModel, targets: Sequence, *, seed: int,
                       noise_sigma: float = 2.0) -> list[np.ndarray]:
    """One rendered image per `PlanarTarget` (plain wall behind, sensor noise, no pointer)."""
    from vision.scene import SensorSpec
    from vision.sources import SyntheticCamera

    targets = list(targets)
    scene = PointerScene(None, stick=None, boards=lambda t: [targets[int(round(t))]],
                         background=BackgroundSpec(kind="plain"),
                         sensor=SensorSpec(noise_sigma=noise_sigma, exposure_s=0.0))
    cam = SyntheticCamera(model, scene, np.random.default_rng(seed), fps=1.0)
    return [cam.read(1.0).image for _ in targets]
