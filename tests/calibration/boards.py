"""Chessboard photos rendered through a known camera (intrinsics and distortion), for vlp-calibrate's tests.

Every pixel's ray (the camera's own inverse of its distortion) meets the board's plane; the pattern is
antialiased by each pixel's footprint on the board (a box filter along both board axes); then Gaussian
optics blur, read noise and 8-bit quantisation.
"""

import cv2
import numpy as np

from planner.calibration.chessboard import Board
from planner.camera.model import Camera


def board_pose(tilt_deg: float, tilt_dir_deg: float, spin_deg: float, centre_m, distance_m: float):
    """Board-to-camera rotation and the board origin [m]: the board faces the camera, tilted by ``tilt_deg``
    towards ``tilt_dir_deg``, turned by ``spin_deg`` in its plane, its centre at ``centre_m`` (x, y) times the
    distance and ``distance_m`` ahead."""
    spin, tilt, d = np.radians(spin_deg), np.radians(tilt_deg), np.radians(tilt_dir_deg)
    rz = np.array([[np.cos(spin), -np.sin(spin), 0], [np.sin(spin), np.cos(spin), 0], [0, 0, 1]])
    axis = np.array([-np.sin(d), np.cos(d), 0.0])
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rt = np.eye(3) + np.sin(tilt) * k + (1 - np.cos(tilt)) * k @ k
    return rt @ rz, np.array([centre_m[0] * distance_m, centre_m[1] * distance_m, distance_m])


def render_board(camera: Camera, board: Board, rotation: np.ndarray, centre: np.ndarray, rng: np.random.Generator,
                 blur_px: float = 0.8, noise_dn: float = 2.0, rays: np.ndarray | None = None,
                 texture: np.ndarray | None = None) -> np.ndarray:
    """The 8-bit grey photo of ``board`` (one square of white margin round it, on a grey wall) whose centre is at
    ``centre`` [m] in the camera frame, board axes ``rotation`` (board-to-camera). ``texture`` (float32, 0 black
    .. 1 white, the board's squares only) replaces the chessboard pattern: a ChArUco board, sampled bilinearly.
    """
    if rays is None:
        rays = pixel_rays(camera)
    sq = board.square_m
    size = np.array([(board.cols + 1) * sq, (board.rows + 1) * sq])
    origin = centre - rotation[:, :2] @ (size / 2 - sq)  # the first inner corner, OpenCV's board origin
    # Board coordinates of each ray's hit, in squares from the board's edge: p = t r with n . (p - origin) = 0.
    normal = rotation[:, 2]
    t = np.float32(normal @ origin) / (rays @ normal.astype(np.float32))
    uv = np.stack([(rays @ (rotation[:, i] / sq).astype(np.float32)) * t - np.float32(origin @ rotation[:, i] / sq - 1)
                   for i in range(2)], axis=-1)
    foot = np.stack([np.hypot(*np.gradient(uv[..., i])) for i in range(2)], axis=-1)  # squares per pixel
    # Box-filtered square wave along each axis: +1 / -1 squares, linear across a pixel's footprint.
    s = [np.clip(2 * (0.5 - np.abs(np.mod(uv[..., i] + 0.5, 2.0) - 1.0)) / np.maximum(foot[..., i], 1e-6), -1, 1)
         for i in range(2)]
    inside = [np.clip(np.minimum(uv[..., i] - 0.0, size[i] / sq - uv[..., i]) / np.maximum(foot[..., i], 1e-6)
                      + 0.5, 0, 1) for i in range(2)]
    margin = [np.clip(np.minimum(uv[..., i] + 1.0, size[i] / sq + 1.0 - uv[..., i]) / np.maximum(foot[..., i], 1e-6)
                      + 0.5, 0, 1) for i in range(2)]
    squares = 0.5 - 0.5 * s[0] * s[1]  # 1 white, 0 black (black corners)
    if texture is not None:  # a ChArUco board's own image (squares and markers), texels per square as its scale
        scale = texture.shape[0] / (board.rows + 1)
        squares = cv2.remap(texture, uv[..., 0] * scale - 0.5, uv[..., 1] * scale - 0.5, cv2.INTER_LINEAR,
                            borderMode=cv2.BORDER_REPLICATE)
    on_board = inside[0] * inside[1]
    paper = margin[0] * margin[1]
    white, black, wall = 220.0, 25.0, 110.0
    level = wall + paper * ((white - wall) + on_board * (black + squares * (white - black) - white))
    level = np.where(t > 0, level, wall).astype(np.float32)
    if blur_px > 0:
        level = cv2.GaussianBlur(level, (0, 0), blur_px)
    level += rng.normal(0.0, noise_dn, level.shape).astype(np.float32)
    return np.clip(np.rint(level), 0, 255).astype(np.uint8)


def charuco_texture(board: Board, px_per_square: int = 40) -> np.ndarray:
    """The ChArUco board's image (float32, 0 black .. 1 white), lightly blurred so that sampling it antialiases."""
    image = board.charuco().generateImage(((board.cols + 1) * px_per_square, (board.rows + 1) * px_per_square),
                                          marginSize=0, borderBits=1)
    return cv2.GaussianBlur(image.astype(np.float32) / 255, (0, 0), 0.6)


def pixel_rays(camera: Camera, step_px: int = 4) -> np.ndarray:
    """Camera-frame rays (height, width, 3) through every pixel centre: the camera's exact inverse on a grid every
    ``step_px`` pixels, cubic-interpolated in between (the map is smooth: under 0.002 px off)."""
    from scipy.ndimage import map_coordinates

    pad = 4 * step_px  # beyond the image, so that the spline's ends lie outside it
    gu = np.arange(-pad, camera.width_px + pad + step_px, step_px, dtype=float)
    gv = np.arange(-pad, camera.height_px + pad + step_px, step_px, dtype=float)
    grid = camera.normalized(np.stack(np.meshgrid(gu, gv), axis=-1))
    v, u = (np.mgrid[0:camera.height_px, 0:camera.width_px].astype(float) + pad) / step_px
    xy = [map_coordinates(grid[..., i], [v, u], order=3) for i in range(2)]
    rays = np.stack([xy[0], xy[1], np.ones_like(xy[0])], axis=-1)
    return (rays / np.linalg.norm(rays, axis=-1, keepdims=True)).astype(np.float32)  # float32: twice as fast


POSES = [  # tilt, tilt direction, spin [deg], centre (x/z, y/z), distance [m]: the board over the whole image
    (0, 0, 3, (0.0, 0.0), 0.55), (35, 0, -8, (0.0, 0.0), 0.6), (35, 90, 10, (0.0, 0.0), 0.6),
    (35, 180, 5, (0.0, 0.0), 0.6), (35, 270, -5, (0.0, 0.0), 0.6), (25, 45, 20, (-0.28, -0.2), 0.7),
    (25, 135, -15, (0.28, -0.2), 0.7), (25, 225, 12, (0.28, 0.2), 0.7), (25, 315, -20, (-0.28, 0.2), 0.7),
    (15, 30, 30, (-0.3, 0.0), 0.75), (15, 200, -30, (0.3, 0.0), 0.75), (20, 100, 0, (0.0, -0.25), 0.75),
    (20, 280, 45, (0.0, 0.25), 0.75), (45, 60, -10, (0.1, 0.05), 0.65),
    (20, 45, 10, (-0.42, -0.3), 0.7), (20, 135, -10, (0.42, -0.3), 0.7), (20, 225, 5, (0.42, 0.3), 0.7),
    (20, 315, -5, (-0.42, 0.3), 0.7),  # into the image's corners, where the distortion is largest
]
