"""What every command shares: its parser (:func:`parser`), flag types and groups, output checks, progress.

Every ``vlp-*`` command builds its parser with :func:`parser`, so each ``--help`` has the same
layout, the same ``--json``, ``-v/--verbose`` and ``--version`` and an epilog of the same form
(exit codes, docs page); :func:`console_main` (:mod:`planner.cli.console`) runs it.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from planner import __version__
from planner.cli.console import console_main as console_main  # every command's script: cli.console_main
from planner.cli.console import one_line as one_line
from planner.cli.console import worded as worded
from planner.defaults import (
    CONGRUENCE_TOLERANCE_M,
    DISTORTION_RESIDUAL_PX,
    FOCAL_ERROR_PCT,
    INSTALL_ERROR_M,
    INSTALL_TOLERANCE_M,
    MAX_PHONE_SPEED_M_S,
    MAX_PHONE_TURN_DEG_S,
    MAX_PLAN_POSES,
    MAX_POSES_PER_M2,
    MAX_SEED,
    NOISE_PX,
    PHONE_SPEED_M_S,
    PHONE_TURN_DEG_S,
    POSES_PER_M2,
    PRINCIPAL_ERROR_PX,
    UNIT_TO_M,
)
from planner.errors import InputError, PlannerWarning, UsageError

if TYPE_CHECKING:  # the stages load when a command runs, not when it parses (--help at once)
    from planner.camera.model import Camera
    from planner.layout.read import ReadOptions


class Parser(argparse.ArgumentParser):
    """argparse that raises UsageError instead of exiting, so main() stays testable; made by :func:`parser`."""

    def error(self, message: str) -> NoReturn:
        raise UsageError(f"{message} (see {self.prog} --help)")


class HelpFormatter(argparse.HelpFormatter):
    """argparse's layout, keeping the epilog's lines apart: each line of a text is wrapped on its own."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        return "\n".join(super(HelpFormatter, self)._fill_text(line, width, indent) for line in text.splitlines())


DOCS = "docs/cli.md"
"""Where every command is listed, with its own page."""


def parser(prog: str, description: str, *, ok: str, json: str, docs: str, check_failed: str | None = None,
           bad_input: str = "", usage: str = "", note: str = "") -> Parser:
    """The parser of the command ``prog``, with what every command has: ``--json`` (its help ``json``),
    ``-v/--verbose``, ``--version`` and an epilog naming its exit codes and docs page.

    ``ok`` says what exit 0 means, ``check_failed`` exit 3 (if the command has it); ``bad_input`` and
    ``usage`` add to "1 bad input" and "2 usage error"; ``note`` is a line before the exit codes.
    """
    codes = [f"0 {ok}"] + ([f"3 {check_failed}"] if check_failed else [])
    codes += [f"1 bad input{' ' + bad_input if bad_input else ''}", f"2 usage error{' ' + usage if usage else ''}"]
    pages = docs if docs == DOCS else f"{docs}; every command: {DOCS}"
    epilog = "\n".join([*([note] if note else []), f"Exit codes: {', '.join(codes)}.", f"Docs: {pages}."])
    p = Parser(prog=prog, description=description, epilog=epilog, formatter_class=HelpFormatter)
    p.add_argument("--json", action="store_true", help=json)
    p.add_argument("-v", "--verbose", action="store_true", help="show tracebacks on errors")
    p.add_argument("--version", action="version", version=f"{prog} {__version__}")
    return p


def shown(text: str) -> str:
    """``text`` quoted for an error line, cut short if long (a 5,000-digit number is not echoed whole)."""
    quoted = repr(text)
    return quoted if len(quoted) <= 40 else f"{quoted[:30]}...' ({len(text):,} characters)"


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive whole number, got {shown(text)}")
    return value


def count_up_to(maximum: int) -> Callable[[str], int]:
    """A flag type: a positive whole number up to ``maximum`` (the work it asks is bounded)."""
    def parse(text: str) -> int:
        value = positive_int(text)
        if value > maximum:
            raise argparse.ArgumentTypeError(f"must be at most {maximum:,}, got {shown(text)}")
        return value
    return parse


def _number(text: str, minimum: float, strict: bool, maximum: float = math.inf) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (value > minimum if strict else value >= minimum) or math.isinf(value):
        raise argparse.ArgumentTypeError(f"must be a {'positive' if strict else 'non-negative'} number, got {shown(text)}")
    if value > maximum:
        raise argparse.ArgumentTypeError(f"must be at most {maximum:g}, got {shown(text)}")
    return value


def at_most(maximum: float, strict: bool = True) -> Callable[[str], float]:
    """A flag type: a positive (or, not ``strict``, non-negative) number up to ``maximum``; the work it asks is bounded."""
    def parse(text: str) -> float:
        return _number(text, 0.0, strict, maximum)
    return parse


def share(text: str) -> float:
    """A flag type: a share from 0 to 1."""
    return _number(text, 0.0, False, 1.0)


def seed(text: str) -> int:
    """A random seed: a whole number 0 .. 2**32 - 1."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"must be a whole number from 0 to {MAX_SEED}, got {shown(text)}")
    return value


def positive_float(text: str) -> float:
    return _number(text, 0.0, strict=True)


def non_negative_float(text: str) -> float:
    return _number(text, 0.0, strict=False)


def add_reading_flags(p: argparse.ArgumentParser, title: str, what: str) -> None:
    """The flags that steer how a layout or drawing ``what`` is read (vlp-plan, vlp-inspect); :func:`read_options`."""
    g = p.add_argument_group(title)
    g.add_argument("--units", choices=sorted(UNIT_TO_M), help=f"coordinate unit of {what}, overriding the file")
    g.add_argument("--preset", choices=["auto", "dialux", "revit", "generic"], default="auto",
                   help="DXF luminaire patterns (default: auto = all presets)")
    g.add_argument("--layer", action="append", default=[], metavar="PATTERN",
                   help="DXF layer pattern of luminaires (fnmatch, repeatable; replaces the preset's)")
    g.add_argument("--block", action="append", default=[], metavar="PATTERN",
                   help="DXF block-name pattern of luminaires (repeatable; replaces the preset's)")
    g.add_argument("--height", type=positive_float, metavar="M",
                   help="mounting height [m] where the layout gives none (default 2.5)")
    g.add_argument("--radius", type=positive_float, metavar="M",
                   help="LED radius [m] where the layout gives none (default 0.1)")
    g.add_argument("--room", metavar="PATTERN",
                   help="DXF: the room outline is the closed polylines whose layer, or the name written inside, "
                   "matches PATTERN (fnmatch); default: the whole floor")
    g.add_argument("--storey", metavar="NAME",
                   help="IFC: the building storey whose light fixtures to plan (name or elevation in m)")


def read_options(args: argparse.Namespace) -> ReadOptions:
    """The :class:`~planner.layout.read.ReadOptions` the flags of :func:`add_reading_flags` ask for."""
    from planner.layout.read import ReadOptions

    return ReadOptions(args.units, args.preset, tuple(args.layer), tuple(args.block), args.height, args.radius,
                       args.room, args.storey)


def add_verify_flags(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("verification")
    g.add_argument("--poses-per-m2", type=at_most(MAX_POSES_PER_M2), default=POSES_PER_M2, metavar="N",
                   help=f"camera poses sampled per square metre of floor (default {POSES_PER_M2:g}, "
                   f"at most {MAX_POSES_PER_M2:g})")
    g.add_argument("--max-poses", type=count_up_to(10**11), default=None, metavar="N",
                   help=f"most camera poses the run may sample in all (default {MAX_PLAN_POSES:,}, fewer if the "
                   "largest sample would not fit in the memory available); refused beyond, before any work")
    g.add_argument("--tolerance", type=positive_float, default=CONGRUENCE_TOLERANCE_M, metavar="M",
                   help=f"triangles whose sides differ by less than this look alike to the receiver [m] "
                   f"(default {CONGRUENCE_TOLERANCE_M:g})")
    g.add_argument("--install-tolerance", type=non_negative_float, default=None if p.prog == "vlp-verify" else
                   INSTALL_TOLERANCE_M, metavar="M",
                   help="installed luminaires may lie this far from the drawing; every triangle that may then be a "
                   f"window is protected [m] (default {INSTALL_TOLERANCE_M:g}"
                   + (", or the plan's" if p.prog == "vlp-verify" else "") + ")")
    if p.prog == "vlp-plan":
        add_camera_flag(g, "default: the paper's camera")
        g.add_argument("--no-verify", action="store_true",
                       help="skip verification of a paper or unique plan (needs an explicit --scheme; the window "
                       "scheme is built from verification and always verified)")
    else:
        add_camera_flag(g, "default: the camera recorded in the plan")


def add_parallel_flags(p: argparse.ArgumentParser) -> None:
    """``--workers`` and ``--scheduler``: where the proof's tiles run (:func:`planner.parallel.runner`)."""
    g = p.add_argument_group("parallel")
    g.add_argument("--workers", type=count_up_to(256), default=1, metavar="N",
                   help="run the proof's and the rival search's tiles on N local processes (default 1: in this "
                   "process); the outputs are byte-identical whatever runs them")
    g.add_argument("--scheduler", metavar="ADDRESS",
                   help="run the tiles on the Dask cluster whose scheduler is at ADDRESS (tcp://host:8786; "
                   "its workers need this package installed)")


def add_camera_flag(g, default: str) -> None:
    """``--camera NAME|YAML``: a bundled profile (``vlp-plan --list-cameras``) or a camera file."""
    g.add_argument("--camera", metavar="NAME|YAML",
                   help="camera profile (paper, main, wide, ultrawide, ...: vlp-plan --list-cameras) or camera "
                   f"file (docs/camera.md); {default}")


def add_error_budget_flags(p: argparse.ArgumentParser, what: str) -> None:
    """The error budget's terms (:class:`~planner.positioning.error_terms.ErrorTerms`), one group; ``what`` is
    the simulation they enter. :func:`error_terms` reads them."""
    g = p.add_argument_group("error budget", f"Error sources {what} simulates besides the method's own; 0 switches "
                             "one off (docs/positioning.md#error-budget).")
    g.add_argument("--install-error", type=non_negative_float, default=INSTALL_ERROR_M, metavar="M",
                   help="luminaires lie uniformly within this distance of their drawn position, horizontally "
                   f"[m] (default {INSTALL_ERROR_M:g}, assumed)")
    g.add_argument("--focal-error", type=at_most(100.0, strict=False), default=FOCAL_ERROR_PCT, metavar="PCT",
                   help=f"calibrated focal length's error, 1 sigma [%%] (default {FOCAL_ERROR_PCT:g})")
    g.add_argument("--principal-error-px", type=non_negative_float, default=PRINCIPAL_ERROR_PX, metavar="PX",
                   help=f"calibrated principal point's error per axis, 1 sigma [px] (default {PRINCIPAL_ERROR_PX:g})")
    g.add_argument("--distortion-residual-px", type=non_negative_float, default=DISTORTION_RESIDUAL_PX, metavar="PX",
                   help="lens distortion left after calibration, RMS over the image, 1 sigma [px] (default "
                   f"{DISTORTION_RESIDUAL_PX:g})")
    g.add_argument("--noise-px", type=non_negative_float, default=NOISE_PX, metavar="PX",
                   help=f"edge-point noise before rounding to whole pixels, 1 sigma [px] (default {NOISE_PX:g})")
    g.add_argument("--phone-speed", type=at_most(MAX_PHONE_SPEED_M_S, strict=False), default=PHONE_SPEED_M_S,
                   metavar="M/S", help="speed of the phone during the rolling shutter's readout, in a random "
                   f"horizontal direction [m/s] (default {PHONE_SPEED_M_S:g}, assumed)")
    g.add_argument("--phone-turn", type=at_most(MAX_PHONE_TURN_DEG_S, strict=False), default=PHONE_TURN_DEG_S,
                   metavar="DEG/S", help="angular rate of the phone during the readout, about a random axis [deg/s] "
                   f"(default {PHONE_TURN_DEG_S:g}, assumed)")
    g.add_argument("--pixel-noise-only", action="store_true",
                   help="switch every term but the edge noise off (the model before the error budget)")


def error_terms(args: argparse.Namespace):
    """The :class:`~planner.positioning.error_terms.ErrorTerms` the flags of :func:`add_error_budget_flags` ask for."""
    from planner.positioning.error_terms import ErrorTerms

    terms = ErrorTerms(args.install_error, args.focal_error / 100, args.principal_error_px,
                       args.distortion_residual_px, args.noise_px, args.phone_speed, math.radians(args.phone_turn))
    return terms.only("edge") if args.pixel_noise_only else terms


def camera_from_args(args, default: Camera | None = None) -> Camera:
    """The camera ``--camera`` names (a profile or a file), else ``default`` (the plan's), else the paper's."""
    from planner.camera.file import camera_from
    from planner.camera.model import Camera

    if not args.camera:
        return default or Camera()
    return camera_from(args.camera)


def progress(message: str) -> None:
    if sys.stderr.isatty():
        print(f"  .. {message}", file=sys.stderr, flush=True)


def verification_line(v: dict) -> str:
    n = max(v["poses"], 1)
    w = v.get("window_set")
    two = bool(w and "pairs" in w)  # the gravity receiver's two-LED windows
    line = (f"{v['poses']} sampled poses: {100 * v['coverage']:.1f} % decodable, {v['ambiguous']} ambiguous, "
            f"{100 * v['collinear'] / n:.1f} % collinear, {100 * v['too_few_leds'] / n:.1f} % see fewer than "
            f"{2 if two else 3} LEDs")
    if v["first_conflicts"]:
        group = v["first_conflicts"][0]
        line += "; first conflict: " + " vs ".join("(" + ", ".join(t) + ")" for t in group[:2])
    if w:
        what, other = ("pairs", "pair") if two else ("triangles", "triple")
        bound = ("every pose of the envelope" if w.get("complete") else
                 f"empty, sides up to {w['max_length_m' if two else 'max_side_m']:g} m from samples")
        cap = w.get("window_length_cap_m")
        capped = "" if cap is None else (f" up to {cap:g} m long (the receiver reads no longer pair; the proof keeps "
                                         f"{w['proved_pairs_beyond_cap']:,} longer ones)")
        line += (f"\n  windows  {w[what]} {what}{capped} that may be windows ({bound}, installed within "
                 f"{w['install_tolerance_m']:g} m): {w['read_alike']} read like another {other}")
        if w["first_conflicts"]:
            line += "; first: " + " vs ".join("(" + ", ".join(t) + ")" for t in w["first_conflicts"][0][:2])
        seen = (f"whose two nearest whole LEDs are at most {cap:g} m apart" if cap is not None else
                 "that sees a window")
        line += (f"\n  proof    every pose of the envelope {seen} names one place: proved" if w.get("proved") else
                 "\n  proof    not proved: " + (w.get("not_proved_because") or f"a {other} that may be a window "
                                                 f"reads like another {other}"))
    return line


def output_file(flag: str, value: str | None) -> Path | None:
    """The file an option such as ``--plot PNG`` names (None if not given), checked before any work:
    its folder must exist, else :class:`UsageError` naming the flag."""
    if not value:
        return None
    path = Path(value)
    if not path.resolve().parent.is_dir():
        raise UsageError(f"{flag} {value}: directory {path.parent} does not exist")
    if path.is_dir():
        raise UsageError(f"{flag} {value}: is a folder; give a file name in it")
    if path.exists() and not path.is_file():
        raise UsageError(f"{flag} {value}: exists and is not a regular file (a device or pipe); give a file name")
    return path


def output_dir(flag: str, value: str | None) -> Path | None:
    """The folder an option such as ``--save-failures DIR`` names (None if not given), checked before any
    work: it may not be an existing file, else :class:`UsageError` naming the flag."""
    if not value:
        return None
    path = Path(value)
    if path.exists() and not path.is_dir():
        raise UsageError(f"{flag} {value}: exists and is not a folder; give a folder, or a name not yet taken")
    return path


def site_key(path: str | Path | None, *, env: bool = True, warn: bool = True) -> bytes:
    """The site key from ``--key-file`` (hex digits, whitespace ignored, or raw bytes), else from
    ``VLP_SITE_KEY`` (hex) when ``env``; 16 to 64 bytes (docs/protocol.md). A key file every user may read is
    warned about when ``warn`` (:class:`~planner.errors.PlannerWarning`, printed by :func:`console_main` after a
    run that ends without error, so an error stays the only line)."""
    from planner._files import read_bytes
    from planner.flash.keys import KEY_FILE_MAX_BYTES, readable_by_all, site_key_from

    if path:
        try:
            raw = read_bytes(path, "key file", "cannot read (no such file)", max_bytes=KEY_FILE_MAX_BYTES)
        except InputError as exc:
            raise UsageError(f"--key-file {exc}") from None
        if warn and readable_by_all(path):  # a warning, not a refusal: the key may have leaked, the job goes on
            warnings.warn(PlannerWarning(f"--key-file {path} is readable by every user of this machine: "
                                         f"chmod 600 {path}"), stacklevel=2)
        where, from_file = f"--key-file {path}", True
    elif env and os.environ.get("VLP_SITE_KEY"):
        raw, where, from_file = os.environ["VLP_SITE_KEY"].encode("utf-8", "surrogateescape"), "VLP_SITE_KEY", False
    else:
        raise UsageError("no site key: give --key-file FILE" + (" or set VLP_SITE_KEY (hex)" if env else ""))
    try:
        return site_key_from(raw, raw=from_file)
    except ValueError as exc:
        raise UsageError(f"{where}: {exc}") from None
