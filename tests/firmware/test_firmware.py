"""Firmware artifacts: headers compiled and run on the host, golden files, the binary image.

Golden files live in tests/golden/firmware/. After an intended change to the templates or
the image layout, regenerate them with

    VLP_UPDATE_GOLDEN=1 python -m pytest -q tests/firmware/test_firmware.py -k golden

and review the diff before committing.
"""

import hashlib
import hmac
import json
import os
import shutil
import struct
import subprocess
import zlib
from pathlib import Path

import pytest

from conftest import ROOT, minimal_plan
from planner.errors import InputError, UsageError
from planner.firmware.image import (
    CRC_OFFSET,
    IMAGE_BYTES,
    SIGNATURE_OFFSET,
    config_image,
    pack_chips,
    parse_config_image,
)
from planner.firmware.render import chip_timer, default_template_dir, file_name, render_firmware, write_firmware
from planner.plan.file import PlanFile

HERE = ROOT / "tests"
HARNESS = HERE / "harness"
GOLDEN = HERE / "golden" / "firmware"
GCC = shutil.which("gcc")
CFLAGS = ["-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror"]
HASH = "0123456789abcdef"

# Frames built here, independent of planner.modulation.frame: preamble + line-coded word.
FOUR_B_SIX_B = ("001110", "001101", "010011", "010110", "010101", "100011", "100110", "100101",
                "011001", "011010", "011100", "110001", "110010", "101001", "101010", "101100")


def manchester(word: int, bits: int) -> str:
    return "01110001" + "".join("10" if b == "1" else "01" for b in format(word, f"0{bits}b"))


def four_b_six_b(word: int, nibbles: int) -> str:
    text = format(word, f"0{4 * nibbles}b")
    return "011111000001" + "".join(FOUR_B_SIX_B[int(text[i:i + 4], 2)] for i in range(0, len(text), 4))


FRAMES = {
    "m4": (manchester(4, 4), "manchester"),        # 16 chips, the 512 grid's shape
    "m11": (manchester(1234, 11), "manchester"),   # 30 chips, not a multiple of 8
    "b1": (four_b_six_b(9, 1), "4b6b"),            # 18 chips
    "b31": (four_b_six_b(0xDEADBEEF12345678ABCDEF0123456, 31), "4b6b"),  # 198 chips
    "m96": (manchester(2**95 + 12345, 96), "manchester"),  # 200 chips
    "short": ("011100010", "manchester"),          # 9 chips
    "max": ("".join(format(b, "08b") for b in hashlib.sha256(b"x").digest() * 2)[:511], "manchester"),
}


def plan_doc(*luminaires: dict) -> PlanFile:
    """A minimal plan holding these luminaires (one stands in when none is given), checked as vlp-plan checks it."""
    return minimal_plan(list(luminaires) or [lum("R1", 1, "01")])


def lum(name: str, lum_id: int, chips: str, line_code: str = "manchester", rate_hz: float = 4470.0) -> dict:
    return {"name": name, "x": 0.25, "y": 0.5, "z": 3.0, "radius": 0.1, "parity": "odd", "region": 0,
            "id": lum_id, "frame": {"chips": chips, "chip_rate_hz": rate_hz, "line_code": line_code}}


def compile_and_run(folder: Path, tmp_path: Path, source: str = "play_frame.c") -> bytes:
    exe = tmp_path / (folder.name + "-" + Path(source).stem)
    assert GCC, "these tests compile the generated header with the real gcc: install it (apt-get install gcc)"
    build = subprocess.run([GCC, *CFLAGS, "-I", str(folder), str(HARNESS / source), "-o", str(exe)],
                           capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    return subprocess.run([str(exe)], capture_output=True, check=True).stdout


@pytest.mark.needs_gcc
@pytest.mark.parametrize("key", sorted(FRAMES))
def test_compiled_header_plays_the_frame(tmp_path, key):
    chips, code = FRAMES[key]
    doc = plan_doc(lum(f"L-{key}", 17, chips, code, 3333.3))
    write_firmware(doc, HASH, tmp_path)
    folder = tmp_path / "firmware" / f"L-{key}"
    out = compile_and_run(folder, tmp_path).decode()
    timer = chip_timer(3333.3, 16e6)
    assert out == (f"id 17\nchips {len(chips)}\nreload {timer.reload}\nticks {timer.ticks}\nmillihz 3333300\n"
                   f"rate 3333.300000\nframe {chips * 2}\nline_code {code}\nplan {HASH}\nname L-{key}\n")
    compile_and_run(folder, tmp_path, "include_only.c")  # nothing used: still no warning


@pytest.mark.needs_gcc
@pytest.mark.parametrize("name", ['a*/b "x"??/ \\', "/* é */ end \\", "?" * 9 + "*", "名前 */ #define X"])
def test_hostile_names_stay_inside_strings_and_comments(tmp_path, name):
    write_firmware(plan_doc(lum(name, 3, FRAMES["m4"][0])), HASH, tmp_path)
    (folder,) = (tmp_path / "firmware").iterdir()
    out = compile_and_run(folder, tmp_path)
    assert out.endswith(b"\nname " + name.encode("utf-8") + b"\n")
    assert json.loads((folder / "vlp_config.json").read_text("utf-8"))["luminaire"] == name


def test_names_with_control_characters_never_reach_a_template(tmp_path):
    """The name rule (planner.layout.model.name_problem) holds at every reader, so no output must escape a newline."""
    with pytest.raises(InputError, match=r"luminaires\[0\]\.name: the name holds the control character U\+000A"):
        write_firmware(plan_doc(lum("/* é */ \n\t end", 3, FRAMES["m4"][0])), HASH, tmp_path)
    assert not (tmp_path / "firmware").exists()


def hex_dump(data: bytes) -> str:
    return "".join(f"{k:04x}: {data[k:k + 16].hex(' ')}\n" for k in range(0, len(data), 16))


def test_golden_files(tmp_path):
    doc = plan_doc(lum("R01C01", 5, FRAMES["m4"][0]))
    write_firmware(doc, HASH, tmp_path)
    folder = tmp_path / "firmware" / "R01C01"
    got = {"vlp_config.h": (folder / "vlp_config.h").read_text("utf-8"),
           "vlp_config.json": (folder / "vlp_config.json").read_text("utf-8"),
           "vlp_config.bin.hex": hex_dump((folder / "vlp_config.bin").read_bytes())}
    if os.environ.get("VLP_UPDATE_GOLDEN") == "1":
        GOLDEN.mkdir(parents=True, exist_ok=True)
        for name, text in got.items():
            (GOLDEN / name).write_text(text, "utf-8", newline="\n")
    for name, text in got.items():
        assert text == (GOLDEN / name).read_text("utf-8"), f"{name} differs; see this file's docstring"


def test_json_is_valid_and_matches_the_plan(tmp_path):
    chips = FRAMES["m11"][0]
    write_firmware(plan_doc(lum("R1", 9, chips, rate_hz=4470.0)), HASH, tmp_path, mcu_clock_hz=8e6, image_version=4)
    cfg = json.loads((tmp_path / "firmware" / "R1" / "vlp_config.json").read_text("utf-8"))
    assert cfg["generator"] == "vlp-plan 0.1.0" and cfg["plan_hash"] == HASH and cfg["luminaire"] == "R1"
    assert (cfg["id"], cfg["chips"], cfg["chip_count"], cfg["image_version"]) == (9, chips, 30, 4)
    assert cfg["frame_hex"] == pack_chips(chips).hex() and cfg["mcu_clock_hz"] == 8_000_000
    assert cfg["timer_ticks"] == 1790 and cfg["timer_reload"] == 1789
    assert cfg["chip_rate_error_ppm"] == pytest.approx((8e6 / 1790 - 4470) / 4470 * 1e6, abs=1e-3)


def test_chip_timer_rounds_to_the_nearest_tick():
    timer = chip_timer(4470.0, 16e6)
    assert (timer.ticks, timer.reload) == (3579, 3578)
    assert timer.actual_chip_rate_hz == pytest.approx(16e6 / 3579)
    assert timer.error_ppm == pytest.approx(116.89, abs=0.01)
    assert chip_timer(1000.0, 2500.0).ticks == 3  # 2.5 ties up
    with pytest.raises(InputError, match="too fast"):
        chip_timer(1e6, 1.4e6)


def test_pack_chips_msb_first():
    assert pack_chips("1") == b"\x80"
    assert pack_chips("0111000110011010") == b"\x71\x9a"
    assert pack_chips("011111000001010011") == b"\x7c\x14\xc0"


# --- binary image -----------------------------------------------------------

def image(**kw) -> bytes:
    args = {"name": "R01C01", "luminaire_id": 5, "chips": FRAMES["m11"][0], "chip_rate_hz": 4470.25,
            "plan_hash": HASH} | kw
    return config_image(**args)


def test_image_round_trip_and_layout():
    data = image(image_version=7)
    assert len(data) == IMAGE_BYTES == 168 and (SIGNATURE_OFFSET, CRC_OFFSET) == (132, 164)
    assert data[:4] == b"VLPC" and struct.unpack_from("<HHI", data, 4) == (1, 12, 168)
    assert data[SIGNATURE_OFFSET:CRC_OFFSET] == bytes(32)
    assert struct.unpack_from("<I", data, CRC_OFFSET)[0] == zlib.crc32(data[:CRC_OFFSET])
    got = parse_config_image(data)
    assert got["name"] == "R01C01" and got["id"] == 5 and got["chips"] == FRAMES["m11"][0]
    assert (got["chip_rate_hz"], got["chip_count"], got["image_version"], got["plan_hash"]) == (4470.25, 30, 7, HASH)
    long = image(name="é" * 16, chips=FRAMES["max"][0], luminaire_id=2**32 - 1)
    got = parse_config_image(long)
    assert (got["name"], got["chips"], got["id"]) == ("é" * 16, FRAMES["max"][0], 2**32 - 1)


def test_image_signature_covers_everything_before_it():
    data = bytearray(image())
    key = b"site key"
    mac = hmac.new(key, bytes(data[:SIGNATURE_OFFSET]), hashlib.sha256).digest()
    data[SIGNATURE_OFFSET:CRC_OFFSET] = mac  # what the flasher of issue 6 does
    data[CRC_OFFSET:] = struct.pack("<I", zlib.crc32(bytes(data[:CRC_OFFSET])))
    assert parse_config_image(bytes(data))["signature"] == mac


def test_every_flipped_byte_is_refused():
    data = image()
    for k in range(len(data)):
        bad = bytearray(data)
        bad[k] ^= 0x01
        with pytest.raises(InputError):
            parse_config_image(bytes(bad))
    bad = bytearray(data)
    bad[60] ^= 0x10  # a chip
    with pytest.raises(InputError, match="CRC mismatch"):
        parse_config_image(bytes(bad))


def test_bad_magic_version_and_length_are_refused():
    data = image()
    with pytest.raises(InputError, match="magic b'XLPC'"):
        parse_config_image(b"X" + data[1:])
    with pytest.raises(InputError, match="format version 2"):
        parse_config_image(data[:4] + struct.pack("<H", 2) + data[6:])
    with pytest.raises(InputError, match="too short"):
        parse_config_image(data[:5])
    with pytest.raises(InputError, match="167 bytes"):
        parse_config_image(data[:-1])
    with pytest.raises(InputError, match="169 bytes"):
        parse_config_image(data + b"\0")


def test_image_refuses_what_does_not_fit():
    assert parse_config_image(image(name="N" * 32))["name"] == "N" * 32
    with pytest.raises(InputError, match="at most 32 UTF-8 bytes.*has 33"):
        image(name="N" * 33)
    with pytest.raises(InputError, match="has 34"):
        image(name="é" * 17)
    with pytest.raises(InputError, match="513 chips"):
        image(chips="01" * 256 + "1")
    with pytest.raises(InputError, match="ID 0"):
        image(luminaire_id=0)
    with pytest.raises(InputError, match="has 40"):
        write_firmware(plan_doc(lum("X" * 40, 1, "0110")), HASH, Path("/nonexistent"))


# --- templates, names, determinism -----------------------------------------

def test_default_templates_are_found():
    assert {p.name for p in default_template_dir().glob("*.j2")} >= {"vlp_config.h.j2", "vlp_config.json.j2"}


def test_custom_template_folder(tmp_path):
    tpl = tmp_path / "tpl"
    tpl.mkdir()
    (tpl / "board.ini.j2").write_text("id={{ id }}\nx={{ luminaire.x }}\nrate={{ modulation.chip_rate_hz }}\n")
    (tpl / "README").write_text("not a template")
    paths = write_firmware(plan_doc(lum("R1", 4, "0110")), HASH, tmp_path / "out", template_dir=tpl)
    assert sorted(p.name for p in paths) == ["board.ini", "vlp_config.bin"]
    assert (tmp_path / "out/firmware/R1/board.ini").read_text() == "id=4\nx=0.25\nrate=4470.0\n"


@pytest.mark.parametrize("text,message", [
    ("a\nb\n{{ foo }}\n", "my.h.j2 line 3: 'foo' is undefined"),
    ("{{ luminaire.nope }}", "my.h.j2 line 1: 'dict object' has no attribute 'nope'"),
    ("a\n{% if %}\n", "my.h.j2 line 2: Expected an expression, got 'end of statement block'"),
    ("\n\n\n{{ 1 // 0 }}", "my.h.j2 line 4: ZeroDivisionError: integer division or modulo by zero"),
])
def test_broken_template_gives_one_line(tmp_path, text, message):
    (tmp_path / "my.h.j2").write_text(text)
    with pytest.raises(InputError) as err:
        render_firmware(plan_doc(lum("R1", 4, "0110")), HASH, template_dir=tmp_path)
    assert str(err.value) == f"{(tmp_path / 'my.h.j2').resolve()} {message.removeprefix('my.h.j2 ')}"


def test_template_folder_errors(tmp_path):
    with pytest.raises(UsageError, match="no such template folder"):
        render_firmware(plan_doc(), HASH, template_dir=tmp_path / "missing")
    with pytest.raises(UsageError, match="no \\*.j2 templates"):
        render_firmware(plan_doc(), HASH, template_dir=tmp_path)
    (tmp_path / "vlp_config.bin.j2").write_text("x")
    with pytest.raises(UsageError, match="overwrite the binary image"):
        render_firmware(plan_doc(), HASH, template_dir=tmp_path)


def test_file_names():
    assert file_name("R01C01") == "R01C01" and file_name("hall-2.lamp_3") == "hall-2.lamp_3"
    for unsafe in ("a/b", "..", ".hidden", "CON", "nul.txt", "x" * 65, "é", "a b", ""):
        safe = file_name(unsafe)
        assert safe != unsafe and not safe.startswith(".") and len(safe) <= 57
        assert all(c.isascii() and (c.isalnum() or c in "._-") for c in safe)
        assert safe[-9:] == "-" + hashlib.sha256(unsafe.encode()).hexdigest()[:8]
    assert file_name("a/b") == "a_b-" + hashlib.sha256(b"a/b").hexdigest()[:8] != file_name("a_b")


def test_colliding_or_unfit_luminaires_are_refused():
    with pytest.raises(InputError, match="share the firmware folder"):
        render_firmware(plan_doc(lum("R1", 1, "01"), lum("r1", 2, "10")), HASH)
    unframed = {k: v for k, v in lum("R1", 1, "01").items() if k != "frame"}
    with pytest.raises(InputError, match="has no frame"):
        render_firmware(minimal_plan([unframed], modulation=None), HASH)
    with pytest.raises(InputError, match=r"luminaires\[0\]\.frame\.chips: must match pattern"):
        plan_doc(lum("R1", 1, "012"))
    with pytest.raises(InputError, match="16 lowercase hex"):
        render_firmware(plan_doc(lum("R1", 1, "01")), "xyz")
    with pytest.raises(UsageError, match="whole number"):
        render_firmware(plan_doc(lum("R1", 1, "01")), HASH, mcu_clock_hz=1.5e6 + 0.5)


def test_output_is_deterministic(tmp_path):
    doc = plan_doc(*(lum(f"R{k:02d}", k, chips, code) for k, (chips, code) in enumerate(FRAMES.values(), 1)))
    first = write_firmware(doc, HASH, tmp_path / "a")
    second = write_firmware(doc, HASH, tmp_path / "b")
    assert [p.relative_to(tmp_path / "a") for p in first] == [p.relative_to(tmp_path / "b") for p in second]
    assert all(a.read_bytes() == b.read_bytes() for a, b in zip(first, second))
    assert len(first) == 3 * len(FRAMES)


def test_packaging_lists_every_subpackage():
    # pyproject.toml lists packages explicitly (to map firmware_templates/ in); a new
    # subpackage missing there would be absent after `pip install .`.
    import tomllib

    listed = set(tomllib.loads((HERE.parent / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(HERE.parent).parts) for p in (HERE.parent / "planner").rglob("__init__.py")}
    assert found | {"planner.firmware_templates"} <= listed


@pytest.mark.needs_gcc
def test_vlp_plan_writes_headers_that_play_the_plans_frames(tmp_path):
    """End to end: the real planner's frames, through the bundled templates, compiled and played."""
    from planner.cli.plan import main as plan_main
    from planner.plan.file import load_plan
    from planner.plan.model import plan_hash

    out = tmp_path / "g32"
    plan_main([str(HERE.parent / "layouts" / "grid-32.yaml"), "-o", str(out), "--no-map", "--json",
               "--error-poses-per-m2", "0", "--line-code", "4b6b"])
    plan = load_plan(out / "plan.yaml")
    digest = plan_hash((out / "plan.yaml").read_text("utf-8"))
    for entry in (plan.luminaires[0], plan.luminaires[-1]):
        assert entry.frame is not None
        folder = out / "firmware" / file_name(entry.name)
        played = compile_and_run(folder, tmp_path).decode().splitlines()
        assert played[0] == f"id {entry.id}" and played[6] == "frame " + entry.frame.chips * 2
        assert f"plan {digest}" in played and "line_code 4b6b" in played
        image = parse_config_image((folder / "vlp_config.bin").read_bytes())
        assert image["chips"] == entry.frame.chips and image["plan_hash"] == digest
