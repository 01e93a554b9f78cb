"""Fins and webs moved onto the target: control vertices whose limit point lies far from it, each moved by
that point's gap to its closest target point, as far as every face stays sound.

A least-squares fit cannot remove a fin (a thin double sheet of surface past the data, e.g. between two
knobs of a bone) or a web (surface spanning the gap between protrusions, e.g. a wing and a tail plane): the
fin's samples are pulled towards their closest target points, which lie beside them on the protrusions, and
the fit settles there (a local minimum). Moving the fin's control vertices by their own limit points' gaps
folds it onto the target in one step; a fit from there converges to a different, closer cage (bone, 162
control vertices: 2.0e-3 of the diagonal both ways after a converged fit, 1.0e-3 after two snaps and fits;
a quad remesh fitted alike reaches 1.6e-3 with 141).

Each vertex moves alone, farthest first, by the largest share of its gap (:data:`SHARES`) that keeps every
face passing the mesh ops' checks, so the moves replay one by one as vertex translations. Vertices that
share no face are tried together (one soundness check per share for each such set).
"""

from __future__ import annotations

import numpy as np

from ..geometry.polymesh import PolyMesh
from ..geometry.subdivision import get_catmull_clark

SHARES = (1.0, 0.75, 0.5, 0.25, 0.1)
"""Shares of a vertex's gap tried, largest first (a full move may fold a face that a shorter one keeps)."""


def limit_points(mesh: PolyMesh) -> np.ndarray:
    """Each control vertex's own point on the limit surface."""
    cc = get_catmull_clark(mesh, 1, "all")
    return np.asarray(cc.limit_matrix[:mesh.n_vertices] @ mesh.vertices)


def _independent_sets(mesh: PolyMesh, order: np.ndarray) -> list[np.ndarray]:
    """``order`` split greedily, in its order, into sets of vertices no two of which share a face."""
    sizes = mesh.face_sizes
    face_of = np.repeat(np.arange(mesh.n_faces), sizes)
    faces_at: list[list[int]] = [[] for _ in range(mesh.n_vertices)]
    for f, v in zip(face_of.tolist(), mesh.corners.tolist()):
        faces_at[v].append(f)
    sets: list[list[int]] = []
    taken: list[set[int]] = []
    for v in order.tolist():
        mine = faces_at[v]
        for k, used in enumerate(taken):
            if not used.intersection(mine):
                sets[k].append(v)
                used.update(mine)
                break
        else:
            sets.append([v])
            taken.append(set(mine))
    return [np.asarray(s, dtype=np.int64) for s in sets]


def snap_far_vertices(mesh: PolyMesh, closest, threshold: float, unsound) -> tuple[PolyMesh, int]:
    """``mesh`` with every control vertex whose limit point is farther than ``threshold`` from the target
    moved by that point's gap (module docstring): ``(the cage, how many vertices moved)``.

    ``closest(points) -> (distances, closest target points)``; ``unsound(mesh, reference_normals)`` -> per
    face, whether it fails the mesh ops' checks (reference: ``mesh``'s own face normals)."""
    lim = limit_points(mesh)
    dist, foot = closest(lim)
    far = np.flatnonzero(dist > threshold)
    if far.size == 0:
        return mesh, 0
    far = far[np.argsort(-dist[far], kind="stable")]
    gap = foot - lim
    reference = mesh.face_newell
    V = np.array(mesh.vertices, dtype=np.float64)
    sizes = mesh.face_sizes
    face_of = np.repeat(np.arange(mesh.n_faces), sizes)
    already = unsound(mesh, reference)  # (a cage the fit left skewed: only new failures count)

    def worse(vertices: np.ndarray) -> bool:
        return bool((unsound(mesh.with_vertices(vertices), reference) & ~already).any())

    moved = 0
    for group in _independent_sets(mesh, far):
        todo = group
        for share in SHARES:
            if todo.size == 0:
                break
            trial = V.copy()
            trial[todo] += share * gap[todo]
            bad = unsound(mesh.with_vertices(trial), reference) & ~already
            if bad.any():
                # a vertex is refused when a face it belongs to, or one across an edge of one, turns unsound
                touched = np.zeros(mesh.n_vertices, dtype=bool)
                touched[mesh.corners[bad[face_of]]] = True
                edge_faces = mesh.topology.edge_faces
                inner = edge_faces[:, 1] >= 0
                a, b = edge_faces[inner, 0], edge_faces[inner, 1]
                near = np.zeros(mesh.n_faces, dtype=bool)
                near[a[bad[b]]] = True
                near[b[bad[a]]] = True
                touched[mesh.corners[near[face_of]]] = True
                ok = todo[~touched[todo]]
            else:
                ok = todo
            if ok.size:
                joint = V.copy()
                joint[ok] = trial[ok]
                if worse(joint):
                    # two accepted vertices fold faces across an edge between them: one at a time
                    kept = []
                    for v in ok.tolist():
                        joint = V.copy()
                        joint[v] = trial[v]
                        if not worse(joint):
                            V = joint
                            kept.append(v)
                    ok = np.asarray(kept, dtype=np.int64)
                else:
                    V = joint
                moved += int(ok.size)
            todo = np.setdiff1d(todo, ok, assume_unique=True)
    return mesh.with_vertices(V), moved
