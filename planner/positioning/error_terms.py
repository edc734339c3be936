"""The error budget: what moves a camera fix besides pixel noise, each term simulated.

The receiver solves with the drawing's luminaire positions and the camera it believes
(the plan's); the image is made by the luminaires as installed, a camera whose
calibration is off, and a rolling shutter on a moving phone. The terms
(:class:`ErrorTerms`; defaults in :mod:`planner.defaults`, docs/positioning.md#error-budget):

- **install**: each luminaire's centre lies uniformly in a horizontal disc of radius
  ``install_m`` around its drawn position (one draw per site, or per trial of the paper's rig).
- **calibration**: the imaging camera's focal lengths are the believed ones times
  ``1 + e``, ``e ~ N(0, focal_rel)`` (one ``e`` for both axes), its principal point is
  off by ``N(0, principal_px)`` per axis, and a radial term ``k1 r^2`` the calibration
  missed displaces points by an RMS over the image of ``|N(0, distortion_px)|``.
- **edge**: Gaussian noise of ``edge_px`` on every rim point, then rounding to whole
  pixels (the observation model's, :mod:`planner.positioning.observation`); off, the
  rim points are exact.
- **skew**: the rolling shutter exposes row ``v`` ``(v - cy) row_time_s`` after the
  middle row while the phone moves at ``speed_m_s`` in a random horizontal direction
  and turns at ``turn_rad_s`` about a random axis; the truth is the pose at the middle row.
- **accelerometer**: the gravity receiver's measured vertical is the true one turned by
  ``gravity_rad`` RMS (the twin's model, :func:`planner.positioning.gravity.accelerometer`); off (0) by
  default, a gravity plan switches it on at its receiver's ``accelerometer_sigma_deg``.

Each term draws from its own random stream, so a run with one term alone and a run
with all share that term's draws.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from planner.camera.ellipse import centre_and_shape, fit_ellipse
from planner.camera.model import Camera, disc_dual_conic
from planner.defaults import (
    DISTORTION_RESIDUAL_PX,
    FOCAL_ERROR_PCT,
    INSTALL_ERROR_M,
    NOISE_PX,
    PHONE_SPEED_M_S,
    PHONE_TURN_DEG_S,
    PRINCIPAL_ERROR_PX,
)
from planner.positioning.observation import Sighting, seen_leds

TERMS = {
    "install": ("install_m",),
    "calibration": ("focal_rel", "principal_px", "distortion_px"),
    "edge": ("edge_px",),
    "skew": ("speed_m_s", "turn_rad_s"),
    "accelerometer": ("gravity_rad",),
}
"""The budget's terms and the :class:`ErrorTerms` fields each is made of."""

TERM_NAMES = {"install": "luminaire install tolerance", "calibration": "camera calibration error",
              "edge": "edge noise", "skew": "rolling-shutter skew",
              "accelerometer": "accelerometer error", "exact": "the method's own error"}
"""What each term (and the run without any, ``exact``) is called in tables and reports."""


@dataclass(frozen=True)
class ErrorTerms:
    """The error sources a simulation includes (0 switches one off); see the module docstring."""

    install_m: float = INSTALL_ERROR_M
    focal_rel: float = FOCAL_ERROR_PCT / 100
    principal_px: float = PRINCIPAL_ERROR_PX
    distortion_px: float = DISTORTION_RESIDUAL_PX
    edge_px: float = NOISE_PX
    speed_m_s: float = PHONE_SPEED_M_S
    turn_rad_s: float = math.radians(PHONE_TURN_DEG_S)
    gravity_rad: float = 0.0  # the gravity receiver's only; its plans set it (module docstring)

    def only(self, term: str) -> ErrorTerms:
        """These terms with every one but ``term`` switched off."""
        return dataclasses.replace(self, **{f: 0.0 for name, fields in TERMS.items() if name != term for f in fields})

    @property
    def active(self) -> list[str]:
        """The terms switched on, in :data:`TERMS` order."""
        return [name for name, fields in TERMS.items() if any(getattr(self, f) for f in fields)]

    def to_dict(self) -> dict:
        """The terms as recorded (``plan.yaml``, ``--json``): SI units, the turn rate in degrees, focal in %."""
        return {"install_m": self.install_m, "focal_pct": round(100 * self.focal_rel, 6),
                "principal_px": self.principal_px, "distortion_px": self.distortion_px, "edge_px": self.edge_px,
                "speed_m_s": self.speed_m_s, "turn_deg_s": round(math.degrees(self.turn_rad_s), 6),
                "accelerometer_deg": round(math.degrees(self.gravity_rad), 6)}

    @classmethod
    def from_dict(cls, d: dict) -> ErrorTerms:
        return cls(d["install_m"], d["focal_pct"] / 100, d["principal_px"], d["distortion_px"], d["edge_px"],
                   d["speed_m_s"], math.radians(d["turn_deg_s"]), math.radians(d.get("accelerometer_deg", 0.0)))


DEFAULT_TERMS = ErrorTerms()
"""Every term at its default."""

PIXEL_ONLY = DEFAULT_TERMS.only("edge")
"""Edge noise alone: the model the error map had before the budget."""

NO_TERMS = DEFAULT_TERMS.only("")
"""No error at all: exact images, the method's own error."""


def describe(terms: ErrorTerms) -> dict[str, str]:
    """Each active term's values in words, e.g. ``{"install": "uniform within 2 cm of the drawing"}``."""
    t = terms
    text = {"install": f"uniform within {100 * t.install_m:g} cm of the drawing",
            "calibration": f"1 sigma: focal length {100 * t.focal_rel:g} %, principal point {t.principal_px:g} px, "
                           f"distortion residual {t.distortion_px:g} px",
            "edge": f"{t.edge_px:g} px per edge point, then whole pixels",
            "skew": f"phone at {t.speed_m_s:g} m/s turning {math.degrees(t.turn_rad_s):g} deg/s",
            "accelerometer": f"1 sigma {math.degrees(t.gravity_rad):g} deg on the measured vertical"}
    return {name: text[name] for name in t.active}


def dominant(alone: dict[str, float]) -> str | None:
    """The largest contributor, from the error of each term alone and of ``exact`` images (the method's own).

    A term's contribution is its error alone with the method's own removed in quadrature
    (independent errors add so), ``sqrt(e_k^2 - e_exact^2)``; the method's own is ``e_exact``.
    None with fewer than two terms.
    """
    base = alone.get("exact", 0.0)
    share = {k: math.sqrt(max(e * e - base * base, 0.0)) for k, e in alone.items() if k not in ("exact", "all")}
    if len(share) < 2:
        return None
    return max([*share, "exact"], key=lambda k: base if k == "exact" else share[k])


def included_text(terms: ErrorTerms) -> str:
    """What a simulation with ``terms`` includes, in words, for tables and reports."""
    parts = [f"{TERM_NAMES[k]} ({v})" for k, v in describe(terms).items()]
    return "; ".join(parts) if parts else "no error source (exact images)"


def streams(seed: int) -> dict[str, np.random.Generator]:
    """One random stream per term (and one for the poses' own draws), the same for every subset of terms; the
    accelerometer's comes after the poses', so the older streams kept their numbers."""
    order = [*(t for t in TERMS if t != "accelerometer"), "pose", "accelerometer"]
    return {name: np.random.default_rng((seed, k)) for k, name in enumerate(order)}


def installed(xyz: np.ndarray, install_m: float, rng: np.random.Generator) -> np.ndarray:
    """Luminaire centres (N x 3) [m] as installed: each uniform in a horizontal disc of radius ``install_m``."""
    n = len(xyz)
    r, phi = install_m * np.sqrt(rng.uniform(size=n)), rng.uniform(0, 2 * np.pi, n)
    return xyz + np.column_stack([r * np.cos(phi), r * np.sin(phi), np.zeros(n)])


@lru_cache(maxsize=16)
def _rms_r3(camera: Camera) -> float:
    """RMS over the image of ``r^3`` (``r`` the normalised radius): the displacement of ``k1 = 1`` is ``f r^3``."""
    u, v = np.meshgrid(np.linspace(0, camera.width_px, 41), np.linspace(0, camera.height_px, 31))
    r2 = ((u - camera.cx_px) / camera.fx_px) ** 2 + ((v - camera.cy_px) / camera.fy_px) ** 2
    return float(np.sqrt(np.mean(r2 ** 3)))


@dataclass(frozen=True)
class _Imaging:
    """The camera that made one image: perturbed intrinsics, residual ``k1``, and the phone's motion."""

    camera: Camera
    k1: float
    velocity_m_s: np.ndarray
    omega_rad_s: np.ndarray  # camera frame

    def project(self, cam: np.ndarray) -> np.ndarray:
        px = self.camera.project(cam)
        if self.k1:
            c = self.camera
            x, y = (px[:, 0] - c.cx_px) / c.fx_px, (px[:, 1] - c.cy_px) / c.fy_px
            grow = self.k1 * (x * x + y * y)
            px = px + np.column_stack([c.fx_px * grow * x, c.fy_px * grow * y])
        return px


def _imaging(camera: Camera, terms: ErrorTerms, rngs: dict[str, np.random.Generator]) -> _Imaging:
    g, s = rngs["calibration"], rngs["skew"]
    e, dc, k = g.normal(0.0, 1.0), g.normal(0.0, 1.0, 2), g.normal(0.0, 1.0)
    imaging = dataclasses.replace(camera, fx_px=camera.fx_px * (1 + terms.focal_rel * e),
                                  fy_px=camera.fy_px * (1 + terms.focal_rel * e),
                                  cx_px=camera.cx_px + terms.principal_px * dc[0],
                                  cy_px=camera.cy_px + terms.principal_px * dc[1])
    k1 = terms.distortion_px * k / (camera.fx_px * _rms_r3(camera))
    heading, axis = s.uniform(0, 2 * np.pi), s.normal(0.0, 1.0, 3)
    velocity = terms.speed_m_s * np.array([math.cos(heading), math.sin(heading), 0.0])
    return _Imaging(imaging, k1, velocity, terms.turn_rad_s * axis / np.linalg.norm(axis))


def _rim(centres: np.ndarray, radii: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Site points (sum(counts) x 3) [m] evenly spaced round horizontal discs' rims."""
    owner = np.repeat(np.arange(len(counts)), counts)
    phi = 2 * np.pi * (np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)) / counts[owner]
    return centres[owner] + radii[owner, None] * np.column_stack([np.cos(phi), np.sin(phi), np.zeros_like(phi)])


def _image_points(rim: np.ndarray, position: np.ndarray, rotation: np.ndarray, im: _Imaging) -> np.ndarray:
    """Where the rim points land [px]: each row exposed at its own time of the rolling shutter."""
    px = im.project((rim - position) @ rotation)
    if not (im.velocity_m_s.any() or im.omega_rad_s.any()):
        return px
    for _ in range(2):  # a point's row sets its time, which moves its row (by far under a pixel)
        t = (px[:, 1] - im.camera.cy_px) * im.camera.row_time_s
        cam = (rim - position - t[:, None] * im.velocity_m_s) @ rotation
        rate = float(np.linalg.norm(im.omega_rad_s))
        turned = _rotate(cam, im.omega_rad_s / rate, -rate * t) if rate > 0 else cam
        px = im.project(turned)
    return px


def _rotate(v: np.ndarray, axis: np.ndarray, angle_rad: np.ndarray) -> np.ndarray:
    """Vectors (N x 3) each turned about one unit ``axis`` by its own angle (N,) [rad] (Rodrigues' formula)."""
    c, s = np.cos(angle_rad)[:, None], np.sin(angle_rad)[:, None]
    return v * c + np.cross(axis, v) * s + np.outer(v @ axis, axis) * (1 - c)


def observe_with(position: np.ndarray, rotation: np.ndarray, xyz_installed: np.ndarray, radii: np.ndarray,
                 camera: Camera, terms: ErrorTerms, rngs: dict[str, np.random.Generator]) -> Sighting:
    """The ellipses a receiver that believes ``camera`` fits to one image made with ``terms`` at work.

    The rim points are imaged by the perturbed, moving camera (one point per pixel of
    perimeter, as :func:`planner.positioning.observation.observe`), get the edge
    noise, and are mapped through the believed camera's lens model to ideal pixels
    before the fit: solve with ``camera.ideal()``.
    """
    im = _imaging(camera, terms, rngs)
    index = seen_leds(position, rotation, xyz_installed, radii, im.camera)
    if len(index) == 0:
        return Sighting(index, [])
    _, shape, _ = centre_and_shape(disc_dual_conic(position, rotation, xyz_installed[index], radii[index], im.camera))
    counts = np.maximum(16, (np.pi * np.trace(shape, axis1=1, axis2=2)).astype(int))  # perimeter [px]
    pts = _image_points(_rim(xyz_installed[index], radii[index], counts), position, rotation, im)
    noise = rngs["edge"].normal(0.0, 1.0, pts.shape)
    if terms.edge_px > 0:
        pts = np.round(pts + terms.edge_px * noise)
    if camera.distorted:
        pts = camera.ideal_pixels(pts)
    return Sighting(index, [fit_ellipse(p) for p in np.split(pts, np.cumsum(counts)[:-1])])
