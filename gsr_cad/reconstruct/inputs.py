"""Loading and validating curve targets: ordered 2D points from CSV/TXT/NPY files or arrays.

Every problem with the input becomes an :class:`~gsr_cad.errors.InputError` with a one-line reason.
"""

from __future__ import annotations

import dataclasses
import functools
import io
import json
import os
import stat
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from ..errors import GsrWarning, InputError

CURVE_SUFFIXES = (".csv", ".txt", ".xy", ".npy")
MAX_INPUT_BYTES = 1 << 30
"""Largest input file read (1 GiB): enough for 10^7 text points; anything bigger is refused before reading."""
MAX_POINTS = 20_000_000
"""Most points a target may have."""
MAX_COORDINATE = 1e9
"""Largest coordinate magnitude accepted: a result holds coordinates up to 1e12
(:data:`gsr_cad.reconstruct.result.MAX_COORDINATE`), and the search's box may reach out a hundred
diagonals beyond the data (a curve's ``bounds_margin``)."""
MIN_EXTENT = 1e-50
"""Smallest extent of a target (fourth powers of smaller ones underflow)."""
MIN_RELATIVE_EXTENT = 1e-12
"""Smallest extent relative to the largest coordinate (below, the points differ only in rounding)."""
MAX_JSON_BYTES = 256 << 20
"""Largest JSON document read (256 MiB)."""
MAX_JSON_INT_DIGITS = 30
"""Longest integer literal accepted in a JSON document."""
UTF8_BOM = b"\xef\xbb\xbf"


def _size(n: int) -> str:
    return f"{n / (1 << 20):.0f} MiB" if n >= 1 << 20 else f"{n} bytes"


def open_input(path: str | os.PathLike[str], what: str = "file", limit: int = MAX_INPUT_BYTES,
               label: str | None = None) -> int:
    """Check that ``path`` is a readable, non-empty regular file of at most ``limit`` bytes; returns its size.

    FIFOs, devices, sockets and directories are refused (reading them could block or never end). Messages
    start with ``label`` (default: the path).
    """
    if os.fspath(path) == "":
        raise InputError(f"empty {what} name")
    p = Path(path)
    name = str(p) if label is None else label
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise InputError(f"{name}: no such file") from None
    except OSError as exc:
        raise InputError(f"{name}: cannot read ({exc.strerror or exc})") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{name}: cannot read: is a directory, not a {what}")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{name}: cannot read: not a regular file (a device, FIFO or socket cannot be a {what})")
    if st.st_size == 0:
        raise InputError(f"{name}: file is empty")
    if st.st_size > limit:
        raise InputError(f"{name}: file is {_size(st.st_size)}; the limit for a {what} is {_size(limit)}")
    if not os.access(p, os.R_OK):
        raise InputError(f"{name}: cannot read (permission denied)")
    return int(st.st_size)


def read_input(path: str | os.PathLike[str], what: str = "file", limit: int = MAX_INPUT_BYTES,
               label: str | None = None) -> bytes:
    """The bytes of a regular input file (at most ``limit``; see :func:`open_input`), without a UTF-8 BOM."""
    open_input(path, what, limit, label)
    name = str(path) if label is None else label
    try:
        with open(path, "rb") as fh:
            data = fh.read(limit + 1)
    except OSError as exc:
        raise InputError(f"{name}: cannot read ({exc.strerror or exc})") from None
    if len(data) > limit:
        raise InputError(f"{name}: file grew beyond the limit for a {what} ({_size(limit)})")
    return data[len(UTF8_BOM):] if data.startswith(UTF8_BOM) else data


def _json_int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_JSON_INT_DIGITS:
        raise ValueError(f"an integer of {len(text)} digits (at most {MAX_JSON_INT_DIGITS} are accepted)")
    return int(text)


def _json_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number")


def read_json(path: str | os.PathLike[str], what: str = "JSON file", limit: int = MAX_JSON_BYTES) -> Any:
    """Parse a bounded JSON file: size, integer length and nesting depth are limited; InputError otherwise."""
    data = read_input(path, what, limit)
    try:
        return json.loads(data.decode("utf-8"), parse_int=_json_int, parse_constant=_json_constant)
    except RecursionError:
        raise InputError(f"{path}: not a readable {what} (nested too deeply)") from None
    except (UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{path}: not a readable {what} ({str(exc).splitlines()[0]})") from None


def load_npy(path: str | os.PathLike[str]) -> np.ndarray:
    """A real numeric 2D ``.npy`` array, its header checked before any data is read (memory-mapped)."""
    size = open_input(path, "point file")
    try:
        with open(path, "rb") as fh:
            version = np.lib.format.read_magic(fh)
            header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                      else np.lib.format.read_array_header_2_0)
            shape, fortran, dtype = header(fh, max_header_size=10_000)
            offset = fh.tell()
    except (ValueError, OSError, SyntaxError, TypeError) as exc:
        raise InputError(f"{path}: not a readable .npy array ({str(exc).splitlines()[0]})") from None
    if dtype.kind not in "iuf" or dtype.hasobject or dtype.fields:
        kind = {"c": "complex numbers", "b": "booleans", "O": "Python objects"}.get(dtype.kind, f"dtype {dtype}")
        raise InputError(f"{path}: .npy holds {kind}; real numbers (float or int) are needed")
    if len(shape) != 2:
        raise InputError(f"{path}: expected a 2D array of points, got shape {shape}")
    count = int(np.prod(shape, dtype=object))
    if shape[0] > MAX_POINTS:
        raise InputError(f"{path}: .npy claims {shape[0]} points; at most {MAX_POINTS} are accepted")
    if offset + count * dtype.itemsize > size:
        raise InputError(f"{path}: .npy is truncated (its header claims shape {shape}, "
                         f"{count * dtype.itemsize} bytes of data; the file has {size - offset})")
    try:
        data = np.memmap(path, dtype=dtype, mode="r", offset=offset, shape=tuple(shape),
                         order="F" if fortran else "C")
        return np.array(data, dtype=np.float64)
    except (ValueError, OSError) as exc:
        raise InputError(f"{path}: not a readable .npy array ({exc})") from None


def check_coordinates(pts: np.ndarray, source: str) -> None:
    """InputError for NaN/inf, or magnitudes whose distances overflow (beyond :data:`MAX_COORDINATE`)."""
    if not np.all(np.isfinite(pts)):
        bad = int(np.argwhere(~np.isfinite(pts))[0, 0])
        raise InputError(f"{source}: point {bad + 1} is NaN or infinite")
    if len(pts) > MAX_POINTS:
        raise InputError(f"{source}: {len(pts)} points; at most {MAX_POINTS} are accepted")
    big = np.abs(pts).max(initial=0.0)
    if big > MAX_COORDINATE:
        bad = int(np.argwhere(np.abs(pts) > MAX_COORDINATE)[0, 0])
        raise InputError(f"{source}: point {bad + 1} has a coordinate of magnitude {big:.3g}; at most "
                         f"{MAX_COORDINATE:.0e} is supported (rescale the data, or subtract an offset)")
    spread = float((pts.max(axis=0) - pts.min(axis=0)).max(initial=0.0)) if len(pts) else 0.0
    if 0.0 < spread < MIN_EXTENT:
        raise InputError(f"{source}: the points span only {spread:.3g}; the extent must be at least "
                         f"{MIN_EXTENT:.0e} (rescale the data)")
    if 0.0 < spread < MIN_RELATIVE_EXTENT * big:
        raise InputError(f"{source}: the points span only {spread:.3g} at coordinates of {big:.3g}: they differ "
                         f"only in rounding (the extent must be at least {MIN_RELATIVE_EXTENT:.0e} of the largest "
                         "coordinate; subtract an offset)")


class _PointSet:
    """Bounding box, diagonal and KD-tree of a target's ``points`` (computed once, on first use)."""

    points: np.ndarray

    @functools.cached_property
    def bbox(self) -> np.ndarray:
        return np.stack([self.points.min(axis=0), self.points.max(axis=0)])

    @property
    def diagonal(self) -> float:
        return float(np.linalg.norm(self.bbox[1] - self.bbox[0]))

    @functools.cached_property
    def kdtree(self) -> cKDTree:
        return cKDTree(self.points)


@dataclasses.dataclass(frozen=True, eq=False)
class CurveTarget(_PointSet):
    """Ordered 2D or 3D target points with their bounding box and scale."""

    points: np.ndarray
    name: str = "points"

    def __len__(self) -> int:
        return len(self.points)


def _cells(line: str) -> list[str]:
    return [c for c in line.replace(";", ",").replace("\t", ",").replace(" ", ",").split(",") if c != ""]


def _fast_table(text: str) -> np.ndarray | None:
    """The table parsed by numpy's C reader (10^6 rows in about a second), or None when anything is unusual
    (the line-by-line reader then finds and names the problem)."""
    start = 0
    while start < len(text):  # skip blank and comment lines, then a header line if it is not numeric
        end = text.find("\n", start)
        end = len(text) if end < 0 else end + 1
        line = text[start:end].split("#", 1)[0].strip()
        if line:
            try:
                [float(c) for c in _cells(line)]
            except ValueError:
                start = end
            break
        start = end
    body = text[start:]
    if not body.strip():
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            table = np.loadtxt(io.StringIO(body.replace(",", " ").replace(";", " ")), comments="#", ndmin=2,
                               dtype=np.float64)
    except (ValueError, Warning):
        return None
    return table if table.size else None


def _read_text_table(path: Path) -> np.ndarray:
    try:
        text = read_input(path, "point file").decode("utf-8")
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a text file") from None
    table = _fast_table(text)
    if table is not None:
        if len(table) > MAX_POINTS:
            raise InputError(f"{path}: more than {MAX_POINTS} rows")
        return table
    rows = []
    first = True
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        cells = _cells(line)
        try:
            rows.append([float(c) for c in cells])
        except ValueError:
            if not first:
                raise InputError(f"{path}:{lineno}: non-numeric value in {raw.strip()!r}") from None
        first = False
        if len(rows) > MAX_POINTS:
            raise InputError(f"{path}: more than {MAX_POINTS} rows")
    if not rows:
        raise InputError(f"{path}: no data rows")
    widths = {len(r) for r in rows}
    if len(widths) != 1:
        raise InputError(f"{path}: rows have different numbers of columns ({sorted(widths)})")
    return np.asarray(rows, dtype=np.float64)


def load_curve_points(path: str | os.PathLike[str]) -> np.ndarray:
    """Read an ordered ``x, y`` point file (CSV/TXT with optional header, or NPY)."""
    p = Path(path)
    open_input(p, "point file")
    suffix = p.suffix.lower()
    if suffix == ".npy":
        data = load_npy(p)
    elif suffix in CURVE_SUFFIXES or suffix == "":
        data = _read_text_table(p)
    else:
        raise InputError(f"{p}: unsupported point file type {suffix!r} (use {', '.join(CURVE_SUFFIXES)})")
    return validate_curve_points(data, source=str(p))


def _as_points(points: Any, source: str) -> np.ndarray:
    """``points`` as a float64 array; complex, boolean or non-numeric data raise InputError."""
    if np.iscomplexobj(points):
        raise InputError(f"{source}: points are complex numbers; real coordinates are needed")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            return np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError, OverflowError, Warning):
        raise InputError(f"{source}: points must be real numbers in rows of equal length") from None


def validate_curve_points(points: np.ndarray, source: str = "points") -> np.ndarray:
    """Check an ordered 2D or 3D point array; returns it as float64 ``(n, 2)`` or ``(n, 3)``."""
    pts = _as_points(points, source)
    if pts.ndim != 2:
        raise InputError(f"{source}: expected rows of x, y[, z] (got an array of shape {pts.shape})")
    if pts.shape[1] not in (2, 3):
        raise InputError(f"{source}: expected 2 or 3 columns (x, y[, z]), got {pts.shape[1]}")
    check_coordinates(pts, source)
    if len(pts) < 4:
        raise InputError(f"{source}: need at least 4 points, got {len(pts)}")
    steps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    scale = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    if scale == 0.0:
        raise InputError(f"{source}: all points are equal")
    dup = np.flatnonzero(steps <= 1e-12 * scale)
    if dup.size:
        raise InputError(f"{source}: points {dup[0] + 1} and {dup[0] + 2} are duplicates "
                         "(consecutive points must differ)")
    return pts


def curve_target(points_or_path: np.ndarray | str | os.PathLike[str] | CurveTarget,
                 name: str | None = None) -> CurveTarget:
    """A validated :class:`CurveTarget` from an array, a file path or a target."""
    if isinstance(points_or_path, CurveTarget):
        pts = validate_curve_points(points_or_path.points, points_or_path.name)
        return points_or_path if name is None else CurveTarget(pts, name)
    if isinstance(points_or_path, (str, os.PathLike)):
        pts = load_curve_points(points_or_path)
        return CurveTarget(pts, name or Path(points_or_path).stem)
    return CurveTarget(validate_curve_points(points_or_path), name or "points")


def target_kind(path: str | os.PathLike[str]) -> str:
    """"curve" or "surface" for a target file: meshes, .xyz/.pts and 3-column data are surfaces, 2-column
    data curves (the file is read to count its columns)."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix in SURFACE_MESH_SUFFIXES or suffix in (".xyz", ".pts"):
        return "surface"
    if suffix not in CURVE_SUFFIXES and suffix != "":
        raise InputError(f"{p}: unsupported target type {suffix!r} (curves: {', '.join(CURVE_SUFFIXES)}; "
                         f"surfaces: {', '.join(SURFACE_MESH_SUFFIXES + SURFACE_CLOUD_SUFFIXES)})")
    data = load_npy(p) if suffix == ".npy" else _read_text_table(p)
    return "curve" if data.ndim == 2 and data.shape[1] == 2 else "surface"


# --- surface targets ------------------------------------------------------------------------------------------

SURFACE_MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off")
SURFACE_CLOUD_SUFFIXES = (".xyz", ".csv", ".txt", ".pts", ".npy")
CLOUD_SAMPLING_NEIGHBOURS = 6
"""A cloud point's sampling radius is the distance to its 6th nearest neighbour (see surface_distance)."""


@dataclasses.dataclass(frozen=True, eq=False)
class SurfaceTarget(_PointSet):
    """A surface to reconstruct: 3D points and, for a mesh, its faces as triangles (polygons fan-split).

    ``faces`` is ``(m, 3)`` vertex indices into ``points`` or None for a point cloud. The KD-tree, the
    triangle set and the cloud's sampling radii are built once, on first use.
    """

    points: np.ndarray
    faces: np.ndarray | None = None
    name: str = "target"

    def __post_init__(self):
        pts = np.array(self.points, dtype=np.float64)
        pts.setflags(write=False)
        object.__setattr__(self, "points", pts)
        if self.faces is not None:
            tri = np.array(self.faces, dtype=np.int64).reshape(-1, 3)
            tri.setflags(write=False)
            object.__setattr__(self, "faces", tri)

    @property
    def kind(self) -> str:
        """"mesh" or "cloud"."""
        return "cloud" if self.faces is None else "mesh"

    @functools.cached_property
    def triangle_set(self):
        """:class:`~gsr_cad.geometry.surface_distance.TriangleSet` of a mesh target (None for a cloud)."""
        from ..geometry.surface_distance import TriangleSet

        return None if self.faces is None else TriangleSet(self.points, self.faces)

    @functools.cached_property
    def sampling_radius(self) -> np.ndarray:
        """Per point, the distance to its 6th nearest neighbour (the cloud's local spacing)."""
        from ..geometry.surface_distance import sampling_radius

        return sampling_radius(self.points, self.kdtree, CLOUD_SAMPLING_NEIGHBOURS)

    def closest(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(distance, corresponding point)`` of each row of ``x`` to this target: the closest point on a
        mesh's triangles; for a cloud the nearest sample, at the distance beyond its sampling radius (0
        within it)."""
        if self.triangle_set is not None:
            c = self.triangle_set.closest(x)
            return c.distance, c.point
        d, idx = self.kdtree.query(x)
        return np.maximum(d - self.radius_at(idx), 0.0), self.points[idx]

    def radius_at(self, idx: np.ndarray) -> np.ndarray:
        """The sampling radius (:attr:`sampling_radius`) of the points ``idx`` only, unless all are known: a
        few queries on a huge cloud do not pay for its every point's neighbours."""
        if "sampling_radius" in self.__dict__:
            return self.sampling_radius[idx]
        k = min(CLOUD_SAMPLING_NEIGHBOURS, len(self.points) - 1)
        if k < 1:
            return np.zeros(len(idx))
        distinct, back = np.unique(idx, return_inverse=True)
        d, _ = self.kdtree.query(self.points[distinct], k=k + 1)
        return d[:, -1][back]

    def __len__(self) -> int:
        return len(self.points)

    def subsampled(self, max_points: int, seed: int = 0) -> SurfaceTarget:
        """This target, or for a cloud of more than ``max_points`` points a fixed random subset of that many
        (same seed, same subset; order kept): the search can run on it while the final metrics use all
        points. A mesh target is returned as it is (its triangles carry the surface)."""
        if self.faces is not None or max_points <= 0 or len(self.points) <= max_points:
            return self
        keep = np.sort(np.random.default_rng(seed).choice(len(self.points), max_points, replace=False))
        return SurfaceTarget(self.points[keep], None, self.name)

    def __getstate__(self) -> dict:
        """Pickle the data only (worker processes rebuild their trees)."""
        return {"points": self.points, "faces": self.faces, "name": self.name}

    def __setstate__(self, state: dict) -> None:
        for key, value in state.items():
            object.__setattr__(self, key, value)


def validate_surface_points(points: np.ndarray, source: str = "points") -> np.ndarray:
    """Check 3D target points; returns them as float64 ``(n, 3)``.

    Rejects: non-numbers, 2D data, NaN/inf, fewer than 4 points, a single point, and collinear or flat
    data (a closed surface has volume).
    """
    pts = _as_points(points, source)
    if pts.ndim != 2:
        raise InputError(f"{source}: expected rows of x, y, z (got an array of shape {pts.shape})")
    if pts.shape[1] == 2:
        raise InputError(f"{source}: 2D data (x, y); a surface needs x, y, z (use gsr curve for planar curves)")
    if pts.shape[1] == 6:  # x y z nx ny nz: normals are not used
        pts = pts[:, :3]
    if pts.shape[1] != 3:
        raise InputError(f"{source}: expected 3 columns (x, y, z), got {pts.shape[1]}")
    check_coordinates(pts, source)
    if len(pts) < 4:
        raise InputError(f"{source}: need at least 4 points, got {len(pts)}")
    centred = pts - pts.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if sv[0] <= 1e-12 * float(np.abs(pts).max()):
        raise InputError(f"{source}: all points coincide (a single point)")
    if sv[1] <= 1e-9 * sv[0]:
        raise InputError(f"{source}: degenerate target: all points lie on a line")
    if sv[2] <= 1e-9 * sv[0]:
        raise InputError(f"{source}: degenerate target: all points lie in one plane (a flat target has no volume)")
    return pts


def _obj_has_faces(data: bytes) -> bool:
    return any(line.split(None, 1)[:1] == [b"f"] for line in data.splitlines())


def _read_obj_points(data: bytes, what: str) -> np.ndarray:
    rows = []
    for lineno, raw in enumerate(data.decode("utf-8", errors="replace").splitlines(), 1):
        parts = raw.split("#", 1)[0].split()
        if parts and parts[0] == "v":
            try:
                rows.append([float(x) for x in parts[1:4]])
            except ValueError:
                raise InputError(f"{what}:{lineno}: non-numeric vertex {raw.strip()!r}") from None
            if len(rows[-1]) != 3:
                raise InputError(f"{what}:{lineno}: a vertex needs x y z")
    if not rows:
        raise InputError(f"{what}: no vertices")
    return np.asarray(rows, dtype=np.float64)


def load_surface_target(path: str | os.PathLike[str], name: str | None = None) -> SurfaceTarget:
    """Read a surface target: a mesh (OBJ, PLY, STL, OFF) or a point cloud (XYZ, CSV, TXT, PTS, NPY, or an
    OBJ/PLY without faces). Every problem is an InputError (or TopologyError) with a one-line reason.

    Files are read only if they are regular files of at most :data:`MAX_INPUT_BYTES`. A mesh target is
    repaired where that is safe (zero-area triangles are dropped, with a :class:`~gsr_cad.errors.GsrWarning`)
    and refused where it is not (non-manifold edges, inconsistent orientation: TopologyError).
    """
    from .meshio import read_mesh_bytes, read_ply_vertices

    p = Path(path)
    open_input(p, "mesh or point file")
    suffix = p.suffix.lower()
    label = name or p.stem
    if suffix in SURFACE_CLOUD_SUFFIXES:
        data = load_npy(p) if suffix == ".npy" else _read_text_table(p)
        return SurfaceTarget(validate_surface_points(data, str(p)), None, label)
    if suffix not in SURFACE_MESH_SUFFIXES:
        raise InputError(f"{p}: unsupported target type {suffix or '(no suffix)'!r} "
                         f"(use {', '.join(SURFACE_MESH_SUFFIXES + SURFACE_CLOUD_SUFFIXES)})")
    raw = read_input(p, "mesh file")
    if suffix == ".ply":
        vertices, faces = read_ply_vertices(raw, p.name)
        if faces is None:
            return SurfaceTarget(validate_surface_points(vertices, str(p)), None, label)
    if suffix == ".obj" and not _obj_has_faces(raw):
        return SurfaceTarget(validate_surface_points(_read_obj_points(raw, p.name), str(p)), None, label)
    return mesh_target(read_mesh_bytes(raw, suffix[1:], p.name), p.name, label)


def mesh_target(mesh, source: str, label: str) -> SurfaceTarget:
    """A mesh target: its checked triangles (:func:`target_triangles`) on the vertices they use; vertices no
    face uses are dropped with a warning (a stray one would stretch the box and count in the distances)."""
    validate_surface_points(mesh.vertices, source)
    tri = target_triangles(mesh, source)
    used = np.unique(tri)
    v = np.asarray(mesh.vertices, dtype=np.float64)
    if len(used) < len(v):
        warnings.warn(f"{source}: ignored {len(v) - len(used)} vertex(es) that no face of non-zero area uses", GsrWarning,
                      stacklevel=2)
        remap = np.full(len(v), -1, dtype=np.int64)
        remap[used] = np.arange(len(used))
        v, tri = v[used], remap[tri]
    return SurfaceTarget(validate_surface_points(v, source), tri, label)


def target_triangles(mesh, source: str) -> np.ndarray:
    """The triangles of a target mesh, checked: zero-area triangles are dropped (with a warning);
    non-manifold edges or inconsistent orientation raise TopologyError (they make the inside ambiguous)."""
    from ..errors import TopologyError
    from ..geometry.polymesh import PolyMesh
    from ..geometry.surface_distance import triangulate
    from ..geometry.validation import DEGENERATE_AREA, validate_mesh

    tri = triangulate(mesh.corners, mesh.offsets)
    v = np.asarray(mesh.vertices, dtype=np.float64)
    area = 0.5 * np.linalg.norm(np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]]), axis=1)
    diag = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    flat = area <= DEGENERATE_AREA * diag**2
    if flat.all():
        raise TopologyError(f"{source}: every face has zero area")
    if flat.any():
        warnings.warn(f"{source}: dropped {int(flat.sum())} zero-area triangle(s) of {len(tri)}", GsrWarning,
                      stacklevel=2)
        tri = tri[~flat]
    used = np.unique(tri)
    remap = np.full(len(v), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    try:
        validate_mesh(PolyMesh(v[used], remap[tri].ravel(), np.arange(0, 3 * len(tri) + 1, 3)))
    except TopologyError as exc:
        raise TopologyError(f"{source}: unusable target mesh: {exc} (repair it, or give its vertices as a "
                            "point cloud)") from None
    return tri


def surface_target(source, name: str | None = None) -> SurfaceTarget:
    """A validated :class:`SurfaceTarget` from a path, an ``(n, 3)`` point array, a PolyMesh or a target."""
    from ..geometry.polymesh import PolyMesh

    if isinstance(source, SurfaceTarget):
        validate_surface_points(source.points, source.name)
        return source if name is None else SurfaceTarget(source.points, source.faces, name)
    if isinstance(source, (str, os.PathLike)):
        return load_surface_target(source, name)
    if isinstance(source, PolyMesh):
        return mesh_target(source, name or "mesh", name or "mesh")
    return SurfaceTarget(validate_surface_points(source, name or "points"), None, name or "points")


def validate_template(mesh, source: str = "template"):
    """A template must be a valid quad mesh (manifold, oriented, no degenerate faces); returns it."""
    from ..errors import TopologyError
    from ..geometry.validation import validate_mesh

    try:
        return validate_mesh(mesh, require_quads=True)
    except TopologyError as exc:
        raise TopologyError(f"{source}: not a valid quad mesh: {exc}") from None


def load_template(path: str | os.PathLike[str]):
    """Read a template control mesh file and check that it is a valid quad mesh (TopologyError if not)."""
    from .meshio import load_mesh

    p = Path(path)
    return validate_template(load_mesh(p, validate=False), p.name)
