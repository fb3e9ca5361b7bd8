"""The lists of methods, interactions and output formats agree everywhere a user reads them
(issue 27): the command line's messages, the Python API and its stubs, and the documentation (the
scenario-file reference and the methods table, docs/guide/*.md, once README.md) all name
exactly the entries of the C++ registries (src/app/method_registry.hpp registered_method_traits,
src/io/formats/registry.cpp registered_formats, src/app/interactions/registry.cpp interaction_kinds), in their
order.

The truth is lgvi._core.METHODS, FORMATS and INTERACTIONS, which the compiled module reads from
those tables (src/python/module.cpp), not retyped. A method, format or interaction added to a
table and not to the stubs or the docs (or the reverse) fails here, naming the list.
"""

import ast
import os
import pathlib
import re
import subprocess

import pytest

import lgvi
import lgvi._core as core

SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
PACKAGE = SOURCE / "python" / "lgvi"
# The documentation pages users copy names from: the scenario file's reference block ([integrator],
# [output]: docs/guide/scenario-files.md), the [interaction] block (docs/guide/many-bodies.md) and the
# table of methods (docs/guide/compare.md); read as one text, in that order.
DOCS = [SOURCE / "docs" / "guide" / page for page in ("scenario-files.md", "many-bodies.md", "compare.md")]


def _docs_lines():
    return [line for page in DOCS for line in page.read_text(encoding="utf-8").splitlines()]
BINARY = os.environ.get("LGVI_BINARY")

TABLES = {"method": core.METHODS, "format": core.FORMATS, "interaction": core.INTERACTIONS}


def _quoted(text):
    """The double-quoted names in `text`, in order."""
    return re.findall(r'"([^"]+)"', text)


def test_tables_are_whole():
    # Guards the truth itself: an empty or duplicated table would make every comparison below
    # vacuous or ambiguous. The defaults the docs and the reader name must be in them.
    for kind, names in TABLES.items():
        assert len(names) == len(set(names)) > 0, f"{kind}: {names}"
    assert core.METHODS[0] == "lgvi" and core.FORMATS[0] == "csv" and core.INTERACTIONS[0] == "none"


def test_python_api_names_are_the_tables():
    # lgvi.METHODS etc. are what users test against and what the argument checks use.
    assert lgvi.METHODS == core.METHODS
    assert lgvi.FORMATS == core.FORMATS
    assert lgvi.INTERACTIONS == core.INTERACTIONS


def _interaction_error(kind):
    bodies = lgvi.Body(mass=1.0, inertia=[[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])
    return lgvi.Scenario.from_arrays(bodies=[bodies, bodies], positions=[[0, 0, 0], [3, 0, 0]],
                                     quaternions=[[1, 0, 0, 0]] * 2, momenta=[[0, 0, 0]] * 2, omegas=[[0, 0, 0]] * 2,
                                     step=0.1, duration=1.0, interaction={"kind": kind, "G": 1.0})


def test_python_interaction_check_lists_the_table():
    # The Python API checks interaction={"kind": ...} itself (to name the argument); the kinds
    # its message lists, i.e. the ones it accepts, must be the reader's.
    with pytest.raises(ValueError, match="interaction.kind") as e:
        _interaction_error("no-such-kind")
    assert tuple(_quoted(str(e.value).split("one of", 1)[1].split(", got")[0])) == core.INTERACTIONS


def _literal(stub, alias):
    """The strings of `alias = Literal[...]` in a stub file."""
    tree = ast.parse((PACKAGE / stub).read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and [getattr(t, "id", None) for t in node.targets] == [alias]:
            value = node.value
            assert isinstance(value, ast.Subscript) and getattr(value.value, "id", "") == "Literal", alias
            elts = value.slice.elts if isinstance(value.slice, ast.Tuple) else [value.slice]
            return tuple(e.value for e in elts)
    raise AssertionError(f"{stub}: no {alias} = Literal[...]")


@pytest.mark.parametrize("alias, names", [("Method", core.METHODS), ("OutputFormat", core.FORMATS),
                                          ("InteractionKind", core.INTERACTIONS), ("Solver", core.SOLVERS)])
def test_stub_literals_are_the_tables(alias, names):
    # The stubs had Method = Literal["lgvi", "lgvi-lagrangian"] while there were nine methods:
    # a type checker then rejected seven valid methods.
    assert _literal("__init__.pyi", alias) == names


def _between(text, start, end):
    text = " ".join(text.split())
    assert start in text and end in text.split(start, 1)[1], f"{start!r} ... {end!r} not in the docstring"
    return tuple(_quoted(text.split(start, 1)[1].split(end, 1)[0]))


def test_docstrings_list_the_tables():
    # help(lgvi.Scenario) spells the methods and formats out; a name added to a table and not
    # there (or removed and left there) fails.
    doc = lgvi.Scenario.__doc__
    assert _between(doc, "``method`` one of lgvi.METHODS", "``solver``") == core.METHODS
    assert _between(doc, "``output_format`` for the CLI", "``name``") == core.FORMATS
    assert _between(lgvi.Scenario.output_format.__doc__, "format:", "(LAMMPS)") == core.FORMATS


def _readme_setting(key, table_line):
    """The names of the docs' scenario-file comment `key = "..."  # "a" | "b" ...` (with its
    continuation comment lines), the one in the block after `table_line`."""
    lines = _docs_lines()
    start = lines.index(table_line)
    for i in range(start + 1, len(lines)):
        m = re.match(rf'{key} = "[^"]*"\s+#(.*)', lines[i])
        if m:
            text = m.group(1)
            for cont in lines[i + 1:]:
                c = re.match(r"\s+#(.*)", cont)
                if not c:
                    break
                text += c.group(1)
            return tuple(_quoted(text))
    raise AssertionError(f"docs/guide: no {key} = ... after {table_line}")


def _readme_method_table():
    """The first column of the docs' table | method | header | what it is | (docs/guide/compare.md)."""
    lines = _docs_lines()
    start = lines.index("| method | header | what it is |")
    names = []
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        names.append(re.match(r"\| `([^`]+)` \|", line).group(1))
    return tuple(names)


@pytest.mark.parametrize("where, read, names", [
    ("[integrator] method", lambda: _readme_setting("method", "[integrator]"), core.METHODS),
    ("[output] format", lambda: _readme_setting("format", "[output]"), core.FORMATS),
    ("[interaction] kind", lambda: _readme_setting("kind", "[interaction]"), core.INTERACTIONS),
    ("the table | method | header | what it is |", _readme_method_table, core.METHODS)])
def test_readme_lists_are_the_tables(where, read, names):
    # The docs' scenario-file reference (the comment after each key) and its table of methods
    # are the lists users copy names from.
    assert read() == names, f"docs/guide's {where} disagrees with the C++ table"


def test_readme_parsers_see_the_lists():
    # The docs parsers on a text where one name is missing must notice (a parser returning
    # the first quoted word only would pass the test above on a one-entry table, not here).
    assert len(_readme_setting("method", "[integrator]")) == len(core.METHODS) > 2
    assert len(_readme_method_table()) > 2


# ---------------------------------------------------------------------------
# The command line: its messages for a name it does not know list the names it knows.

needs_cli = pytest.mark.skipif(not BINARY, reason="LGVI_BINARY not set (ctest sets it)")


def _cli_error(args, tmp_path):
    run = subprocess.run([BINARY, *args], capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert run.returncode != 0, f"lgvi {' '.join(args)} accepted a name that does not exist"
    message = run.stderr + run.stdout
    assert "is not one of" in message, message
    return tuple(_quoted(message.split("is not one of", 1)[1].splitlines()[0]))


def _scenario_text(**changes):
    body = lgvi.Body(mass=1.0, inertia=[[1.0, 0, 0], [0, 2.0, 0], [0, 0, 3.0]])
    return lgvi.Scenario(body=body, step=0.1, duration=1.0,
                         position=[0, 0, 0], quaternion=[1, 0, 0, 0], momentum=[0, 0, 0], w=[0, 0, 0],
                         **changes).toml


@needs_cli
@pytest.mark.parametrize("kind", ["method", "format", "interaction"])
def test_cli_scenario_messages_list_the_tables(kind, tmp_path):
    # lgvi run reads the scenario with the C++ reader; a name it does not know is refused with the
    # list it accepts (the reader's own list, built from the registries: this is where a drift
    # between the reader and the compiled module's tables would show).
    if kind == "method":
        text = _scenario_text().replace('method = "lgvi"', 'method = "no-such-method"')
    elif kind == "format":
        text = _scenario_text(output_format="npz").replace('format = "npz"', 'format = "no-such-format"')
    else:
        text = _interaction_error("gravity").toml.replace('kind = "gravity"', 'kind = "no-such-kind"')
    assert "no-such-" in text, "the replacement above did not apply: the scenario writer's spelling changed"
    path = tmp_path / "bad.toml"
    path.write_text(text)
    assert _cli_error(["run", str(path), "--out", str(tmp_path / "out"), "--no-figures", "-q"], tmp_path) \
        == TABLES[kind]


@needs_cli
def test_cli_compare_message_lists_the_methods(tmp_path):
    # lgvi compare --methods takes method names on the command line: its refusal lists them.
    path = tmp_path / "free.toml"
    path.write_text(_scenario_text())
    assert _cli_error(["compare", str(path), "--methods", "lgvi,no-such-method", "--out", str(tmp_path / "c"),
                       "--no-figures", "-q"], tmp_path) == core.METHODS


@needs_cli
@pytest.mark.parametrize("command", ["run", "compare", "ensemble"])
def test_cli_help_has_no_partial_list(command):
    # A list of names written into a --help text (two or more names of a table, quoted as in the
    # scenario file) must be the whole table: a partial or stale list of methods, formats or
    # interactions there fails. (The method table of run and compare is checked below.)
    text = subprocess.run([BINARY, command, "--help"], capture_output=True, text=True, timeout=60).stdout
    assert "Usage" in text, text
    quoted = set(_quoted(text))
    for kind, names in TABLES.items():
        listed = quoted & set(names)
        assert len(listed) < 2 or listed == set(names), f"lgvi {command} --help lists the {kind}s {sorted(listed)}"


@needs_cli
@pytest.mark.parametrize("command", ["run", "compare"])
def test_cli_help_lists_every_method_in_registry_order(command):
    # lgvi run / compare --help print the method registry's table (src/app/method_registry.cpp,
    # method_table): one line per method, its name first, in the registry's order.
    text = subprocess.run([BINARY, command, "--help"], capture_output=True, text=True, timeout=60).stdout
    table = text[text.index("Methods ([integrator] method"):].split("\n\n", 1)[0]
    listed = [line.split()[0] for line in table.splitlines()[1:] if not line.startswith("    ")]
    assert listed == list(core.METHODS), text


def test_the_loader_knows_every_formats_file():
    # lgvi.load (python/lgvi/_io.py, pure numpy: it does not import the compiled module) looks for a
    # run folder's trajectory by file name, and refuses the exports for viewers by name: both lists
    # must be the registry's, split by whether the format holds the trajectory's columns.
    from lgvi import _io
    assert set(core.FORMAT_FILES) == set(core.FORMATS)
    assert _io.TRAJECTORY_FILES == tuple(f for f, columns in core.FORMAT_FILES.values() if columns)
    assert _io.EXPORT_FILES == tuple(f for f, columns in core.FORMAT_FILES.values() if not columns)
