"""Counts of how the code is laid out (issue 34), read from the source with ``ast``.

Run from a checkout: ``python benchmarks/layout_counts.py [ROOT]`` (ROOT defaults to this
checkout; give another checkout to count a commit before). It reads the Python files under
``usdscene/`` and ``converters/`` and prints:

* files over 600 lines;
* functions (and methods) over 80 lines;
* public functions with more than 6 parameters (not ``self``/``cls``, ``*args``/``**kwargs``
  not counted; names starting with ``_`` and functions nested in functions are private),
  compiled kernels (``@njit``) counted apart;
* modules that branch on the lens model: a comparison (``==``, ``is``, ``in`` ...) with a
  ``LensModel.<member>`` in it;
* places that list export format names: a tuple, list, set or dict literal holding two or
  more of the built-in format names (or calls that start with them, as the registry's
  ``ExportFormat("coco", ...)``), or a string naming two or more of them in a row
  (``"coco, yolo, rois"``); docstrings are not counted.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

FORMAT_NAMES = ("coco", "yolo", "rois", "mot", "multiview")
LONG_FILE_LINES = 600
LONG_FUNCTION_LINES = 80
MANY_PARAMETERS = 6
_NAMED_IN_A_ROW = re.compile(r"\b(" + "|".join(FORMAT_NAMES) + r")\b(,|/| or| and)\s*\b(" + "|".join(FORMAT_NAMES) + r")\b")


def _sources(root: Path) -> list[Path]:
    return sorted(p for folder in ("usdscene", "converters") for p in (root / folder).rglob("*.py")
                  if ".venv" not in p.parts)


def _parameters(node: ast.FunctionDef) -> int:
    args = [*node.args.posonlyargs, *node.args.args, *node.args.kwonlyargs]
    return sum(1 for a in args if a.arg not in ("self", "cls"))


def _is_kernel(node: ast.FunctionDef) -> bool:
    return any("njit" in ast.unparse(d) or "jit" == ast.unparse(d).split("(")[0].split(".")[-1]
               for d in node.decorator_list)


def _functions(tree: ast.Module):
    """``(node, public)`` of every function and method; nested functions are private."""
    def walk(body, public_scope: bool):
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                yield node, public_scope and not node.name.startswith("_")
                yield from walk(node.body, False)
            elif isinstance(node, ast.ClassDef):
                yield from walk(node.body, public_scope and not node.name.startswith("_"))
    yield from walk(tree.body, True)


def _branches_on_lens(tree: ast.Module) -> bool:
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            for part in ast.walk(node):
                if isinstance(part, ast.Attribute) and isinstance(part.value, ast.Name) and part.value.id == "LensModel":
                    return True
    return False


def _named(node: ast.AST):
    """The string a literal element is, or that a call (``ExportFormat("coco", ...)``) starts with."""
    if isinstance(node, ast.Call) and node.args:
        node = node.args[0]
    return node.value if isinstance(node, ast.Constant) else None


def _format_lists(tree: ast.Module) -> list[int]:
    """Line numbers of the literals and strings naming two or more format names."""
    lines = []
    for node in ast.walk(tree):
        items = None
        if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
            items = node.elts
        elif isinstance(node, ast.Dict):
            items = [k for k in node.keys if k is not None]
        if items is not None:
            names = {_named(e) for e in items} & set(FORMAT_NAMES)
            if len(names) >= 2:
                lines.append(node.lineno)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and _NAMED_IN_A_ROW.search(node.value):
            lines.append(node.lineno)
    return lines


def _is_docstring(tree: ast.Module, line: int) -> bool:
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if (isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant)
                    and isinstance(first.value.value, str) and first.lineno == line):
                return True
    return False


def counts(root: Path) -> dict:
    """The counts of the checkout at ``root`` (see the module docstring), each with its list."""
    out = {"long_files": [], "long_functions": [], "many_parameters": [], "many_parameter_kernels": [],
           "lens_branching_modules": [], "format_name_lists": []}
    for path in _sources(root):
        text = path.read_text(encoding="utf-8")
        rel = path.relative_to(root).as_posix()
        tree = ast.parse(text)
        n_lines = len(text.splitlines())
        if n_lines > LONG_FILE_LINES:
            out["long_files"].append(f"{rel} ({n_lines})")
        for node, public in _functions(tree):
            length = node.end_lineno - node.lineno + 1
            if length > LONG_FUNCTION_LINES:
                out["long_functions"].append(f"{rel}:{node.name} ({length})")
            if public and _parameters(node) > MANY_PARAMETERS:
                key = "many_parameter_kernels" if _is_kernel(node) else "many_parameters"
                out[key].append(f"{rel}:{node.name} ({_parameters(node)})")
        if _branches_on_lens(tree):
            out["lens_branching_modules"].append(rel)
        out["format_name_lists"] += [f"{rel}:{line}" for line in _format_lists(tree) if not _is_docstring(tree, line)]
    return out


def main(argv: list[str]) -> int:
    root = Path(argv[0]).resolve() if argv else Path(__file__).resolve().parents[1]
    found = counts(root)
    titles = {"long_files": f"files over {LONG_FILE_LINES} lines",
              "long_functions": f"functions over {LONG_FUNCTION_LINES} lines",
              "many_parameters": f"public functions with more than {MANY_PARAMETERS} parameters",
              "many_parameter_kernels": f"compiled kernels with more than {MANY_PARAMETERS} parameters",
              "lens_branching_modules": "modules that branch on the lens model",
              "format_name_lists": "places that list export format names (docstrings not counted)"}
    for key, title in titles.items():
        print(f"{title}: {len(found[key])}")
        for item in found[key]:
            print(f"    {item}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
