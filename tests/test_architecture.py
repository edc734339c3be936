"""Imports run one way (issue 35): no import circle in ``planner/``, and no stage imports a later one.

The graph is built from the source with :mod:`ast`: every ``import`` and ``from ... import`` of a
``planner`` module counts, at module level, inside functions and under ``if TYPE_CHECKING:`` alike
(a type-only import still makes one module unreadable without the other).
"""

from __future__ import annotations

import ast
import graphlib
from pathlib import Path

import planner

PACKAGE = Path(planner.__file__).parent

BASE = ("planner", "planner.errors", "planner.defaults", "planner._files", "planner._schema", "planner.plot_style",
        "planner.parallel")
"""Shared base modules: any stage may import them; they import only each other."""

STAGES: tuple[tuple[str, ...], ...] = (
    ("planner.camera",),  # camera model, lens projections, camera files, LED ellipse images
    ("planner.layout",),  # a drawing or list read into a typed layout
    ("planner.graph",),  # the neighbour graph
    ("planner.verify",),  # the windows a camera sees and their proofs (code design proves its candidates)
    ("planner.codes",),  # the IDs
    ("planner.modulation",),  # frames, multi-frame words, chip rates
    ("planner.plan.file",),  # plan.yaml read back: the contract every later stage reads
    ("planner.layout.dxf_annotate", "planner.layout.ifc_annotate"),  # plan IDs written back into the drawing
    ("planner.decode",),  # the phone image decoder: image to blobs to IDs
    ("planner.firmware", "planner.firmware_templates"),  # the templates: firmware_templates/, mapped in
    ("planner.flash",),
    ("planner.positioning",),
    ("planner.receivers",),  # receiver modes: each one's window rule, proof, identification, accuracy model
    ("planner.twin",),
    ("planner.photo",),
    ("planner.calibration",),
    ("planner.advice",),
    ("planner.plan.model",),  # the typed plan: every stage's result for one site
    ("planner.report",),
    ("planner.plan",),  # the work budget and the stage runner
    ("planner.studies",),
    ("planner.cli",),
)
"""The stages in pipeline order, earliest first; a module belongs to the longest prefix naming it.
A stage may import its own modules, the base and earlier stages, never a later one."""

MAX_LOOSE_MODULES = 8


def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _target(name: str) -> str:
    """The module an imported dotted name lives in (a name imported from a module is that module)."""
    while name not in MODULES:
        name = name.rpartition(".")[0]
    return name


def _imports(module: str, path: Path) -> set[str]:
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found |= {_target(a.name) for a in node.names if a.name.split(".")[0] == "planner"}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            if source.split(".")[0] != "planner":
                continue
            for alias in node.names:
                full = f"{source}.{alias.name}"
                found.add(full if full in MODULES else _target(source))
    found.discard(module)
    return found


GRAPH = {m: _imports(m, p) for m, p in MODULES.items()}


def _stage(module: str) -> int:
    """Position of the module's stage (-1: the base), by the longest prefix naming it."""
    if module in BASE:
        return -1
    best, rank = "", None
    for k, names in enumerate(STAGES):
        for name in names:
            if (module == name or module.startswith(name + ".")) and len(name) > len(best):
                best, rank = name, k
    assert rank is not None, f"{module} is in no stage: add its package to STAGES in {__file__}"
    return rank


def test_the_graph_sees_imports_of_every_kind():
    """The graph holds a module-level, a function-level and a TYPE_CHECKING import it must find."""
    assert "planner.camera.lens" in GRAPH["planner.camera.model"]
    assert "planner.modulation.timing" in GRAPH["planner.plan.budget"]  # inside a function
    assert "planner.advice.advise" in GRAPH["planner.plan.model"]  # under TYPE_CHECKING


def test_every_module_has_a_stage():
    for module in GRAPH:
        _stage(module)


def test_no_import_circle():
    try:
        graphlib.TopologicalSorter(GRAPH).prepare()
    except graphlib.CycleError as e:
        raise AssertionError(f"import circle: {' -> '.join(e.args[1])}") from None


def test_no_stage_imports_a_later_one():
    upward = sorted(f"{m} imports {t}" for m, targets in GRAPH.items() for t in targets if _stage(t) > _stage(m))
    assert not upward, "\n".join(upward)


def test_base_imports_only_base():
    assert all(set(GRAPH[m]) <= set(BASE) for m in BASE if m in GRAPH)


def test_few_loose_modules():
    """``ls planner/`` reads as the pipeline: stage packages plus a few shared base modules."""
    loose = sorted(p.name for p in PACKAGE.glob("*.py"))
    assert len(loose) <= MAX_LOOSE_MODULES, loose


def _constants(node: ast.expr) -> list[object]:
    if isinstance(node, ast.Constant):
        return [node.value]
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return [e.value for e in node.elts if isinstance(e, ast.Constant)]
    return []


def test_no_receiver_mode_compared_by_name_outside_receivers():
    """A receiver mode is a type chosen once (planner.receivers.modes); no other module tests a mode's name."""
    from planner.receivers.modes import RECEIVERS

    found = []
    for module, path in MODULES.items():
        if module == "planner.receivers" or module.startswith("planner.receivers."):
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Compare) and any(
                    value in RECEIVERS for side in (node.left, *node.comparators) for value in _constants(side)):
                found.append(f"{module}:{node.lineno}")
    assert not found, found


def test_every_receiver_mode_implements_the_whole_mode():
    from planner.receivers.base import Receiver
    from planner.receivers.modes import RECEIVERS

    required = ("plan", "verify", "window_leds", "decodable", "smallest_image_rows")  # coverage: from window_leds
    for name, mode in RECEIVERS.items():
        assert mode.name == name and mode.leds in (2, 3)
        assert all(getattr(type(mode), m) is not getattr(Receiver, m) for m in required), name
