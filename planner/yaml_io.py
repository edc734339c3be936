"""Reading a YAML input file, with the one-line errors every reader gives."""

from __future__ import annotations

from pathlib import Path

import yaml

from planner.errors import InputError

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
