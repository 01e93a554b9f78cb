"""The paper's surface examples, rebuilt from their descriptions as true genomes on the unit cube.

Each sample's target is the level-2 limit mesh (:data:`LEVELS`, the fitness level by default) of its
true control mesh, so a reconstruction that finds the true structure can match it exactly. Its
point-cloud version (:attr:`SurfaceSample.cloud`) is drawn by area on the exact limit surface, half as
many again as the mesh has vertices, so its density is unlike the limit mesh's
(what the paper's mixed mean distance handles badly). Samples register into
:mod:`gsr_cad.reconstruct.samples` under kind "surface" and are written as OBJ by ``gsr sample``.

* ``extended``: the cube extruded in one direction (paper Fig. 5 top);
* ``flattened_extended``: the top face lowered, then a side extruded (Fig. 5 bottom);
* ``inset_extrude``: the top face inset, then extruded (Fig. 6 top; note that on a cube this control mesh
  has the connectivity of two parallel edge loops, or of an edge loop and an inset);
* ``random_ops``: a seeded random sequence of 4 to 6 ops (Fig. 6 bottom), see :func:`random_ops_sample`;
* ``unreachable``: a square ring (genus 1); no cube genome reaches it (the ops keep the genus).
"""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

import numpy as np

from .. import genome as genome_mod
from ..atomic import write_text
from ..errors import InputError
from ..geometry.limit_surface import LimitSurface
from ..geometry.polymesh import PolyMesh, unit_cube
from ..geometry.subdivision import limit_mesh
from ..ops.mesh import Extrude, Inset, TranslateFace, random_ops
from .meshio import save_mesh
from .samples import SAMPLES, register

LEVELS = 2
CLOUD_FACTOR = 1.5  # cloud points per target vertex
CLOUD_SUFFIXES = (".xyz", ".csv", ".txt")
RANDOM_SEED = 0
"""Seed of the registered ``random_ops`` sample (:func:`random_ops_sample` makes others)."""

# unit cube face indices (gsr_cad.geometry.polymesh.unit_cube): -x, +x, -y, +y, -z, +z
_PX, _PZ = 1, 5


def _frozen(a: np.ndarray) -> np.ndarray:
    out = np.array(a, dtype=np.float64)
    out.setflags(write=False)
    return out


@dataclasses.dataclass(frozen=True, eq=False)
class SurfaceSample:
    """A surface target with its ground truth.

    ``target``: the limit mesh to reconstruct from; ``truth_control``: the control mesh it is the limit
    of; ``truth_genome``: the ops that build that control mesh from the unit cube (None when no cube
    genome does); ``cloud``: the point-cloud version of the target.
    """

    name: str
    description: str
    truth_control: PolyMesh
    truth_genome: tuple | None
    target: PolyMesh
    cloud: np.ndarray
    seed: int = 0

    def __post_init__(self):
        object.__setattr__(self, "cloud", _frozen(self.cloud))

    @property
    def kind(self) -> str:
        return "surface"

    @property
    def has_truth(self) -> bool:
        return True

    @property
    def true_ops(self) -> str:
        """Letters of the true genome ("" when no cube genome reaches the target)."""
        return "" if self.truth_genome is None else "".join(op.letter for op in self.truth_genome)

    def write(self, path: str | os.PathLike[str]) -> Path:
        """The target: a mesh by suffix (OBJ, OFF, PLY, STL), or its point cloud for .xyz/.csv/.txt."""
        p = Path(path)
        if p.suffix.lower() in CLOUD_SUFFIXES:
            return self.write_cloud(p)
        return save_mesh(self.target, p)

    def write_cloud(self, path: str | os.PathLike[str]) -> Path:
        """The point-cloud version: ``x y z`` rows (commas for .csv), 17 significant digits."""
        p = Path(path)
        sep = "," if p.suffix.lower() == ".csv" else " "
        head = "x,y,z\n" if sep == "," else ""
        rows = "\n".join(sep.join(f"{x:.17g}" for x in row) for row in self.cloud.tolist())
        return write_text(p, head + rows + "\n")

    def write_truth(self, path: str | os.PathLike[str]) -> Path:
        """The true control mesh (OBJ unless the suffix names another mesh format)."""
        return save_mesh(self.truth_control, path)

    def write_genome(self, path: str | os.PathLike[str]) -> Path:
        if self.truth_genome is None:
            raise InputError(f"sample {self.name!r} has no true genome (no cube genome reaches it)")
        return write_text(path, json.dumps(genome_mod.to_json(self.truth_genome), indent=1) + "\n")

    def bundle(self, directory: str | os.PathLike[str]) -> dict[str, str]:
        d = Path(directory)
        files = {f"{self.name}.obj": f"target: level-{LEVELS} limit mesh ({self.target.n_vertices} vertices, "
                                     f"{self.target.n_faces} quads)",
                 f"{self.name}.cloud.xyz": f"point-cloud version: {len(self.cloud)} points on its limit surface",
                 f"{self.name}.truth.obj": f"true control mesh ({self.truth_control.n_vertices} vertices, "
                                           f"{self.truth_control.n_faces} faces)"}
        self.write(d / f"{self.name}.obj")
        self.write_cloud(d / f"{self.name}.cloud.xyz")
        self.write_truth(d / f"{self.name}.truth.obj")
        if self.truth_genome is not None:
            self.write_genome(d / f"{self.name}.genome.json")
            files[f"{self.name}.genome.json"] = f"true genome on the unit cube: {self.true_ops}"
        return files


def _sample(name: str, description: str, control: PolyMesh, genome: tuple | None, seed: int) -> SurfaceSample:
    target = limit_mesh(control, LEVELS)
    cloud = LimitSurface.of(control).random_points(int(round(CLOUD_FACTOR * target.n_vertices)), seed)
    return SurfaceSample(name, description, control, genome, target, cloud, seed)


def _from_genome(name: str, description: str, genome: tuple, seed: int) -> SurfaceSample:
    return _sample(name, description, genome_mod.replay(unit_cube(), genome), genome, seed)


def random_ops_sample(seed: int, name: str | None = None, description: str | None = None) -> SurfaceSample:
    """A target built by 4 to 6 valid random ops (all seven kinds, default ranges) on the unit cube."""
    rng = np.random.default_rng(seed)
    n_ops = int(rng.integers(4, 7))
    ops, _ = random_ops(rng, unit_cube(), n_ops)
    return _from_genome(name or f"random_ops_{seed}",
                        description or f"{n_ops} random ops on the cube (seed {seed})", ops, seed)


def square_ring(outer: float = 0.5, inner: float = 0.22, half_height: float = 0.18) -> PolyMesh:
    """A genus-1 quad mesh: a square frame of 16 vertices and 16 quads (outward normals)."""
    corners = [(1, 1), (-1, 1), (-1, -1), (1, -1)]  # counter-clockwise seen from +z
    v = []
    for r in (outer, inner):
        for z in (-half_height, half_height):
            v.extend((r * x, r * y, z) for x, y in corners)
    # index: ring (0 outer, 1 inner) * 8 + level (0 bottom, 1 top) * 4 + corner
    def i(ring: int, level: int, k: int) -> int:
        return ring * 8 + level * 4 + k % 4

    faces = []
    for k in range(4):
        faces.append((i(0, 0, k), i(0, 0, k + 1), i(0, 1, k + 1), i(0, 1, k)))  # outer wall
        faces.append((i(1, 0, k + 1), i(1, 0, k), i(1, 1, k), i(1, 1, k + 1)))  # inner wall
        faces.append((i(0, 1, k), i(0, 1, k + 1), i(1, 1, k + 1), i(1, 1, k)))  # top
        faces.append((i(0, 0, k + 1), i(0, 0, k), i(1, 0, k), i(1, 0, k + 1)))  # bottom
    return PolyMesh.from_faces(np.asarray(v, dtype=float), faces)


@register("surface", "extended", "cube extruded in one direction (paper Fig. 5 top)")
def _extended(name, description):
    return _from_genome(name, description, (Extrude(_PX, 1.0),), 501)


@register("surface", "flattened_extended", "cube flattened, then extended in one direction (paper Fig. 5 bottom)")
def _flattened_extended(name, description):
    return _from_genome(name, description, (TranslateFace(_PZ, -0.6), Extrude(_PX, 1.0)), 502)


@register("surface", "inset_extrude", "cube with its top face inset, then extruded (paper Fig. 6 top)")
def _inset_extrude(name, description):
    return _from_genome(name, description, (Inset(_PZ, 0.2), Extrude(_PZ, 0.5)), 503)


@register("surface", "random_ops", f"a seeded random sequence of 4 to 6 ops on the cube (seed {RANDOM_SEED}; "
                                   "paper Fig. 6 bottom)")
def _random_ops(name, description):
    return random_ops_sample(RANDOM_SEED, name, description)


@register("surface", "unreachable", "a square ring (genus 1): no cube genome reaches it")
def _unreachable(name, description):
    return _sample(name, description, square_ring(), None, 505)


SURFACE_SAMPLES = {n: info.build for n, info in SAMPLES.items() if info.kind == "surface"}
"""Name -> builder of every registered surface sample."""

__all__ = ["LEVELS", "SURFACE_SAMPLES", "SurfaceSample", "random_ops_sample", "square_ring"]
