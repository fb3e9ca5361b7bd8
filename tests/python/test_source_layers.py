"""The C++ application's sources are layered (issue 27, the layout of src/).

src/io (files: formats, the trajectory schema, JSON and TOML) includes nothing of the
application; src/app (scenarios, runs, checkpoints, summaries, comparisons, ensembles) builds
on io; the two front ends, src/cli (the command line) and src/python (the compiled module),
build on app and io and not on each other. Read from the `#include "..."` lines of the source,
so that an include in the wrong direction fails here, not in a later refactor.
"""

import os
import pathlib
import posixpath
import re

SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2])) / "src"

#: Each folder of src/ and the folders its files may include from ("" + name: headers beside
#: the file in a front end's own folder, such as the Python module's).
MAY_INCLUDE = {
    "io": {"io"},
    "app": {"io", "app"},
    "cli": {"io", "app", "cli"},
    "python": {"io", "app", "python"},
}

INCLUDE = re.compile(r'^\s*#\s*include\s*([<"])([^>"]+)[>"]', re.MULTILINE)


def sources():
    return sorted(p for p in SOURCE.rglob("*") if p.suffix in (".cpp", ".hpp", ".h"))


def test_every_source_file_is_in_a_layer():
    stray = [p.relative_to(SOURCE).as_posix() for p in sources() if p.relative_to(SOURCE).parts[0] not in MAY_INCLUDE]
    assert sources() and not stray, stray


def test_includes_go_down_the_layers_only():
    wrong = []
    for path in sources():
        layer = path.relative_to(SOURCE).parts[0]
        for bracket, written in INCLUDE.findall(path.read_text()):
            included = posixpath.normpath(written)
            folder = included.split("/")[0] if "/" in included else None
            if bracket == "<":
                # A system or library header; one of src/'s folders by <> is still an include of it.
                if folder in MAY_INCLUDE and folder not in MAY_INCLUDE[layer]:
                    wrong.append(f"{path.relative_to(SOURCE)}: <{written}>")
                continue
            if folder is None:
                # A header named without a folder must be beside the file (a front end's own).
                if not (path.parent / included).exists():
                    wrong.append(f"{path.relative_to(SOURCE)}: {included} (no folder, not beside it)")
                continue
            if folder not in MAY_INCLUDE.get(layer, set()):
                wrong.append(f"{path.relative_to(SOURCE)}: {written}")
    assert not wrong, "\n".join(wrong)
