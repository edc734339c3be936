"""What the tests of vlp-flash against simulated drivers share: the site key, grid-32's names and its two plans, a
bus URL, a driver booted from its flash file, the installed ``vlp-flash`` and a journal's entries."""

import json
import subprocess
from pathlib import Path

from conftest import SITE_KEY, grid32_copy, vlp
from planner.flash.sim.driver import Flash, SimulatedDriver

KEY = SITE_KEY
NAMES32 = [f"R{r:02d}C{c:02d}" for r in range(1, 5) for c in range(1, 9)]  # grid-32 in plan order


def planned_twice(tmp_path_factory) -> Path:
    """grid-32 planned twice: ``a``, and its re-plan ``b`` (another height, so another plan hash); read only."""
    base = tmp_path_factory.mktemp("plans")
    (base / "key").write_text(KEY.hex())
    for name, extra in (("a", []), ("b", ["--height", "2.4"])):  # sealed: vlp-flash flashes no other plan
        grid32_copy(tmp_path_factory, base / name, *extra, sealed=True)  # planned once per run, for tests/flash
    return base


def bus_url(n: int, flash: Path | None = None, extra: str = "") -> str:
    """``n`` simulated drivers under the site key (their flash files in ``flash``, if given)."""
    return f"sim://?drivers={n}&key={KEY.hex()}" + (f"&flash={flash}" if flash else "") + extra


def booted(path: Path, serial_: str = "check") -> SimulatedDriver:
    """A driver booted from a flash file, as after a power cycle."""
    return SimulatedDriver(1, serial_, KEY, Flash(4096, path))


def flash_run(*args: str) -> subprocess.CompletedProcess:
    """The installed ``vlp-flash`` console script."""
    return vlp("vlp-flash", *args)


def journal_entries(journal: Path) -> dict[str, dict]:
    return json.loads(journal.read_text())["luminaires"]
