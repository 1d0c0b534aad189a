"""The import rule (README, Layout): cli -> app -> {plot, io} -> {comparison, design} ->
calibration -> core -> errors. Imports flow one way; the math never imports files, plots or the
command line."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src" / "odocal"

# The layers from the top; a layer may import the layers below it, never one above it or a
# sibling (io and plot; comparison and design). presets (built-in robots) sits just above core;
# the version (odocal._version, a leaf) is imported by the command layers only (cli, app), which
# pass it down where it is written; nothing imports the package root (its lazy public API).
LAYERS = [
    ("cli",),
    ("app",),
    ("plot", "io"),
    ("comparison", "design"),
    ("calibration",),
    ("presets",),
    ("core",),
    ("errors",),
]
VERSION_USERS = ("cli", "app")
ALLOWED = {
    name: {below for lower in LAYERS[i + 1 :] for below in lower}
    | ({"_version"} if name in VERSION_USERS else set())
    for i, layer in enumerate(LAYERS)
    for name in layer
} | {"_version": set()}


def _layer(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[0] == "odocal" else None


def test_the_rule_is_the_readme_s():
    assert ALLOWED["cli"] >= {"app", "io", "core"} and "cli" not in ALLOWED["app"]
    assert "io" not in ALLOWED["plot"] and "plot" not in ALLOWED["io"]
    assert "design" not in ALLOWED["comparison"] and "comparison" not in ALLOWED["design"]
    assert ALLOWED["core"] == {"errors"} and "_version" not in ALLOWED["io"]
    assert "_version" in ALLOWED["app"]


def _import_module_target(node: ast.Call, package: list[str]) -> str | None:
    """The module a call ``importlib.import_module("odocal.x")`` (or ``import_module(".x",
    __package__)``, ``__import__("odocal.x")``) imports, when it is a string written in the
    code; None for any other call (or a name computed at run time)."""
    func = node.func
    name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
    if name not in ("import_module", "__import__") or not node.args:
        return None
    arg = node.args[0]
    if not (isinstance(arg, ast.Constant) and isinstance(arg.value, str)):
        return None
    target = arg.value
    if target.startswith("."):  # relative to the module's own package
        level = len(target) - len(target.lstrip("."))
        base = package[: len(package) - level + 1]
        target = ".".join(base + ([target.lstrip(".")] if target.lstrip(".") else []))
    return target


def _imports(path: Path) -> list[tuple[int, str]]:
    """Every module ``path`` imports: import statements, and calls of ``import_module`` or
    ``__import__`` with a string written in the code (an import the statements would hide)."""
    rel = path.relative_to(SRC.parent).with_suffix("")
    package = list(rel.parts[:-1]) if rel.name != "__init__" else list(rel.parts[:-1])
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Call):
            target = _import_module_target(node, package)
            if target is not None:
                out.append((node.lineno, target))
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
                if node.module is None:  # from . import x
                    out += [(node.lineno, f"{mod}.{a.name}") for a in node.names]
                    continue
            else:
                mod = node.module or ""
            out.append((node.lineno, mod))
        elif isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
    return out


def test_every_import_follows_the_rule():
    bad = []
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC)
        own = rel.parts[0].removesuffix(".py") if len(rel.parts) > 1 else rel.stem
        if own in ("__init__", "__main__"):
            continue
        allowed = ALLOWED[own] | {own}
        for line, mod in _imports(path):
            layer = _layer(mod)
            if layer is not None and layer not in allowed:
                bad.append(f"{rel}:{line} imports {mod} ({own} may not import {layer})")
    assert not bad, "\n".join(bad)


MATH = ("odocal.core", "odocal.calibration", "odocal.design", "odocal.comparison")


def test_the_math_imports_no_files_plots_or_command_line():
    # import every module of each package with the I/O side made unimportable (one fresh
    # interpreter for all four: the same modules are blocked for each, and each package's
    # failure is reported on its own)
    code = f"""
import sys, pkgutil, importlib, traceback
for name in ("matplotlib", "rosbags", "yaml", "odocal.io", "odocal.cli", "odocal.app",
             "odocal.plot"):
    sys.modules[name] = None
for package in {MATH!r}:
    try:
        pkg = importlib.import_module(package)
        for m in pkgutil.iter_modules(pkg.__path__):
            importlib.import_module(package + "." + m.name)
    except ImportError:
        print("FAILED", package, file=sys.stderr)
        traceback.print_exc()
    else:
        print(package)
"""
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert res.returncode == 0 and res.stderr == "", res.stderr
    assert res.stdout.split() == list(MATH), res.stderr


def test_import_module_strings_are_seen():
    """An upward import through ``importlib.import_module("odocal....")`` is an import too."""
    f = SRC / "design" / "_probe.py"  # only parsed, never imported or written
    code = (
        "import importlib\n"
        "x = importlib.import_module('odocal.app.design')\n"
        "y = importlib.import_module('.sweep', __package__)\n"
        "z = importlib.import_module(name)\n"
    )
    tree = ast.parse(code)
    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call)]
    rel = f.relative_to(SRC.parent).with_suffix("")
    package = list(rel.parts[:-1])
    found = [t for t in (_import_module_target(c, package) for c in calls) if t is not None]
    assert found == ["odocal.app.design", "odocal.design.sweep"]
    assert _layer(found[0]) not in ALLOWED["design"]
