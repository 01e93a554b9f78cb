"""``--help`` says what every flag means (one source: the config fields' metadata), ``--version``, ``-o/--out``,
and lengths in model units or percent of the diagonal."""

from __future__ import annotations

import argparse
import dataclasses
import re

import pytest

from gsr_cad.cli import build_parser
from gsr_cad.errors import ConfigError
from gsr_cad.reconstruct.config import OP_KINDS, CurveConfig, SurfaceConfig
from gsr_cad.reconstruct.units import Length, format_length, model_metrics, parse_length, resolve_lengths


def subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(sub.choices)


def flags(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    return [a for a in parser._actions if a.option_strings and a.help is not argparse.SUPPRESS
            and not isinstance(a, (argparse._HelpAction, argparse._VersionAction))]


BARE_DEFAULT = re.compile(r"\(?default:? \S+\)?\.?", re.IGNORECASE)


@pytest.mark.parametrize("name", ["curve", "surface", "replay", "validate", "subdivide", "sample"])
def test_every_flag_has_a_sentence_and_no_bare_default(name):
    parser = subparsers()[name]
    for action in flags(parser):
        text = (action.help or "").strip()
        assert len(text) > 12 and not BARE_DEFAULT.fullmatch(text), (action.option_strings, text)
    page = parser.format_help()
    assert "CFG_" not in page
    for line in page.splitlines():  # a flag whose whole help is "default X" (what argparse users often write)
        assert not re.fullmatch(r"\s*-\S+( \S+)?\s+\(?default:? \S+", line, re.IGNORECASE), line


@pytest.mark.parametrize("cls", [CurveConfig, SurfaceConfig])
def test_every_config_field_has_help_metadata_with_its_default_shown(cls):
    parser = subparsers()["curve" if cls is CurveConfig else "surface"]
    by_flag = {a.option_strings[0]: a for a in flags(parser)}
    for field in dataclasses.fields(cls):
        text = field.metadata.get("help", "")
        assert text.endswith((".", ":")) and len(text.split()) >= 4, field.name
        action = by_flag["--" + field.name.replace("_", "-")]
        assert "Default: " in action.help and action.metavar != f"CFG_{field.name.upper()}"


def test_metavars_units_and_lengths_in_the_help():
    curve = " ".join(subparsers()["curve"].format_help().split())
    assert "--max-distance DIST" in curve and "--population N" in curve and "--p-add X" in curve
    assert "N%% of the target's bounding-box diagonal" not in curve  # the % is printed, not doubled
    assert "N% of the target's bounding-box diagonal" in curve
    assert "Default: 0.001% of the diagonal" in curve  # tolerance 1e-5, a fraction, shown as percent
    assert "--units {model,mm,cm,m,in,ft}" in curve
    assert "--local-add, --no-local-add" in curve and "Default: on." in curve


def test_op_letters_are_expanded_from_one_table():
    page = " ".join(subparsers()["surface"].format_help().split())
    assert "--op-kinds LETTERS" in page
    for letter, meaning in OP_KINDS.items():
        assert f"{letter} {meaning}" in page
    assert "V vertex translate, E face extrude, L edge loop" in page
    with pytest.raises(ConfigError, match="letters from " + "".join(OP_KINDS)):
        SurfaceConfig(op_kinds="VQ").validated()


def test_version(capsys):
    with pytest.raises(SystemExit) as stop:
        build_parser().parse_args(["--version"])
    assert stop.value.code == 0
    assert re.fullmatch(r"gsr \d+\.\d+\S*\n", capsys.readouterr().out)


def test_one_out_flag_everywhere_and_the_old_output_still_works(gsr, tmp_path):
    for name in ("curve", "surface", "replay", "subdivide", "sample"):
        strings = {s for a in subparsers()[name]._actions for s in a.option_strings}
        assert {"-o", "--out"} <= strings, name
    assert "--output" not in subparsers()["sample"].format_help()
    assert gsr("sample", "bspline_05", "--output", tmp_path / "a.csv").code == 0
    assert gsr("sample", "extended", "--out", tmp_path / "b.obj").code == 0
    assert gsr("subdivide", tmp_path / "b.obj", "--output", tmp_path / "c.obj").code == 0
    assert (tmp_path / "a.csv").exists() and (tmp_path / "c.obj").exists()
    run = gsr("subdivide", tmp_path / "b.obj")
    assert run.code == 2 and run.err.startswith("error: subdivide needs -o")


def test_lengths_in_model_units_or_percent_of_the_diagonal():
    assert parse_length("0.05") == Length(0.05) and parse_length(" 0.1% ") == Length(0.1, percent=True)
    assert parse_length(0.5).fraction(10.0) == pytest.approx(0.05)
    assert parse_length("0.1%").fraction(123.0) == pytest.approx(1e-3)
    for bad in ("abc", "-1", "nan", "1e999", "%", "1%%"):
        with pytest.raises(ConfigError):
            parse_length(bad)
    resolved = resolve_lengths({"max_distance": Length(0.05), "tolerance": "0.2%", "population": 7}, 50.0,
                               CurveConfig)
    assert resolved == {"max_distance": pytest.approx(1e-3), "tolerance": pytest.approx(2e-3), "population": 7}
    assert resolve_lengths({"history_tolerance": Length(2.0)}, 4.0, SurfaceConfig) == {"history_tolerance": 0.5}
    assert format_length(1e-3, 52.0, "mm") == "0.052 mm (0.1 %)"
    assert format_length(0.25, 2.0, "model") == "0.5 model units (25 %)"
    extra = model_metrics({"mean_distance": 1e-3, "max_distance": 2e-3, "fitness": 5.0, "tolerance_met": True,
                           "data_to_fit_max": 4e-3}, 50.0, "in")
    assert extra == {"units": "in", "diagonal": 50.0, "mean_distance_model": pytest.approx(0.05),
                     "max_distance_model": pytest.approx(0.1), "data_to_fit_max_model": pytest.approx(0.2)}


def test_a_bad_length_or_unit_is_one_usage_error(gsr, tmp_path):
    path = tmp_path / "p.csv"
    assert gsr("sample", "bspline_05", "-o", path).code == 0
    for flags_ in (["--max-distance", "0.1mm"], ["--tolerance", "-1%"], ["--units", "furlong"]):
        run = gsr("curve", path, "-o", tmp_path / "out", "--quiet", *flags_)
        assert run.code == 2 and run.err.startswith("error: ") and run.err.count("\n") == 1, run.err
    assert not (tmp_path / "out").exists()
    with pytest.raises(ConfigError, match="units must be one of"):
        CurveConfig(units="furlong").validated()
