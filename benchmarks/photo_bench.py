"""Benchmark: ``vlp-locate --image`` on 33 MP phone photos (issue 37's aim: under 2 s and 500 MB a photo).

Run from the repository root, with the package installed:  python benchmarks/photo_bench.py [--photos 3]

Plans ``layouts/tone-rig.yaml`` (and the same five positions as a frame site) for a 33 MP phone (7,056 x 4,704 px,
2,835 px focal length, 21 us rows), renders photos as ``tests/photo/test_phone_photos.py`` does (saturated 2 cm LEDs
in a glow, blooming, sRGB, JPEG at quality 90; landscape and a turned portrait file) and runs the installed
``vlp-locate`` on each, one process a photo as a user would. Prints per photo the wall and CPU time, the process's
peak memory and the position error. Times include the interpreter's start and imports (about 0.5-1 s).
"""

from __future__ import annotations

import argparse
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests" / "photo"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photos", type=int, default=3, help="poses per site (default 3; two files each)")
    args = parser.parse_args()
    import test_phone_photos as photos  # the tests' renderer: one definition of the photo

    print(f"# {platform.node()} {platform.processor() or platform.machine()}, {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d')}; load average {' '.join(f'{x:.1f}' for x in __import__('os').getloadavg())}")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        camera = photos._camera(folder, photos.PHONE)
        layout = yaml.safe_load((ROOT / "layouts" / "tone-rig.yaml").read_text())
        for lum in layout["luminaires"]:
            del lum["tone_hz"]
        (folder / "frame-rig.yaml").write_text(yaml.safe_dump(layout))
        for site, source in (("tone", ROOT / "layouts" / "tone-rig.yaml"), ("frame", folder / "frame-rig.yaml")):
            subprocess.run(["vlp-plan", str(source), "-o", str(folder / site), "--no-firmware", "--camera", str(camera)],
                           capture_output=True, check=True)
            plan = folder / site / "plan.yaml"
            shots = photos._photos(plan, camera, range(args.photos), folder)
            for seed, (truth, files) in shots.items():
                for name, photo in files.items():
                    timing = folder / "time.txt"  # GNU time: wall, user + system CPU [s], peak resident [KiB]
                    done = subprocess.run(["/usr/bin/time", "-o", str(timing), "-f", "%e %U %S %M", "vlp-locate",
                                           str(plan), "--image", str(photo), "--camera", str(camera)],
                                          capture_output=True, text=True)
                    wall, user, system, peak_kib = (float(v) for v in timing.read_text().split()[-4:])
                    error = (np.linalg.norm(np.array(yaml.safe_load(done.stdout)["position_m"]) - truth) * 100
                             if done.returncode == 0 else float("nan"))
                    print(f"{site:5} pose {seed} {name:9}  wall {wall:5.2f} s  cpu {user + system:5.2f} s  peak "
                          f"{peak_kib / 1024:5.0f} MiB  error {error:5.2f} cm", flush=True)


if __name__ == "__main__":
    main()
