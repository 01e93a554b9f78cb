"""Loading and validating curve targets: ordered 2D points from CSV/TXT/NPY files or arrays.

Every problem with the input becomes an :class:`~gsr_cad.errors.InputError` with a one-line reason.
"""

from __future__ import annotations

import dataclasses
import functools
import os
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError

CURVE_SUFFIXES = (".csv", ".txt", ".xy", ".npy")


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


def _read_text_table(path: Path) -> np.ndarray:
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a text file") from None
    rows = []
    first = True
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        cells = [c for c in line.replace(";", ",").replace("\t", ",").replace(" ", ",").split(",") if c != ""]
        try:
            rows.append([float(c) for c in cells])
        except ValueError:
            if not first:
                raise InputError(f"{path}:{lineno}: non-numeric value in {raw.strip()!r}") from None
        first = False
    if not rows:
        raise InputError(f"{path}: no data rows")
    widths = {len(r) for r in rows}
    if len(widths) != 1:
        raise InputError(f"{path}: rows have different numbers of columns ({sorted(widths)})")
    return np.asarray(rows, dtype=np.float64)


def load_curve_points(path: str | os.PathLike[str]) -> np.ndarray:
    """Read an ordered ``x, y`` point file (CSV/TXT with optional header, or NPY)."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: no such file")
    if p.is_dir():
        raise InputError(f"{p}: is a directory, not a point file")
    if p.stat().st_size == 0:
        raise InputError(f"{p}: file is empty")
    suffix = p.suffix.lower()
    if suffix == ".npy":
        try:
            data = np.load(p, allow_pickle=False)
        except (ValueError, OSError) as exc:
            raise InputError(f"{p}: not a readable .npy array ({exc})") from None
    elif suffix in CURVE_SUFFIXES or suffix == "":
        data = _read_text_table(p)
    else:
        raise InputError(f"{p}: unsupported point file type {suffix!r} (use {', '.join(CURVE_SUFFIXES)})")
    return validate_curve_points(data, source=str(p))


def validate_curve_points(points: np.ndarray, source: str = "points") -> np.ndarray:
    """Check an ordered 2D or 3D point array; returns it as float64 ``(n, 2)`` or ``(n, 3)``."""
    try:
        pts = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{source}: points must be numbers") from None
    if pts.ndim != 2:
        raise InputError(f"{source}: expected rows of x, y[, z] (got an array of shape {pts.shape})")
    if pts.shape[1] not in (2, 3):
        raise InputError(f"{source}: expected 2 or 3 columns (x, y[, z]), got {pts.shape[1]}")
    if not np.all(np.isfinite(pts)):
        bad = int(np.argwhere(~np.isfinite(pts))[0, 0])
        raise InputError(f"{source}: point {bad + 1} is NaN or infinite")
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
        from ..geometry.surface_distance import cloud_distance

        if self.triangle_set is not None:
            c = self.triangle_set.closest(x)
            return c.distance, c.point
        d, idx = cloud_distance(x, self.points, self.sampling_radius, self.kdtree)
        return d, self.points[idx]

    def __len__(self) -> int:
        return len(self.points)

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
    try:
        pts = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{source}: points must be numbers") from None
    if pts.ndim != 2:
        raise InputError(f"{source}: expected rows of x, y, z (got an array of shape {pts.shape})")
    if pts.shape[1] == 2:
        raise InputError(f"{source}: 2D data (x, y); a surface needs x, y, z (use gsr curve for planar curves)")
    if pts.shape[1] == 6:  # x y z nx ny nz: normals are not used
        pts = pts[:, :3]
    if pts.shape[1] != 3:
        raise InputError(f"{source}: expected 3 columns (x, y, z), got {pts.shape[1]}")
    if not np.all(np.isfinite(pts)):
        bad = int(np.argwhere(~np.isfinite(pts))[0, 0])
        raise InputError(f"{source}: point {bad + 1} is NaN or infinite")
    if len(pts) < 4:
        raise InputError(f"{source}: need at least 4 points, got {len(pts)}")
    centred = pts - pts.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if sv[0] <= 1e-12 * max(1.0, float(np.abs(pts).max())):
        raise InputError(f"{source}: all points coincide (a single point)")
    if sv[1] <= 1e-9 * sv[0]:
        raise InputError(f"{source}: degenerate target: all points lie on a line")
    if sv[2] <= 1e-9 * sv[0]:
        raise InputError(f"{source}: degenerate target: all points lie in one plane (a flat target has no volume)")
    return pts


def _ply_has_faces(data: bytes) -> bool:
    end = data.find(b"end_header")
    header = data[:end if end >= 0 else len(data)].decode("ascii", errors="replace").split("\n")
    for line in header:
        parts = line.split()
        if len(parts) >= 3 and parts[0] == "element" and parts[1] == "face":
            return parts[2] != "0"
    return False


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


def _read_ply_points(path: Path) -> np.ndarray:
    import trimesh

    try:
        loaded = trimesh.load(str(path), file_type="ply", process=False)
    except Exception as exc:  # trimesh raises many types on malformed files
        raise InputError(f"{path.name}: cannot read PLY point cloud ({exc})") from None
    pts = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), dtype=np.float64)
    if not len(pts):
        raise InputError(f"{path.name}: no vertices")
    return pts


def load_surface_target(path: str | os.PathLike[str], name: str | None = None) -> SurfaceTarget:
    """Read a surface target: a mesh (OBJ, PLY, STL, OFF) or a point cloud (XYZ, CSV, TXT, PTS, NPY, or an
    OBJ/PLY without faces). Every problem is an InputError (or TopologyError) with a one-line reason."""
    from ..geometry.surface_distance import triangulate
    from .meshio import load_mesh

    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: no such file")
    if p.is_dir():
        raise InputError(f"{p}: is a directory, not a mesh or point file")
    if p.stat().st_size == 0:
        raise InputError(f"{p}: file is empty")
    suffix = p.suffix.lower()
    label = name or p.stem
    if suffix in SURFACE_CLOUD_SUFFIXES:
        if suffix == ".npy":
            try:
                data = np.load(p, allow_pickle=False)
            except (ValueError, OSError) as exc:
                raise InputError(f"{p}: not a readable .npy array ({exc})") from None
        else:
            data = _read_text_table(p)
        return SurfaceTarget(validate_surface_points(data, str(p)), None, label)
    if suffix not in SURFACE_MESH_SUFFIXES:
        raise InputError(f"{p}: unsupported target type {suffix or '(no suffix)'!r} "
                         f"(use {', '.join(SURFACE_MESH_SUFFIXES + SURFACE_CLOUD_SUFFIXES)})")
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise InputError(f"{p}: cannot read ({exc.strerror or exc})") from None
    if suffix == ".ply" and not _ply_has_faces(raw):
        return SurfaceTarget(validate_surface_points(_read_ply_points(p), str(p)), None, label)
    if suffix == ".obj" and not _obj_has_faces(raw):
        return SurfaceTarget(validate_surface_points(_read_obj_points(raw, p.name), str(p)), None, label)
    mesh = load_mesh(p, validate=False)
    pts = validate_surface_points(mesh.vertices, str(p))
    return SurfaceTarget(pts, triangulate(mesh.corners, mesh.offsets), label)


def surface_target(source, name: str | None = None) -> SurfaceTarget:
    """A validated :class:`SurfaceTarget` from a path, an ``(n, 3)`` point array, a PolyMesh or a target."""
    from ..geometry.polymesh import PolyMesh
    from ..geometry.surface_distance import triangulate

    if isinstance(source, SurfaceTarget):
        validate_surface_points(source.points, source.name)
        return source if name is None else SurfaceTarget(source.points, source.faces, name)
    if isinstance(source, (str, os.PathLike)):
        return load_surface_target(source, name)
    if isinstance(source, PolyMesh):
        pts = validate_surface_points(source.vertices, name or "mesh")
        return SurfaceTarget(pts, triangulate(source.corners, source.offsets), name or "mesh")
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
