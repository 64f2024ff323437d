"""Start-up work of the command line: plain help, and parameter conversion without pydantic.

The light converter (``senscal.cli._params``) must convert every value exactly
as Typer's own pydantic-based conversion does, or hand the value to it: the
comparisons below run over every parameter of every command.
"""

from __future__ import annotations

import functools
import math
import re
from pathlib import Path

import pytest
import typer
from hypothesis import given, settings
from hypothesis import strategies as st

from senscal.cli import _prepare, load_commands
from senscal.cli._clickcompat import click
from senscal.cli._params import LightRuntimeParam, converter_for
from senscal.cli.app import app

build_runtime_param = pytest.importorskip("typer._coercion").build_runtime_param


def _tree():
    """``[(command path, command, context, [params incl. --help])]`` of every command and group."""
    load_commands()
    out = []

    def walk(cmd, path):
        ctx = click.Context(cmd, info_name=path.rsplit(" ", 1)[-1])
        params = list(cmd.params)
        help_opt = cmd.get_help_option(ctx)
        if help_opt is not None:
            params.append(help_opt)
        out.append((path, cmd, ctx, params))
        for name, sub in (getattr(cmd, "commands", None) or {}).items():
            walk(sub, f"{path} {name}")

    walk(typer.main.get_command(app), "senscal")
    return out


TREE = _tree()
ALL_PARAMS = [(path, ctx, p) for path, _, ctx, params in TREE for p in params]


def _norm(v):
    if isinstance(v, float) and math.isnan(v):
        return "nan"
    if isinstance(v, (list, tuple)):
        return type(v).__name__, tuple((type(x).__name__, _norm(x)) for x in v)
    return v


def _outcome(runtime, param, ctx, value):
    try:
        v = runtime.coerce(value, param=param, ctx=ctx)
    except click.exceptions.BadParameter as exc:
        return "refused", exc.format_message()
    except Exception as exc:  # noqa: BLE001 - whatever Typer raises, the light path must raise the same
        return "raised", type(exc).__name__
    return "ok", type(v).__name__, _norm(v)


@functools.lru_cache(maxsize=None)
def _runtimes(param):
    """(light, Typer's own) converters of ``param``, built once (Typer's builds a pydantic adapter)."""
    return (LightRuntimeParam(converter_for(param), param.type_descriptor, build_runtime_param),
            build_runtime_param(param.type_descriptor))


def _compare(param, ctx, value):
    light, typers = _runtimes(param)
    assert _outcome(light, param, ctx, value) == _outcome(typers, param, ctx, value), (param.name, value)


def _compare_text(param, ctx, text: str):
    for value in ([(text,), (text, "1"), text] if param.multiple or param.nargs == -1 else [text]):
        _compare(param, ctx, value)


REPRESENTATIVE = [
    "1", "-3", "+7", "0", "-0", "00012", "12.5", "-0.25", ".5", "5.", "1e3", "1E-3", "-2.5e+10", "1e400", "1e-400",
    "9" * 25, "inf", "-inf", "+Infinity", "INF", "infin", "nan", "NaN", "-nan", "+nan", "nan0", " 1", "1 ", "\t2\n",
    "1_000",
    "1__0", "_1", "1_", "1.0", "1.00", "-0.0", "1.", "1_000.0", "0x10", "1 000", "", " ", "true", "no", "on",
    "１", "٣", "\u00a01", "e3", "1.5e", "--freq", "-", "x.csv", "data/sine.csv", "-file-with-dash",
    "ünïcödé/π.csv", "a b", "[/]", "\udcff", "a\x00b", ".", "..",
]


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    # Paths are checked against the file system: an existing file, a folder and nothing.
    monkeypatch.chdir(tmp_path)
    rows = [f"{i / 200:.4f},{math.sin(2 * math.pi * 10 * i / 200 + 0.1 * i % 3):.6f}" for i in range(400)]
    (tmp_path / "x.csv").write_text("t,x\n" + "\n".join(rows) + "\n")
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "sine.csv").write_text("t,x\n0,1\n")


def test_every_parameter_gets_the_light_converter():
    # A parameter type the light converter does not cover would import pydantic again on every run.
    load_commands()
    root = _prepare(typer.main.get_command(app))
    missing = []

    def walk(cmd, path):
        for p in cmd.params:
            if not isinstance(p._runtime_param, LightRuntimeParam):
                missing.append(f"{path} {p.name}: {p.type_descriptor.annotation!r}")
        for name, sub in (getattr(cmd, "commands", None) or {}).items():
            walk(sub, f"{path} {name}")

    walk(root, "senscal")
    assert not missing, "parameters Typer converts with pydantic (extend senscal.cli._params): " + "; ".join(missing)
    assert len(ALL_PARAMS) > 300  # the whole tree was walked


# A few values of each shape for every parameter; the whole list for one parameter of each conversion kind
# (below): the light converter depends on nothing else, and Typer's path check costs a pydantic adapter a call.
SHORT = ["3", "-12.5", "1e3", "inf", "nan", " 1", "1_000", "1.0", "", "x.csv", "-", "ünï", "true"]


def test_light_conversion_equals_typers_on_every_parameter():
    for _, ctx, param in ALL_PARAMS:
        for text in SHORT:
            _compare_text(param, ctx, text)
        # Defaults and unset options go through the converter as Python values.
        for value in (param.get_default(ctx, call=False), None, 3, -2.5, True, 2**60, Path("x.csv"), ()):
            _compare(param, ctx, value)


def test_light_conversion_equals_typers_on_representative_strings():
    for ctx, param in KINDS:
        for text in REPRESENTATIVE:
            _compare_text(param, ctx, text)


@pytest.mark.parametrize("annotation, text", [(int, "3"), (int, "-12"), (float, "12.5"), (float, "1e-3"),
                                              (float, "-inf"), (str, "ch1"), ("Path", "x.csv")])
def test_plain_values_do_not_reach_pydantic(annotation, text):
    # Otherwise the comparison above would be vacuous: the common values must take the light path.
    params = [(ctx, p) for _, ctx, p in ALL_PARAMS
              if getattr(p.type_descriptor.annotation, "__name__", None) in (getattr(annotation, "__name__", None),
                                                                           annotation)]
    assert params
    for ctx, param in params:
        light = LightRuntimeParam(converter_for(param), param.type_descriptor, build_runtime_param)
        light.coerce((text,) if param.multiple or param.nargs == -1 else text, param=param, ctx=ctx)
        assert light._fallback is None, (param.name, text)


def _kinds():
    """One parameter per distinct conversion (type, list or not, path flags): what hypothesis explores."""
    seen = {}
    for _, ctx, p in ALL_PARAMS:
        info = p.type_descriptor.parameter_info
        key = (repr(p.type_descriptor.annotation), p.multiple, p.nargs, info.exists, info.readable, info.allow_dash)
        seen.setdefault(key, (ctx, p))
    return list(seen.values())


KINDS = _kinds()
NUMBERISH = st.from_regex(re.compile(r"\s?[+-]{0,2}[0-9_]{0,6}\.?[0-9_]{0,4}(?:[eE][+-]?[0-9_]{0,3})?\s?"),
                          fullmatch=True)
WORDS = st.tuples(st.sampled_from(["", "+", "-"]),
                  st.sampled_from(["inf", "infinity", "nan", "in", "infin", "infinit", "na", "nann"]),
                  st.lists(st.booleans(), min_size=8, max_size=8)).map(
    lambda t: t[0] + "".join(c.upper() if up else c for c, up in zip(t[1], t[2])))
STRINGS = st.one_of(NUMBERISH, WORDS, st.floats().map(repr), st.integers().map(str), st.text(max_size=12),
                    st.text(alphabet="-_./ab x", max_size=8))


@settings(max_examples=150, deadline=None)
@given(text=STRINGS)
def test_light_conversion_equals_typers_on_generated_strings(text):
    for ctx, param in KINDS:
        _compare_text(param, ctx, text)


def test_a_refused_value_is_one_line_naming_the_option(cli):
    for args, option in [(["fit", "x.csv", "--harmonics", "two"], "--harmonics"),
                         (["fit", "x.csv", "--freq", "12,5"], "--freq"),
                         (["simulate", "sine", "--out", "o", "--seed", "1.5"], "--seed")]:
        r = cli(*args)
        assert r.code == 2 and len(r.err.strip().splitlines()) == 1 and option in r.err, (args, r.err)
    # Odd but valid spellings still work (converted by Typer's own path).
    r = cli("fit", "x.csv", "--harmonics", " 2", "--freq", "1_0.0", "--json")
    assert r.code == 0 and '"thd_percent"' in r.out, r.err


def _visible_sections(ctx, params):
    names = []
    for p in params:
        if p.get_help_record(ctx) is None:
            continue
        default = "Options" if p.param_type_name == "option" else "Arguments"
        names.append(getattr(p, "rich_help_panel", None) or default)
    return list(dict.fromkeys(names))


@functools.lru_cache(maxsize=None)
def _prepared_root():
    # The tree as `senscal` prepares it (plain help), built once: through main() every command's first use
    # rebuilds the whole Typer tree of the modules loaded so far.
    load_commands()
    return _prepare(typer.main.get_command(app))


def _help_at_80(path: str):
    node = _prepared_root()
    ctx = click.Context(node, info_name="senscal", terminal_width=80)
    for part in path.split()[1:]:
        node = node.commands[part]
        ctx = click.Context(node, info_name=part, parent=ctx, terminal_width=80)
    return node.get_help(ctx), node, ctx


@pytest.mark.parametrize("path", [path for path, *_ in TREE])
def test_help_reads_at_80_columns(path):
    text, cmd, ctx = _help_at_80(path)
    long = [ln for ln in text.splitlines() if len(ln) > 80]
    assert not long, long
    assert text.startswith(f"Usage: {path} ")
    assert "<bool>" not in text and "╭" not in text and "\x1b[" not in text
    params = cmd.get_params(ctx)
    headings = [ln[:-1] for ln in text.splitlines() if ln and not ln.startswith(" ") and ln.endswith(":")]
    expected = _visible_sections(ctx, params)
    assert headings[:len(expected)] == sorted(expected, key=lambda s: (s != "Arguments", s != "Options")), headings
    if getattr(cmd, "commands", None):
        assert headings[-1] == "Commands" and all(f"\n  {n} " in text for n in cmd.commands)
    for p in params:
        if p.get_help_record(ctx) is None:
            continue
        name = p.opts[0] if p.param_type_name == "option" else p.name
        assert name in text, name
        if p.required:
            assert "[required]" in " ".join(text.split()), name


def test_fit_help_shows_defaults_and_panels(cli, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    out = cli("fit", "--help").out
    flat = " ".join(out.split())
    assert "Number of harmonics K (1 = fundamental). [default: 1]" in flat
    assert out.index("\nOptions:") < out.index("\nSensor registry:")
    assert re.search(r"^  --json +Print", out, re.M)  # a flag shows no type


@pytest.mark.parametrize("args", [[], ["registry"]])
def test_no_command_prints_the_help_and_one_line(cli, args):
    r = cli(*args)
    assert r.code == 2 and r.out.startswith(f"Usage: {' '.join(['senscal', *args])} ") and "Commands:" in r.out
    assert r.err.strip().splitlines() == [f"senscal: error: missing command; see '{' '.join(['senscal', *args])} --help'"]


def test_help_does_not_break_hyphenated_words(cli, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    out = cli("response", "--help").out
    # Click alone wrapped these as "back-" / "to-back)" and "[default: no-" / "drift]".
    assert "(back-to-back)" in out and "no-drift]" in out
