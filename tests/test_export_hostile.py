"""A hostile-result corpus: nothing in result.json or a stem can become code in a generated script.

Three layers are tested: the typed result refuses hostile values in every field (one clear InputError or
OpError); the literal encoder turns any accepted string into data (every generated script parses and holds
exactly the statements of the clean one); and in the real hosts a payload that would create a marker file
never runs. ``gsr validate`` refuses hand-placed, modified and symlinked scripts without running them.
"""

from __future__ import annotations

import ast
import copy
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from test_export_results import hand_result
from test_export_surface_hosts import surface_result

from gsr_cad.errors import ExportError, GsrError, InputError
from gsr_cad.exporters import hosts
from gsr_cad.exporters.blender import BlenderExporter, curve_script
from gsr_cad.exporters.cadquery import CadqueryExporter
from gsr_cad.exporters.encode import fill_python, fill_scad, literal, scad_comment
from gsr_cad.exporters.freecad import FreecadMacroExporter
from gsr_cad.exporters.model import curve_model
from gsr_cad.exporters.openscad import OpenscadExporter
from gsr_cad.reconstruct.export import MANIFEST, export, validate
from gsr_cad.reconstruct.result import Result

SCRIPT_EXPORTERS = (BlenderExporter(), FreecadMacroExporter(), CadqueryExporter())


def payloads(marker: Path) -> list[str]:
    """Strings that would run code (creating ``marker``) if pasted into a script, a docstring or a comment."""
    code = f"open({str(marker)!r}, 'w').write('x')"
    return [f'b"""\n{code}\n"""', f"'''\n{code}\n'''", f"\"; {code}; \"", f"')\n{code}\n('", "x\x00y",
            f"\\\n{code}", f"*/ {code} /*", f"\n{code}\n# ", "{DATA}", "%s %d {0}", "\r\n" + code, "\u2028" + code]


def statements(text: str) -> list[str]:
    """The statement node types of a module, in order (what a script *does*)."""
    return [type(n).__name__ for n in ast.walk(ast.parse(text)) if isinstance(n, ast.stmt)]


def data_of(text: str) -> object:
    (node,) = [n for n in ast.parse(text).body if isinstance(n, ast.Assign) and n.targets[0].id == "DATA"]
    return ast.literal_eval(node.value)


# --- the typed result refuses hostile values ------------------------------------------------------------

def _clean_document() -> dict:
    return hand_result(seed=31, n_ops=6).to_json()


HOSTILE_FIELDS = [
    ("kind", "curve\n"), ("kind", ["curve"]), ("version", "1"), ("version", True),
    ("config", "bspline"), ("config", None),
    ("config.scheme", 'b"""\nopen("MARK","w")\n"""'), ("config.scheme", "bspline\n"), ("config.scheme", 3),
    ("config.scheme", "BSPLINE"), ("config.fitness", "geometric; rm -rf /"), ("config.polish", "yes"),
    ("config.polish", 1), ("config.tolerance", "1e-5"), ("config.tolerance", 1e301), ("config.tolerance", -1.0),
    ("config.generations", 1.5), ("config.generations", 2**70), ("config.generations", True),
    ("config.max_distance", [1.0]), ("config.preset", "paper\n"), ("config.preset", "evil"),
    ("config.template", "[[0, 0]]"), ("config.template", [[0.0, 0.0]]), ("config.template", [[0.0, "x"], [1, 1]]),
    ("config.template", [[0.0, 0.0], [1e300, 1.0]]), ("config.template", [[0.0, 0.0, 0.0, 0.0]] * 4),
    ("config.template", [[True, 0.0], [1.0, 1.0]]), ("config.bounds", [[0.0, 0.0]]),
    ("config.bounds", "everything"), ("config.target", "x" * 5000), ("config.target", {"a": {"b": {"c": {"d": {
        "e": {"f": {"g": 1}}}}}}}), ("config.target", {1: 2}), ("config.extra", {"k": "x" * 2000}),
    ("seed", -1), ("seed", 2**64), ("seed", "7"), ("seed", 1.5), ("seed", True),
    ("genome", "add_point"), ("genome", [["add_point", 1]]), ("genome", [{"op": "__import__('os')"}]),
    ("genome", [{"op": "extrude", "face": 0, "distance": 0.1}]),
    ("genome", [{"op": "add_point", "index": 1}]),
    ("genome", [{"op": "add_point", "index": 1, "position": [0.5, 0.5], "code": "print(1)"}]),
    ("genome", [{"op": "add_point", "index": "1", "position": [0.5, 0.5]}]),
    ("genome", [{"op": "add_point", "index": 1.5, "position": [0.5, 0.5]}]),
    ("genome", [{"op": "add_point", "index": 1, "position": ["0.5", 0.5]}]),
    ("genome", [{"op": "add_point", "index": 1, "position": [0.5]}]),
    ("genome", [{"op": "add_point", "index": 1, "position": [1e301, 0.5]}]),
    ("genome", [{"op": "add_point", "index": 1, "position": [1e200, 0.5]}]),
    ("genome", [{"op": "add_point", "index": 99, "position": [0.5, 0.5]}]),
    ("genome", [{"op": "move_point", "index": 1, "delta": [[0.1], 0.2]}]),
    ("control_points", [[0.0, "nan"]]), ("control_points", [[0.0, 0.0, 0.0, 0.0]]), ("control_points", "[]"),
    ("metrics", {"k": {"a": [[[[[[[1]]]]]]]}}), ("metrics", {"k": "x" * 5000}), ("metrics", {"k": 2**80}),
    ("metrics", [1, 2]), ("metrics", {"k": {"deep": {1: 2}}}), ("history", {"generation": 1}),
    ("history", [1, 2]), ("history", [{"best_fitness": "1"}] * 0 + [{"best": {"a": {"b": {"c": {"d": {"e": 1}}}}}}]),
    ("interrupted", "yes"), ("interrupted", 1), ("surplus", "key"),
]


def _set(doc: dict, field: str, value: object) -> dict:
    doc = copy.deepcopy(doc)
    keys = field.split(".")
    target = doc
    for key in keys[:-1]:
        target = target[key]
    target[keys[-1]] = value
    return doc


@pytest.mark.parametrize("field,value", HOSTILE_FIELDS, ids=[f"{f}-{i}" for i, (f, _) in enumerate(HOSTILE_FIELDS)])
def test_a_hostile_field_is_one_clear_error(field, value):
    with pytest.raises(GsrError) as info:
        Result.from_json(_set(_clean_document(), field, value))
    message = str(info.value)
    assert "\n" not in message and len(message) < 300
    assert isinstance(info.value, InputError) or "no longer applies" in message


def test_every_config_field_refuses_a_wrong_type():
    from gsr_cad.reconstruct.config import CurveConfig, SurfaceConfig

    import dataclasses

    doc = _clean_document()
    for field in dataclasses.fields(CurveConfig):
        for wrong in ({"x": 1}, [1], "str" if field.type not in ("str",) else 5):
            if isinstance(wrong, str) and "Literal" in str(field.type):
                continue
            with pytest.raises(InputError, match=f"config.{field.name}|{field.name.replace('_', '-')}"):
                Result.from_json(_set(doc, f"config.{field.name}", wrong))
    surface = surface_result().to_json()
    for field in dataclasses.fields(SurfaceConfig):
        with pytest.raises(InputError):
            Result.from_json(_set(surface, f"config.{field.name}", {"x": [1]}))


def test_nan_infinity_and_deep_nesting_in_the_file_are_refused(tmp_path):
    path = tmp_path / "result.json"
    text = json.dumps(_clean_document())
    for bad in (text.replace('"metrics": {}', '"metrics": {"a": NaN}'),
                text.replace('"metrics": {}', '"metrics": {"a": -Infinity}'),
                text.replace('"metrics": {}', '"metrics": ' + "[" * 100_000 + "]" * 100_000)):
        assert bad != text
        path.write_text(bad)
        with pytest.raises(InputError) as info:
            Result.load(path)
        assert "\n" not in str(info.value)


def test_replay_of_the_injection_from_the_issue_exits_2_and_runs_nothing(gsr, tmp_path):
    marker = tmp_path / "MARK"
    doc = _set(_clean_document(), "config.scheme", f'b"""\nopen({str(marker)!r},"w")\n"""')
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "result.json").write_text(json.dumps(doc))
    run = gsr("replay", tmp_path / "in", "-o", tmp_path / "out")
    assert run.code == 2 and run.err.startswith("error: result.json config.scheme must be one of bspline, chaikin")
    assert not (tmp_path / "out").exists() and not marker.exists()


def test_open_mappings_and_new_config_keys_are_kept():
    doc = _clean_document()
    doc["metrics"] = {"data_to_fit_mean": 1e-3, "tolerance_met": True, "units": "mm", "front": [[1, 2.5], [3, None]],
                      "nested": {"genus": 0}}
    doc["config"]["a_new_setting"] = {"kind": "future", "values": [1, 2, 3]}
    result = Result.from_json(doc)
    assert result.metrics == doc["metrics"] and result.config["a_new_setting"] == doc["config"]["a_new_setting"]
    assert type(result).__name__ == "CurveResult" and result.to_json() == doc


# --- the literal encoder --------------------------------------------------------------------------------

def test_literal_encoder_round_trips_plain_data_and_refuses_the_rest(tmp_path):
    for text in payloads(tmp_path / "MARK"):
        value = {"label": text, "nested": [text, {"k": text}], "n": [-0.0, 1e-300, 1.7976931348623157e308, -5]}
        encoded = literal(value, indent=4)
        assert ast.literal_eval(encoded) == value
        assert statements("DATA = " + encoded) == ["Assign"]
    import numpy as np

    for bad in (float("nan"), float("inf"), np.float64(1.0), object(), {1: "x"}, b"bytes", {"a": set()},
                ValueError("x")):
        with pytest.raises(ExportError):
            literal(bad)
    deep: list = []
    for _ in range(20):
        deep = [deep]
    with pytest.raises(ExportError, match="deeply"):
        literal(deep)


@pytest.mark.parametrize("module", ["blender_curve.py", "blender_mesh.py", "freecad_macro.py", "freecad_read.py",
                                    "cadquery_script.py"])
def test_hostside_modules_hold_one_data_line_and_parse(module):
    from gsr_cad.exporters.encode import host_file

    text = host_file(module)
    assert text.splitlines().count("DATA = {}") == 1
    compile(text, module, "exec")
    hostile = fill_python(module, {"label": "'''\nimport os\n'''", "x": "\x00"})
    assert statements(hostile) == statements(fill_python(module, {}))


def test_every_script_of_a_hostile_stem_parses_with_the_clean_statements(tmp_path):
    curve, surface = hand_result(seed=32, n_ops=5), surface_result()
    for result in (curve, surface):
        clean = {e.name: e.render(result, result.kind) for e in SCRIPT_EXPORTERS}
        for i, stem in enumerate(payloads(tmp_path / "MARK")):
            stem = stem.replace("/", "_").replace("\x00", "_")
            for exporter in SCRIPT_EXPORTERS:
                (text,) = exporter.render(result, stem).values()
                (want,) = clean[exporter.name].values()
                assert statements(text) == statements(want), (exporter.name, stem)
            (scad,) = OpenscadExporter().render(result, stem).values()
            assert scad.count("\n") == next(iter(OpenscadExporter().render(result, "s").values())).count("\n")


def test_scad_comments_and_values_cannot_escape():
    assert scad_comment("a\nb\r\nc */ d") == "// a_b__c _/ d"
    for bad in (float("nan"), "1; cube(1)", [1, "x"], None):
        with pytest.raises(ExportError):
            fill_scad("curve.scad", {"width": bad, "gsr_curve_points": [], "gsr_control_points": [], "gsr_unit": 1,
                                     "gsr_closed": False})
    text = fill_scad("curve.scad", {"width": 1.0, "gsr_curve_points": [[0.0, 0.0]], "gsr_control_points": [[1, 2]],
                                    "gsr_unit": 1, "gsr_closed": True}, {"title": ["x\ncube(5);"]})
    assert "\ncube(5);" not in text and "// x_cube(5);" in text


# --- the real hosts run no payload ----------------------------------------------------------------------

def _hostile_scripts(tmp_path: Path, marker: Path) -> dict[str, Path]:
    """Scripts of clean results (Blender and FreeCAD: a curve, CadQuery: a surface) with every label, name and
    string in their DATA replaced by payloads."""
    result = hand_result(seed=33, n_ops=4)
    texts = {}
    pay = payloads(marker)
    data = data_of(curve_script(curve_model(result), "clean"))
    data["name"] = pay[0]
    for i, step in enumerate(data["steps"]):
        step["label"] = pay[i % len(pay)][:60]
    texts["blender"] = fill_python("blender_curve.py", data)
    (macro,) = FreecadMacroExporter().render(result, "clean").values()
    data = data_of(macro)
    data["scheme"] = pay[1]
    for i, step in enumerate(data["steps"]):
        step["label"] = pay[-1 - i % len(pay)]
    texts["freecad"] = fill_python("freecad_macro.py", data)
    (script,) = CadqueryExporter().render(surface_result(), "clean").values()
    data = data_of(script)
    data["statement"] = "\n".join(pay)
    texts["cadquery"] = fill_python("cadquery_script.py", data)
    out = {}
    for host, text in texts.items():
        path = tmp_path / f"{host}_hostile.py"
        path.write_text(text, encoding="utf-8")
        out[host] = path
    return out


@pytest.mark.blender
@pytest.mark.freecad
def test_hosts_run_the_hostile_scripts_without_running_the_payload(tmp_path):
    marker = tmp_path / "MARK"
    scripts = _hostile_scripts(tmp_path, marker)
    ran = 0
    if hosts.find_host("blender"):
        out = tmp_path / "built.json"
        hosts.run_blender(scripts["blender"], ["--json", out], timeout=300)
        built = json.loads(out.read_text())
        assert len(built["history"]) == 5
        ran += 1
    if hosts.find_host("freecad"):
        proc = hosts.run_freecad(scripts["freecad"], [tmp_path / "hostile.FCStd"], timeout=300)
        assert '"steps": 5' in proc.stdout
        ran += 1
    if hosts.cadquery_python():
        step = tmp_path / "hostile.step"
        hosts.run_cadquery(scripts["cadquery"], [step], timeout=300)
        assert step.stat().st_size > 0
        ran += 1
    proc = subprocess.run([sys.executable, "-c", "import ast,sys; ast.parse(open(sys.argv[1]).read())",
                           scripts["blender"]], capture_output=True, timeout=60)
    assert proc.returncode == 0
    if not ran:
        pytest.skip("none of Blender, FreeCAD and CadQuery is installed")
    assert not marker.exists()


@pytest.mark.openscad
def test_openscad_renders_a_hostile_stem_and_no_injected_statement(tmp_path):
    if hosts.find_host("openscad") is None:
        pytest.skip("OpenSCAD is not installed")
    result = hand_result(seed=34, n_ops=4)
    stem = "x\ncube(1000);\n// "
    (text,) = OpenscadExporter().render(result, stem).values()
    assert "\ncube(1000);" not in text
    path = tmp_path / "hostile.scad"
    path.write_text(text)
    stl = tmp_path / "out.stl"
    hosts.run_openscad(path, stl, defines={"height": "1"})
    import trimesh

    mesh = trimesh.load(str(stl), force="mesh")
    assert mesh.extents.max() < 100  # a 1000-unit cube would show


# --- validate runs only what gsr wrote ------------------------------------------------------------------

@pytest.fixture
def exported_dir(tmp_path):
    result = hand_result(seed=35, n_ops=5)
    out = tmp_path / "out"
    result.save(out)
    export(result, out, ["scad", "blender", "fcmacro", "svg"])
    return result, out


def _rows(checks, name):
    return [c for c in checks if c.file == name]


def test_validate_refuses_hand_placed_modified_and_symlinked_scripts(exported_dir, tmp_path, monkeypatch):
    for host in ("BLENDER", "FREECAD", "OPENSCAD"):  # the refusals need no host: hide them all
        monkeypatch.setenv(f"GSR_{host}", str(tmp_path / "no-such-host"))
    result, out = exported_dir
    marker = tmp_path / "MARK"
    (out / "extra_blender.py").write_text(f"open({str(marker)!r}, 'w')\n")
    blender = out / "curve_blender.py"
    blender.write_text(blender.read_text() + f"\nopen({str(marker)!r}, 'w')\n")
    outside = tmp_path / "elsewhere.scad"
    shutil.copy(out / "curve.scad", outside)
    (out / "curve.scad").unlink()
    (out / "curve.scad").symlink_to(outside)
    checks = validate(out)
    refused = {c.file: c.detail for c in checks if c.check == "written by gsr" and c.passed is False}
    assert refused.keys() == {"extra_blender.py", "curve_blender.py", "curve.scad"}
    assert refused["extra_blender.py"].startswith("not written by gsr")
    assert refused["curve_blender.py"].startswith("modified")
    assert refused["curve.scad"].startswith("a symlink")
    for name in refused:
        assert len(_rows(checks, name)) == 1  # refused, nothing else was run
    assert [c.status for c in _rows(checks, "curve.FCMacro")] == ["skip"]
    assert not marker.exists()


def test_a_new_export_clears_the_previous_runs_files_only(exported_dir):
    result, out = exported_dir
    (out / "notes.txt").write_text("mine")
    manifest = json.loads((out / MANIFEST).read_text())
    manifest["files"]["result.json"] = {"format": "svg", "stem": "curve", "sha256": "0" * 64}  # a tampered list
    (out / MANIFEST).write_text(json.dumps(manifest))
    before = json.loads((out / MANIFEST).read_text())["files"]
    assert set(before) == {"curve.scad", "curve_blender.py", "curve.FCMacro", "curve.svg", "result.json"}
    written = export(result, out, ["svg"], stem="again")
    assert [p.name for p in written] == ["again.svg"]
    assert sorted(p.name for p in out.iterdir()) == sorted([MANIFEST, "again.svg", "notes.txt", "result.json"])
    (out / "again.svg").write_text("edited by hand")  # changed since gsr wrote it: kept
    export(result, out, [])
    assert sorted(p.name for p in out.iterdir()) == ["again.svg", "notes.txt", "result.json"]


@pytest.mark.parametrize("scale", [1e-9, 1e11])
def test_extreme_but_valid_magnitudes_give_the_clean_scripts(scale):
    clean, extreme = hand_result(seed=36, n_ops=5), hand_result(seed=36, n_ops=5, scale=scale, offset=(-scale, scale))
    for exporter in (*SCRIPT_EXPORTERS, OpenscadExporter()):
        (want,) = exporter.render(clean, "curve").values()
        (text,) = exporter.render(extreme, "curve").values()
        if exporter.name == "scad":
            assert text.count("\n") == want.count("\n") and "nan" not in text and "inf" not in text
        else:
            assert statements(text) == statements(want)
            assert data_of(text).keys() == data_of(want).keys()


def test_an_op_kind_added_later_parses_and_the_scripts_refuse_it_clearly(monkeypatch):
    """New op kinds (corners, creases, holes...) flow through result.json by the op registry; a host script
    that does not know one says so instead of writing a script that fails in the host."""
    import dataclasses

    from gsr_cad.ops import base as ops_base
    from gsr_cad.ops import curve as curve_ops

    @dataclasses.dataclass(frozen=True)
    class Nudge(ops_base.Op):  # a curve op kind the exporters were not written for
        index: int
        amount: float

        def apply(self, state):
            pts = state.points.copy()
            pts[self.index, 1] += self.amount
            return curve_ops.Polygon(pts, state.lo, state.hi)

    Nudge.name = "test_nudge"
    monkeypatch.setitem(ops_base.REGISTRY, "test_nudge", Nudge)
    doc = _clean_document()
    doc["genome"].append({"op": "test_nudge", "index": 1, "amount": 0.01})
    result = Result.from_json(doc)
    assert result.genome[-1] == Nudge(1, 0.01) and result.states[-1].points[1, 1] == \
        pytest.approx(result.states[-2].points[1, 1] + 0.01)
    with pytest.raises(InputError, match="amount must be a finite number"):
        Result.from_json(_set(doc, "genome", [{"op": "test_nudge", "index": 1, "amount": "x"}]))
    for exporter in (BlenderExporter(), FreecadMacroExporter()):
        with pytest.raises(ExportError, match="replays add_point, move_point, corner, not test_nudge"):
            exporter.render(result, "curve")
    (scad,) = OpenscadExporter().render(result, "curve").values()  # formats of the geometry need no op kinds
    assert "gsr_control_points" in scad
