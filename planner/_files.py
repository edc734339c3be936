"""Files at the edge: reading a YAML input with the one-line errors every reader gives, and the
one atomic writer every output goes through (never a half-written file)."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import yaml

from planner.errors import InputError

if TYPE_CHECKING:
    import jinja2

_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # libyaml: 20x faster on large plans


def load_yaml(path: str | Path, missing: str = "no such file"):
    """Parse ``path``; a missing file or bad YAML raises :class:`InputError` naming the file and line."""
    path = Path(path)
    try:
        return yaml.load(path.read_text(encoding="utf-8"), Loader=_LOADER)
    except FileNotFoundError:
        raise InputError(f"{path}: {missing}") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a text file; expected YAML") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" line {mark.line + 1}:" if mark else ""
        raise InputError(f"{path}:{line} not valid YAML ({getattr(exc, 'problem', None) or exc})") from exc


def write_atomically(path: str | Path, write: Callable[[Path], object]) -> None:
    """Fill ``path`` through ``write(tmp)``, a temporary file beside it, then rename it into place.

    Readers see the old file or the whole new one; on any failure (or Ctrl-C) the temporary
    file is removed and ``path`` is untouched. The file gets the usual permissions (umask).
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.resolve().parent)
    os.close(fd)
    try:
        write(Path(tmp))
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_bytes_atomically(path: str | Path, data: bytes) -> None:
    """:func:`write_atomically` of ``data``."""
    write_atomically(path, lambda tmp: tmp.write_bytes(data))


def write_text_atomically(path: str | Path, text: str) -> None:
    """:func:`write_atomically` of ``text`` in UTF-8."""
    write_atomically(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def jinja_environment(folder: str | Path, *, html: bool) -> jinja2.Environment:
    """The one way templates load: from ``folder``, strict (an undefined name is an error), the
    trailing newline kept; HTML autoescaped, C and JSON with block lines trimmed instead."""
    import jinja2

    return jinja2.Environment(loader=jinja2.FileSystemLoader(str(folder)), undefined=jinja2.StrictUndefined,
                              keep_trailing_newline=True, autoescape=html, trim_blocks=not html,
                              lstrip_blocks=not html)
