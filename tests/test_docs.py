"""The documentation: the site builds with ``mkdocs build --strict`` (every link and every
API reference resolves), the README stays a front page, and user docs carry no issue
numbers or commit hashes."""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest


ROOT = Path(__file__).resolve().parents[1]
USER_DOCS = [ROOT / "README.md", ROOT / "BENCHMARKS.md", *sorted((ROOT / "docs").glob("*.md"))]


def _mkdocs() -> str:
    path = shutil.which("mkdocs", path=str(Path(sys.executable).parent)) or shutil.which("mkdocs")
    if path is None:
        pytest.fail("mkdocs is not installed: install the test extra (pip install -e '.[test]')")
    return path


def test_site_builds_strictly(tmp_path):
    run = subprocess.run([_mkdocs(), "build", "--strict", "-d", str(tmp_path / "site")],
                         cwd=ROOT, capture_output=True, text=True,
                         env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    assert run.returncode == 0, run.stdout + run.stderr
    api = (tmp_path / "site" / "api" / "fitting" / "index.html").read_text()
    assert "fitting.fit" in api and "fitting.diagnose" in api
    core = (tmp_path / "site" / "api" / "jaxfric" / "index.html").read_text()
    assert "jaxfric.simulate" in core and "TwoState" in core
    cli = (tmp_path / "site" / "cli" / "index.html").read_text()
    assert "jaxfric diagnose --help" in cli  # the hook put the live help in


def test_readme_is_a_front_page():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 200, len(lines)
    text = "\n".join(lines)
    assert 'pip install -e . && jaxfric demo' in text
    assert 'pip install -e ".[test]" && pytest' in text
    ci = (ROOT / ".ci" / "run").read_text()
    assert 'pip install -e ".[test]" && pytest' in ci


def _prose(text: str) -> str:
    """The text outside code blocks and inline code."""
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    return re.sub(r"`[^`]*`", "", text)


@pytest.mark.parametrize("path", USER_DOCS, ids=lambda p: p.name)
def test_user_docs_carry_no_issue_numbers_or_commit_hashes(path):
    prose = _prose(path.read_text())
    prose = re.sub(r"\]\([^)]*\)", "]", prose)  # link targets (anchors, URLs)
    issues = re.findall(r"(?:#\d+\b|\bissues? \d+\b)", prose)
    issues = [i for i in issues if "lineax" not in prose[max(0, prose.find(i) - 40):
                                                         prose.find(i)]]
    assert not issues, f"{path.name}: {issues}"
    hashes = [h for h in re.findall(r"\b[0-9a-f]{7,40}\b", prose) if re.search(r"[a-f]", h)
              and re.search(r"\d", h)]
    assert not hashes, f"{path.name}: {hashes}"
