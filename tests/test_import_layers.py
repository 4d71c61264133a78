"""The package's layers (docs/architecture.md, "Layers"): every module's imports, deferred ones
inside functions included, go to its own layer or a lower one, and no modules import each other
in a circle. Imports under ``if TYPE_CHECKING:`` are annotations, not dependencies, and are left
out."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "idefix_rules"

# Lowest first; a module belongs to the layer of the longest prefix that names it.
LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("base", ("idefix_rules", "idefix_rules.errors", "idefix_rules.units", "idefix_rules.signals",
              "idefix_rules.chain_end",
              "idefix_rules.limits", "idefix_rules.files", "idefix_rules.plain",
              "idefix_rules.timestamps", "idefix_rules.commands", "idefix_rules.shell",
              "idefix_rules.diagnostic_codes")),
    ("models", ("idefix_rules.rulebook", "idefix_rules.fmu", "idefix_rules.obstacles")),
    ("stages", ("idefix_rules.campaign", "idefix_rules.results")),
    ("outputs", ("idefix_rules.diff", "idefix_rules.report", "idefix_rules.testing")),
    ("pipelines", ("idefix_rules.campaign.runner", "idefix_rules.campaign.rescore",
                   "idefix_rules.campaign.worst.pipeline")),
    ("front ends", ("idefix_rules.cli", "idefix_rules.lsp", "idefix_rules.__main__")),
)


def module_name(path: Path, root: Path = PACKAGE) -> str:
    parts = path.relative_to(root.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def layer_of(module: str) -> int:
    best, rank = -1, -1
    for position, (_, prefixes) in enumerate(LAYERS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > best:
                best, rank = len(prefix), position
    assert rank >= 0, f"{module} is in no layer: add it to LAYERS and docs/architecture.md"
    return rank


def _type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def imports(path: Path, modules: set[str], root: Path = PACKAGE) -> set[str]:
    """The package's modules ``path`` imports, at any depth but under TYPE_CHECKING."""
    own = module_name(path, root)
    package = own if path.name == "__init__.py" else own.rpartition(".")[0]
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _type_checking(node):
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, *([node.module] if node.module else [])])
            for alias in node.names:
                name = f"{base}.{alias.name}"
                found.add(name if name in modules else base)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(ast.parse(path.read_text(encoding="utf-8")))
    return {name for name in found if name in modules and name != own}


def graph() -> dict[str, set[str]]:
    paths = {module_name(path): path for path in PACKAGE.rglob("*.py")}
    modules = set(paths)
    return {name: imports(path, modules) for name, path in paths.items()}


def test_every_module_imports_only_its_own_layer_or_lower() -> None:
    upward = sorted(f"{module} ({LAYERS[layer_of(module)][0]}) imports {target} "
                    f"({LAYERS[layer_of(target)][0]})"
                    for module, targets in graph().items() for target in targets
                    if layer_of(target) > layer_of(module))
    assert upward == []


def test_no_modules_import_each_other_in_a_circle() -> None:
    edges = graph()
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles: list[list[str]] = []

    def connect(module: str) -> None:  # Tarjan's strongly connected components
        index[module] = low[module] = len(index)
        stack.append(module)
        for target in sorted(edges[module]):
            if target not in index:
                connect(target)
                low[module] = min(low[module], low[target])
            elif target in stack:
                low[module] = min(low[module], index[target])
        if low[module] == index[module]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == module:
                    break
            if len(component) > 1:
                circles.append(sorted(component))

    for module in sorted(edges):
        if module not in index:
            connect(module)
    assert circles == []


# The campaign's stages in the order of the data flow, lowest first (docs/architecture.md,
# "The campaign's stages"); ``adaptive``, ``runner`` and ``worst`` sit above them all.
CAMPAIGN_STAGES = ("input", "statistics", "storage", "simulation", "evaluation", "outcome")


def campaign_stage(module: str) -> int | None:
    parts = module.split(".")
    if parts[:2] != ["idefix_rules", "campaign"] or len(parts) < 3:
        return None
    return CAMPAIGN_STAGES.index(parts[2]) if parts[2] in CAMPAIGN_STAGES \
        else len(CAMPAIGN_STAGES)


def test_a_campaign_stage_imports_only_its_own_stage_or_earlier_ones() -> None:
    upward = sorted(f"{module} imports {target}"
                    for module, targets in graph().items() for target in targets
                    if (own := campaign_stage(module)) is not None
                    and (other := campaign_stage(target)) is not None and other > own)
    assert upward == []


def test_the_read_side_imports_only_the_campaign_s_description() -> None:
    # results.h5 is read back with the modules that describe a campaign, never a stage
    reached = sorted(f"{module} imports {target}"
                     for module, targets in graph().items()
                     if module.startswith("idefix_rules.results")
                     for target in targets
                     if target.startswith("idefix_rules.campaign")
                     and not target.startswith("idefix_rules.campaign.input"))
    assert reached == []


@pytest.mark.parametrize(("module", "layer"), [
    ("idefix_rules.campaign.runner", "pipelines"),
    ("idefix_rules.campaign.simulation.simulate", "stages"),
    ("idefix_rules.rulebook.check", "models"), ("idefix_rules.cli.run", "front ends")])
def test_a_module_s_layer_is_its_longest_prefix(module: str, layer: str) -> None:
    assert LAYERS[layer_of(module)][0] == layer


def test_the_check_catches_a_deferred_import_from_a_higher_layer(tmp_path: Path) -> None:
    # the rule engine importing the report inside a function would be an arrow up; the same
    # import under TYPE_CHECKING is an annotation and not counted
    root = tmp_path / "idefix_rules"
    source = root / "rulebook" / "bad.py"
    source.parent.mkdir(parents=True)
    modules = {"idefix_rules.report", "idefix_rules.rulebook.bad"}
    source.write_text("def f():\n    from idefix_rules.report import write_report\n")
    assert imports(source, modules, root) == {"idefix_rules.report"}
    assert layer_of("idefix_rules.report") > layer_of("idefix_rules.rulebook.bad")
    source.write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                      "    from idefix_rules.report import write_report\n")
    assert imports(source, modules, root) == set()


def private_imports(path: Path, root: Path = PACKAGE) -> list[str]:
    """Names starting with one underscore that ``path`` imports from a module of the package
    (``__version__`` and other dunders are public)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith(
                root.name)):
            found += [f"{node.module}.{alias.name}" for alias in node.names
                      if alias.name.startswith("_") and not alias.name.startswith("__")]
    return found


def test_no_module_imports_another_module_s_private_name(tmp_path: Path) -> None:
    found = sorted(f"{module_name(path)} imports {name}" for path in PACKAGE.rglob("*.py")
                   for name in private_imports(path))
    assert found == []
    # and the check sees one
    bad = tmp_path / "idefix_rules" / "campaign" / "bad.py"
    bad.parent.mkdir(parents=True)
    bad.write_text("def f():\n    from idefix_rules.campaign.simulation.simulate import _map\n")
    assert private_imports(bad, tmp_path / "idefix_rules") == [
        "idefix_rules.campaign.simulation.simulate._map"]
