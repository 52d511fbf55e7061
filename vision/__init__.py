"""Marker pointer: cameras, HSV colour calibration, blob detection, tracking, 3-D position.

Never imports viser; the web layer shows what the tracker produces. Modules, by what they hold:

- `camera_model` (`CameraModel`), `rigs` (ready camera arrangements), `frame` (`Frame`)
- `sources`: OpenCV cameras/files/streams, image folders, replay, the `SyntheticCamera`;
  `scene`, `trajectories`, `render`: what the synthetic camera draws and how
- `color`: `ColorProfile`; `color_calibration`: `calibrate_ellipse` / `calibrate_from_ellipse`
  (tolerant of background in the ellipse, says when the colour is not separable, with the
  mask); `calibration_targets`, `intrinsics`, `extrinsics`: camera calibration
- `detection` (`BlobDetector`), `geometry` (sphere ray, triangulation, single-camera size
  estimate), `kalman`, `tracking2d`, `tracking3d`, `clutter` (still look-alikes), `dwell`
- `pointer`: `PointerSystem`, the facade the Session uses (`pointer_types`: its params and
  states: `offered_position` is the only position to teach from); `scripted`: `simulate_dwell`
- `appearance` (`AppearanceMemory`): finds a ball merged with a same-coloured region by its
  last clean look (marked `Detection.method == "appearance"`), else by its outline (`outline`,
  `method == "outline"`); `pointer_hypotheses`: the
  candidate stereo fixes of a frame, for `PointerSystem` to choose from
- `errors`: every exception raised on purpose
"""
