"""Imports run one way, from the command line down to the document model, and never in a circle.

The stages of the pipeline are ranked below, lowest first. A module may import modules of its
own rank or of a lower one; an import of a higher rank, or any circle of imports between
modules (also through imports inside functions), fails. The graph is read from the source with
``ast``, so nothing is imported to check it.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

pytestmark = pytest.mark.unit

REPO = Path(__file__).resolve().parents[1]

# Lowest first. A module's rank is that of the longest prefix naming it.
RANKS: tuple[tuple[str, ...], ...] = (
    # foundation: errors, atomic files, shipped data, bulk building, compiled kernels
    ("usdscene", "usdscene.errors", "usdscene.files", "usdscene.shipped", "usdscene.bulk",
     "usdscene.compiled"),
    ("usdscene.document",),    # the SceneSpec model, stage names, output layout, containment
    ("usdscene.lens",),        # the lens models: projection, Blender camera settings (registry)
    ("usdscene.scene",),       # catalog, places, placement, composition
    ("usdscene.labels",),      # projection, amodal, boxes and polygons, pixel density
    ("usdscene.converters",),  # openlabel/ and stage/ ↔ SceneSpec; exports/ (COCO, YOLO, MOT ...)
    ("usdscene.validation",),  # the gate: schema, catalog and placement checks of a document
    ("usdscene.render",),      # Blender workers, executors, the render driver
    ("usdscene.assetgen",),    # building the shipped library, importing users' files
    ("usdscene.generate",),    # design-time document generators: sequences, motion
    ("usdscene.dataset",),     # annotation, export, statistics, report of a rendered run
    ("usdscene.design",),      # coverage and camera planning
    ("usdscene.pipeline",),    # the whole job
    ("usdscene.commands", "usdscene.cli", "usdscene.__main__"),  # the command line
)


def module_name(path: Path) -> str:
    relative = path.relative_to(REPO).with_suffix("")
    parts = list(relative.parts)
    if parts[0] == "converters":
        parts = ["usdscene", *parts]
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def source_modules() -> dict[str, Path]:
    paths = [*REPO.joinpath("usdscene").rglob("*.py"), *REPO.joinpath("converters").rglob("*.py")]
    return {module_name(p): p for p in paths}


def imports_of(name: str, path: Path, known: set[str]) -> set[str]:
    """Modules of the project that ``path`` imports anywhere in its body."""
    found: set[str] = set()
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            targets = [f"{base}.{alias.name}" for alias in node.names] + [base]
        else:
            continue
        for target in targets:
            while target and target not in known:
                target = target.rpartition(".")[0]
            if target and target != name:
                found.add(target)
    return found


def rank_of(name: str) -> int:
    best, best_length = None, -1
    for rank, prefixes in enumerate(RANKS):
        for prefix in prefixes:
            if (name == prefix or name.startswith(prefix + ".")) and len(prefix) > best_length:
                best, best_length = rank, len(prefix)
    assert best is not None, f"{name} has no rank in RANKS: add its package"
    return best


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    modules = source_modules()
    known = set(modules)
    # A package's __init__ only names what is below it; `from usdscene.labels import x` means x.
    return {name: imports_of(name, path, known) for name, path in modules.items()}


def test_every_module_has_a_rank(graph):
    unranked = []
    for name in graph:
        try:
            rank_of(name)
        except AssertionError:
            unranked.append(name)
    assert not unranked, f"modules outside every rank: {unranked}"


def test_imports_run_from_the_command_line_down(graph):
    against = sorted(f"{a} (rank {rank_of(a)}) imports {b} (rank {rank_of(b)})"
                     for a, targets in graph.items() for b in targets if rank_of(b) > rank_of(a))
    assert not against, "imports against the stated direction:\n" + "\n".join(against)


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's components of more than one module (each is an import circle)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    circles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                circles.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return circles


def test_no_import_circles(graph):
    circles = strongly_connected(graph)
    assert not circles, "import circles: " + "; ".join(" ↔ ".join(c) for c in circles)


def test_the_checks_see_a_circle_and_a_wrong_direction():
    """The two checks above fail on a graph that has what they look for."""
    assert strongly_connected({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert rank_of("usdscene.document.model") < rank_of("usdscene.scene.compose")
    assert rank_of("usdscene.commands.run") > rank_of("usdscene.pipeline")
    assert rank_of("usdscene.converters.exports.coco") == rank_of("usdscene.converters")
