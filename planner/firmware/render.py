"""Per-luminaire firmware artifacts: a C header and JSON from templates, a binary image.

Each luminaire gets ``firmware/<file name>/`` with one file per ``*.j2`` template
(default: ``vlp_config.h`` and ``vlp_config.json``) and ``vlp_config.bin``, the
configuration image a flasher writes to the driver (its format: :mod:`planner.firmware.image`).
Everything here is pure except :func:`write_firmware`, the writer at the edge. docs/firmware.md has the template
variables, the header's contents and the image layout.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import traceback
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import jinja2

from planner._files import jinja_environment
from planner.defaults import MCU_CLOCK_HZ
from planner.errors import InputError, UsageError
from planner.firmware.image import config_image, pack_chips
from planner.plan.file import Entry, PlanFile

IMAGE_FILE = "vlp_config.bin"

_SAFE_NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]{0,63}")
_WINDOWS_RESERVED = {"CON", "PRN", "AUX", "NUL", *(f"COM{i}" for i in range(1, 10)), *(f"LPT{i}" for i in range(1, 10))}


@dataclass(frozen=True)
class TimerSetting:
    """The MCU timer that paces chips: ``ticks`` clock cycles per chip, reload ``ticks - 1``."""

    ticks: int
    reload: int
    actual_chip_rate_hz: float
    error_ppm: float


def chip_timer(chip_rate_hz: float, mcu_clock_hz: float) -> TimerSetting:
    """Nearest whole number of clock ticks per chip (ties round up) and the rate it gives."""
    ticks = math.floor(mcu_clock_hz / chip_rate_hz + 0.5)
    if ticks < 2:
        raise InputError(f"chip rate {chip_rate_hz:g} Hz is too fast for an MCU clock of {mcu_clock_hz:g} Hz")
    if ticks > 0xFFFFFFFF:  # the header's constants are 32-bit
        raise InputError(f"{ticks:,} clock ticks per chip do not fit the header's 32-bit timer constants; "
                         f"an MCU clock of {mcu_clock_hz:g} Hz is too fast for {chip_rate_hz:g} chips/s")
    actual = mcu_clock_hz / ticks
    return TimerSetting(ticks, ticks - 1, actual, (actual - chip_rate_hz) / chip_rate_hz * 1e6)


def file_name(name: str) -> str:
    """A luminaire's folder name: the name itself if safe, else a sanitised name + hash.

    Safe: 1-64 of ``A-Z a-z 0-9 . _ -``, not starting with ``.``, not a Windows device
    name. Otherwise every other character becomes ``_``, the result is cut to 48
    characters and ``-`` plus the first 8 hex digits of the name's SHA-256 are added.
    """
    if _SAFE_NAME.fullmatch(name) and name.split(".")[0].upper() not in _WINDOWS_RESERVED:
        return name
    stem = re.sub(r"[^A-Za-z0-9._-]", "_", name)[:48].lstrip(".") or "_"
    return f"{stem}-{hashlib.sha256(name.encode('utf-8')).hexdigest()[:8]}"


def c_string(text: str) -> str:
    """A C99 string literal: printable ASCII kept, ``" \\ ?`` escaped, other bytes as octal."""
    out = []
    for byte in str(text).encode("utf-8"):
        ch = chr(byte)
        out.append("\\" + ch if ch in '"\\?' else ch if 0x20 <= byte < 0x7F else f"\\{byte:03o}")
    return '"' + "".join(out) + '"'


def c_comment(text: str) -> str:
    """Text safe inside a C block comment: :func:`c_string`, with ``*/`` and ``/*`` split."""
    return re.sub(r"\*(?=/)|/(?=\*)", r"\g<0> ", c_string(text))


def default_template_dir() -> Path:
    """The bundled templates: the installed ``planner.firmware_templates``, else the source tree's."""
    try:
        path = Path(str(resources.files("planner.firmware_templates")))
        if path.is_dir():
            return path
    except ModuleNotFoundError:
        pass
    return Path(__file__).resolve().parents[2] / "firmware_templates"


def template_context(plan: PlanFile, lum: Entry, plan_hash: str, *, mcu_clock_hz: float, image_version: int) -> dict:
    """The variables a template sees for one luminaire (docs/firmware.md lists them)."""
    if lum.frame is None:
        raise InputError(f"luminaire {lum.name!r} has no frame: make the plan with a vlp-plan that writes frames")
    chips, rate = lum.frame.chips, lum.frame.chip_rate_hz
    timer = chip_timer(rate, mcu_clock_hz)
    return {
        "generator": plan.generator or "vlp-plan", "plan_hash": plan_hash, "name": lum.name,
        "file_name": file_name(lum.name), "id": lum.id, "chips": chips, "chip_count": len(chips),
        "frame_bytes": list(pack_chips(chips)), "chip_rate_hz": rate, "chip_rate_millihz": round(rate * 1000),
        "line_code": lum.frame.line_code, "mcu_clock_hz": int(mcu_clock_hz), "timer_ticks": timer.ticks,
        "timer_reload": timer.reload, "actual_chip_rate_hz": round(timer.actual_chip_rate_hz, 6),
        "chip_rate_error_ppm": round(timer.error_ppm, 3), "image_version": image_version,
        "luminaire": lum.model_dump(exclude_none=True),
        "modulation": plan.modulation.model_dump(exclude_none=True) if plan.modulation else {},
    }


def _environment(template_dir: Path) -> jinja2.Environment:
    env = jinja_environment(template_dir, html=False)
    env.filters.update(c_string=c_string, c_comment=c_comment, json=lambda v: json.dumps(v, ensure_ascii=False))
    return env


def _render(env: jinja2.Environment, template_dir: Path, name: str, context: dict) -> str:
    """Render one template; any failure becomes one InputError naming file and line."""
    path = template_dir / name
    line: int | None
    try:
        return env.get_template(name).render(context)
    except jinja2.TemplateSyntaxError as exc:
        where, line, message = Path(exc.filename or path), exc.lineno, exc.message
    except Exception as exc:  # a user's template may fail in any way: report where
        frames = [f for f in traceback.extract_tb(exc.__traceback__) if Path(f.filename).parent == template_dir]
        where, line = (Path(frames[-1].filename), frames[-1].lineno) if frames else (path, None)
        message = str(exc) if isinstance(exc, jinja2.TemplateError) else f"{type(exc).__name__}: {exc}"
    raise InputError(f"{where}{f' line {line}' if line else ''}: {message}") from None


def render_firmware(plan: PlanFile, plan_hash: str, *, template_dir: Path | None = None, mcu_clock_hz: float = MCU_CLOCK_HZ,
                    image_version: int = 1) -> dict[str, bytes]:
    """Every luminaire's artifacts as ``{"firmware/<folder>/<file>": content}``."""
    if not re.fullmatch(r"[0-9a-f]{16}", plan_hash):
        raise InputError(f"plan hash {plan_hash!r} must be 16 lowercase hex digits")
    if not (math.isfinite(mcu_clock_hz) and mcu_clock_hz >= 1 and mcu_clock_hz == int(mcu_clock_hz)):
        raise UsageError(f"MCU clock {mcu_clock_hz!r} Hz must be a positive whole number of Hz")
    template_dir = Path(template_dir).resolve() if template_dir is not None else default_template_dir()
    if not template_dir.is_dir():
        raise UsageError(f"{template_dir}: no such template folder")
    names = sorted(p.name for p in template_dir.glob("*.j2") if p.is_file())
    if not names:
        raise UsageError(f"{template_dir}: no *.j2 templates in the folder")
    if IMAGE_FILE + ".j2" in names:
        raise UsageError(f"{template_dir / (IMAGE_FILE + '.j2')}: would overwrite the binary image; rename it")
    env = _environment(template_dir)
    out: dict[str, bytes] = {}
    folders: dict[str, str] = {}  # folder name (lower case) -> the luminaire it belongs to
    for lum in plan.luminaires:
        ctx = template_context(plan, lum, plan_hash, mcu_clock_hz=mcu_clock_hz, image_version=image_version)
        other = folders.setdefault(ctx["file_name"].lower(), ctx["name"])
        if other != ctx["name"]:
            raise InputError(f"luminaires {other!r} and {ctx['name']!r} share the firmware folder "
                             f"{ctx['file_name']!r} (names compared ignoring case); rename one")
        base = f"firmware/{ctx['file_name']}/"
        for name in names:
            out[base + name[:-3]] = _render(env, template_dir, name, ctx).encode("utf-8")
        out[base + IMAGE_FILE] = config_image(ctx["name"], ctx["id"], ctx["chips"], ctx["chip_rate_hz"], plan_hash,
                                              image_version=image_version)
    return out


def write_firmware(plan: PlanFile, plan_hash: str, outdir: Path, *, template_dir: Path | None = None,
                   mcu_clock_hz: float = MCU_CLOCK_HZ, image_version: int = 1) -> list[Path]:
    """Write :func:`render_firmware`'s files under ``outdir`` (a staging folder); return their paths."""
    files = render_firmware(plan, plan_hash, template_dir=template_dir, mcu_clock_hz=mcu_clock_hz,
                            image_version=image_version)
    paths = []
    for rel, content in files.items():
        path = Path(outdir) / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(content)
        paths.append(path)
    return paths
