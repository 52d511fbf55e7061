"""Marker pointer: cameras, HSV colour calibration, blob detection, tracking, 3-D position.

Never imports viser; the web layer shows what the tracker produces. Modules, by what they hold:

- `camera_model` (`CameraModel`), `rigs` (ready camera arrangements), `frame` (`Frame`)
- `sources`: OpenCV cameras/files/streams, image folders, replay, the `SyntheticCamera`;
  `scene`, `trajectories`, `render`: what the synthetic camera draws and how
- `color`: `ColorProfile`, `calibrate_from_ellipse`; `calibration_targets`, `intrinsics`,
  `extrinsics`: camera calibration
- `detection` (`BlobDetector`), `geometry` (sphere ray, triangulation, single-camera size
  estimate), `kalman`, `tracking2d`, `tracking3d`, `dwell`
- `pointer`: `PointerSystem`, the facade the Session uses; `scripted`: `simulate_dwell`
- `errors`: every exception raised on purpose
"""
