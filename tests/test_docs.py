"""The READMEs' and the documentation pages' links, pictures and quoted commands match the
repository and the code: every ``#anchor`` names a heading, every relative path exists,
every option a quoted ``openup-ompl`` command or benchmark script passes is one that
command accepts, and the Python the README and the pipeline page show runs as written.
(The Sphinx build, ``-n -W``, checks the pages' own cross-references.)"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from openup_ompl.__main__ import build_parser

ROOT = Path(__file__).resolve().parent.parent
READMES = [ROOT / "README.md", ROOT / "benchmarks" / "README.md"]
PAGES = sorted(path for path in (ROOT / "docs").rglob("*.md") if "_build" not in path.parts)
QUOTING = READMES + PAGES
FLAG = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def _headings(text: str) -> set[str]:
    outside = re.sub(r"```.*?```", "", text, flags=re.S)
    return {_slug(m) for m in re.findall(r"^#{1,6} (.+)$", outside, flags=re.M)}


def _links(text: str) -> list[str]:
    return re.findall(r"\]\(([^)\s]+)\)", text)


def _flowing(text: str) -> str:
    """``text`` with each paragraph outside code blocks on one line (a code span may wrap)
    and shell line continuations joined."""
    parts = re.split(r"(```.*?```)", text, flags=re.S)
    return "".join(
        part if part.startswith("```") else re.sub(r"(?<!\n)\n(?!\n)", " ", part) for part in parts
    ).replace("\\\n", " ")


def _quoted(text: str, command: str) -> list[tuple[str, str]]:
    """``(name, rest of the line)`` for every ``command NAME ...`` in ``text``, the line
    cut at a shell operator, a comment or the end of a code span."""
    found = []
    pattern = rf"{re.escape(command)}([a-z][\w./-]*)([^`\n]*)"
    for match in re.finditer(pattern, _flowing(text)):
        rest = re.split(r"&&|\|\||;|\||#", match.group(2))[0]
        found.append((match.group(1), rest))
    return found


@pytest.mark.parametrize("readme", READMES, ids=lambda p: str(p.relative_to(ROOT)))
def test_anchors_name_headings(readme: Path) -> None:
    text = readme.read_text()
    headings = _headings(text)
    anchors = [link[1:] for link in _links(text) if link.startswith("#")]
    missing = [anchor for anchor in anchors if anchor not in headings]
    assert not missing, f"{readme.name}: anchors without a heading: {missing}"


@pytest.mark.parametrize("readme", READMES, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_exist(readme: Path) -> None:
    text = readme.read_text()
    paths = [
        link.split("#")[0]
        for link in _links(text)
        if not link.startswith(("#", "http://", "https://", "mailto:"))
    ]
    assert paths or readme != READMES[0], "the README links no file"
    missing = [path for path in paths if not (readme.parent / path).exists()]
    assert not missing, f"{readme.name}: links to missing files: {missing}"


def test_quoted_cli_options_exist() -> None:
    """Each ``openup-ompl COMMAND ... --option`` quoted in a README or a documentation page
    names a command and options of that command (synopses' ``[--option ...]`` included)."""
    parser = build_parser()
    commands = next(
        action for action in parser._actions if isinstance(action, argparse._SubParsersAction)
    ).choices
    options = {
        name: {flag for action in sub._actions for flag in action.option_strings}
        for name, sub in commands.items()
    }
    checked, wrong = 0, []
    for readme in QUOTING:
        for command, rest in _quoted(readme.read_text(), "openup-ompl "):
            if command not in options:
                wrong.append(f"{readme.name}: openup-ompl {command}")
                continue
            for flag in FLAG.findall(rest):
                checked += 1
                if flag not in options[command]:
                    wrong.append(f"{readme.name}: openup-ompl {command} {flag}")
    assert checked >= 20, checked
    assert not wrong, wrong


def test_quoted_benchmark_options_exist() -> None:
    """Each benchmark script a README or a page quotes (``benchmarks/SCRIPT.py``) exists, and
    each ``SCRIPT.py ... --option`` quoted is an option its ``--help`` lists."""
    scripts = {path.name for path in (ROOT / "benchmarks").glob("*.py")}
    quoted: dict[str, set[str]] = {}
    wrong = []
    for readme in QUOTING:
        text = _flowing(readme.read_text())
        wrong += [
            f"{readme.name}: no benchmarks/{name}"
            for name in re.findall(r"benchmarks/([\w-]+\.py)", text)
            if name not in scripts
        ]
        for script in scripts:
            for rest in re.findall(rf"(?<![\w]){re.escape(script)}([^`\n]*)", text):
                rest = re.split(r"&&|\|\||;|\||#", rest)[0]
                quoted.setdefault(script, set()).update(FLAG.findall(rest))
    assert sum(map(len, quoted.values())) >= 10, quoted
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    for script, flags in sorted(quoted.items()):
        if not flags:
            continue
        done = subprocess.run(
            [sys.executable, str(ROOT / "benchmarks" / script), "--help"],
            cwd=ROOT,
            env=env,
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert done.returncode == 0, done.stderr[-2000:]
        known = set(FLAG.findall(done.stdout))
        wrong += [f"{script} {flag}" for flag in sorted(flags - known)]
    assert not wrong, wrong


def _python_blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def test_readme_reads_in_five_minutes() -> None:
    """The README stays short (at most 250 lines): the rest belongs to the documentation."""
    assert len((ROOT / "README.md").read_text().splitlines()) <= 250


def test_docs_hold_no_commit_hashes() -> None:
    """No README or documentation page cites a commit (history goes to CHANGELOG.md)."""
    commit = re.compile(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b")
    cited = [
        f"{path.relative_to(ROOT)}: {match}"
        for path in [*QUOTING, ROOT / "CHANGELOG.md"]
        for match in commit.findall(re.sub(r"```.*?```", "", path.read_text(), flags=re.S))
    ]
    assert not cited, cited


@pytest.mark.slow  # plans, closes the hand, runs a 20-plan sweep and one rollout
def test_python_examples_run_as_written(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The README's Python example, then the pipeline page's blocks, run in order as a user
    would paste them into one session at the repository root, and the values their
    comments announce (``# True here``, ``# False: ...``) are what they return. (The
    ``ot.Benchmark`` block is examples/ompl_benchmark.py's, run by tests/test_examples.py.)"""
    readme = _python_blocks(READMES[0].read_text())
    page = _python_blocks((ROOT / "docs" / "pipeline.md").read_text())
    blocks = readme + [block for block in page if "ot.Benchmark" not in block]
    assert len(readme) == 1 and len(blocks) >= 6, len(blocks)
    (tmp_path / "scenes").symlink_to(ROOT / "scenes")
    monkeypatch.chdir(tmp_path)
    namespace: dict[str, object] = {}
    announced = 0
    for block in blocks:
        exec(compile(block, "docs", "exec"), namespace)  # noqa: S102 - the docs' code
        for line in block.splitlines():
            match = re.match(r"^(\S.*?)\s+# (True|False)\b", line)
            if match and "=" not in match.group(1).split("(")[0]:
                announced += 1
                value = eval(match.group(1), namespace)  # noqa: S307 - the docs' code
                assert bool(value) is (match.group(2) == "True"), line
    assert announced >= 2
    assert (tmp_path / "plan.json").is_file()
    assert (tmp_path / "robustness").is_dir()
