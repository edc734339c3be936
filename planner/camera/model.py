"""The camera model: the receiver the plan is made for, its poses, and what it sees.

Defaults follow the paper's experiment and PRODUCT.md: horizontal field of view
50.4 deg, a 4000 x 3000 px image (assumed; the paper does not say), receiver
0.5-1.5 m above the floor, tilt up to 40 deg in any direction, any rotation
about the optical axis, rolling-shutter row time 20 us. Angles are radians
inside; degrees only at the user's edge (``to_dict``, camera YAML).

Camera frame: z along the optical axis (towards the ceiling), x to the image's
right, y down the image; pixel (u, v) = (fx X/Z + cx, fy Y/Z + cy) with the
origin at the top-left corner.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from planner.camera import lens


@dataclass(frozen=True)
class Camera:
    """A pinhole camera with a rolling shutter, and the poses it is held in.

    Attributes
    ----------
    width_px, height_px : int
        Image size [px].
    fx_px, fy_px, cx_px, cy_px : float
        Focal lengths and principal point [px].
    min_height_m, max_height_m : float
        Range of receiver heights above the floor [m].
    max_tilt_rad : float
        Largest tilt of the optical axis from vertical, in any direction [rad].
    row_time_s : float
        Rolling-shutter time between two image rows [s].
    lens : str
        Distortion model: ``"pinhole"`` (OpenCV's ``k1 k2 p1 p2 k3``) or ``"fisheye"``
        (OpenCV's ``k1 k2 k3 k4``); see :mod:`planner.camera.lens`.
    distortion : tuple of float
        The model's coefficients in OpenCV's order; empty (or all zero) is the ideal pinhole.
    name : str
        The profile the camera came from (``--camera NAME``), or empty.
    """

    width_px: int = 4000
    height_px: int = 3000
    fx_px: float = 2000.0 / math.tan(math.radians(50.4) / 2)
    fy_px: float = 2000.0 / math.tan(math.radians(50.4) / 2)
    cx_px: float = 2000.0
    cy_px: float = 1500.0
    min_height_m: float = 0.5
    max_height_m: float = 1.5
    max_tilt_rad: float = math.radians(40.0)
    row_time_s: float = 20e-6
    lens: str = "pinhole"
    distortion: tuple[float, ...] = ()
    name: str = ""

    @classmethod
    def from_fov(cls, hfov_rad: float, width_px: int = 4000, height_px: int = 3000, **kw) -> Camera:
        """Square pixels, principal point at the image centre, focal length from the field of view."""
        f = (width_px / 2) / math.tan(hfov_rad / 2)
        return cls(width_px, height_px, f, f, width_px / 2, height_px / 2, **kw)

    @property
    def hfov_rad(self) -> float:
        """Horizontal field of view through the principal point [rad], the lens's distortion included."""
        if not self.distorted:
            return 2 * math.atan(self.width_px / (2 * self.fx_px))
        left, right = self.rays(np.array([[0.0, self.cy_px], [float(self.width_px), self.cy_px]]))
        return math.atan2(-left[0], left[2]) + math.atan2(right[0], right[2])

    @property
    def distorted(self) -> bool:
        """Whether the lens distorts (any non-zero coefficient)."""
        return any(self.distortion)

    @property
    def dist_coeffs(self) -> np.ndarray:
        """The distortion coefficients as OpenCV takes them (5 for pinhole, 4 for fisheye)."""
        return lens.padded(self.lens, self.distortion)

    def ideal(self) -> Camera:
        """This camera with its distortion ignored (what a receiver that forgets it assumes)."""
        return dataclasses.replace(self, lens="pinhole", distortion=())

    def project(self, points_cam: np.ndarray) -> np.ndarray:
        """Pixels (..., 2) [px] of camera-frame points or rays (..., 3), with the lens's distortion."""
        xy = lens.distort_rays(self.lens, self.distortion, points_cam) if self.distorted else \
            np.asarray(points_cam, float)[..., :2] / np.asarray(points_cam, float)[..., 2:3]
        return np.stack([self.fx_px * xy[..., 0] + self.cx_px, self.fy_px * xy[..., 1] + self.cy_px], axis=-1)

    def normalized(self, uv_px: np.ndarray) -> np.ndarray:
        """Ideal normalised coordinates (..., 2) ``(X/Z, Y/Z)`` of pixels (..., 2) [px], distortion
        removed (NaN where the lens's map folds)."""
        uv = np.asarray(uv_px, float)
        xy_d = np.stack([(uv[..., 0] - self.cx_px) / self.fx_px, (uv[..., 1] - self.cy_px) / self.fy_px], axis=-1)
        return lens.undistort_normalized(self.lens, self.distortion, xy_d) if self.distorted else xy_d

    def ideal_pixels(self, uv_px: np.ndarray) -> np.ndarray:
        """Where pixels (..., 2) [px] would be with an ideal lens of the same intrinsics: the bridge from a
        distorted image to every pinhole formula (the paper's Eq. 1-14, P3P, the disc conics)."""
        xy = self.normalized(uv_px)
        return np.stack([self.fx_px * xy[..., 0] + self.cx_px, self.fy_px * xy[..., 1] + self.cy_px], axis=-1)

    def distorted_pixels(self, ideal_px: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`ideal_pixels`: where the lens puts ideal-pinhole pixels (..., 2) [px]."""
        uv = np.asarray(ideal_px, float)
        xy = np.stack([(uv[..., 0] - self.cx_px) / self.fx_px, (uv[..., 1] - self.cy_px) / self.fy_px], axis=-1)
        if self.distorted:
            xy = lens.distort_normalized(self.lens, self.distortion, xy)
        return np.stack([self.fx_px * xy[..., 0] + self.cx_px, self.fy_px * xy[..., 1] + self.cy_px], axis=-1)

    @cached_property
    def view_px(self) -> tuple[float, float, float, float]:
        """The *view* ``(u_lo, u_hi, v_lo, v_hi)`` in ideal pixels [px]: an LED counts as wholly seen when its
        ideal (pinhole) image lies inside this rectangle. Without distortion it is the sensor itself; with
        distortion, the rectangle about the principal point whose distorted image lies on the sensor
        (:func:`planner.camera.lens.view_rectangle`; docs/verification.md, "Lens distortion")."""
        if not self.distorted:
            return 0.0, float(self.width_px), 0.0, float(self.height_px)
        sensor = ((0.0 - self.cx_px) / self.fx_px, (self.width_px - self.cx_px) / self.fx_px,
                  (0.0 - self.cy_px) / self.fy_px, (self.height_px - self.cy_px) / self.fy_px)
        xl, xr, yt, yb = lens.view_rectangle(self.lens, tuple(self.distortion), sensor)
        return (self.cx_px + self.fx_px * xl, self.cx_px + self.fx_px * xr,
                self.cy_px + self.fy_px * yt, self.cy_px + self.fy_px * yb)

    def rays(self, uv_px: np.ndarray) -> np.ndarray:
        """Unit camera-frame rays (..., 3) through pixels (..., 2) [px], distortion removed."""
        xy = self.normalized(uv_px)
        r = np.concatenate([xy, np.ones_like(xy[..., :1])], axis=-1)
        return r / np.linalg.norm(r, axis=-1, keepdims=True)

    @property
    def intrinsics(self) -> np.ndarray:
        """The 3 x 3 camera matrix K [px]."""
        return np.array([[self.fx_px, 0, self.cx_px], [0, self.fy_px, self.cy_px], [0, 0, 1.0]])

    def to_dict(self) -> dict:
        """The camera as written into ``plan.yaml`` (degrees and SI units, as named)."""
        return {
            "width_px": self.width_px,
            "height_px": self.height_px,
            "fx_px": round(self.fx_px, 3),
            "fy_px": round(self.fy_px, 3),
            "cx_px": round(self.cx_px, 3),
            "cy_px": round(self.cy_px, 3),
            "hfov_deg": round(math.degrees(self.hfov_rad), 4),
            "receiver_height_m": [self.min_height_m, self.max_height_m],
            "max_tilt_deg": round(math.degrees(self.max_tilt_rad), 6),
            "row_time_s": self.row_time_s,
            **({"lens": self.lens, "distortion": [float(k) for k in self.distortion]} if self.distorted else {}),
            **({"name": self.name} if self.name else {}),
        }

    @classmethod
    def from_dict(cls, d: dict) -> Camera:
        """Inverse of :meth:`to_dict`; also accepts ``hfov_deg`` without focal lengths."""
        extra: dict[str, Any] = {
            "min_height_m": float(d.get("receiver_height_m", [0.5, 1.5])[0]),
            "max_height_m": float(d.get("receiver_height_m", [0.5, 1.5])[1]),
            "max_tilt_rad": math.radians(float(d.get("max_tilt_deg", 40.0))),
            "row_time_s": float(d.get("row_time_s", 20e-6)),
            "lens": str(d.get("lens", "pinhole")),
            "distortion": tuple(float(k) for k in d.get("distortion", ())),
            "name": str(d.get("name", "")),
        }
        w, h = int(d.get("width_px", 4000)), int(d.get("height_px", 3000))
        if "fx_px" in d:
            return cls(w, h, float(d["fx_px"]), float(d.get("fy_px", d["fx_px"])),
                       float(d.get("cx_px", w / 2)), float(d.get("cy_px", h / 2)), **extra)
        return cls.from_fov(math.radians(float(d.get("hfov_deg", 50.4))), w, h, **extra)


@dataclass(frozen=True)
class Poses:
    """Camera poses, stored as angles; rotations are built when asked for (per batch),
    so ten million poses take 0.5 GB, not several.

    Attributes
    ----------
    position : numpy.ndarray, shape (P, 3)
        Camera centre in site coordinates [m].
    tilt_rad, azimuth_rad, roll_rad : numpy.ndarray, shape (P,)
        Tilt of the optical axis from vertical, the plan direction it tilts towards,
        and the rotation about the optical axis [rad] (see :func:`rotation_from_angles`).
    """

    position: np.ndarray
    tilt_rad: np.ndarray
    azimuth_rad: np.ndarray
    roll_rad: np.ndarray

    def __len__(self) -> int:
        return len(self.position)

    @cached_property
    def rotation(self) -> np.ndarray:
        """Camera-to-site rotations, shape (P, 3, 3): columns are the camera's x, y, z axes."""
        return rotation_from_angles(self.tilt_rad, self.azimuth_rad, self.roll_rad)

    def subset(self, index) -> Poses:
        return Poses(self.position[index], self.tilt_rad[index], self.azimuth_rad[index], self.roll_rad[index])


def rotation_from_angles(tilt_rad, azimuth_rad, roll_rad) -> np.ndarray:
    """Camera-to-site rotations, shape (P, 3, 3), of a camera looking up.

    Roll turns the camera about its optical axis; then the axis is tilted by
    ``tilt_rad`` from vertical towards the plan direction ``azimuth_rad``.
    """
    tilt, az, roll = (np.atleast_1d(np.asarray(a, dtype=float)) for a in (tilt_rad, azimuth_rad, roll_rad))
    cr, sr = np.cos(roll), np.sin(roll)
    base = np.zeros((len(roll), 3, 3))  # level camera, rolled: x, y horizontal, z up
    base[:, 0, 0], base[:, 1, 0] = cr, sr
    base[:, 0, 1], base[:, 1, 1] = -sr, cr
    base[:, 2, 2] = 1.0
    # Rodrigues rotation by `tilt` about the horizontal axis k = (-sin az, cos az, 0),
    # which takes the vertical towards (cos az, sin az).
    k = np.stack([-np.sin(az), np.cos(az), np.zeros_like(az)], axis=1)
    kx = np.zeros((len(az), 3, 3))
    kx[:, 0, 1], kx[:, 0, 2] = -k[:, 2], k[:, 1]
    kx[:, 1, 0], kx[:, 1, 2] = k[:, 2], -k[:, 0]
    kx[:, 2, 0], kx[:, 2, 1] = -k[:, 1], k[:, 0]
    st, ct = np.sin(tilt)[:, None, None], np.cos(tilt)[:, None, None]
    tilt_rot = np.eye(3)[None] + st * kx + (1 - ct) * (kx @ kx)
    return tilt_rot @ base


def project_discs(poses: Poses, centres: np.ndarray, radii: np.ndarray, camera: Camera) -> dict:
    """Exact perspective images of horizontal LED discs, for pose/LED pairs.

    ``centres`` has shape (P, K, 3) [m] and ``radii`` (P, K) [m]: K LEDs per pose.
    The disc's image is the conic whose dual is ``C* = H diag(r^2, r^2, -1) H^T``,
    with ``H`` the homography from the disc's plane to the image, so the image's
    bounding box is exact (tangent lines ``u = const`` solve a quadratic in ``u``).

    Returns arrays of shape (P, K): ``u``, ``v`` (projected disc centre [px]),
    ``in_front`` (every rim point in front of the camera), ``inside`` (the whole
    disc image lies inside the image), and ``depth`` (centre depth along the axis [m]).

    With lens distortion ``u, v`` and the conic are those of the ideal pinhole of the same
    intrinsics (``camera.ideal_pixels`` space, where the distance from the principal point
    ranks LEDs by ray angle), and ``inside`` means inside ``camera.view_px``, the rectangle
    of ideal pixels that the lens maps onto the sensor (docs/verification.md).
    """
    return project_discs_at(poses.position, poses.rotation, centres, radii, camera)


def _disc_terms(position: np.ndarray, rotation: np.ndarray, centres: np.ndarray, radii: np.ndarray,
                camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Columns of ``H = K R^T [x y (c - p)]``, the map from a disc's plane (site x, y axes
    through its centre ``c``) to the image: ``h1``, ``h2`` (..., 1, 3), ``h3`` (..., K, 3), and
    ``r^2`` (..., K) [m^2]; shapes as in :func:`disc_conics`."""
    kr = camera.intrinsics @ np.swapaxes(rotation, -1, -2)  # (..., 3, 3): K R^T
    h3 = np.einsum("...ij,...kj->...ki", kr, centres - position[..., None, :])
    return kr[..., None, :, 0], kr[..., None, :, 1], h3, np.asarray(radii, float) ** 2


def _conic_entry(terms: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], i: int, j: int) -> np.ndarray:
    """Entry ``(i, j)`` of the dual conics of :func:`disc_conics`, alone (the hot paths need five)."""
    h1, h2, h3, r2 = terms
    return r2 * (h1[..., i] * h1[..., j] + h2[..., i] * h2[..., j]) - h3[..., i] * h3[..., j]


def disc_conics(position: np.ndarray, rotation: np.ndarray, centres: np.ndarray, radii: np.ndarray,
                camera: Camera) -> np.ndarray:
    """Dual conics ``C* = H diag(r^2, r^2, -1) H^T`` of horizontal discs' exact images (..., K, 3, 3).

    The one disc-image model (:func:`_disc_terms`), for camera centres ``position`` (..., 3) [m]
    and camera-to-site rotations ``rotation`` (..., 3, 3); ``centres`` (..., K, 3) [m] and
    ``radii`` broadcastable to (..., K) [m].
    """
    h1, h2, h3, r2 = _disc_terms(position, rotation, centres, radii, camera)
    base = h1[..., :, None] * h1[..., None, :] + h2[..., :, None] * h2[..., None, :]
    return r2[..., None, None] * base - h3[..., :, None] * h3[..., None, :]


RIM_SAMPLES = 32
"""Rim points per disc from which a distorted camera's image heights are bounded below."""


def disc_image_rows(position: np.ndarray, rotation: np.ndarray, centres: np.ndarray, radii: np.ndarray,
                    camera: Camera) -> np.ndarray:
    """Height [rows] of the exact images of horizontal discs, shapes as in :func:`disc_conics`.

    With lens distortion the image is no conic: the height is the spread of :data:`RIM_SAMPLES` rim
    points projected through the lens, a lower bound (the rim between samples can only reach further),
    short of the true height by at most ``1 - cos(pi / RIM_SAMPLES)`` (0.5 %) of it.
    """
    if camera.distorted:
        return _distorted_rows(np.asarray(position, float), np.asarray(rotation, float),
                               np.asarray(centres, float), np.asarray(radii, float), camera)
    t = _disc_terms(position, rotation, centres, radii, camera)
    c11, c12, c22 = _conic_entry(t, 1, 1), _conic_entry(t, 1, 2), _conic_entry(t, 2, 2)
    return 2 * np.sqrt(np.maximum(c12**2 - c11 * c22, 0.0)) / np.abs(c22)


def _distorted_rows(position: np.ndarray, rotation: np.ndarray, centres: np.ndarray, radii: np.ndarray,
                    camera: Camera) -> np.ndarray:
    """:func:`disc_image_rows` through the lens: rows spanned by projected rim samples (a lower bound)."""
    lead = centres.shape[:-1]
    pos = np.broadcast_to(position[..., None, :], lead + (3,)).reshape(-1, 3)
    rot = np.broadcast_to(rotation[..., None, :, :], lead + (3, 3)).reshape(-1, 3, 3)
    c, r = centres.reshape(-1, 3), np.broadcast_to(radii, lead).reshape(-1)
    phi = 2 * np.pi * np.arange(RIM_SAMPLES) / RIM_SAMPLES
    ring = np.column_stack([np.cos(phi), np.sin(phi), np.zeros_like(phi)])
    out = np.empty(len(c))
    for s in range(0, len(c), 20_000):  # (chunk, RIM_SAMPLES, 3) temporaries
        part = slice(s, s + 20_000)
        rim = c[part, None, :] + r[part, None, None] * ring - pos[part, None, :]
        cam = np.einsum("nji,nkj->nki", rot[part], rim)  # site -> camera: R^T (x - p)
        out[part] = np.ptp(camera.project(cam)[..., 1], axis=1)
    return out.reshape(lead)


def project_discs_at(position: np.ndarray, rotation: np.ndarray, centres: np.ndarray, radii: np.ndarray,
                     camera: Camera) -> dict:
    """:func:`project_discs` for camera centres (P, 3) [m] and camera-to-site rotations (P, 3, 3)."""
    rot_t = np.swapaxes(rotation, 1, 2)  # site -> camera
    terms = _disc_terms(position, rotation, centres, radii, camera)
    h3 = terms[2]
    depth = np.einsum("pj,pkj->pk", rot_t[:, 2], centres - position[:, None, :])
    rim_depth = radii * np.hypot(rot_t[:, 2, 0], rot_t[:, 2, 1])[:, None]
    in_front = depth - rim_depth > 1e-9
    c22 = _conic_entry(terms, 2, 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = h3[..., 0] / h3[..., 2]
        v = h3[..., 1] / h3[..., 2]
        inside = in_front.copy()
        u_lo, u_hi, v_lo, v_hi = camera.view_px
        for axis, low, size in ((0, u_lo, u_hi), (1, v_lo, v_hi)):
            c00, c02 = _conic_entry(terms, axis, axis), _conic_entry(terms, axis, 2)
            disc = np.sqrt(np.maximum(c02**2 - c00 * c22, 0.0))
            lo, hi = (c02 - disc) / c22, (c02 + disc) / c22
            inside &= (np.minimum(lo, hi) >= low) & (np.maximum(lo, hi) <= size)
    return {"u": u, "v": v, "in_front": in_front, "inside": inside, "depth": depth}


def disc_dual_conic(position: np.ndarray, rotation: np.ndarray, centre: np.ndarray, radius_m,
                    camera: Camera) -> np.ndarray:
    """:func:`disc_conics` for one camera (centre [m], camera-to-site rotation 3 x 3);
    ``centre`` (3,) or (N, 3) [m] and ``radius_m`` scalar or (N,) [m]; returns (3, 3) or (N, 3, 3)."""
    c = np.asarray(centre, float)
    out = disc_conics(np.asarray(position, float), np.asarray(rotation, float), c.reshape(-1, 3),
                      np.broadcast_to(np.asarray(radius_m, float), c.shape[:-1]).reshape(-1), camera)
    return out[0] if c.ndim == 1 else out
