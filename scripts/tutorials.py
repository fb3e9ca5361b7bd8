#!/usr/bin/python3
"""Runs the tutorials of docs/tutorials/ as a reader would, so that they cannot rot.

    /usr/bin/python3 scripts/tutorials.py [--binary build/lgvi] [--work DIR] [--copy-figures] [NAME ...]

Every ```sh block of a tutorial runs with bash (-euo pipefail), and every ```python block with this
interpreter, in the order of the page, from one working folder that looks like the repository root to
them: `build/lgvi` is the binary under test, and `scenarios/`, `docs/`, `benchmarks/`, `scripts/` are the
source tree's. A ```text block right after a block that runs is that block's output as the page shows
it, and must be what the block prints (trailing blanks aside): the numbers a page quotes there cannot
drift from what the commands give. Other fenced blocks (toml) are not run. A page names the figures it
shows and the files its commands write them to in MyST comments,

    % figure results/didymos/libration.png -> figures/didymos-libration.png

and the run checks each one was written; --copy-figures copies them into docs/tutorials/ (how the
committed figures are made). tests/docs/test_tutorials.py runs this and then checks the physics of the
results. Exit status 1 at the first block that fails or prints other than its page shows.
"""

import argparse
import os
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile

SOURCE = pathlib.Path(__file__).resolve().parents[1]
TUTORIALS = SOURCE / "docs" / "tutorials"
LINKED = ("scenarios", "docs", "benchmarks", "scripts")
FENCE = re.compile(r"^```(\w+)[^\n]*\n(.*?)^```[ \t]*$", re.M | re.S)
FIGURE = re.compile(r"^% figure (\S+) -> (\S+)[ \t]*$", re.M)


class OutputMismatch(Exception):
    """A block printed other than the ```text block after it shows."""


def blocks(text):
    """(language, code, shown output or None) of each fenced block that runs, sh and python, in page
    order; the shown output is a ```text block that follows it with nothing but blank lines between."""
    fences = list(FENCE.finditer(text))
    out = []
    for i, m in enumerate(fences):
        if m.group(1) not in ("sh", "python"):
            continue
        after = fences[i + 1] if i + 1 < len(fences) else None
        shown = None
        if after is not None and after.group(1) == "text" and not text[m.end():after.start()].strip():
            shown = after.group(2)
        out.append((m.group(1), m.group(2), shown))
    return out


def _lines(text):
    return [line.rstrip() for line in text.strip("\n").splitlines()]


def figures(text):
    """(file written by the commands, path under docs/tutorials/) of each figure the page shows."""
    return FIGURE.findall(text)


def prepare(work, binary, python_dir=None):
    """A working folder that looks like the repository root: build/lgvi and the source folders."""
    work.mkdir(parents=True, exist_ok=True)
    (work / "build").mkdir(exist_ok=True)
    if not (work / "build" / "lgvi").exists():
        (work / "build" / "lgvi").symlink_to(pathlib.Path(binary).resolve())
    if python_dir and not (work / "build" / "python").exists():
        (work / "build" / "python").symlink_to(pathlib.Path(python_dir).resolve())
    for name in LINKED:
        if not (work / name).exists():
            (work / name).symlink_to(SOURCE / name)


def run_tutorial(name, work, env=None, log=sys.stdout):
    """Runs every block of docs/tutorials/NAME.md in `work`; returns the page's text and each block's
    output. Raises subprocess.CalledProcessError at the first block that fails, OutputMismatch at one that
    prints other than its page shows, FileNotFoundError for a figure that was not written."""
    text = (TUTORIALS / f"{name}.md").read_text(encoding="utf-8")
    outputs = []
    for i, (language, code, shown) in enumerate(blocks(text)):
        print(f"--- {name}: block {i + 1} ({language})\n{code.rstrip()}", file=log, flush=True)
        if language == "sh":
            command = ["bash", "-euo", "pipefail", "-c", code]
        else:
            command = [sys.executable, "-c", code]
        proc = subprocess.run(command, cwd=work, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        print(proc.stdout, end="", file=log, flush=True)
        if proc.returncode != 0:
            raise subprocess.CalledProcessError(proc.returncode, f"{name}.md block {i + 1}", proc.stdout)
        if shown is not None and _lines(proc.stdout) != _lines(shown):
            raise OutputMismatch(f"{name}.md block {i + 1} printed\n{proc.stdout}\nbut the page shows\n{shown}")
        outputs.append(proc.stdout)
    for written, _ in figures(text):
        if not (work / written).is_file():
            raise FileNotFoundError(f"{name}.md shows {written}, which its commands did not write")
    return text, outputs


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", help="tutorials (docs/tutorials/NAME.md; default: all)")
    parser.add_argument("--binary", default=str(SOURCE / "build" / "lgvi"), help="the lgvi binary (default build/lgvi)")
    parser.add_argument("--work", help="working folder (default: a new temporary folder, kept)")
    parser.add_argument("--copy-figures", action="store_true", help="copy the figures the pages show into docs/tutorials/")
    args = parser.parse_args(argv)
    names = args.names or sorted(p.stem for p in TUTORIALS.glob("*.md") if p.stem != "index")
    work = pathlib.Path(args.work or tempfile.mkdtemp(prefix="lgvi-tutorials-"))
    prepare(work, args.binary, SOURCE / "build" / "python")
    env = dict(os.environ)
    env.setdefault("PYTHONPATH", str(SOURCE / "build" / "python"))
    for name in names:
        try:
            text, _ = run_tutorial(name, work, env)
        except (subprocess.CalledProcessError, OutputMismatch, FileNotFoundError) as e:
            print(f"tutorials: {name}: {e}", file=sys.stderr)
            return 1
        if args.copy_figures:
            for written, shown in figures(text):
                (TUTORIALS / shown).parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(work / written, TUTORIALS / shown)
                print(f"tutorials: {written} -> docs/tutorials/{shown}")
    print(f"tutorials: ran {', '.join(names)} in {work}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
