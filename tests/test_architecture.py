"""The package layout of docs/architecture.md: layers import only downwards, ask kinds live in chapters."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from solver.registry import CHAPTERS, load_all

PACKAGE = Path(__file__).resolve().parents[1] / "solver"

# Lowest first. A module may import modules of its own layer or of a lower one, never of a higher one.
LAYERS: list[tuple[str, tuple[str, ...]]] = [
    ("base", ("solver.results", "solver.registry")),
    ("math", ("solver.math",)),
    ("spec", ("solver.spec",)),
    ("chapters", tuple(f"solver.{c}" for c in CHAPTERS)),
    ("core", ("solver.solve", "solver.verify", "solver.sandbox")),
    ("apps", ("solver.grading", "solver.publish")),
    ("cli", ("solver.cli", "solver.__main__", "solver")),
]


def layer_of(module: str) -> int:
    """Index in LAYERS of the longest prefix that names ``module``'s package."""
    best, best_len = -1, -1
    for i, (_, prefixes) in enumerate(LAYERS):
        for p in prefixes:
            if (module == p or module.startswith(p + ".")) and len(p) > best_len:
                best, best_len = i, len(p)
    if best < 0:
        raise AssertionError(f"{module} is in no layer of docs/architecture.md")
    return best


def module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _type_checking_block(node: ast.AST) -> bool:
    test = getattr(node, "test", None)
    return isinstance(node, ast.If) and (
        (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING")
        or (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"))


def imports_of(path: Path, here: str | None = None) -> list[tuple[int, str]]:
    """(line, module) of every import of a robosolve module in ``path`` (module ``here``), at any depth
    (functions included), except under ``if TYPE_CHECKING:`` (annotations only)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    here = here or module_name(path)
    package = here if path.name == "__init__.py" else here.rsplit(".", 1)[0]
    out: list[tuple[int, str]] = []

    def visit(node: ast.AST) -> None:
        if _type_checking_block(node):
            return
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod == "solver" or mod.startswith("solver."):
                for alias in node.names:  # from solver.spec import expr: the module solver.spec.expr
                    sub = f"{mod}.{alias.name}"
                    out.append((node.lineno, sub if (PACKAGE.parent / (sub.replace(".", "/") + ".py")).exists()
                                else mod))
        elif isinstance(node, ast.Import):
            out.extend((node.lineno, a.name) for a in node.names if a.name.split(".")[0] == "solver")
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    return out


MODULES = sorted(PACKAGE.rglob("*.py"))


@pytest.mark.parametrize("path", MODULES, ids=lambda p: module_name(p))
def test_imports_go_down_the_layers(path: Path) -> None:
    here = module_name(path)
    mine = layer_of(here)
    wrong = [f"line {line}: {mod} ({LAYERS[layer_of(mod)][0]})" for line, mod in imports_of(path)
             if layer_of(mod) > mine]
    assert not wrong, f"{here} ({LAYERS[mine][0]}) imports a higher layer: " + "; ".join(wrong)


def test_the_checker_sees_an_upward_import(tmp_path: Path) -> None:
    """The import reader finds imports inside functions and skips TYPE_CHECKING blocks."""
    f = tmp_path / "probe.py"
    f.write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from solver.spec.robot import Robot\n"
                 "from ..spec import expr\n"
                 "def f():\n    from solver.grading.grader import grade\n", encoding="utf-8")
    assert imports_of(f, "solver.math.probe") == [(4, "solver.spec.expr"), (6, "solver.grading.grader")]
    assert layer_of("solver.grading.grader") > layer_of("solver.math.probe")


def test_few_modules_at_the_top() -> None:
    top = sorted(p.name for p in PACKAGE.glob("*.py"))
    assert len(top) <= 8, top


def test_every_ask_kind_lives_in_a_chapter() -> None:
    kinds = load_all()
    assert kinds
    for name, kind in kinds.items():
        module = kind.solve.__module__
        assert module.split(".")[1] in CHAPTERS, f"ask kind {name} is solved in {module}, not in a chapter package"
