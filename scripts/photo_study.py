"""Measure vlp-locate --image over covered poses: docs/photos.md's "Tests and measurements" figures.

    python scripts/photo_study.py PLAN POSES OVEREXPOSURE JPEG_QUALITY

photographs ``POSES`` covered poses of PLAN (seed 5) as tests/photo/test_photo.py does
(LEDs ``OVEREXPOSURE`` times full scale, blooming, a lit ceiling, noise, sRGB, JPEG at
``JPEG_QUALITY``), decodes and locates each, and prints the located share and errors.
"""

import json
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path[:0] = [str(Path(__file__).resolve().parents[1] / "tests" / d) for d in ("", "photo")]
from test_photo import photograph  # noqa: E402

from planner.decode.image import FrameFormat  # noqa: E402
from planner.photo.asbuilt import locate_photo  # noqa: E402
from planner.photo.read import photo_blobs  # noqa: E402
from planner.plan.file import load_plan  # noqa: E402
from planner.positioning.locate import Site  # noqa: E402
from planner.twin.twin import Twin, covered_poses  # noqa: E402


def main(plan: str, count: int, overexposure: float, quality: int) -> dict:
    doc = load_plan(plan)
    camera, site, fmt = doc.camera_model(), Site.from_plan(doc), FrameFormat.from_plan(doc)
    poses = covered_poses(Twin.from_plan(doc), count, seed=5)
    errors, failures = [], []
    with tempfile.TemporaryDirectory() as tmp:
        photo = Path(tmp) / "photo.jpg"
        for k in range(count):
            angles = np.degrees([poses.tilt_rad[k], poses.azimuth_rad[k], poses.roll_rad[k]])
            truth, _ = photograph(Path(plan), (*poses.position[k], *angles), photo, seed=k,
                                  overexposure=overexposure, quality=quality)
            fix = locate_photo(site, photo_blobs(photo, camera, fmt), camera)
            if fix.located is None:
                failures.append(fix.problem)
            else:
                errors.append(float(np.linalg.norm(fix.located.fix.position - truth)))
    e = np.array(errors)
    return {"poses": count, "overexposure": overexposure, "quality": quality, "located": len(e),
            "median_mm": round(1e3 * float(np.median(e)), 2) if len(e) else None,
            "max_mm": round(1e3 * float(e.max()), 2) if len(e) else None, "failures": failures}


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4]))))
