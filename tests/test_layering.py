"""Imports only point down the pipeline, and packages import each other in no circle.

The layers of ``edge/``, lowest first (imports point down: towards ``codes``); a module may import
from its own layer and any lower layer, never from a higher one (static ``import`` / ``from ... import`` statements anywhere in a file,
including the lazy ones inside functions; ``importlib`` look-ups by name, such as the pipeline
registry `edge.device.PIPELINES`, are data and not counted)::

    edge (the package root: __version__ only)
    numba_cache  edge/numba_cache.py: the lock on numba's on-disk cache (numba only)
    triangulation  edge/triangulation.py: disparity <-> depth (numpy only)
    codes      code values, CRC, source codes
    capture    the coded-capture type (frames, white, black, exposure, bit depth)
    patterns   projector frames from a code
    sim        scenes, image formation, metrics
    source     light-source codes: spreading, matched filters, events, curtains
    device     edge/device.py: the profile-derived device facts (frame schedule, dot pattern, ...)
    sensors    frame sources (sim, replay, oak, event)
    decode     decoders, EDC check, real captures
    edc        adaptive re-projection loop
    profiles   firmware profiles -> validated settings (+ the config-freeze policy)
    runtime    the service: assembly, queue, pipelines, depth, status
    io         zenoh, MCAP, ROS, PLY: the service's outside world
    eval       the paper's evaluations, driven by the decoder settings
    commands / cli / __main__   the command line

`KNOWN_VIOLATIONS` lists the imports that break this today (each with the engineer area that owns
it); the coordinator empties it as those are fixed.  A violation not listed fails
`test_imports_point_down_the_pipeline`; a listed one that is gone fails
`test_known_violations_are_still_real` (so the list only shrinks).
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "edge"

#: (layer, packages / top-level modules of edge/ in it), lowest first
LAYERS: list[tuple[str, ...]] = [
    ("",),  # edge/__init__.py
    ("numba_cache",),  # edge/numba_cache.py: installed by every package / module with numba kernels
    ("triangulation",),  # edge/triangulation.py: the depth formula (numpy only)
    ("codes",),
    ("capture",),
    ("patterns",),
    ("sim",),
    ("source",),
    ("device",),
    ("sensors",),
    ("decode",),
    ("edc",),
    ("profiles",),
    ("runtime",),
    ("io",),
    ("eval",),
    ("commands", "cli", "__main__"),
]
RANK = {name: i for i, layer in enumerate(LAYERS) for name in layer}

#: Imports that point up the pipeline today: (importing module, imported package).  To be emptied.
KNOWN_VIOLATIONS: set[tuple[str, str]] = set()


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _package(module: str) -> str:
    """'edge.runtime.service' -> 'runtime'; 'edge.device' -> 'device'; 'edge' -> ''."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def edge_imports() -> dict[str, set[str]]:
    """{importing module: {imported edge modules}} over every .py file of edge/."""
    out: dict[str, set[str]] = defaultdict(set)
    for path in sorted(ROOT.rglob("*.py")):
        module = _module_name(path)
        is_pkg = path.name == "__init__.py"
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = module.split(".") if is_pkg else module.split(".")[:-1]
                    base = base[: len(base) - (node.level - 1)]
                    head = ".".join(base + ([node.module] if node.module else []))
                else:
                    head = node.module or ""
                # "from edge import device" imports the module edge.device; "from edge import
                # __version__" a name of the package root
                targets = [f"edge.{a.name}" if head == "edge" and _is_module(a.name) else head for a in node.names]
            else:
                continue
            out[module].update(t for t in targets if t == "edge" or t.startswith("edge."))
    return out


def _is_module(name: str) -> bool:
    return (ROOT / name / "__init__.py").exists() or (ROOT / f"{name}.py").exists()


def violations() -> set[tuple[str, str]]:
    found = set()
    for module, targets in edge_imports().items():
        src = _package(module)
        for target in targets:
            dst = _package(target)
            if dst != src and RANK[dst] > RANK[src]:
                found.add((module, dst))
    return found


def test_every_package_has_a_layer():
    names = {p.name for p in ROOT.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    names |= {p.stem for p in ROOT.glob("*.py") if p.stem != "__init__"}
    missing = sorted(names - set(RANK))
    assert not missing, f"place these in LAYERS (tests/test_layering.py) and docs/architecture.md: {missing}"


def test_imports_point_down_the_pipeline():
    new = sorted(violations() - KNOWN_VIOLATIONS)
    assert not new, "imports that point up the pipeline (module -> package above it):\n" + "\n".join(
        f"  {m} -> edge.{p}" for m, p in new)


def test_known_violations_are_still_real():
    stale = sorted(KNOWN_VIOLATIONS - violations())
    assert not stale, "fixed: remove these from KNOWN_VIOLATIONS:\n" + "\n".join(f"  {m} -> edge.{p}" for m, p in stale)


def test_no_import_cycles_between_packages():
    graph: dict[str, set[str]] = defaultdict(set)
    for module, targets in edge_imports().items():
        src = _package(module)
        for target in targets:
            dst = _package(target)
            if dst != src and (module, dst) not in KNOWN_VIOLATIONS:
                graph[src].add(dst)
    # Tarjan's strongly connected components: any component with more than one package is a circle
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    circles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                circles.append(sorted(comp))

    for v in list(graph):
        if v not in index:
            visit(v)
    assert not circles, f"packages that import each other: {circles}"
