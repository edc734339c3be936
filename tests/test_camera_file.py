import math

import pytest

from planner.camera.file import read_camera
from planner.camera.model import Camera
from planner.errors import InputError


def test_defaults_are_the_papers_camera(tmp_path):
    path = tmp_path / "cam.yaml"
    path.write_text("{}\n")
    cam = read_camera(path)
    assert cam == Camera()
    assert math.degrees(cam.hfov_rad) == pytest.approx(50.4)


def test_intrinsics_and_limits(tmp_path):
    path = tmp_path / "phone.yaml"
    path.write_text("width_px: 4032\nheight_px: 3024\nfx_px: 3100\ncx_px: 2000\nmax_tilt_deg: 30\n"
                    "receiver_height_m: [1.0, 1.2]\nrow_time_s: 1.6e-5\n")
    cam = read_camera(path)
    assert (cam.fx_px, cam.fy_px, cam.cx_px, cam.cy_px) == (3100, 3100, 2000, 1512)
    assert cam.max_tilt_rad == pytest.approx(math.radians(30))
    assert (cam.min_height_m, cam.max_height_m, cam.row_time_s) == (1.0, 1.2, 1.6e-5)
    assert Camera.from_dict(cam.to_dict()) == cam  # what plan.yaml records reads back the same


@pytest.mark.parametrize("text,message", [
    ("fov: 50\n", "fov: unknown field; known: width_px, height_px"),
    ("max_tilt_deg: 85\n", "max_tilt_deg: must be less than 80"),
    ("receiver_height_m: [2, 1]\n", "receiver_height_m must be"),
    ("hfov_deg: wide\n", "hfov_deg: must be a valid number (got 'wide')"),
    ("width_px: 1000000000\n", "width_px: must be less than or equal to 20000"),
    ("row_time_s: .nan\n", "row_time_s: must be a finite number"),
    ("- 1\n", "expected a mapping"),
])
def test_bad_camera_files(tmp_path, text, message):
    path = tmp_path / "cam.yaml"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        read_camera(path)
    assert message in str(err.value) and str(err.value).startswith(str(path))
