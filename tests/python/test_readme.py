"""README.md stays a short entry point into docs/ (issue 31): at most 250 lines, the two commands CI and
users run, and links that resolve on GitHub as well as in the tree: every relative link names a file that
exists, and a #anchor into a Markdown page names one of its headings (GitHub's spelling of it)."""

import os
import pathlib
import re

SOURCE = pathlib.Path(os.environ.get("LGVI_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
README = SOURCE / "README.md"


def _github_slug(heading):
    """GitHub's anchor of a Markdown heading: lower case, punctuation other than '-' and '_' dropped,
    spaces to '-' (backquotes and other markup dropped with the punctuation)."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def _headings(page):
    text = re.sub(r"(?ms)^```.*?^```", "", page.read_text(encoding="utf-8"))  # not the comments in code blocks
    return {_github_slug(m.group(1)) for m in re.finditer(r"(?m)^#{1,6} (.+)$", text)}


def test_readme_is_short():
    assert len(README.read_text(encoding="utf-8").splitlines()) <= 250


def test_readme_has_the_two_commands():
    # .ci/run runs scripts/test.sh: "exactly the README's test command".
    text = README.read_text(encoding="utf-8")
    assert "scripts/paper.sh   # install what is missing, build (Release), run the paper's experiment" in text
    assert "scripts/test.sh    # install what is missing, build (Release), run the whole test suite" in text


def test_readme_links_resolve():
    text = README.read_text(encoding="utf-8")
    links = re.findall(r"\]\(([^)\s]+)\)", text)
    local = [link for link in links if not re.match(r"[a-z]+:", link)]
    assert len(local) > 10, links  # the feature list links into docs/
    for link in local:
        path, _, anchor = link.partition("#")
        target = (README.parent / path).resolve()
        assert target.exists(), f"README.md links to {link}: no such file"
        if anchor and target.suffix == ".md":
            assert anchor in _headings(target), f"README.md links to {link}: no such heading in {path}"


def test_slug_of_a_heading():
    # The spelling the links above are checked against.
    assert _github_slug("First run: the paper's experiment, reproduced") == "first-run-the-papers-experiment-reproduced"
    assert _github_slug("Methods side by side: `lgvi compare`") == "methods-side-by-side-lgvi-compare"
