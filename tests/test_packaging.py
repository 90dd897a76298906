"""Packaging: one import namespace with every package and data file in the wheel, and a
library that never calls into the command line layer."""

from __future__ import annotations

import ast
import fnmatch
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PYPROJECT = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))
SETUPTOOLS = PYPROJECT["tool"]["setuptools"]
SOURCE_FOLDERS = ("usdscene", "converters", "tests", "benchmarks", "docs", "examples", "layers", "assets")


def _python_files():
    for folder in SOURCE_FOLDERS:
        yield from sorted((REPO / folder).rglob("*.py"))


def test_every_package_folder_is_listed_and_mapped_inside_usdscene():
    listed = set(SETUPTOOLS["packages"])
    mapping = SETUPTOOLS["package-dir"]
    assert all(name == "usdscene" or name.startswith("usdscene.") for name in listed)
    found = set()
    for package, folder in mapping.items():
        for init in (REPO / folder).rglob("__init__.py"):
            relative = init.parent.relative_to(REPO / folder).parts
            found.add(".".join((package, *relative)))
    missing = sorted(found - listed)
    assert not missing, f"packages missing from pyproject.toml [tool.setuptools] packages: {missing}"
    assert mapping["usdscene.converters"] == "converters"


def test_every_data_file_is_package_data():
    data = SETUPTOOLS["package-data"]
    for package, folder in (("usdscene.assets", "assets"), ("usdscene.layers", "layers"), ("usdscene", "usdscene")):
        patterns = data[package]
        files = [p for p in (REPO / folder).rglob("*") if p.is_file() and p.suffix != ".py"
                 and "__pycache__" not in p.parts]
        assert files
        for path in files:
            relative = path.relative_to(REPO / folder).as_posix()
            assert any(fnmatch.fnmatch(relative, pattern) or fnmatch.fnmatch(relative, pattern.replace("**/", ""))
                       for pattern in patterns), f"{folder}/{relative} would be left out of the wheel"


def test_only_the_command_line_imports_usdscene_commands():
    offenders = []
    for path in _python_files():
        relative = path.relative_to(REPO).as_posix()
        if relative == "usdscene/cli.py" or relative.startswith("usdscene/commands/"):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            if any(n == "usdscene.commands" or n.startswith("usdscene.commands.") for n in names):
                offenders.append(f"{relative}:{node.lineno}")
    assert not offenders, offenders


def test_no_top_level_converters_imports():
    offenders = []
    for path in _python_files():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else [])
            if any(n == "converters" or n.startswith("converters.") for n in names):
                offenders.append(f"{path.relative_to(REPO)}:{node.lineno}")
    assert not offenders, offenders
