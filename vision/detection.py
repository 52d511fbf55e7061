"""Finding the coloured ball in one image: HSV threshold, median filter, morphological closing,
blobs (outer contours of the mask), size and roundness filters, sub-pixel centre (moments of
the filled blob) and apparent radius.

The thesis chain (003, §6.5.3) plus tests that a ball passes from any direction and most
look-alikes fail: the second-moment axis ratio (the thesis' circularity), how much of its
minimum enclosing circle the blob fills (rejects triangles and bars), and shading (a lit sphere
is not evenly bright; a square red sticker, which moments call round, is).
The bare `threshold_centroid` baseline is kept here so benchmarks can compare against it.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from vision.color import ColorProfile


@dataclass(frozen=True)
class DetectorParams:
    """Filters of the blob detector; radii in pixels of the apparent ball radius."""

    median_ksize: int = 5
    close_ksize: int = 5
    min_radius_px: float = 2.5
    max_radius_px: float = 60.0
    min_axis_ratio: float = 0.65
    min_fill: float = 0.72
    min_shading: float = 0.1  # std/mean of V inside the blob; 0 disables
    max_hole_fraction: float = 0.2  # a highlight is a small hole; the "O" of a red STOP is not
    max_candidates: int = 8

    def __post_init__(self) -> None:
        for k in (self.median_ksize, self.close_ksize):
            if k < 0 or (k > 1 and k % 2 == 0):
                raise ValueError(f"kernel sizes must be odd (or 0/1 to disable), got {k}")
        if not 0 < self.min_radius_px < self.max_radius_px:
            raise ValueError("need 0 < min_radius_px < max_radius_px")


@dataclass(frozen=True)
class Detection:
    """One ball candidate: centre (x, y) and apparent radius in full-image pixels."""

    center_px: np.ndarray
    radius_px: float
    area_px: float
    axis_ratio: float
    fill: float
    shading: float = 0.0  # std/mean of brightness inside the blob
    hole_fraction: float = 0.0  # share of the outline's area not in the colour mask
    method: str = "blob"  # "blob": a whole blob of the mask; "appearance": found by its look
    # inside a same-coloured region (`vision.appearance`), held to stricter rules
    match: float = float("nan")  # appearance matches: the normalised correlation
    ring_fraction: float = float("nan")  # share of a ring just outside the outline in the
    # colour mask (0: stands alone; NaN: not measured) - a blob touching a same-coloured
    # region may pass the shape tests with a centre a pixel off

    @property
    def diameter_px(self) -> float:
        return 2.0 * self.radius_px

    @property
    def score(self) -> float:
        """Roundness in 0..1 (1 = a perfect disc); used to rank candidates."""
        return float(min(self.axis_ratio, 1.0) * min(self.fill, 1.0))


Window = tuple[int, int, int, int]  # x0, y0, x1, y1 (exclusive), full-image pixels


def window_around(center_px: np.ndarray, half_size: float, width: int, height: int) -> Window:
    """Search window clipped to the image (may be empty if the centre is far outside)."""
    cx, cy = float(center_px[0]), float(center_px[1])
    h = max(1.0, float(half_size))
    x0, y0 = int(max(0, np.floor(cx - h))), int(max(0, np.floor(cy - h)))
    x1, y1 = int(min(width, np.ceil(cx + h) + 1)), int(min(height, np.ceil(cy + h) + 1))
    return x0, y0, max(x0, x1), max(y0, y1)


class BlobDetector:
    """Detects round blobs of one colour profile. Stateless per call; cheap to keep around."""

    def __init__(self, profile: ColorProfile, params: DetectorParams | None = None) -> None:
        self.profile = profile
        self.params = params or DetectorParams()
        p = self.params
        self._close_kernel = (cv2.getStructuringElement(cv2.MORPH_ELLIPSE,
                                                        (p.close_ksize, p.close_ksize))
                              if p.close_ksize > 1 else None)
        self._min_area = np.pi * p.min_radius_px**2
        self._max_area = np.pi * p.max_radius_px**2

    def mask(self, image_bgr: np.ndarray) -> np.ndarray:
        """The cleaned binary mask (after median and closing), for overlays and debugging."""
        return self._clean(self.profile.mask(cv2.cvtColor(image_bgr, cv2.COLOR_BGR2HSV)))

    def _clean(self, mask: np.ndarray) -> np.ndarray:
        p = self.params
        if p.median_ksize > 1:
            mask = cv2.medianBlur(mask, p.median_ksize)
        if self._close_kernel is not None:
            mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, self._close_kernel)
        return mask

    def detect(self, image_bgr: np.ndarray, window: Window | None = None,
               radius_range: tuple[float, float] | None = None) -> list[Detection]:
        """Round blobs of the profile's colour, best first.

        `window` restricts the search (a locked track's prediction); blobs cut by the window
        edge or the image edge are dropped, since their centre would be biased. `radius_range`
        narrows the size filter when the distance to the ball is known; only then are blobs
        that fail the shape test split by opening (a ball merged with a red bar or patch it
        passes in front of), since without a known size that turns square stickers into
        "balls".
        """
        if not isinstance(image_bgr, np.ndarray) or image_bgr.dtype != np.uint8 \
                or image_bgr.ndim != 3 or image_bgr.shape[2] != 3:
            raise ValueError("detection needs a BGR uint8 image (H, W, 3)")
        h, w = image_bgr.shape[:2]
        x0, y0, x1, y1 = (0, 0, w, h) if window is None else window
        if x1 - x0 < 3 or y1 - y0 < 3:
            return []
        roi = image_bgr[y0:y1, x0:x1]
        hsv = cv2.cvtColor(roi, cv2.COLOR_BGR2HSV)
        raw = self.profile.mask(hsv)
        mask = self._clean(raw)
        r_lo, r_hi = self.params.min_radius_px, self.params.max_radius_px
        if radius_range is not None:
            r_lo, r_hi = max(r_lo, radius_range[0]), min(r_hi, radius_range[1])
        split = radius_range is not None
        found = self._blobs(mask, hsv, raw, x0, y0, r_lo, r_hi, split)
        # a round, well-filled blob of the right size was found: no need to cut necks
        whole = any(d.axis_ratio >= 0.85 and d.fill >= 0.8 for d in found)
        if split and not whole:
            # the ball may touch a patch of its own colour (it passes in front of a red box or
            # a red stripe): a 5x5 median or closing can bridge the gap, so look again with a
            # 3x3 median only (when nothing was found); and open with a disc a little over
            # half the expected radius to cut a real neck. The ball survives whole; the patch
            # is cut off by the window edge or fails the shape tests.
            retry = [] if found else [cv2.medianBlur(raw, 3)]
            if r_lo >= 3.0:
                k = int(round(0.9 * r_lo))
                kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * k + 1, 2 * k + 1))
                retry.append(cv2.morphologyEx(mask, cv2.MORPH_OPEN, kernel))
            for alt in retry:
                more = self._blobs(alt, hsv, raw, x0, y0, r_lo, r_hi, False)
                found = _merge_rounder(found, more)
                if found:
                    break
        found.sort(key=lambda d: -d.score)
        return found[: self.params.max_candidates]

    def _blobs(self, mask: np.ndarray, hsv: np.ndarray, raw: np.ndarray, x0: int, y0: int,
               r_lo: float, r_hi: float, split: bool) -> list[Detection]:
        # outer contours, not connectedComponentsWithStats: the same blobs at a fraction of
        # the cost on a sparse mask (0.1 ms vs 2-5 ms at 640x480 on one core)
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        rh, rw = mask.shape
        found: list[Detection] = []
        for contour in contours:
            bx, by, bw, bh = cv2.boundingRect(contour)
            if max(bw, bh) < 1.4 * r_lo or min(bw, bh) > 2.0 * r_hi * 1.6 + 2:
                continue
            if bx == 0 or by == 0 or bx + bw >= rw or by + bh >= rh:
                continue  # touches the window / image edge
            if not self._plausible(contour, r_lo, r_hi, split):
                continue
            component = np.zeros((bh, bw), np.uint8)
            cv2.drawContours(component, [contour], -1, 1, cv2.FILLED, offset=(-bx, -by))
            value = hsv[by:by + bh, bx:bx + bw, 2]
            raw_in = raw[by:by + bh, bx:bx + bw] > 0
            det = self._measure(component > 0, value, raw_in, bx + x0, by + y0)
            if det is not None and self._accept(det, r_lo, r_hi):
                found.append(det)
            elif det is not None and split and det.radius_px >= r_lo:
                found.extend(d for d in self._split(component > 0, value, raw_in, bx + x0,
                                                    by + y0, r_lo)
                             if self._accept(d, r_lo, r_hi))
        return found

    def _plausible(self, contour: np.ndarray, r_lo: float, r_hi: float, split: bool) -> bool:
        """Cheap tests on the outline polygon before any pixel is looked at: size, and a
        loose version of the roundness tests (a blob merged with a bar may still be split)."""
        m = cv2.moments(contour)
        a = m["m00"]  # polygon through boundary pixel centres: ~pi (r - 0.5)^2 for a disc
        if a <= 0:
            return r_lo <= 1.0
        if not np.pi * max(r_lo - 1.0, 0.0) ** 2 * 0.6 <= a <= 1.5 * np.pi * r_hi**2:
            return False
        if split:
            return True
        mu20, mu02, mu11 = m["mu20"] / a, m["mu02"] / a, m["mu11"] / a
        common = np.sqrt((mu20 - mu02) ** 2 + 4 * mu11**2)
        l1, l2 = 0.5 * (mu20 + mu02 + common), 0.5 * (mu20 + mu02 - common)
        if l1 <= 0 or np.sqrt(max(l2, 0.0) / l1) < self.params.min_axis_ratio - 0.1:
            return False
        _, r_enc = cv2.minEnclosingCircle(contour)
        return a / (np.pi * (r_enc + 0.5) ** 2) >= 0.6 * self.params.min_fill

    def _accept(self, det: Detection, r_lo: float, r_hi: float) -> bool:
        p = self.params
        return (r_lo <= det.radius_px <= r_hi and det.axis_ratio >= p.min_axis_ratio
                and det.fill >= p.min_fill and det.shading >= p.min_shading
                and det.hole_fraction <= p.max_hole_fraction)

    def _split(self, component: np.ndarray, value: np.ndarray, raw: np.ndarray, ox: int,
               oy: int, r_lo: float) -> list[Detection]:
        """Recover a ball merged with a thin look-alike (a red bar it passes in front of).

        Opening with a disc a little smaller than the largest inscribed disc leaves a ball
        whole (a disc is open w.r.t. any smaller disc) and removes bars thinner than the
        kernel, so the centre survives almost unbiased.
        """
        comp = np.pad(component.astype(np.uint8), 1)
        r_in = float(cv2.distanceTransform(comp, cv2.DIST_L2, 5).max())
        k = int(0.75 * r_in)
        if r_in < r_lo or k < 2:
            return []
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * k + 1, 2 * k + 1))
        opened = cv2.morphologyEx(comp, cv2.MORPH_OPEN, kernel)
        n, labels = cv2.connectedComponents(opened, connectivity=8)
        out = []
        for j in range(1, n):
            d = self._measure((labels == j)[1:-1, 1:-1], value, raw, ox, oy)
            if d is not None:
                out.append(d)
        return out

    @staticmethod
    def _measure(component: np.ndarray, value: np.ndarray, raw: np.ndarray, ox: int,
                 oy: int) -> Detection | None:
        """Centre, radius, roundness and shading of one component (holes such as a highlight
        filled). Shading: a lit sphere is brighter towards its middle than at its rim, while
        a flat sticker of the same colour and outline is evenly bright. Holes are judged on
        the raw colour mask, since closing also fills the hole of a small red "O"."""
        comp = np.pad(component.astype(np.uint8), 1)
        contours, _ = cv2.findContours(comp, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        if not contours:
            return None
        contour = max(contours, key=cv2.contourArea)
        filled = np.zeros_like(comp)
        cv2.drawContours(filled, [contour], -1, 1, thickness=cv2.FILLED)
        m = cv2.moments(filled, binaryImage=True)
        if m["m00"] <= 0:
            return None
        area = m["m00"]
        cx, cy = m["m10"] / area, m["m01"] / area
        mu20, mu02, mu11 = m["mu20"] / area, m["mu02"] / area, m["mu11"] / area
        common = np.sqrt(max(0.0, (mu20 - mu02) ** 2 + 4 * mu11**2))
        l1, l2 = 0.5 * (mu20 + mu02 + common), 0.5 * (mu20 + mu02 - common)
        axis_ratio = float(np.sqrt(max(l2, 0.0) / l1)) if l1 > 0 else 0.0
        _, r_enc = cv2.minEnclosingCircle(contour)
        fill = float(area / (np.pi * (r_enc + 0.5) ** 2))
        own = (filled[1:-1, 1:-1] > 0) & raw
        v = value[own].astype(np.float32)
        shading = float(v.std() / v.mean()) if v.size and v.mean() > 0 else 0.0
        holes = 1.0 - float(own.sum()) / area
        return Detection(
            center_px=np.array([cx - 1 + ox, cy - 1 + oy]),
            radius_px=float(np.sqrt(area / np.pi)),
            area_px=float(area),
            axis_ratio=axis_ratio,
            fill=fill,
            shading=shading,
            hole_fraction=max(0.0, holes),
        )


def threshold_centroid(image_bgr: np.ndarray, profile: ColorProfile,
                       min_pixels: int = 5) -> np.ndarray | None:
    """The bare baseline: centroid of every pixel in the colour range; None if too few."""
    mask = profile.mask(cv2.cvtColor(image_bgr, cv2.COLOR_BGR2HSV))
    m = cv2.moments(mask, binaryImage=True)
    if m["m00"] < min_pixels:
        return None
    return np.array([m["m10"] / m["m00"], m["m01"] / m["m00"]])


def _merge_rounder(found: list[Detection], more: list[Detection]) -> list[Detection]:
    """`found` plus the blobs of `more` found nowhere near them; where one of `more` is the
    same blob as one found (centres within half its radius) and rounder, it takes its place:
    opening cut off the specks or the edge of a same-coloured patch that had bent the
    outline, and with them the pixel or so they had pulled the centre."""
    out = list(found)
    for d in more:
        near = [k for k, e in enumerate(out)
                if np.linalg.norm(d.center_px - e.center_px) <= max(2.0, 0.5 * e.radius_px)]
        if not near:
            out.append(d)
        elif len(near) == 1 and d.score > out[near[0]].score:
            out[near[0]] = d
    return out
