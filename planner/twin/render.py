"""Render the frame a rolling-shutter camera captures of a planned ceiling: LED stripes on a dark ceiling.

Every luminaire in front of the camera is drawn as its exact perspective image
(the disc's conic, :func:`planner.camera.model.disc_dual_conic`), antialiased by its
signed distance to the rim. Image row ``v`` is exposed from ``v * row_time_s``
for ``exposure_s``; a pixel of LED ``k`` gets the mean of that LED's drive over
its row's exposure, the drive being the LED's frame (``plan.yaml``'s chips)
repeated at the site's chip rate from a random start phase. Then optics blur
(Gaussian), shot and read noise, and 8-bit quantisation. Pixel ``(v, u)`` has
its centre at image coordinates ``(u, v)``, as in the observation model.

Through a distorting lens the disc's image is no conic: each pixel centre is mapped to
where the ideal pinhole of the same intrinsics would see it (``Camera.ideal_pixels``, from
a cubic spline of a map sampled every :data:`MAP_STEP_PX`) and tested against the disc's
ideal conic there; the antialiasing distance is then in ideal pixels (docs/twin.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from scipy.interpolate import RectBivariateSpline

from planner.camera.ellipse import centre_and_shape
from planner.camera.model import Camera, disc_dual_conic, project_discs_at
from planner.defaults import SENSOR_BLUR_PX, SENSOR_EXPOSURE_S, SENSOR_READ_NOISE_DN


@dataclass(frozen=True)
class Sensor:
    """How the receiver's camera turns light into 8-bit pixels.

    Attributes
    ----------
    exposure_s : float
        Exposure of one row [s] (a phone's shortest settings are 1/10,000-1/100,000 s).
    blur_px : float
        Standard deviation of the optics' Gaussian blur [px].
    dark_dn : float
        Level of the unlit ceiling [DN].
    led_dn : float
        Level of a lit LED, before its own brightness factor [DN].
    led_spread : float
        Each LED's brightness is ``led_dn`` times a factor drawn uniformly from ``1 +- led_spread``.
    off_level : float
        Light of an "off" chip as a share of "on" (0: the driver switches fully off).
    read_noise_dn : float
        Standard deviation of the read noise [DN].
    shot_dn : float
        Shot noise: its variance is ``shot_dn`` times the signal [DN].
    """

    exposure_s: float = SENSOR_EXPOSURE_S
    blur_px: float = SENSOR_BLUR_PX
    dark_dn: float = 6.0
    led_dn: float = 210.0
    led_spread: float = 0.15
    off_level: float = 0.0
    read_noise_dn: float = SENSOR_READ_NOISE_DN
    shot_dn: float = 0.5


@dataclass(frozen=True)
class Frame:
    """A rendered frame and what is true about it."""

    image: np.ndarray  # (height, width) uint8
    drawn: np.ndarray  # indices of the luminaires drawn (some perhaps cut by the border)
    phase_chips: np.ndarray  # start phase of every luminaire's frame [chips], (N,)


def exposure_means(chips: str, phase_chips: float, row_start_s: np.ndarray, exposure_s: float,
                   chip_rate_hz: float, off_level: float = 0.0) -> np.ndarray:
    """Mean drive (0 off .. 1 on) of an LED over each row's exposure, its frame repeating from ``phase_chips``.

    Exact for the piecewise-constant drive: the integral of the repeated frame
    between the exposure's start and end, divided by its length.
    """
    level = np.array([1.0 if c == "1" else off_level for c in chips])
    cum = np.concatenate([[0.0], np.cumsum(level)])
    n_chips = len(level)

    def integral(x: np.ndarray) -> np.ndarray:  # of the drive from chip 0 to x [chips]
        whole = np.floor(x)
        k = whole.astype(np.int64)
        return (k // n_chips) * cum[-1] + cum[k % n_chips] + (x - whole) * level[k % n_chips]

    start = row_start_s * chip_rate_hz + phase_chips
    span = exposure_s * chip_rate_hz
    return (integral(start + span) - integral(start)) / span


MAP_STEP_PX = 8
"""Spacing of the samples of a distorting lens's pixel -> ideal-pixel map that the renderer interpolates [px]."""


@lru_cache(maxsize=4)
def _ideal_map(camera: Camera) -> tuple[RectBivariateSpline, RectBivariateSpline] | None:
    """Cubic splines (rows, columns) -> ideal u, v of the camera's pixel map; None where the map folds in view."""
    u = np.arange(-2 * MAP_STEP_PX, camera.width_px + 3 * MAP_STEP_PX, MAP_STEP_PX, dtype=float)
    v = np.arange(-2 * MAP_STEP_PX, camera.height_px + 3 * MAP_STEP_PX, MAP_STEP_PX, dtype=float)
    grid = camera.ideal_pixels(np.stack(np.meshgrid(u, v), axis=-1))
    if not np.isfinite(grid).all():
        return None
    return RectBivariateSpline(v, u, grid[..., 0]), RectBivariateSpline(v, u, grid[..., 1])


def _ideal_grid(camera: Camera, cols: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ideal pixel coordinates (u, v), each (rows, cols), of the pixel centres of a block of the frame."""
    splines = _ideal_map(camera)
    if splines is None:  # a folding lens: every pixel through Newton's method (NaN where it folds)
        grid = camera.ideal_pixels(np.stack(np.meshgrid(cols, rows), axis=-1))
        return grid[..., 0], grid[..., 1]
    return splines[0](rows, cols), splines[1](rows, cols)


def _coverage(u: np.ndarray, v: np.ndarray, centre: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Share of each pixel inside the ellipse ``(p - c)^T q (p - c) <= 1``, from the signed distance to its rim."""
    return _coverage_at(u[None, :] - centre[0], v[:, None] - centre[1], q)


def _coverage_at(du: np.ndarray, dv: np.ndarray, q: np.ndarray) -> np.ndarray:
    """:func:`_coverage` at offsets ``du, dv`` (broadcast together) from the ellipse's centre [px]."""
    gu, gv = q[0, 0] * du + q[0, 1] * dv, q[1, 0] * du + q[1, 1] * dv
    d = du * gu + dv * gv
    root = np.sqrt(np.maximum(d, 1e-12))
    signed = (root - 1.0) * root / np.maximum(np.hypot(gu, gv), 1e-12)  # [px], negative inside
    return np.clip(0.5 - signed, 0.0, 1.0)


def _unit_circle(count: int = 128) -> np.ndarray:
    phi = 2 * np.pi * np.arange(count) / count
    return np.column_stack([np.cos(phi), np.sin(phi)])


def render_frame(xyz: np.ndarray, radii: np.ndarray, chips: list[str], chip_rate_hz: float | np.ndarray, camera: Camera,
                 position: np.ndarray, rotation: np.ndarray, sensor: Sensor = Sensor(),
                 rng: np.random.Generator | None = None, phase_chips: np.ndarray | None = None,
                 gain: np.ndarray | None = None, glow: tuple[float, float] | None = None) -> Frame:
    """The frame the camera at ``position`` [m] with camera-to-site ``rotation`` captures.

    ``chips`` is every luminaire's frame ('0'/'1' per chip), ``chip_rate_hz`` the site's
    chip rate (or each luminaire's, (N,): a tone site, :func:`render_tones`); ``rng`` draws
    the phases, brightness factors and noise (seeded for tests).
    ``phase_chips`` (each frame's phase at row 0's exposure start) and ``gain`` (each LED's
    brightness factor), when given, are used instead of drawn: consecutive video frames.
    ``glow`` (radius factor, brightness share) adds round each LED a concentric, wider and dimmer disc playing
    the same chips: a small chip (often saturated) in the glow of its diffuser (issue 37).
    """
    rng = rng or np.random.default_rng()
    n = len(xyz)
    rates = np.broadcast_to(np.asarray(chip_rate_hz, dtype=float), (n,))
    if phase_chips is None:
        phase_chips = rng.uniform(0.0, [len(c) for c in chips]) if n else np.zeros(0)
    if gain is None:
        gain = 1.0 + rng.uniform(-sensor.led_spread, sensor.led_spread, n)
    if glow is not None:
        frame = render_frame(np.vstack([xyz, xyz]), np.r_[radii, glow[0] * np.asarray(radii)], list(chips) * 2,
                             np.r_[rates, rates], camera, position, rotation, sensor, rng,
                             np.r_[phase_chips, phase_chips], np.r_[gain, glow[1] * gain])
        return Frame(frame.image, np.unique(frame.drawn % n), phase_chips)
    height, width = camera.height_px, camera.width_px
    phase = phase_chips
    img: np.ndarray = np.full((height, width), sensor.dark_dn, np.float32)  # float32 (cv2's blur keeps it)
    in_front = project_discs_at(position[None], rotation[None], xyz[None], radii[None], camera)["in_front"][0]
    centres, shapes, ok = centre_and_shape(disc_dual_conic(position, rotation, xyz, radii, camera))
    drawn = []
    margin = 2.0 + 3.0 * sensor.blur_px
    for k in np.flatnonzero(in_front & ok):
        m2 = shapes[k] @ shapes[k]
        half = np.sqrt(np.diag(m2))
        if camera.distorted:  # the block holding the disc's distorted rim
            rim = camera.distorted_pixels(centres[k] + _unit_circle() @ shapes[k])
            rim = rim[np.isfinite(rim).all(axis=1)]
            if not len(rim):
                continue  # a rim the lens model maps nowhere (rays past the edge of its range): not imaged
            lo, hi = rim.min(axis=0) - margin, rim.max(axis=0) + margin
        else:
            lo, hi = centres[k] - half - margin, centres[k] + half + margin
        if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
            continue
        edge = [float(width), float(height)]  # clipped first: a disc far off the sensor maps past int64
        u0, v0 = np.floor(np.clip(lo, 0.0, edge)).astype(int)
        u1, v1 = np.ceil(np.clip(hi, -1.0, [width - 1.0, height - 1.0])).astype(int)
        if u0 > u1 or v0 > v1:
            continue
        rows = np.arange(v0, v1 + 1)
        if camera.distorted:
            iu, iv = _ideal_grid(camera, np.arange(u0, u1 + 1, dtype=float), rows.astype(float))
            cover = np.nan_to_num(_coverage_at(iu - centres[k][0], iv - centres[k][1], np.linalg.inv(m2)))
        else:
            cover = _coverage(np.arange(u0, u1 + 1, dtype=float), rows.astype(float), centres[k], np.linalg.inv(m2))
        drive = exposure_means(chips[k], phase[k], rows * camera.row_time_s, sensor.exposure_s, float(rates[k]),
                               sensor.off_level)
        img[v0:v1 + 1, u0:u1 + 1] += (sensor.led_dn * gain[k]) * cover * drive[:, None].astype(np.float32)
        drawn.append(k)
    if sensor.blur_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), sensor.blur_px)
    sigma = sensor.shot_dn * img  # in place from here on: the frame is 12 M pixels
    sigma += sensor.read_noise_dn**2
    noise = rng.standard_normal(img.shape, dtype=np.float32)
    noise *= np.sqrt(sigma, out=sigma)
    img += noise
    return Frame(np.clip(np.rint(img, out=img), 0, 255, out=img).astype(np.uint8), np.array(drawn, int), phase)


def render_tones(xyz: np.ndarray, radii: np.ndarray, tones_hz: np.ndarray, camera: Camera, position: np.ndarray,
                 rotation: np.ndarray, sensor: Sensor = Sensor(), rng: np.random.Generator | None = None,
                 glow: tuple[float, float] | None = None) -> Frame:
    """The frame of a tone site (docs/tones.md): each LED a square wave at its tone [Hz], i.e. the frame ``10``
    played at twice the tone, from a random phase. ``glow`` (radius factor, brightness share) adds a concentric,
    dimmer disc playing the same wave: a small chip (often saturated) in the glow of its diffuser."""
    rng = rng or np.random.default_rng()
    n = len(xyz)
    phase = rng.uniform(0.0, 2.0, n)
    gain = 1.0 + rng.uniform(-sensor.led_spread, sensor.led_spread, n)
    return render_frame(xyz, radii, ["10"] * n, 2.0 * np.asarray(tones_hz, dtype=float), camera, position, rotation,
                        sensor, rng, phase, gain, glow)
