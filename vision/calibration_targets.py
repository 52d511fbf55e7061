"""Printed calibration patterns: chessboard and ChArUco specs, their 3-D corner coordinates,
printable textures (also used by the synthetic camera), and corner detection in an image.

Board frame: origin at the top-left of the printed sheet (a one-square white margin included),
x along the columns, y down the rows, z into the board; metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from vision.scene import PlanarTarget

_MARGIN_SQUARES = 1


@dataclass(frozen=True)
class ChessboardSpec:
    """`inner_cols` x `inner_rows` inner corners (OpenCV's pattern size), squares of `square_m`."""

    inner_cols: int = 9
    inner_rows: int = 6
    square_m: float = 0.03

    def __post_init__(self) -> None:
        if self.inner_cols < 2 or self.inner_rows < 2 or self.square_m <= 0:
            raise ValueError("a chessboard needs at least 2x2 inner corners and a positive size")

    @property
    def pattern_size(self) -> tuple[int, int]:
        return self.inner_cols, self.inner_rows

    def object_points(self) -> np.ndarray:
        """(N, 3) inner corners in the board frame, in OpenCV's detection order (row-major)."""
        m = _MARGIN_SQUARES + 1
        j, i = np.mgrid[0:self.inner_rows, 0:self.inner_cols]
        pts = np.column_stack([(i.ravel() + m) * self.square_m, (j.ravel() + m) * self.square_m,
                               np.zeros(i.size)])
        return pts.astype(np.float64)

    def texture(self, px_per_square: int = 40) -> tuple[np.ndarray, float, float]:
        """BGR image of the printed board, and its width and height in metres."""
        nx, ny = self.inner_cols + 1, self.inner_rows + 1
        mx, my = nx + 2 * _MARGIN_SQUARES, ny + 2 * _MARGIN_SQUARES
        img = np.full((my * px_per_square, mx * px_per_square), 255, np.uint8)
        for r in range(ny):
            for c in range(nx):
                if (r + c) % 2 == 0:
                    y0, x0 = (r + _MARGIN_SQUARES) * px_per_square, (c + _MARGIN_SQUARES) \
                        * px_per_square
                    img[y0:y0 + px_per_square, x0:x0 + px_per_square] = 0
        return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR), mx * self.square_m, my * self.square_m

    def target(self, T_world_board: np.ndarray, px_per_square: int = 40) -> PlanarTarget:
        tex, w, h = self.texture(px_per_square)
        return PlanarTarget(tex, w, h, np.asarray(T_world_board, float))

    def detect(self, image_bgr: np.ndarray) -> np.ndarray | None:
        """Sub-pixel inner corners (N, 2) in `object_points` order, or None if not all seen."""
        gray = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2GRAY)
        flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
        ok, corners = cv2.findChessboardCorners(gray, self.pattern_size, flags=flags)
        if not ok:
            return None
        crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4)
        corners = cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), crit)
        return corners.reshape(-1, 2).astype(np.float64)


@dataclass(frozen=True)
class CharucoSpec:
    """A ChArUco board: chessboard squares with ArUco markers in the white ones, so partial
    views still give identified corners."""

    squares_x: int = 7
    squares_y: int = 5
    square_m: float = 0.04
    marker_m: float = 0.03
    dictionary: str = "DICT_4X4_50"

    def __post_init__(self) -> None:
        if self.squares_x < 3 or self.squares_y < 3 or not 0 < self.marker_m < self.square_m:
            raise ValueError("a ChArUco board needs >= 3x3 squares and 0 < marker < square")
        if not hasattr(cv2.aruco, self.dictionary):
            raise ValueError(f"unknown ArUco dictionary {self.dictionary!r}")

    def board(self) -> cv2.aruco.CharucoBoard:
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard((self.squares_x, self.squares_y), self.square_m,
                                      self.marker_m, d)

    def object_points(self) -> np.ndarray:
        """(N, 3) ChArUco corners in the board frame, indexed by corner id."""
        pts = np.asarray(self.board().getChessboardCorners(), dtype=np.float64).reshape(-1, 3)
        pts[:, :2] += _MARGIN_SQUARES * self.square_m
        return pts

    def texture(self, px_per_square: int = 60) -> tuple[np.ndarray, float, float]:
        """Drawn square by square from the board's own marker layout (OpenCV 4.14's
        `generateImage` asserts when the board exactly fills the image, which we need)."""
        board = self.board()
        d = board.getDictionary()
        pad = _MARGIN_SQUARES * px_per_square
        scale = px_per_square / self.square_m  # texture pixels per metre
        img = np.full((self.squares_y * px_per_square + 2 * pad,
                       self.squares_x * px_per_square + 2 * pad), 255, np.uint8)
        white = set()
        side = int(round(self.marker_m * scale))
        for mid, corners in zip(board.getIds().ravel(), board.getObjPoints(), strict=True):
            c = np.asarray(corners, float).reshape(-1, 3)[:, :2]
            centre = c.mean(axis=0)
            white.add((int(centre[0] // self.square_m), int(centre[1] // self.square_m)))
            x0 = int(round(c[:, 0].min() * scale)) + pad
            y0 = int(round(c[:, 1].min() * scale)) + pad
            img[y0:y0 + side, x0:x0 + side] = cv2.aruco.generateImageMarker(d, int(mid), side)
        for r in range(self.squares_y):
            for col in range(self.squares_x):
                if (col, r) not in white:
                    y0, x0 = pad + r * px_per_square, pad + col * px_per_square
                    img[y0:y0 + px_per_square, x0:x0 + px_per_square] = 0
        mx = (self.squares_x + 2 * _MARGIN_SQUARES) * self.square_m
        my = (self.squares_y + 2 * _MARGIN_SQUARES) * self.square_m
        return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR), mx, my

    def target(self, T_world_board: np.ndarray, px_per_square: int = 60) -> PlanarTarget:
        tex, w, h = self.texture(px_per_square)
        return PlanarTarget(tex, w, h, np.asarray(T_world_board, float))

    def detect(self, image_bgr: np.ndarray, min_corners: int = 6
               ) -> tuple[np.ndarray, np.ndarray] | None:
        """Identified corners: (pixels (N, 2), ids (N,)), or None if fewer than `min_corners`."""
        gray = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2GRAY)
        detector = cv2.aruco.CharucoDetector(self.board())
        corners, ids, _, _ = detector.detectBoard(gray)
        if ids is None or len(ids) < min_corners:
            return None
        return corners.reshape(-1, 2).astype(np.float64), ids.ravel().astype(int)
