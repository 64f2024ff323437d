"""Dependencies point one way: nothing under senscal/ except cli/ imports senscal.cli (issue 16)."""

from __future__ import annotations

import ast
from pathlib import Path

import senscal

PACKAGE = Path(senscal.__file__).resolve().parent


def _imports(tree: ast.AST, module: str) -> list[tuple[int, str]]:
    """(line, imported module) of every import in a module, relative ones resolved."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".")[: -node.level]
                name = ".".join(base + ([node.module] if node.module else []))
            else:
                name = node.module or ""
            out.append((node.lineno, name))
            # "from senscal import cli" imports the package too.
            out += [(node.lineno, f"{name}.{a.name}") for a in node.names]
    return out


def _modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE.parent).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        yield path, ".".join(parts)


def test_no_module_outside_cli_imports_cli():
    offenders = []
    for path, module in _modules():
        # senscal/__main__.py is ``python -m senscal``: the command line's own entry point.
        if module in ("senscal.cli", "senscal.__main__") or module.startswith("senscal.cli."):
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for line, name in _imports(tree, module if path.name != "__init__.py" else module + ".__init__"):
            if name == "senscal.cli" or name.startswith("senscal.cli."):
                offenders.append(f"{path.relative_to(PACKAGE.parent)}:{line} imports {name}")
    assert not offenders, "modules outside senscal/cli import the command line:\n" + "\n".join(offenders)


def test_the_walk_sees_an_import_of_cli(tmp_path):
    # The check must be able to fail: a plain, a from- and a relative import of cli are all found.
    src = "import senscal.cli.common\nfrom senscal.cli import main\nfrom ..cli.common import load\nfrom senscal import cli\n"
    found = [n for _, n in _imports(ast.parse(src), "senscal.demo.job_x")]
    assert "senscal.cli.common" in found and "senscal.cli" in found and "senscal.cli.common.load" in found
    assert sum(n == "senscal.cli" or n.startswith("senscal.cli.") for n in found) >= 4
