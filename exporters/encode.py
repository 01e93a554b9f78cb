"""The one way data enters generated host code: literals, never formatted code.

Host scripts are real files in :mod:`gsr_cad.exporters.hostside` (lintable Python modules and OpenSCAD
files). :func:`fill_python` replaces the single line ``DATA = {}`` of such a module with ``DATA = <literal>``,
(and inlines the shared pure-Python helpers of that folder at their ``# gsr:inline`` import line), where the
literal is produced by :func:`literal` from plain data only: None, bools, ints, finite floats,
strings (as ``repr``, which escapes quotes, newlines and NUL), and lists and str-keyed dicts of those.
Anything else (numpy scalars, objects, NaN, infinities) is refused, and the text is parsed back to prove it
is one literal expression. :func:`fill_scad` does the same for OpenSCAD: numbers and vectors of numbers
only, in lines ``name = ...;  // gsr:data``, and comment lines reduced to a safe character set.
"""

from __future__ import annotations

import ast
import math
import re
from collections.abc import Mapping
from importlib import resources
from typing import Any

from gsr_cad.errors import ExportError

MARKER = "DATA = {}"
"""The line of a hostside Python module that :func:`fill_python` replaces."""
SCAD_MARKER = "  // gsr:data"
SCAD_COMMENT_MARKER = "// gsr:comment "
_MAX_DEPTH = 12
_INLINE = 100
_LITERAL_NODES = (ast.Expression, ast.Constant, ast.List, ast.Dict, ast.UnaryOp, ast.USub, ast.Load)
_INLINE_IMPORT = re.compile(r"from (\w+) import [\w, ]+  # gsr:inline")
_SAFE_COMMENT = re.compile(r"[^A-Za-z0-9 .,:;()\[\]_+\-=/]")


def _atom(value: Any) -> str | None:
    """The text of a scalar, None when ``value`` is a container; ExportError for anything else."""
    if value is None or isinstance(value, bool):
        return repr(value)
    if type(value) is int:
        return repr(value)
    if type(value) is float:
        if not math.isfinite(value):
            raise ExportError(f"cannot encode the non-finite number {value!r}")
        return repr(value)
    if type(value) is str:
        return repr(value)
    if isinstance(value, (list, tuple, Mapping)):
        return None
    raise ExportError(f"cannot encode a {type(value).__name__} as a literal")


def _encode(value: Any, depth: int, indent: int) -> str:
    atom = _atom(value)
    if atom is not None:
        return atom
    if depth >= _MAX_DEPTH:
        raise ExportError("data nested too deeply to encode")
    if isinstance(value, Mapping):
        for key in value:
            if type(key) is not str:
                raise ExportError(f"cannot encode a {type(key).__name__} dict key")
        items, ends = [f"{key!r}: {_encode(v, depth + 1, indent)}" for key, v in value.items()], "{}"
    else:
        items, ends = [_encode(v, depth + 1, indent) for v in value], "[]"
    flat = ends[0] + ", ".join(items) + ends[1]
    children = value.values() if isinstance(value, Mapping) else value
    if not indent or all(_atom(v) is not None for v in children) or (len(flat) <= _INLINE and "\n" not in flat):
        return flat
    pad, inner = " " * indent * depth, " " * indent * (depth + 1)
    return ends[0] + "\n" + "".join(f"{inner}{item},\n" for item in items) + pad + ends[1]


def literal(value: Any, indent: int = 0) -> str:
    """Python literal text of plain data (one line, or with ``indent``, one item per line for nested
    containers); ExportError for anything that is not plain data. The text is parsed back and must be a
    single literal expression (constants, lists, dicts, negation) equal to ``value``."""
    text = _encode(value, 0, indent)
    tree = ast.parse(text, mode="eval")
    if not all(isinstance(node, _LITERAL_NODES) for node in ast.walk(tree)):
        raise ExportError("the encoded data is not a pure literal")
    return text


def host_file(name: str) -> str:
    """The text of a file in :mod:`gsr_cad.exporters.hostside`."""
    return resources.files("gsr_cad.exporters.hostside").joinpath(name).read_text(encoding="utf-8")


def _inlined(module: str) -> str:
    """The code of the hostside module ``module`` (a pure-Python helper) without its docstring."""
    text = host_file(module + ".py")
    body = ast.parse(text).body
    start = body[1].lineno - 1 if body and isinstance(body[0], ast.Expr) and len(body) > 1 else 0
    return "\n".join(text.split("\n")[start:]).strip("\n")


def fill_python(name: str, data: Mapping[str, Any]) -> str:
    """The hostside module ``name`` with its one ``DATA = {}`` line replaced by ``DATA = <literal of data>`` and
    every line ``from HELPER import ...  # gsr:inline`` by the code of the hostside module ``HELPER``."""
    text = host_file(name)
    lines = text.split("\n")
    hits = [i for i, line in enumerate(lines) if line == MARKER]
    if len(hits) != 1:
        raise ExportError(f"hostside/{name} must hold exactly one line {MARKER!r}")
    lines[hits[0]] = "DATA = " + literal(dict(data), indent=4)
    for i, line in enumerate(lines):
        if (match := _INLINE_IMPORT.fullmatch(line)) is not None:
            lines[i] = _inlined(match.group(1))
    return "\n".join(lines)


def scad_value(value: Any) -> str:
    """OpenSCAD text of a finite number, a bool, or a (nested) list of those; ExportError otherwise."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if type(value) in (int, float):
        if not math.isfinite(value):
            raise ExportError(f"cannot write the non-finite number {value!r} to OpenSCAD")
        return repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(scad_value(v) for v in value) + "]"
    raise ExportError(f"OpenSCAD data must be numbers or vectors of numbers, not {type(value).__name__}")


def scad_comment(text: str) -> str:
    """``text`` as one OpenSCAD line comment: characters outside a small safe set become '_'."""
    return "// " + _SAFE_COMMENT.sub("_", str(text))[:200]


def fill_scad(name: str, values: Mapping[str, Any], comments: Mapping[str, list[str]] | None = None) -> str:
    """The hostside OpenSCAD file ``name`` with each line ``NAME = ...;  // gsr:data`` set to
    ``NAME = <scad_value>;`` and each line ``// gsr:comment KEY`` replaced by the safe comment lines
    ``comments[KEY]``. Every marker must be filled and every value used."""
    comments = comments or {}
    out, used = [], set()
    for line in host_file(name).split("\n"):
        if line.endswith(SCAD_MARKER):
            key = line.split("=", 1)[0].strip()
            if key not in values:
                raise ExportError(f"hostside/{name}: no value for {key}")
            out.append(f"{key} = {scad_value(values[key])};")
            used.add(key)
        elif line.startswith(SCAD_COMMENT_MARKER):
            key = line[len(SCAD_COMMENT_MARKER):].strip()
            out += [scad_comment(c) for c in comments.get(key, [])]
            used.add(key)
        else:
            out.append(line)
    missing = sorted((set(values) | set(comments)) - used)
    if missing:
        raise ExportError(f"hostside/{name} has no place for {', '.join(missing)}")
    return "\n".join(out)
