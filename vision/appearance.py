"""Finding a ball that has merged with a background region of its own colour, by its look.

A ball held in front of something of its colour (an orange suit, a red saucer, a red sticker)
joins that thing in the colour mask: the blob detector then sees one big shape, or a ball with
a bite taken out of it, and rightly refuses it. The ball still looks like itself, though: a lit
sphere has a shading pattern (highlight, darker rim) the flat background does not. So each
camera keeps the ball's last *clean* look - the pixels inside its outline in a frame where the
blob detector measured it whole and the stereo fix was offered - and, while the 3-D track is
followed, looks for that pattern (masked normalised cross-correlation, `cv2.matchTemplate`)
inside the small window the track predicts, at the size the track predicts.

A match is taken only if it is unmistakable: correlation >= `min_ncc` (0.96-0.99 on the ball
over the tuned photographs; look-alikes of the ball's colour elsewhere peak below 0.88), nearly
all of its pixels in the colour profile, brightness within the exposure drift of the template,
the peak inside the window (not on its edge) and no second peak nearly as high. Such a
detection is marked `method="appearance"` so the pointer can hold it to its own rules (see
`PointerSystem._clean_views`). A template is never learnt from an appearance match, so errors
cannot feed on themselves.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field

import cv2
import numpy as np

from vision.color import ColorProfile
from vision.detection import Detection
from vision.outline import OutlineParams, find_outline


@dataclass(frozen=True)
class AppearanceParams:
    """Acceptance tests of a match; see the module docstring for the measured margins."""

    min_ncc: float = 0.93
    min_in_colour: float = 0.85  # share of the matched disc inside the colour profile
    gain_range: tuple[float, float] = (0.7, 1.45)  # brightness now / at learning
    min_peak_margin: float = 0.03  # the best peak must beat any other by this much
    max_age_s: float = 8.0  # a look older than this (the ball turned, the light moved): unused
    scale_range: tuple[float, float] = (0.8, 1.25)  # expected size now / at learning
    min_radius_px: float = 3.0  # below this a shading pattern has too few pixels
    max_ring: float = 0.1  # a blob with more of its surrounding ring in the colour mask than
    # this touches something of its colour: it is not trusted next to a match (its centre may
    # be a pixel off), and a match is looked for instead
    learn_max_ring: float = 0.02  # a look is learnt only from a blob standing quite alone,
    learn_min_axis_ratio: float = 0.9  # round,
    learn_max_reprojection_px: float = 0.3  # and agreeing with the other views of its fix
    max_travel_m: float = 0.1  # a look is used only this near to where it was learnt: the
    # highlight moves over the ball as the view onto it turns (~0.3 px at 10 cm here)
    offer_max_reprojection_px: float = 1.0  # a stereo fix using a match is offered only if
    # its views agree this well (whole blobs: the pointer's `reprojection_gate_px`)
    outline: OutlineParams = field(default_factory=OutlineParams)  # without a usable look


@dataclass
class _Template:
    patch: np.ndarray  # float32 BGR crop around the ball
    centre: np.ndarray  # the ball's centre in `patch` pixels
    radius_px: float  # the blob's radius when learnt
    r_exp: float  # the radius the fix's distance implied (scaled against the track's now)
    time: float
    position_world: np.ndarray  # the fix's 3-D position


class AppearanceMemory:
    """The last clean look of the ball in each camera, and the search for it."""

    def __init__(self, n_cameras: int, params: AppearanceParams | None = None) -> None:
        self.params = params or AppearanceParams()
        self._tpl: list[_Template | None] = [None] * n_cameras
        self.last_refusal: str = ""  # why the last `find` returned None (diagnostics)

    def reset(self) -> None:
        self._tpl = [None] * len(self._tpl)

    def has_template(self, i: int, t: float) -> bool:
        tpl = self._tpl[i]
        return tpl is not None and t - tpl.time <= self.params.max_age_s

    def learn(self, i: int, t: float, image: np.ndarray, det: Detection,
              position_world: np.ndarray, r_exp: float, reprojection_px: float) -> None:
        """Keep the look of a whole, cleanly measured ball (never of an appearance match): a
        blob touching its colour has a centre up to a pixel off, and a look learnt from it
        would carry that error into every match."""
        p = self.params
        if det.method != "blob" or det.radius_px < p.min_radius_px \
                or not det.ring_fraction <= p.learn_max_ring \
                or det.axis_ratio < p.learn_min_axis_ratio \
                or not reprojection_px <= p.learn_max_reprojection_px:
            return
        h, w = image.shape[:2]
        m = int(np.ceil(1.25 * det.radius_px + 3))
        cx, cy = (int(round(v)) for v in det.center_px)
        x0, y0, x1, y1 = cx - m, cy - m, cx + m + 1, cy + m + 1
        if x0 < 0 or y0 < 0 or x1 > w or y1 > h:
            return
        self._tpl[i] = _Template(image[y0:y1, x0:x1].astype(np.float32),
                                 np.array([det.center_px[0] - x0, det.center_px[1] - y0]),
                                 float(det.radius_px), float(r_exp), t,
                                 np.asarray(position_world, float).copy())

    def look_near(self, i: int, t: float, image: np.ndarray, profile: ColorProfile,
                  dets: list[Detection], predicted_px: np.ndarray, predicted_world: np.ndarray,
                  half: float, r_exp: float, followed: bool,
                  is_whole: Callable[[Detection], bool]) -> list[Detection]:
        """Camera i's detections, with the whole blobs within `half` px of the prediction
        given their `ring_fraction`; and, while the track is `followed` and none of them
        stands alone, the ball's look searched for there (or, without a usable look, its
        outline): a match replaces the blobs it overlaps and goes first."""
        dets = [dataclasses.replace(d, ring_fraction=ring_fraction(
                    image, profile, d.center_px, d.radius_px))
                if d.method == "blob" and np.linalg.norm(d.center_px - predicted_px) <= half
                and is_whole(d) else d for d in dets]
        if not followed or any(d.ring_fraction <= self.params.learn_max_ring for d in dets):
            return dets
        found = self.find(i, t, image, profile, predicted_px, half, r_exp, predicted_world) \
            if self.has_template(i, t) else None
        whole_near = any(d.method == "blob" and np.isfinite(d.ring_fraction) for d in dets)
        if found is None and not whole_near:
            # no usable look and no whole blob there: the ball's outline (`vision.outline`)
            found, why = find_outline(image, profile, predicted_px, half, r_exp,
                                      self.params.outline)
            self.last_refusal = why
        if found is None:
            return dets
        rest = [d for d in dets if np.linalg.norm(d.center_px - found.center_px)
                > 1.5 * max(found.radius_px, min(d.radius_px, 2.0 * found.radius_px))]
        return [found, *rest]

    def _scaled(self, tpl: _Template, s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The template at scale `s` about the ball's centre: patch, 3-channel disc mask, and
        the centre in the new patch."""
        r = s * tpl.radius_px
        half = int(np.ceil(r + 1.0))
        c_new = np.array([half, half], float)
        # output pixel q comes from source p = centre + (q - c_new) / s
        M = np.array([[s, 0.0, c_new[0] - s * tpl.centre[0]],
                      [0.0, s, c_new[1] - s * tpl.centre[1]]])
        size = 2 * half + 1
        patch = cv2.warpAffine(tpl.patch, M, (size, size), flags=cv2.INTER_LINEAR,
                               borderMode=cv2.BORDER_REPLICATE)
        yy, xx = np.mgrid[0:size, 0:size]
        disc = ((xx - c_new[0]) ** 2 + (yy - c_new[1]) ** 2 <= (r - 0.5) ** 2)
        mask = np.repeat(disc[..., None], 3, axis=2).astype(np.float32)
        return patch, mask, c_new

    def find(self, i: int, t: float, image: np.ndarray, profile: ColorProfile,
             predicted_px: np.ndarray, half: float, r_exp: float,
             predicted_world: np.ndarray) -> Detection | None:
        """The ball's look within `half` pixels of `predicted_px` at radius `r_exp` (the
        track's prediction, at `predicted_world`), or None unless the match passes every
        test."""
        p = self.params
        tpl = self._tpl[i]
        self.last_refusal = "no clean look of the ball yet"
        if tpl is None or t - tpl.time > p.max_age_s or not np.isfinite(r_exp) \
                or not np.all(np.isfinite(predicted_px)):
            return None
        travel = float(np.linalg.norm(np.asarray(predicted_world) - tpl.position_world))
        self.last_refusal = f"{1e3 * travel:.0f} mm from where its look was learnt"
        if not travel <= p.max_travel_m:
            return None
        s = r_exp / tpl.r_exp
        self.last_refusal = f"size {s:.2f}x that of the clean look"
        if not p.scale_range[0] <= s <= p.scale_range[1]:
            return None
        patch, mask, c = self._scaled(tpl, s)
        th, tw = patch.shape[:2]
        hh = int(np.ceil(half))
        x0 = int(np.floor(predicted_px[0] - c[0])) - hh
        y0 = int(np.floor(predicted_px[1] - c[1])) - hh
        x1, y1 = x0 + tw + 2 * hh + 1, y0 + th + 2 * hh + 1
        h, w = image.shape[:2]
        x0c, y0c, x1c, y1c = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
        self.last_refusal = "at the image edge"
        if x1c - x0c < tw + 2 or y1c - y0c < th + 2:
            return None
        roi = image[y0c:y1c, x0c:x1c].astype(np.float32)
        res = cv2.matchTemplate(roi, patch, cv2.TM_CCOEFF_NORMED, mask=mask)
        res = np.nan_to_num(res, nan=-1.0, posinf=-1.0, neginf=-1.0)
        _, best, _, (px, py) = cv2.minMaxLoc(res)
        self.last_refusal = f"correlation {best:.3f} (or peak on the window edge)"
        if best < p.min_ncc or not (0 < px < res.shape[1] - 1 and 0 < py < res.shape[0] - 1):
            return None  # too poor, or the best place is on the window's edge (may be beyond)
        # a second place nearly as good, a radius or more away: ambiguous, refuse
        others = res.copy()
        cv2.circle(others, (px, py), int(np.ceil(max(r_exp, 2.0))), -1.0, -1)
        self.last_refusal = f"ambiguous: peaks {best:.3f} and {others.max():.3f}"
        if others.max() > best - p.min_peak_margin:
            return None
        dx = _parabola_peak(res[py, px - 1], res[py, px], res[py, px + 1])
        dy = _parabola_peak(res[py - 1, px], res[py, px], res[py + 1, px])
        # the matched pixels: colour and brightness as the ball's
        seen = image[y0c + py:y0c + py + th, x0c + px:x0c + px + tw]
        disc = mask[..., 0] > 0
        in_colour = profile.mask(cv2.cvtColor(seen, cv2.COLOR_BGR2HSV))[disc] > 0
        a, b = seen.astype(np.float32)[disc], patch[disc]
        gain = float((a * b).sum() / max(float((b * b).sum()), 1e-9))
        self.last_refusal = f"{in_colour.mean():.0%} in the colour profile, brightness x{gain:.2f}"
        if in_colour.mean() < p.min_in_colour or not p.gain_range[0] <= gain <= p.gain_range[1]:
            return None
        self.last_refusal = ""
        centre = np.array([x0c + px + dx + c[0], y0c + py + dy + c[1]])
        r = s * tpl.radius_px
        return Detection(center_px=centre, radius_px=float(r), area_px=float(np.pi * r * r),
                         axis_ratio=1.0, fill=1.0, shading=0.0, hole_fraction=0.0,
                         method="appearance", match=float(best))


def ring_fraction(image: np.ndarray, profile: ColorProfile, centre: np.ndarray,
                  radius: float, inner: float = 1.5, outer: float = 4.0) -> float:
    """Share of the ring from `radius + inner` to `radius + outer` pixels around `centre` that
    is in the colour profile (the part of the ring outside the image counts as in it)."""
    h, w = image.shape[:2]
    ro = radius + outer
    x0, y0 = int(np.floor(centre[0] - ro)), int(np.floor(centre[1] - ro))
    x1, y1 = int(np.ceil(centre[0] + ro)) + 1, int(np.ceil(centre[1] + ro)) + 1
    if x0 < 0 or y0 < 0 or x1 > w or y1 > h:
        return 1.0
    crop = image[y0:y1, x0:x1]
    yy, xx = np.mgrid[y0:y1, x0:x1]
    d2 = (xx - centre[0]) ** 2 + (yy - centre[1]) ** 2
    ring = (d2 >= (radius + inner) ** 2) & (d2 <= ro**2)
    inside = profile.mask(cv2.cvtColor(crop, cv2.COLOR_BGR2HSV))[ring] > 0
    return float(inside.mean()) if inside.size else 1.0


def _parabola_peak(left: float, mid: float, right: float) -> float:
    """Sub-pixel offset of a peak from three samples (0 when flat), within +-0.5."""
    den = left - 2.0 * mid + right
    if den >= 0:
        return 0.0
    return float(np.clip(0.5 * (left - right) / den, -0.5, 0.5))
