"""Result of a reconstruction and its ``result.json`` form (DESIGN.md contract, version 1).

A result is parsed and validated whole, however it is made (:meth:`Result.from_json` or the constructor):
every field is typed and bounded (finite numbers of sane magnitude, whole numbers in range, choices among
their choices, lists of bounded length), and anything else is an :class:`~gsr_cad.errors.InputError`
naming the field. ``config`` is checked through :class:`CurveConfig`/:class:`SurfaceConfig` (their field
types, then their own ``validated()``); keys those classes do not know, ``metrics`` and ``history`` are open
mappings of plain data (numbers, bools, short strings, None, bounded lists and dicts of those).

The ops are the source of truth: the genome is replayed ONCE, on the template stored in ``config``, when
the result is made; ``states`` holds the template and the geometry after every op, and ``control_points``
/ ``control_mesh`` are the replay's final state. The stored control geometry is only a cross-check: when
it disagrees with the replay, the genome wins and :attr:`Result.notes` says so (an edited op in
``result.json`` is how the history is edited). An op that no longer applies is an
:class:`~gsr_cad.errors.OpError` naming it. Without a template and without ops, the stored control
geometry is its own template.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np

from .. import genome as genome_mod
from ..atomic import write_text
from ..errors import GsrError, InputError, OpError
from ..geometry.polymesh import PolyMesh
from ..ops import base as ops_base
from ..ops import curve as curve_ops
from ..ops import mesh as mesh_ops
from .config import PRESETS, CurveConfig, SurfaceConfig

RESULT_VERSION = 1
MAX_COORDINATE = 1e12
"""Largest absolute coordinate accepted in a template, bounds or control geometry."""
MAX_NUMBER = 1e300
"""Largest absolute finite number accepted in an open mapping (metrics, history, unknown config keys)."""
MAX_INT = 2**63
MAX_SEED = 2**64
MAX_POINTS = 100_000
MAX_FACES = 100_000
MAX_FACE_SIZE = 64
MAX_OPS = 10_000
MAX_STRING = 1000
MAX_CHOICE_STRING = 256
MAX_ITEMS = 100_000
MAX_DEPTH = 6
MAX_HISTORY = 1_000_000
_CURVE_EXTRAS = ("preset", "template", "bounds", "target")
_SURFACE_EXTRAS = ("preset", "template", "target", "patch_tolerance", "patch_max_level")


def _fail(what: str, requirement: str, value: Any) -> InputError:
    shown = repr(value)
    shown = shown if len(shown) <= 60 else shown[:57] + "..."
    return InputError(f"result.json {what} must {requirement}, not {shown}")


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_real(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def plain(value: Any, what: str, depth: int = 0) -> Any:
    """``value`` when it is plain bounded data (None, bool, finite number, short string, or a list or
    str-keyed dict of those, at most :data:`MAX_DEPTH` deep); InputError otherwise."""
    if value is None or isinstance(value, bool):
        return value
    if _is_int(value):
        if abs(value) >= MAX_INT:
            raise _fail(what, "be an integer of magnitude below 2**63", value)
        return value
    if isinstance(value, float):
        if not (math.isfinite(value) and abs(value) <= MAX_NUMBER):
            raise _fail(what, "be a finite number", value)
        return value
    if isinstance(value, str):
        if len(value) > MAX_STRING:
            raise _fail(what, f"be a string of at most {MAX_STRING} characters", value)
        return value
    if depth >= MAX_DEPTH:
        raise InputError(f"result.json {what} is nested more than {MAX_DEPTH} levels deep")
    if isinstance(value, (list, tuple)):
        if len(value) > MAX_ITEMS:
            raise _fail(what, f"hold at most {MAX_ITEMS} items", f"<{len(value)} items>")
        return [plain(v, f"{what}[{i}]", depth + 1) for i, v in enumerate(value)]
    if isinstance(value, Mapping):
        if len(value) > MAX_ITEMS:
            raise _fail(what, f"hold at most {MAX_ITEMS} keys", f"<{len(value)} keys>")
        out = {}
        for k, v in value.items():
            if not isinstance(k, str) or len(k) > MAX_CHOICE_STRING:
                raise _fail(f"{what} key", "be a short string", k)
            out[k] = plain(v, f"{what}.{k}", depth + 1)
        return out
    raise _fail(what, "be plain JSON data", type(value).__name__)


def typed(value: Any, hint: Any, what: str) -> Any:
    """``value`` checked against a type annotation (bool, int, float, str, Literal, Optional/Union,
    ``tuple[float, ...]``); plain-data check for any other annotation. Returns the value (tuples as lists
    stay lists)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin is Literal:
        if not any(type(value) is type(a) and value == a for a in args):
            raise _fail(what, f"be one of {', '.join(map(str, args))}", value)
        return value
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        errors = []
        for arg in (a for a in args if a is not type(None)):
            try:
                return typed(value, arg, what)
            except InputError as exc:
                errors.append(exc)
        raise errors[0] if errors else _fail(what, "be None", value)
    if hint is bool:
        if not isinstance(value, bool):
            raise _fail(what, "be true or false", value)
        return value
    if hint is int:
        if not _is_int(value) or abs(value) >= MAX_INT:
            raise _fail(what, "be an integer of magnitude below 2**63", value)
        return value
    if hint is float:
        if not (_is_real(value) and math.isfinite(value) and abs(value) <= MAX_NUMBER):
            raise _fail(what, "be a finite number", value)
        return value
    if hint is str:
        if not isinstance(value, str) or len(value) > MAX_CHOICE_STRING:
            raise _fail(what, f"be a string of at most {MAX_CHOICE_STRING} characters", value)
        return value
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise _fail(what, "be a list", value)
        if len(args) == 2 and args[1] is Ellipsis:
            inner = [args[0]] * len(value)
        elif len(args) != len(value):
            raise _fail(what, f"be a list of {len(args)} items", value)
        else:
            inner = list(args)
        return [typed(v, h, f"{what}[{i}]") for i, (v, h) in enumerate(zip(value, inner))]
    return plain(value, what)


def _points(value: Any, what: str, dims: tuple[int, ...], min_rows: int = 1) -> np.ndarray:
    """Finite coordinate rows of one of ``dims`` columns (at most :data:`MAX_POINTS` rows)."""
    if not isinstance(value, (list, tuple)) or not min_rows <= len(value) <= MAX_POINTS:
        raise _fail(what, f"be a list of {min_rows} to {MAX_POINTS} coordinate rows", value)
    dim = len(value[0]) if isinstance(value[0], (list, tuple)) else -1
    if dim not in dims:
        raise _fail(what, f"hold rows of {' or '.join(map(str, dims))} numbers", value[0])
    for i, row in enumerate(value):
        if not isinstance(row, (list, tuple)) or len(row) != dim or not all(_is_real(x) for x in row):
            raise _fail(f"{what}[{i}]", f"be a row of {dim} numbers", row)
    pts = np.asarray(value, dtype=float)
    if not (np.all(np.isfinite(pts)) and np.all(np.abs(pts) <= MAX_COORDINATE)):
        raise _fail(what, f"hold finite coordinates of magnitude at most {MAX_COORDINATE:g}", "a larger number")
    return pts


def _faces(value: Any, what: str, n_vertices: int) -> list[tuple[int, ...]]:
    if not isinstance(value, (list, tuple)) or not 1 <= len(value) <= MAX_FACES:
        raise _fail(what, f"be a list of 1 to {MAX_FACES} faces", value)
    out = []
    for i, face in enumerate(value):
        if (not isinstance(face, (list, tuple)) or not 3 <= len(face) <= MAX_FACE_SIZE
                or not all(_is_int(v) and 0 <= v < n_vertices for v in face)):
            raise _fail(f"{what}[{i}]", f"be 3 to {MAX_FACE_SIZE} vertex indices in [0, {n_vertices})", face)
        out.append(tuple(face))
    return out


def _mesh(value: Any, what: str) -> PolyMesh:
    if not isinstance(value, Mapping) or "vertices" not in value or "faces" not in value:
        raise _fail(what, "be an object with vertices and faces", value)
    vertices = _points(value["vertices"], f"{what}.vertices", (3,), min_rows=4)
    faces = _faces(value["faces"], f"{what}.faces", len(vertices))
    try:
        return PolyMesh.from_faces(vertices, faces)
    except (GsrError, ValueError, TypeError, IndexError) as exc:
        raise InputError(f"result.json {what} is not a usable mesh: {str(exc).splitlines()[0]}") from None


def _config_class(kind: str) -> type:
    return CurveConfig if kind == "curve" else SurfaceConfig


def parse_config(kind: str, raw: Any) -> dict[str, Any]:
    """The config of a ``kind`` result, checked: fields of the config class by their annotations and
    ``validated()`` (missing ones take the defaults for that check), the known extras (preset, template,
    bounds, target, patch options) by shape, any other key as plain data. Returns a copy, order kept."""
    if not isinstance(raw, Mapping):
        raise _fail("config", "be an object", raw)
    cls = _config_class(kind)
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    out: dict[str, Any] = {}
    for key, value in raw.items():
        if not isinstance(key, str) or len(key) > MAX_CHOICE_STRING:
            raise _fail("config key", "be a short string", key)
        what = f"config.{key}"
        if key in names:
            out[key] = typed(value, hints[key], what)
        elif key == "preset":
            out[key] = typed(value, Literal[PRESETS], what)  # type: ignore[valid-type]
        elif key == "template":
            out[key] = value  # shape-checked by parse_template
        elif key == "bounds":
            box = _points(value, what, (2, 3), min_rows=2)
            if len(box) != 2:
                raise _fail(what, "be two corners [lo, hi]", value)
            out[key] = value
        elif key == "patch_tolerance":
            if not (_is_real(value) and math.isfinite(value) and 0 < value <= 1):
                raise _fail(what, "be a number in (0, 1]", value)
            out[key] = value
        elif key == "patch_max_level":
            if not (_is_int(value) and 0 <= value <= 8):
                raise _fail(what, "be an integer in [0, 8]", value)
            out[key] = value
        else:
            out[key] = plain(value, what)
    try:
        cls(**{k: v for k, v in out.items() if k in names}).validated()
    except InputError as exc:
        raise InputError(f"result.json config: {exc}") from None
    return out


def parse_template(kind: str, config: Mapping[str, Any]) -> Any:
    """The template stored in ``config`` (a curve :class:`~gsr_cad.ops.curve.Polygon` bounded by
    ``config.bounds``, or a :class:`PolyMesh`), or None when there is none."""
    if "template" not in config:
        return None
    if kind == "surface":
        return _mesh(config["template"], "config.template")
    pts = _points(config["template"], "config.template", (2, 3), min_rows=2)
    bounds = config.get("bounds")
    if bounds is None:
        lo, hi = np.full(pts.shape[1], -MAX_COORDINATE), np.full(pts.shape[1], MAX_COORDINATE)
    else:
        box = _points(bounds, "config.bounds", (pts.shape[1],), min_rows=2)
        if len(box) != 2:
            raise _fail("config.bounds", "be two corners [lo, hi]", bounds)
        lo, hi = box
    closed = config.get("closed", False)
    if not isinstance(closed, bool):
        raise _fail("config.closed", "be true or false", closed)
    try:
        return curve_ops.Polygon(pts, tuple(lo.tolist()), tuple(hi.tolist()), closed=closed,
                                 degree=2 if config.get("scheme") == "chaikin" else 3)
    except (GsrError, ValueError, TypeError) as exc:
        raise InputError(f"result.json config.template is not a usable polygon: {str(exc).splitlines()[0]}") \
            from None


def _op_fields(cls: type) -> dict[str, Any]:
    hints = typing.get_type_hints(cls)
    return {f.name: hints.get(f.name, Any) for f in dataclasses.fields(cls)}


def parse_genome(kind: str, raw: Any) -> tuple:
    """The genome: op dicts whose ``op`` names a registered op of this kind and whose fields are exactly
    that op's, each typed by the op class's annotations, then built through the op registry."""
    if not isinstance(raw, (list, tuple)) or len(raw) > MAX_OPS:
        raise _fail("genome", f"be a list of at most {MAX_OPS} ops", raw)
    ops = []
    for i, data in enumerate(raw):
        what = f"genome[{i}]"
        if not isinstance(data, Mapping) or not isinstance(data.get("op"), str):
            raise _fail(what, "be an object with an op name", data)
        cls = ops_base.REGISTRY.get(data["op"])
        if cls is None or issubclass(cls, mesh_ops.MeshOp) != (kind == "surface"):
            raise _fail(f"{what}.op", f"name a {kind} op ({', '.join(_op_names(kind))})", data["op"])
        fields = _op_fields(cls)
        extra = sorted(set(data) - set(fields) - {"op"})
        if extra:
            raise _fail(what, f"hold only the fields of {cls.name} ({', '.join(fields)})", extra[0])
        for name, hint in fields.items():
            if name not in data:
                raise InputError(f"result.json {what} ({cls.name}) lacks field {name!r}")
            typed(data[name], hint, f"{what}.{name}")
        try:
            ops.append(ops_base.op_from_json(dict(data)))
        except (GsrError, TypeError, ValueError) as exc:
            raise InputError(f"result.json {what}: {str(exc).splitlines()[0]}") from None
    return tuple(ops)


def _op_names(kind: str) -> list[str]:
    return sorted(n for n, c in ops_base.REGISTRY.items() if issubclass(c, mesh_ops.MeshOp) == (kind == "surface"))


def _describe(op: Any) -> str:
    describe = getattr(op, "describe", None)
    return describe() if callable(describe) else op.name.replace("_", " ")


def replay(template: Any, genome: tuple) -> tuple:
    """The template and the state after every op; OpError naming the first op that no longer applies."""
    states = [template]
    for i, op in enumerate(genome):
        try:
            states.append(op.apply(states[-1]))
        except (GsrError, ValueError, TypeError, IndexError, AttributeError) as exc:
            raise OpError(f"genome op {i} ({_describe(op)}) no longer applies: {str(exc).splitlines()[0]}") \
                from None
    return tuple(states)


@dataclasses.dataclass
class Result:
    """A reconstruction: the genome (modelling history), the control geometry it builds, metrics, history.

    ``control_points`` is set for curves (``(n, 2)`` or ``(n, 3)``), ``control_mesh`` for surfaces; both are
    the replay of the genome (see the module docstring), ``states`` every step of it, ``notes`` what the
    cross-check with the stored geometry found. ``config["scheme"]`` says how a curve is evaluated
    ("bspline": clamped uniform cubic B-spline, "chaikin": Chaikin corner cutting, i.e. its clamped uniform
    quadratic B-spline limit).
    """

    kind: Literal["curve", "surface"]
    config: dict[str, Any]
    seed: int | None
    genome: tuple
    metrics: dict[str, Any]
    history: list[dict[str, Any]]
    control_points: np.ndarray | None = None
    control_mesh: PolyMesh | None = None
    interrupted: bool = False
    states: tuple = dataclasses.field(default=(), init=False, repr=False, compare=False)
    notes: list[str] = dataclasses.field(default_factory=list, init=False, repr=False, compare=False)

    KIND: ClassVar[str | None] = None
    """The kind a typed subclass holds (None: either)."""

    def __post_init__(self) -> None:
        if self.kind not in ("curve", "surface") or self.KIND not in (None, self.kind):
            raise _fail("kind", f"be {self.KIND or 'curve or surface'}", self.kind)
        self.config = parse_config(self.kind, self.config if self.config is not None else {})
        if self.seed is not None and not (_is_int(self.seed) and 0 <= self.seed < MAX_SEED):
            raise _fail("seed", "be null or an integer in [0, 2**64)", self.seed)
        self.genome = tuple(self.genome)
        if len(self.genome) > MAX_OPS:
            raise _fail("genome", f"hold at most {MAX_OPS} ops", f"<{len(self.genome)} ops>")
        for i, op in enumerate(self.genome):
            if not isinstance(op, ops_base.Op) or isinstance(op, mesh_ops.MeshOp) != (self.kind == "surface"):
                raise _fail(f"genome[{i}]", f"be a {self.kind} op", op)
        if not isinstance(self.metrics if self.metrics is not None else {}, Mapping):
            raise _fail("metrics", "be an object", self.metrics)
        self.metrics = plain(dict(self.metrics or {}), "metrics")
        self.history = self._history(self.history)
        if not isinstance(self.interrupted, bool):
            raise _fail("interrupted", "be true or false", self.interrupted)
        stored = self._stored_geometry()
        template = parse_template(self.kind, self.config)
        if template is None and not self.genome and stored is not None:  # the control geometry is its own template
            template = stored if self.kind == "surface" else curve_ops.Polygon(
                stored, tuple(np.full(stored.shape[1], -MAX_COORDINATE)),
                tuple(np.full(stored.shape[1], MAX_COORDINATE)))
        if template is None:  # nothing to replay: keep what was given (exporters needing the history refuse)
            if self.genome:
                self.notes.append("no config.template: the genome cannot be replayed")
            self.control_points, self.control_mesh = (stored, None) if self.kind == "curve" else (None, stored)
            return
        self.states = replay(template, self.genome)
        final = self.states[-1]
        if self.kind == "curve":
            self.control_points = np.array(final.points)
            if stored is not None and (stored.shape != final.points.shape or not np.array_equal(stored, final.points)):
                dev = (float(np.max(np.linalg.norm(stored - final.points, axis=1)))
                       if stored.shape == final.points.shape else math.inf)
                self.notes.append(f"control_points in the result differ from the genome's replay "
                                  f"(largest deviation {dev:.3g}): the genome wins")
        else:
            self.control_mesh = final
            if stored is not None and (stored.faces != final.faces or
                                       not np.array_equal(stored.vertices, final.vertices)):
                self.notes.append("control_mesh in the result differs from the genome's replay: the genome wins")

    @staticmethod
    def _history(raw: Any) -> list[dict[str, Any]]:
        if not isinstance(raw, (list, tuple)) or len(raw) > MAX_HISTORY:
            raise _fail("history", f"be a list of at most {MAX_HISTORY} rows", raw)
        out = []
        for i, row in enumerate(raw):
            if not isinstance(row, Mapping):
                raise _fail(f"history[{i}]", "be an object", row)
            out.append(plain(dict(row), f"history[{i}]", depth=1))
        return out

    def _stored_geometry(self) -> Any:
        """The control geometry given with the result (a cache to cross-check), parsed, or None."""
        if self.kind == "curve":
            pts = self.control_points
            if pts is None:
                return None
            if isinstance(pts, np.ndarray):
                pts = pts.tolist()
            return _points(pts, "control_points", (2, 3), min_rows=2)
        mesh = self.control_mesh
        if mesh is None or isinstance(mesh, PolyMesh):
            return mesh
        return _mesh(mesh, "control_mesh")

    @property
    def template(self) -> Any:
        """The template the genome is replayed on (first of :attr:`states`; None without one)."""
        return self.states[0] if self.states else None

    @property
    def degree(self) -> int:
        """Degree of a curve result's B-spline (3 for "bspline", 2 for "chaikin")."""
        return 2 if self.config.get("scheme") == "chaikin" else 3

    @property
    def scheme(self) -> str:
        """A curve's evaluation scheme ("bspline" or "chaikin")."""
        return str(self.config.get("scheme", "bspline"))

    @property
    def levels(self) -> int:
        """A surface's subdivision levels (config.levels, default 2)."""
        return int(self.config.get("levels", 2))

    @property
    def boundary(self) -> str:
        """A surface's boundary rule (config.boundary, "all" or "corners")."""
        return str(self.config.get("boundary", "all"))

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "kind": self.kind,
            "version": RESULT_VERSION,
            "config": self.config,
            "seed": self.seed,
            "genome": genome_mod.to_json(self.genome),
        }
        if self.kind == "curve":
            out["control_points"] = np.asarray(self.control_points, dtype=float).tolist()
        else:
            mesh = self.control_mesh
            out["control_mesh"] = {"vertices": mesh.vertices.tolist(), "faces": [list(f) for f in mesh.faces]}
        out["metrics"] = self.metrics
        out["history"] = self.history
        if self.interrupted:
            out["interrupted"] = True
        return out

    @classmethod
    def from_json(cls, data: Any) -> Result:
        """Parse a ``result.json`` document into a :class:`CurveResult` or :class:`SurfaceResult`; anything
        malformed raises InputError, an op that no longer applies OpError."""
        if not isinstance(data, Mapping):
            raise InputError("result.json must hold a JSON object")
        if not (_is_int(data.get("version")) and data.get("version") == RESULT_VERSION):
            raise _fail("version", f"be {RESULT_VERSION} (the version this gsr_cad reads)", data.get("version"))
        kind = data.get("kind")
        if kind not in ("curve", "surface"):
            raise _fail("kind", "be curve or surface", kind)
        known = {"kind", "version", "config", "seed", "genome", "metrics", "history", "interrupted",
                 "control_points" if kind == "curve" else "control_mesh"}
        unknown = sorted(k for k in data if k not in known)
        if unknown:
            raise _fail("key", f"be one of {', '.join(sorted(known))}", unknown[0])
        if "config" not in data or "genome" not in data:
            raise InputError("result.json lacks config or genome")
        genome = parse_genome(kind, data["genome"])
        if genome and (not isinstance(data["config"], Mapping) or "template" not in data["config"]):
            raise InputError("result.json has ops but no config.template to replay them on")
        geometry_key = "control_points" if kind == "curve" else "control_mesh"
        if not genome and "template" not in data["config"] and data.get(geometry_key) is None:
            raise InputError(f"result.json has neither a config.template nor {geometry_key}")
        geometry = {"control_points": data.get("control_points")} if kind == "curve" else \
            {"control_mesh": data.get("control_mesh")}
        target = CurveResult if kind == "curve" else SurfaceResult
        return target(kind=kind, config=data["config"], seed=data.get("seed"), genome=genome,
                      metrics=data.get("metrics", {}), history=data.get("history", []),
                      interrupted=data.get("interrupted", False), **geometry)

    def save(self, out_dir: str | os.PathLike[str]) -> Path:
        """Write ``out_dir/result.json`` atomically and return its path."""
        path = Path(out_dir) / "result.json"
        write_text(path, json.dumps(self.to_json(), indent=1) + "\n")
        return path

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Result:
        """Read a ``result.json`` file (or the one inside a directory)."""
        from .inputs import read_json

        p = Path(path)
        if p.is_dir():
            p = p / "result.json"
        return cls.from_json(read_json(p, "result.json"))


@dataclasses.dataclass
class CurveResult(Result):
    """A curve :class:`Result` (``kind`` "curve"): ``control_points`` and ``states`` of curve polygons."""

    KIND: ClassVar[str] = "curve"


@dataclasses.dataclass
class SurfaceResult(Result):
    """A surface :class:`Result` (``kind`` "surface"): ``control_mesh`` and ``states`` of meshes."""

    KIND: ClassVar[str] = "surface"
