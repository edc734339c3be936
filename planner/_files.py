"""Files at the edge: reading a YAML input with the one-line errors every reader gives, and the
one atomic writer every output goes through (never a half-written file)."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import yaml

from planner.errors import InputError

if TYPE_CHECKING:
    import jinja2

_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # libyaml: 20x faster on large plans


def read_bytes(path: str | Path, what: str, missing: str = "no such file", max_bytes: int | None = None) -> bytes:
    """The bytes of ``path``, at most ``max_bytes`` read (more is an :class:`InputError`: ``/dev/zero``,
    a wrong file); a missing file or a folder is an :class:`InputError` too."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            data = f.read() if max_bytes is None else f.read(max_bytes + 1)
    except FileNotFoundError:
        raise InputError(f"{path}: {missing}") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read the {what} ({exc.strerror})") from None
    if max_bytes is not None and len(data) > max_bytes:
        raise InputError(f"{path}: more than {max_bytes:,} bytes, too large for a {what}; check the file name")
    return data


def read_text(path: str | Path, what: str, missing: str = "no such file", max_bytes: int | None = None) -> str:
    """The UTF-8 text of ``path`` (a byte-order mark is dropped; at most ``max_bytes``); a missing file, a
    folder, a larger file or another encoding raises :class:`InputError` naming the file, the byte and what to do."""
    data = read_bytes(path, what, missing, max_bytes)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise InputError(f"{path}: line {line}: byte 0x{data[exc.start]:02x} is not UTF-8 text; save the {what} "
                         "as UTF-8 (e.g. iconv -f latin1 -t utf-8)") from None


def load_yaml(path: str | Path, missing: str = "no such file"):
    """Parse ``path``; a missing file or bad YAML raises :class:`InputError` naming the file and line."""
    return parse_yaml(read_text(path, "YAML file", missing), path)


def parse_yaml(text: str, path: str | Path):
    """Parse ``text``, read from ``path`` (named in errors), as :func:`load_yaml` does."""
    path = Path(path)
    try:
        doc = yaml.load(text, Loader=_LOADER)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" line {mark.line + 1}:" if mark else ""
        what = " ".join(str(getattr(exc, "problem", None) or exc).split())  # some of PyYAML's span lines
        raise InputError(f"{path}:{line} not valid YAML ({what})") from exc
    except (ValueError, OverflowError) as exc:  # a 5,000-digit integer, a date out of range
        raise InputError(f"{path}: a value YAML cannot hold ({str(exc)[:80]})") from None
    except RecursionError:
        raise InputError(f"{path}: YAML nested too deeply") from None
    _check_expanded_size(doc, path)
    return doc


MAX_YAML_VALUES = 10_000_000
"""Most values a YAML file may expand to once its aliases are followed (a 100,000-luminaire plan holds about
3 million): a 'billion laughs' file of nested aliases is refused before anything walks it."""


def _check_expanded_size(doc: object, path: Path) -> None:
    """Count the values ``doc`` holds with every alias followed, sharing work between repeated nodes (linear in
    the file); :class:`InputError` above :data:`MAX_YAML_VALUES` or if a node contains itself."""
    size: dict[int, int] = {}
    stack: list[tuple[object, bool]] = [(doc, False)]
    open_: set[int] = set()
    while stack:
        node, done = stack.pop()
        if not isinstance(node, (list, dict)) or (id(node) in size and not done):
            continue
        children = list(node.keys()) + list(node.values()) if isinstance(node, dict) else node
        if done:
            open_.discard(id(node))
            total = 1 + sum(size.get(id(c), 1) for c in children)
            if total > MAX_YAML_VALUES:
                raise InputError(f"{path}: its aliases (*name) expand to more than {MAX_YAML_VALUES:,} values; "
                                 "write the values out instead of nesting aliases")
            size[id(node)] = total
            continue
        if id(node) in open_:
            raise InputError(f"{path}: an alias (*name) refers to the node that contains it; write the values out")
        open_.add(id(node))
        stack.append((node, True))
        stack.extend((c, False) for c in children if isinstance(c, (list, dict)))


def load_json(path: str | Path, what: str, missing: str = "no such file", max_bytes: int | None = None):
    """Parse the JSON file ``path`` (at most ``max_bytes``); a missing file, another encoding, bad JSON or
    nesting too deep for the parser raises :class:`InputError` naming the file (and line)."""
    path = Path(path)
    text = read_text(path, what, missing, max_bytes)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: line {exc.lineno}: not valid JSON ({exc.msg})") from None
    except ValueError as exc:  # an integer of more digits than Python converts (4,300)
        raise InputError(f"{path}: a number JSON cannot hold here ({str(exc).split(';')[0]})") from None
    except RecursionError:
        raise InputError(f"{path}: JSON nested too deeply to be a {what}") from None


def write_atomically(path: str | Path, write: Callable[[Path], object]) -> None:
    """Fill ``path`` through ``write(tmp)``, a temporary file beside it, then rename it into place.

    Readers see the old file or the whole new one; on any failure (or Ctrl-C) the temporary
    file is removed and ``path`` is untouched. The file gets the usual permissions (umask).
    """
    path = Path(path)
    if path.is_dir() or (path.exists() and not path.is_file()):
        raise InputError(f"{path}: is a folder or a device, not a file; give a file name")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.resolve().parent)
    except OSError as exc:
        raise InputError(f"{path}: cannot write there ({exc.strerror}); choose a folder that exists and "
                         "is writable") from None
    os.close(fd)
    try:
        write(Path(tmp))
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except OSError as exc:  # a full disk, a quota, a read-only file system
        Path(tmp).unlink(missing_ok=True)
        raise InputError(f"{path}: cannot write ({exc.strerror or exc}); nothing was written; free space or "
                         "choose another place") from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def staging_folder(outdir: Path) -> Path:
    """A new hidden folder beside ``outdir`` to fill before it is moved into place, named after this process
    (``.NAME.stage-PID-XXXX``); first removes those a killed run left (``kill -9``, a power cut: its process is
    gone), so they do not pile up. Those of live processes (a run in parallel) are left alone."""
    for old in outdir.parent.glob(f".{outdir.name}.stage-*-*"):
        pid = old.name[len(outdir.name) + 8:].split("-", 1)[0]
        if old.is_dir() and pid.isdigit() and not _alive(int(pid)):
            shutil.rmtree(old, ignore_errors=True)
    return Path(tempfile.mkdtemp(prefix=f".{outdir.name}.stage-{os.getpid()}-", dir=outdir.parent))


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


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
