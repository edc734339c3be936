"""Per-luminaire firmware artifacts: a C header and JSON from templates, a binary image.

Each luminaire gets ``firmware/<file name>/`` with one file per ``*.j2`` template
(default: ``vlp_config.h`` and ``vlp_config.json``) and ``vlp_config.bin``, the
configuration image a flasher writes to the driver. Everything here is pure except
:func:`write_firmware`, the writer at the edge. docs/firmware.md has the template
variables, the header's contents and the image layout.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import struct
import traceback
import zlib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import jinja2

from planner.errors import InputError, UsageError

IMAGE_MAGIC = b"VLPC"
IMAGE_FORMAT_VERSION = 1
NAME_BYTES = 32
MAX_IMAGE_CHIPS = 512  # the image's 64-byte chip area
# magic, format version, header length, total length | name, id, chip rate [mHz], chip count,
# reserved | chips | image version, plan hash | signature | CRC-32 (docs/firmware.md has offsets)
_HEADER = struct.Struct("<4sHHI")
_BODY = struct.Struct(f"<4sHHI{NAME_BYTES}sIIHH{MAX_IMAGE_CHIPS // 8}sI8s")
SIGNATURE_OFFSET = _BODY.size  # the signature covers bytes [0, SIGNATURE_OFFSET)
SIGNATURE_BYTES = 32
CRC_OFFSET = SIGNATURE_OFFSET + SIGNATURE_BYTES  # the CRC covers bytes [0, CRC_OFFSET)
IMAGE_BYTES = CRC_OFFSET + 4
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
    actual = mcu_clock_hz / ticks
    return TimerSetting(ticks, ticks - 1, actual, (actual - chip_rate_hz) / chip_rate_hz * 1e6)


def pack_chips(chips: str) -> bytes:
    """Chips packed MSB first (chip 0 is bit 7 of byte 0); the last byte is zero-padded."""
    padded = chips + "0" * (-len(chips) % 8)
    return bytes(int(padded[i:i + 8], 2) for i in range(0, len(padded), 8))


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


def config_image(name: str, luminaire_id: int, chips: str, chip_rate_hz: float, plan_hash: str,
                 *, image_version: int = 1) -> bytes:
    """The binary configuration image (little-endian, docs/firmware.md), signature zero."""
    raw_name = name.encode("utf-8")
    if len(raw_name) > NAME_BYTES or "\0" in name:
        raise InputError(f"luminaire {name!r}: the image holds names of at most {NAME_BYTES} UTF-8 bytes "
                         f"without NUL (this one has {len(raw_name)}); shorten the name in the layout")
    if len(chips) > MAX_IMAGE_CHIPS:
        raise InputError(f"luminaire {name!r}: frame of {len(chips)} chips; the image holds at most {MAX_IMAGE_CHIPS}")
    if not 1 <= luminaire_id < 2**32:
        raise InputError(f"luminaire {name!r}: ID {luminaire_id} does not fit the image (1 to 2^32 - 1)")
    millihz = round(chip_rate_hz * 1000)
    if not 0 < millihz < 2**32:
        raise InputError(f"luminaire {name!r}: chip rate {chip_rate_hz:g} Hz does not fit the image (u32 mHz)")
    if not 0 <= image_version < 2**32:
        raise UsageError(f"image version {image_version} must be in [0, 2^32)")
    body = _BODY.pack(IMAGE_MAGIC, IMAGE_FORMAT_VERSION, _HEADER.size, IMAGE_BYTES, raw_name, luminaire_id,
                      millihz, len(chips), 0, pack_chips(chips), image_version, bytes.fromhex(plan_hash)) + bytes(SIGNATURE_BYTES)
    return body + struct.pack("<I", zlib.crc32(body))


def parse_config_image(data: bytes) -> dict:
    """Check and decode a configuration image; :class:`InputError` says what is wrong."""
    if len(data) < _HEADER.size:
        raise InputError(f"configuration image is {len(data)} bytes, too short for its header")
    magic, version, header_len, total_len = _HEADER.unpack_from(data)
    if magic != IMAGE_MAGIC:
        raise InputError(f"not a configuration image: magic {magic!r}, expected {IMAGE_MAGIC!r}")
    if version != IMAGE_FORMAT_VERSION:
        raise InputError(f"configuration image format version {version}; this tool reads {IMAGE_FORMAT_VERSION}")
    if header_len != _HEADER.size or total_len != IMAGE_BYTES or len(data) != IMAGE_BYTES:
        raise InputError(f"configuration image is {len(data)} bytes, header says {total_len} "
                         f"(header length {header_len}); version {version} images are {IMAGE_BYTES} bytes")
    crc = struct.unpack_from("<I", data, CRC_OFFSET)[0]
    if zlib.crc32(data[:CRC_OFFSET]) != crc:
        raise InputError(f"configuration image CRC mismatch (stored {crc:08x}, computed "
                         f"{zlib.crc32(data[:CRC_OFFSET]):08x}): the image is damaged")
    fields = _BODY.unpack_from(data)
    raw_name, lum_id, millihz, count, _, packed, image_version, hash_bytes = fields[4:]
    if not 1 <= count <= MAX_IMAGE_CHIPS:
        raise InputError(f"configuration image chip count {count} outside [1, {MAX_IMAGE_CHIPS}]")
    try:
        name = raw_name.rstrip(b"\0").decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"configuration image name is not UTF-8: {exc}") from None
    chips = "".join(format(b, "08b") for b in packed)[:count]
    return {"format_version": version, "name": name, "id": lum_id, "chip_rate_hz": millihz / 1000,
            "chip_count": count, "chips": chips, "image_version": image_version, "plan_hash": hash_bytes.hex(),
            "signature": data[SIGNATURE_OFFSET:CRC_OFFSET], "crc32": crc}


def default_template_dir() -> Path:
    """The bundled templates: the installed ``planner.firmware_templates``, else the source tree's."""
    try:
        path = Path(str(resources.files("planner.firmware_templates")))
        if path.is_dir():
            return path
    except ModuleNotFoundError:
        pass
    return Path(__file__).resolve().parents[2] / "firmware_templates"


def _frame(lum: dict) -> tuple[str, str, int, str, float]:
    """Checked (name, chips, id, line code, chip rate) of a plan entry."""
    name = lum.get("name")
    if not isinstance(name, str) or not name:
        raise InputError(f"luminaire entry without a name: {lum!r}")
    frame = lum.get("frame")
    if not isinstance(frame, dict):
        raise InputError(f"luminaire {name!r} has no frame: make the plan with a vlp-plan that writes frames")
    chips, rate, code, lum_id = frame.get("chips"), frame.get("chip_rate_hz"), frame.get("line_code"), lum.get("id")
    if not isinstance(chips, str) or not chips or set(chips) - {"0", "1"}:
        raise InputError(f"luminaire {name!r}: frame.chips must be a non-empty string of 0 and 1")
    if not isinstance(lum_id, int) or isinstance(lum_id, bool) or lum_id < 1:
        raise InputError(f"luminaire {name!r}: id must be an integer >= 1, not {lum_id!r}")
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not math.isfinite(rate) or rate <= 0:
        raise InputError(f"luminaire {name!r}: frame.chip_rate_hz must be a positive number, not {rate!r}")
    if not isinstance(code, str) or not code:
        raise InputError(f"luminaire {name!r}: frame.line_code must be a name such as 'manchester'")
    return name, chips, lum_id, code, float(rate)


def template_context(doc: dict, lum: dict, plan_hash: str, *, mcu_clock_hz: float, image_version: int) -> dict:
    """The variables a template sees for one luminaire (docs/firmware.md lists them)."""
    name, chips, lum_id, code, rate = _frame(lum)
    timer = chip_timer(rate, mcu_clock_hz)
    return {
        "generator": str(doc.get("generator", "vlp-plan")), "plan_hash": plan_hash, "name": name,
        "file_name": file_name(name), "id": lum_id, "chips": chips, "chip_count": len(chips),
        "frame_bytes": list(pack_chips(chips)), "chip_rate_hz": rate, "chip_rate_millihz": round(rate * 1000),
        "line_code": code, "mcu_clock_hz": int(mcu_clock_hz), "timer_ticks": timer.ticks,
        "timer_reload": timer.reload, "actual_chip_rate_hz": round(timer.actual_chip_rate_hz, 6),
        "chip_rate_error_ppm": round(timer.error_ppm, 3), "image_version": image_version,
        "luminaire": lum, "modulation": doc.get("modulation") or {},
    }


def _environment(template_dir: Path) -> jinja2.Environment:
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(template_dir)), undefined=jinja2.StrictUndefined,
                             keep_trailing_newline=True, trim_blocks=True, lstrip_blocks=True, autoescape=False)
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


def render_firmware(doc: dict, plan_hash: str, *, template_dir: Path | None = None, mcu_clock_hz: float = 16e6,
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
    for lum in doc.get("luminaires") or []:
        ctx = template_context(doc, lum, plan_hash, mcu_clock_hz=mcu_clock_hz, image_version=image_version)
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


def write_firmware(doc: dict, plan_hash: str, outdir: Path, *, template_dir: Path | None = None,
                   mcu_clock_hz: float = 16e6, image_version: int = 1) -> list[Path]:
    """Write :func:`render_firmware`'s files under ``outdir`` (a staging folder); return their paths."""
    files = render_firmware(doc, plan_hash, template_dir=template_dir, mcu_clock_hz=mcu_clock_hz,
                            image_version=image_version)
    paths = []
    for rel, content in files.items():
        path = Path(outdir) / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(content)
        paths.append(path)
    return paths
