"""Camera calibration from chessboard (or ChArUco) photos: OpenCV's corner finders and Zhang's method.

:func:`find_corners` finds a board's inner corners (``cv2.findChessboardCorners`` on an image
scaled to about 1,000 px, else 2,000 px, then ``cv2.cornerSubPix`` at full resolution; a ChArUco
board's by ``cv2.aruco.CharucoDetector``, which needs only part of the board in view);
:func:`calibrate` fits intrinsics and distortion to the corners of every photo the board was found in
(``cv2.calibrateCamera`` for the ``pinhole`` lens, ``k1 k2 p1 p2 k3``; ``cv2.fisheye.calibrate``
for ``fisheye``, ``k1..k4``) and reports the RMS reprojection error, overall and per photo.
Pure: images in, numbers out; reading files is the command line's job.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from planner.camera.model import Camera
from planner.errors import InputError

DETECT_PX = 1000
"""Corners are searched for on a copy scaled to about this many pixels along the long side (fast; if the board is not
found, once more at twice that), then refined at full resolution."""
MIN_VIEWS = 3
"""Fewest photos with the board found that a calibration takes (Zhang's method needs three views of a plane)."""
MIN_CHARUCO_CORNERS = 6
"""Fewest ChArUco corners a photo must show to be used (a homography and then some)."""


@dataclass(frozen=True)
class Board:
    """A chessboard target: ``cols`` x ``rows`` inner corners, squares ``square_m`` [m] on a side; with a
    ``dictionary`` (an OpenCV ArUco dictionary's name, e.g. ``DICT_5X5_100``) a ChArUco board, markers ``marker_m``
    [m] on a side in its white squares, whose corners are found even where the board is partly out of view."""

    cols: int
    rows: int
    square_m: float
    dictionary: str = ""
    marker_m: float = 0.0

    def charuco(self) -> cv2.aruco.CharucoBoard:
        """OpenCV's ChArUco board (squares: one more than the inner corners each way)."""
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard((self.cols + 1, self.rows + 1), self.square_m, self.marker_m, d)

    def points_m(self) -> np.ndarray:
        """The inner corners on the board's plane (z = 0), in OpenCV's order, (cols * rows, 3) [m]."""
        grid = np.mgrid[0:self.cols, 0:self.rows].T.reshape(-1, 2)
        return np.column_stack([grid * self.square_m, np.zeros(len(grid))])


@dataclass(frozen=True)
class Calibration:
    """What :func:`calibrate` found: the camera, the RMS reprojection error overall and per view [px]."""

    camera: Camera
    rms_px: float
    per_view_rms_px: tuple[float, ...]


def find_corners(gray: np.ndarray, board: Board) -> np.ndarray | None:
    """The board's inner corners in the 8-bit grey image (cols * rows, 2) [px], refined to sub-pixel; None if
    the board is not (wholly) seen."""
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    for detect_px in (DETECT_PX, 2 * DETECT_PX):  # a board small in a large photo: once more at twice the size
        scale = min(1.0, detect_px / max(gray.shape))
        small = cv2.resize(gray, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA) if scale < 1 else gray
        found, corners = cv2.findChessboardCorners(small, (board.cols, board.rows), flags=flags)
        if found or scale == 1:
            break
    if not found:
        return None
    corners = corners.reshape(-1, 1, 2).astype(np.float32)
    if scale < 1:  # pixel centres: (u + 0.5) / scale - 0.5
        corners = ((corners + 0.5) / scale - 0.5).astype(np.float32)
    grid = corners.reshape(board.rows, board.cols, 2)
    _refine(gray, corners, min(np.linalg.norm(np.diff(grid, axis=0), axis=-1).min(),
                               np.linalg.norm(np.diff(grid, axis=1), axis=-1).min()))
    return corners.reshape(-1, 2).astype(float)


def _refine(gray: np.ndarray, corners: np.ndarray, spacing_px: float) -> None:
    """``cv2.cornerSubPix`` in place, its window a third of the distance between neighbouring corners (3-25 px)."""
    half = int(max(3, min(25, spacing_px / 3)))
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)
    cv2.cornerSubPix(gray, corners, (half, half), (-1, -1), criteria)


def find_view(gray: np.ndarray, board: Board) -> tuple[np.ndarray, np.ndarray] | None:
    """The board's corners seen in the photo: their places on the board (N, 3) [m] and in the image (N, 2) [px];
    None if the board is not found (a chessboard must be wholly in view; a ChArUco board needs 6 corners)."""
    if not board.dictionary:
        corners = find_corners(gray, board)
        return None if corners is None else (board.points_m(), corners)
    charuco = board.charuco()
    corners, ids, _, _ = cv2.aruco.CharucoDetector(charuco).detectBoard(gray)
    if ids is None or len(ids) < MIN_CHARUCO_CORNERS:
        return None
    index = np.asarray(ids).ravel()
    obj = np.asarray(charuco.getChessboardCorners(), float)[index]  # each corner's id is its index
    # Not refined again: the detector places them already, and cornerSubPix's window would reach into the markers.
    img = np.asarray(corners, float)
    return obj, img.reshape(-1, 2).astype(float)


def calibrate(views: list[tuple[np.ndarray, np.ndarray]], size_px: tuple[int, int], lens: str = "pinhole",
              name: str = "") -> Calibration:
    """Intrinsics and distortion from every view's corners (board points (N, 3) [m], image points (N, 2) [px]) of
    an image of ``size_px`` (width, height); Zhang's method as OpenCV implements it."""
    if len(views) < MIN_VIEWS:
        raise InputError(f"the board was found in {len(views)} photo(s); a calibration needs at least "
                         f"{MIN_VIEWS}, at different tilts")
    width, height = size_px
    if lens == "fisheye":
        fx, fy, cx, cy, dist, rvecs, tvecs = _fisheye(views, size_px)
    else:
        criteria = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12)
        _, mtx, d, rvecs, tvecs = cv2.calibrateCamera([o.astype(np.float32) for o, _ in views],
                                                      [c.astype(np.float32) for _, c in views], size_px, None, None,
                                                      criteria=criteria)
        fx, fy, cx, cy = mtx[0, 0], mtx[1, 1], mtx[0, 2], mtx[1, 2]
        dist = tuple(float(x) for x in d.ravel()[:5])
    if not all(map(math.isfinite, (fx, fy, cx, cy, *dist))) or fx <= 0 or fy <= 0:
        raise InputError("the calibration did not converge: give more photos, with the board tilted in "
                         "different directions and reaching the image's corners")
    cam = Camera(width, height, float(fx), float(fy), float(cx), float(cy), lens=lens, distortion=dist, name=name)
    per_view, squares = [], []
    for (obj, c), r, t in zip(views, rvecs, tvecs):
        rot, _ = cv2.Rodrigues(np.asarray(r, float))
        seen = cam.project(obj @ rot.T + np.asarray(t, float).reshape(1, 3))
        squares.append(np.sum((seen - c) ** 2, axis=1))
        per_view.append(float(np.sqrt(np.mean(squares[-1]))))
    rms = float(np.sqrt(np.mean(np.concatenate(squares))))  # over every corner, as OpenCV's
    return Calibration(cam, rms, tuple(per_view))


def _fisheye(views: list[tuple[np.ndarray, np.ndarray]], size_px: tuple[int, int]):
    """``cv2.fisheye.calibrate``: fx, fy, cx, cy, (k1..k4), rvecs, tvecs."""
    objs = [o.reshape(-1, 1, 3).astype(np.float64) for o, _ in views]
    imgs = [c.reshape(-1, 1, 2).astype(np.float64) for _, c in views]
    base = cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC | cv2.fisheye.CALIB_FIX_SKEW
    criteria = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    for flags in (base | cv2.fisheye.CALIB_CHECK_COND, base):  # the condition check refuses some good sets
        try:
            _, mtx, d, rvecs, tvecs = cv2.fisheye.calibrate(objs, imgs, size_px, np.eye(3), np.zeros((4, 1)),
                                                            flags=flags, criteria=criteria)
            break
        except cv2.error:
            continue
    else:
        raise InputError("the fisheye calibration did not converge: give more photos, with the board tilted in "
                         "different directions and reaching the image's corners")
    return mtx[0, 0], mtx[1, 1], mtx[0, 2], mtx[1, 2], tuple(float(x) for x in d.ravel()[:4]), rvecs, tvecs
