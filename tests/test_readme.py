"""The README's tour and command-line synopsis run against this checkout.

The tour (the ```python block under "A short tour") is executed as written, with three
textual substitutions, each of which must still match the README exactly once (so the test
fails when the README changes under it and this file is not updated):

* ``"scan.di"`` → a real NanoScope file from ``../shared/data/real`` when present, else an
  xtopo NetCDF file written here (``open_topography`` detects either from its content);
* ``(512, 512)`` → ``(256, 256)``: a smaller synthetic surface keeps the contact solves of the
  tour fast (the ``measure`` window of 128 pixels still samples it at its own spacing);
* the ``twin.topo.plot()`` line is dropped when holoviews is not installed.

The files the tour writes (``scan.nc``) go to a temporary directory.
"""

from __future__ import annotations

import argparse
import importlib.util
import pathlib
import re

import pytest

REPO = pathlib.Path(__file__).resolve().parents[1]
README = REPO / "README.md"


def _readme() -> str:
    return README.read_text(encoding="utf-8")


def _section(text: str, heading: str) -> str:
    """The body of the Markdown section ``heading``, up to the next heading of any level
    (``#`` lines inside code blocks are comments, not headings)."""
    body, inside, fenced = None, False, False
    for line in text.splitlines(keepends=True):
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced and re.match(r"#+ ", line):
            if inside:
                break
            inside = line.rstrip("\n").split(" ", 1)[1].strip() == heading
            body = "" if inside else body
            continue
        if inside:
            body += line
    assert body is not None, f"README.md has no section {heading!r}"
    return body


def tour_block() -> str:
    blocks = re.findall(r"^```python\n(.*?)^```", _section(_readme(), "A short tour"), re.S | re.M)
    assert len(blocks) == 1, f"expected one ```python block in the README's tour, found {len(blocks)}"
    return blocks[0]


def substitute(code: str, old: str, new: str) -> str:
    """``code`` with ``old`` replaced by ``new``; ``old`` must occur exactly once."""
    n = code.count(old)
    assert n == 1, f"the README tour should contain {old!r} exactly once (found {n}); update tests/test_readme.py"
    return code.replace(old, new)


@pytest.fixture
def nanoscope_or_netcdf(tmp_path):
    """A NanoScope file of the shared real data, or (without it) an xtopo NetCDF file."""
    from .conftest import REAL_DATA

    real = REAL_DATA / "di-1.di"
    if real.is_file():
        return str(real)
    import xtopo

    return xtopo.to_netcdf(xtopo.datasets.fractal_surface((64, 64), 5e-7, hurst=0.8, rms_height=1e-8),
                           tmp_path / "scan-in.nc")


def test_readme_tour_runs(tmp_path, monkeypatch, nanoscope_or_netcdf):
    code = tour_block()
    code = substitute(code, '"scan.di"', repr(nanoscope_or_netcdf))
    code = substitute(code, "(512, 512)", "(256, 256)")
    plot_line = re.search(r"^twin\.topo\.plot\(\).*\n", code, re.M)
    assert plot_line, "the README tour no longer shows twin.topo.plot(); update tests/test_readme.py"
    if importlib.util.find_spec("holoviews") is None:
        code = code.replace(plot_line.group(0), "")
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    exec(compile(code, "README.md (tour)", "exec"), namespace)
    # the objects the tour names are what it says they are
    import xarray as xr

    assert isinstance(namespace["ds"], xr.Dataset) and isinstance(namespace["twin"], xr.DataTree)
    assert len(namespace["twin"].children) == 24  # "xarray.DataTree of 24 simulated measurements"
    assert (tmp_path / "scan.nc").is_file()
    scalars = namespace["ds"].topo.scalars()
    for name in ("Sq", "Sdq", "Sddq", "Sa", "Sz", "Ssk", "Sku", "Rq", "Rdq", "Rddq"):
        assert name in scalars, name


# ------------------------------------------------------------------------- command line


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """``{"analyze": parser, ..., "batch contact": parser, ...}`` of the ``xtopo`` parser."""
    out = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out[name] = sub
                out.update({f"{name} {k}": v for k, v in _subparsers(sub).items()})
    return out


def _cli_spans() -> list[str]:
    """The code spans of the README's "Command line" section."""
    return re.findall(r"`([^`]+)`", _section(_readme(), "Command line"))


def _commands_of(span: str, known) -> list[str]:
    """Subcommands a synopsis such as ``xtopo batch contact|analyze FILES`` names."""
    words = span.split()
    assert words[0] == "xtopo"
    names = [""]
    for word in words[1:]:
        options = word.split("|")
        extended = [f"{n} {o}".strip() for n in names for o in options]
        if not all(e in known for e in extended):
            break
        names = extended
    assert names != [""], f"README names an unknown command: {span!r}"
    return names


def test_readme_commands_and_options_exist():
    from xtopo.cli import build_parser

    parsers = _subparsers(build_parser())
    spans = _cli_spans()
    commands = [s for s in spans if s.startswith("xtopo ")]
    assert len(commands) >= 6, commands
    named = set()
    for span in commands:
        options = re.findall(r"(?<![\w-])(--?[a-z][\w-]*)", span)
        for name in _commands_of(span, parsers):
            named.add(name)
            accepted = parsers[name]._option_string_actions
            for opt in options:
                assert opt in accepted, f"README: `{span}` names {opt}, which `xtopo {name}` does not accept"
    # a synopsis that says more than the command's name shows the command's required options
    for span in commands:
        words = span.replace("[", " ").replace("]", " ").split()
        if len(span.split()) <= 2:
            continue
        for name in _commands_of(span, parsers):
            for action in parsers[name]._actions:
                if action.option_strings and action.required:
                    assert set(action.option_strings) & set(words), \
                        f"README: `{span}` leaves out the required option {action.option_strings[-1]} of `xtopo {name}`"
    # every command of the parser is in the README, every README command in the parser
    leaves = {n for n, p in parsers.items() if not any(k.startswith(n + " ") for k in parsers)}
    assert leaves <= named | {n.split()[0] for n in named}, sorted(leaves - named)
    # the options for files that store no size or unit apply to every command (they all read files)
    section = _section(_readme(), "Command line")
    generic = re.search(r"Files that store no size or unit[^`]*`(--[^`]+)`", section)
    assert generic, "README no longer says how files without size or unit are read"
    for opt in re.findall(r"--[a-z][\w-]*", generic.group(1)):
        for name in leaves:
            assert opt in parsers[name]._option_string_actions, f"`xtopo {name}` does not accept {opt}"
    # and every other option the section names belongs to some command
    for opt in set(re.findall(r"(?<![\w-])--[a-z][\w-]*", section)):
        assert any(opt in p._option_string_actions for p in parsers.values()), f"README names {opt}: no command has it"


def test_readme_exit_codes_match_the_cli():
    import xtopo.cli
    import xtopo.cli_commands

    text = " ".join(_section(_readme(), "Command line").split())
    assert "exit codes: 0 ok, 1 partial failure" in text and "2 usage or input error" in text
    for module in (xtopo.cli, xtopo.cli_commands):
        doc = " ".join(module.__doc__.split())
        assert "0 success" in doc and "1 partial failure" in doc and "2 usage or input error" in doc


def test_readme_links_exist():
    for target in re.findall(r"\]\(([^)#]+)\)", _readme()):
        if "://" not in target:
            assert (REPO / target).exists(), f"README links to {target}, which does not exist"
    named = re.findall(r"`((?:benchmarks|xtopo|docs|tests)/[\w./*{},-]+)`", _readme())
    assert len(named) >= 8, named
    for path in named:
        braces = re.search(r"\{([^}]*)\}", path)
        for one in ([path.replace(braces[0], alt) for alt in braces[1].split(",")] if braces else [path]):
            assert list(REPO.glob(one)), f"README names {one}, which does not exist"


def test_readme_file_counts_match_the_real_data(real_data):
    """"36 real instrument and software files in 27 formats ... are read, 35 of them natively (26 names)"."""
    import xtopo
    from xtopo.io import registry

    text = " ".join(_section(_readme(), "Files").split())
    m = re.search(r"(\d+) real instrument and software files in (\d+) formats .*? are read, (\d+) of them natively, "
                  r"the format detected from the content \(([^()]*(?:\([^()]*\)[^()]*)*)\)", text)
    assert m, "the README's sentence on the real files changed; update tests/test_readme.py"
    n_files, n_formats, n_native, names = int(m[1]), int(m[2]), int(m[3]), m[4].split(", ")
    files = sorted(p for p in real_data.iterdir() if p.is_file() and p.name != "MANIFEST.md")
    formats, native = set(), set()
    for path in files:
        fmt = registry.detect(path)[0].name
        formats.add(fmt)
        try:
            xtopo.open_topography(path)
        except xtopo.ReaderError:
            xtopo.open_topography(path, file_units="m")  # the text export that stores no unit
        else:
            native.add((path.name, fmt))
    assert len(files) == n_files
    assert len(formats) == n_formats, sorted(formats)
    assert len(native) == n_native
    assert len({fmt for _, fmt in native}) == len(names), (sorted({fmt for _, fmt in native}), names)


def test_readme_layout_formats_are_registered():
    """"11 more formats are read from their published layout ...: Keyence VK4, ..."."""
    from xtopo.io import registry

    text = " ".join(_section(_readme(), "Files").split())
    m = re.search(r"(\d+) more formats are read from their published layout \([^()]*\): ([^.]*)\.", text)
    assert m, "the README's sentence on the layout-tested formats changed; update tests/test_readme.py"
    names = m[2].split(", ")
    keys = {"Keyence VK4": "vk4", "Keyence VK6/VK7": "vk6", "Keyence ZON": "zon", "Zygo DATX": "datx",
            "Sensofar PLUX": "plux", "Olympus LEXT": "lext", "Olympus OIR": "oir", "Olympus POIR": "poir",
            "OmniSurf3D": "os3d", "NT-MDT": "mdt", "KLA Zeta ZMG": "zmg"}
    assert int(m[1]) == len(names) and sorted(names) == sorted(keys)
    assert set(keys.values()) <= set(registry.formats())


def test_every_command_has_help(capsys):
    """"Every command has `--help`"."""
    from xtopo.cli import build_parser, main

    for name in _subparsers(build_parser()):
        with pytest.raises(SystemExit) as exit_:
            main([*name.split(), "--help"])
        assert exit_.value.code == 0
        assert capsys.readouterr().out.startswith(f"usage: xtopo {name}")


def test_readme_preset_names_are_the_presets():
    from xtopo.presets import NAMES

    m = re.search(r"# presets ([\w /]+) \(docs/tradeoffs\.md\)", tour_block())
    assert m, "the tour no longer names the presets; update tests/test_readme.py"
    assert tuple(n.strip() for n in m[1].split("/")) == NAMES
