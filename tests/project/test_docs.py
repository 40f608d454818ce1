"""The documentation: the site builds with ``mkdocs build --strict`` (every link, anchor and
API reference resolves), the README is a front page one click from every guide, its links
resolve, the Getting started example runs, and user docs carry no issue numbers or commit
hashes, in prose or in code."""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest


ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
USER_DOCS = [p for p in [ROOT / "README.md", ROOT / "CONTRIBUTING.md",
                         *sorted(DOCS.rglob("*.md"))] if p.exists()]
#: The task guides that the README must link to (one click from the front page).
GUIDES = ["index.md", "fitting.md", "diagnosis.md", "runs.md", "rotary.md",
          "using_a_model.md", "data.md", "cli.md", "tribometer.md", "validation.md",
          "contributing.md"]
#: Pages whose ``python`` blocks are complete programs (each compiles a fit: slow tests).
RUNNABLE = ["README.md", "docs/index.md"]
RUNNABLE_SLOW = ["docs/runs.md"]
MAX_WORDS = 15_000


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


def _links(text: str) -> list[str]:
    """Markdown link targets, outside code."""
    return re.findall(r"\]\(([^)\s]+)\)", _prose(text))


def _anchors(path: Path) -> set[str]:
    """The heading ids mkdocs gives a page (its default ``toc`` slugify)."""
    ids = set()
    for line in re.sub(r"```.*?```", "", path.read_text(), flags=re.S).splitlines():
        m = re.match(r"#{1,6}\s+(.*?)\s*$", line)
        if m:
            slug = re.sub(r"[^\w\s-]", "", m.group(1).replace("`", "")).strip().lower()
            ids.add(re.sub(r"[-\s]+", "-", slug))
    return ids


def test_readme_is_a_front_page():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 200
    assert 'pip install -e . && jaxfric demo' in text
    assert 'pip install -e ".[test]" && pytest' in text
    assert "pytest -m slow" in text
    ci = (ROOT / ".ci" / "run").read_text()
    assert 'pip install -e ".[test]" && pytest' in ci
    targets = {link.split("#")[0] for link in _links(text)}
    missing = [g for g in GUIDES if f"docs/{g}" not in targets]
    assert not missing, f"README does not link to {missing}"
    figures = text.split("## Headline figures", 1)[1].split("\n## ", 1)[0]
    assert len(figures.split()) <= 250, len(figures.split())


@pytest.mark.parametrize("path", [ROOT / "README.md", *[p for p in [ROOT / "CONTRIBUTING.md"]
                                                        if p.exists()]], ids=lambda p: p.name)
def test_links_outside_the_site_resolve(path):
    """mkdocs checks the links inside docs/; this checks the README's (and a root
    CONTRIBUTING's): every relative target exists and every anchor is a heading there."""
    bad = []
    for link in _links(path.read_text()):
        if re.match(r"[a-z]+:", link):
            continue  # a URL
        target, _, anchor = link.partition("#")
        file = (path.parent / target) if target else path
        if not file.exists():
            bad.append(link)
        elif anchor and file.suffix == ".md" and anchor not in _anchors(file):
            bad.append(link)
    assert not bad, f"{path.name}: {bad}"


def test_docs_stay_short():
    words = sum(len(p.read_text().split()) for p in DOCS.rglob("*.md"))
    assert words <= MAX_WORDS, f"docs/ holds {words} words (at most {MAX_WORDS})"


def _prose(text: str) -> str:
    """The text outside code blocks and inline code."""
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    return re.sub(r"`[^`]*`", "", text)


def _hashes(text: str) -> list[str]:
    """Runs of 7-40 hex digits with a digit and a letter (a commit hash), anywhere in the
    text, code included, outside URLs."""
    text = re.sub(r"https?://\S+", "", text)
    return [h for h in re.findall(r"\b[0-9a-f]{7,40}\b", text)
            if re.search(r"[a-f]", h) and re.search(r"\d", h)]


def test_the_hash_check_sees_code():
    assert _hashes("see `git show 3a09733:x`") == ["3a09733"]
    assert _hashes("```\nat e9c6dcd\n```") == ["e9c6dcd"]
    assert _hashes("1.5e-12 and 2.46645e-05, deadbeef, https://x.org/abc1234def") == []


@pytest.mark.parametrize("path", USER_DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_user_docs_carry_no_issue_numbers_or_commit_hashes(path):
    text = path.read_text()
    prose = re.sub(r"\[[^\]]*\]\(https?://[^)]*\)", "", _prose(text))  # upstream citations
    prose = re.sub(r"\]\([^)]*\)", "]", prose)  # link targets (anchors)
    issues = re.findall(r"(?:#\d+\b|\bissues? \d+\b)", prose)
    assert not issues, f"{path.name}: {issues}"
    assert not _hashes(text), f"{path.name}: {_hashes(text)}"


def _python_blocks(page: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", (ROOT / page).read_text(), flags=re.S)


def _run_blocks(pages, tmp_path):
    blocks = list(dict.fromkeys(b for page in pages for b in _python_blocks(page)))
    assert blocks, pages
    for i, block in enumerate(blocks):
        script = tmp_path / f"block{i}.py"
        script.write_text(block)
        run = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True,
                             text=True, timeout=600,
                             env={**os.environ, "PYTHONPATH": str(ROOT)})
        assert run.returncode == 0, f"{pages}, block {i}:\n{block}\n{run.stderr[-3000:]}"


@pytest.mark.slow
def test_getting_started_example_runs(tmp_path):
    _run_blocks(RUNNABLE, tmp_path)
    assert (tmp_path / "model.json").exists()


@pytest.mark.slow
def test_guide_examples_run(tmp_path):
    _run_blocks(RUNNABLE_SLOW, tmp_path)
