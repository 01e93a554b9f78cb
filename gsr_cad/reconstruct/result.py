"""Result of a reconstruction and its ``result.json`` form (DESIGN.md contract, version 1)."""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path
from typing import Any, Literal

import numpy as np

from .. import genome as genome_mod
from ..atomic import write_text
from ..errors import InputError
from ..geometry.polymesh import PolyMesh

RESULT_VERSION = 1


@dataclasses.dataclass
class Result:
    """A reconstruction: the genome (modelling history), the control geometry it builds, metrics, history.

    ``control_points`` is set for curves (``(n, 2)``), ``control_mesh`` for surfaces.
    ``config["scheme"]`` says how a curve is evaluated ("bspline": clamped uniform cubic B-spline,
    "chaikin": Chaikin corner cutting, i.e. its clamped uniform quadratic B-spline limit).
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

    @property
    def degree(self) -> int:
        """Degree of a curve result's B-spline (3 for "bspline", 2 for "chaikin")."""
        return 2 if self.config.get("scheme") == "chaikin" else 3

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
        """Parse a ``result.json`` document; wrong kind or version raises InputError."""
        if not isinstance(data, dict):
            raise InputError("result.json must hold a JSON object")
        if data.get("version") != RESULT_VERSION:
            raise InputError(f"result.json has version {data.get('version')!r}; "
                             f"this gsr_cad reads version {RESULT_VERSION}")
        kind = data.get("kind")
        if kind not in ("curve", "surface"):
            raise InputError(f"result.json has unknown kind {kind!r}")
        try:
            common = dict(kind=kind, config=dict(data["config"]), seed=data.get("seed"),
                          genome=genome_mod.from_json(data["genome"]), metrics=dict(data.get("metrics", {})),
                          history=list(data.get("history", [])), interrupted=bool(data.get("interrupted", False)))
            bounds = common["config"].get("bounds")
            if bounds is not None:
                b = np.asarray(bounds, dtype=float)
                if b.shape != (2, 2) or not np.all(np.isfinite(b)):
                    raise InputError("result.json config.bounds must be [[x, y], [x, y]] of finite numbers")
            if kind == "curve":
                pts = np.asarray(data["control_points"], dtype=float)
                if pts.ndim != 2 or pts.shape[1] != 2 or not np.all(np.isfinite(pts)):
                    raise InputError("result.json control_points must be finite [x, y] rows")
                return cls(control_points=pts, **common)
            cm = data["control_mesh"]
            mesh = PolyMesh.from_faces(np.asarray(cm["vertices"], dtype=float), cm["faces"])
            return cls(control_mesh=mesh, **common)
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, InputError):
                raise
            raise InputError(f"result.json is malformed: {exc}") from None

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
