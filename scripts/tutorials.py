#!/usr/bin/python3
"""Runs the tutorials of docs/tutorials/ as a reader would, so that they cannot rot.

    /usr/bin/python3 scripts/tutorials.py [--binary build/lgvi] [--work DIR] [--copy-figures] [NAME ...]

Every ```sh block of a tutorial runs with bash (-euo pipefail), and every ```python block with this
interpreter, in the order of the page, from one working folder that looks like the repository root to
them: `build/lgvi` is the binary under test, and `scenarios/`, `docs/`, `benchmarks/`, `scripts/` are the
source tree's. A ```text block right after a block that runs is that block's standard output as the page
shows it, and must be what the block prints (trailing blanks aside; "..." in a line of it stands for any
text, for wall times): the numbers a page quotes there cannot drift from what the commands give. Standard
error goes to the log only. ```toml blocks and MyST directives ({literalinclude}) are not run; a fence of
any other kind, or a ```text block that follows no block that runs, is an error (it would go unchecked).
A page names the figures it shows and the files its commands write them to in MyST comments,

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
FENCE = re.compile(r"^```([^\n]*)\n(.*?)^```[ \t]*$", re.M | re.S)
FIGURE = re.compile(r"^% figure (\S+) -> (\S+)[ \t]*$", re.M)


class OutputMismatch(Exception):
    """A block printed other than the ```text block after it shows."""


class PageError(Exception):
    """A fenced block this runner would leave unchecked."""


def blocks(text):
    """(language, code, shown output or None) of each fenced block that runs, sh and python, in page
    order; the shown output is a ```text block that follows it with nothing but blank lines between."""
    fences = list(FENCE.finditer(text))
    out = []
    for i, m in enumerate(fences):
        kind = m.group(1).strip()
        if kind == "text":
            before = fences[i - 1] if i > 0 else None
            if before is None or before.group(1).strip() not in ("sh", "python") or text[before.end():m.start()].strip():
                raise PageError(f"a ```text block (line {text.count(chr(10), 0, m.start()) + 1}) that follows no "
                                "sh or python block: nothing would check it")
            continue
        if kind == "toml" or kind.startswith("{"):
            continue
        if kind not in ("sh", "python"):
            raise PageError(f"a ```{kind or '(no language)'} block (line {text.count(chr(10), 0, m.start()) + 1}): "
                            "tutorials use sh, python, text (output) and toml")
        after = fences[i + 1] if i + 1 < len(fences) else None
        shown = None
        if after is not None and after.group(1).strip() == "text" and not text[m.end():after.start()].strip():
            shown = after.group(2)
        out.append((kind, m.group(2), shown))
    return out


def _lines(text):
    return [line.rstrip() for line in text.strip("\n").splitlines()]


def matches(printed, shown):
    """Whether the printed lines are the shown ones, "..." in a shown line standing for any text."""
    got, want = _lines(printed), _lines(shown)
    if len(got) != len(want):
        return False
    for g, w in zip(got, want):
        pattern = ".*".join(re.escape(part) for part in w.split("..."))
        if not re.fullmatch(pattern, g):
            return False
    return True


def figures(text):
    """(file written by the commands, path under docs/tutorials/) of each figure the page shows."""
    return FIGURE.findall(text)


def prepare(work, binary, python_dir=None):
    """A working folder that looks like the repository root: build/lgvi and the source folders."""
    work.mkdir(parents=True, exist_ok=True)
    (work / "build").mkdir(exist_ok=True)
    links = [("build/lgvi", pathlib.Path(binary).resolve())] + [(name, SOURCE / name) for name in LINKED]
    if python_dir:
        links.append(("build/python", pathlib.Path(python_dir).resolve()))
    for name, target in links:
        if (work / name).is_symlink():  # (a dangling link of an earlier run too)
            (work / name).unlink()
        if not (work / name).exists():
            (work / name).symlink_to(target)


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
        proc = subprocess.run(command, cwd=work, env=env, capture_output=True, text=True)
        print(proc.stdout + proc.stderr, end="", file=log, flush=True)
        if proc.returncode != 0:
            raise subprocess.CalledProcessError(proc.returncode, f"{name}.md block {i + 1}", proc.stdout + proc.stderr)
        if shown is not None and not matches(proc.stdout, shown):
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
        except (subprocess.CalledProcessError, OutputMismatch, PageError, FileNotFoundError) as e:
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
