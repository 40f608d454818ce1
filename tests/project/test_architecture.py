"""The shape of the code base: layers, circles, file sizes, module docstrings, lint.

The layers are import-linter contracts in pyproject.toml (``[tool.importlinter]``): the core
`jaxfric` never imports `fitting`, nothing below the command line (`fitting.cli`) imports
it, and no two sibling modules import each other. The lint rules (with complexity and size
limits per function) are ruff's, configured in pyproject.toml too.
"""

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import pytest


ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("jaxfric", "fitting")
MAX_LINES = 600


def _tool(name: str) -> str:
    path = shutil.which(name, path=str(Path(sys.executable).parent)) or shutil.which(name)
    if path is None:
        pytest.fail(f"{name} is not installed: install the test extra (pip install -e '.[test]')")
    return path


def _sources(*folders: str) -> list[Path]:
    return sorted(p for f in folders for p in (ROOT / f).rglob("*.py"))


def test_import_contracts_hold():
    run = subprocess.run([_tool("lint-imports")], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "0 broken" in run.stdout


def test_ruff_is_clean_on_the_whole_tree():
    run = subprocess.run([_tool("ruff"), "check", "."], cwd=ROOT, capture_output=True,
                         text=True)
    assert run.returncode == 0, run.stdout + run.stderr


def test_library_files_are_small_and_say_what_they_are():
    files = _sources(*PACKAGES)
    assert len(files) > 20
    too_long = {str(p.relative_to(ROOT)): n for p in files
                if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert not too_long, f"files over {MAX_LINES} lines: {too_long}"
    undocumented = [str(p.relative_to(ROOT)) for p in files if p.read_text().strip()
                    and ast.get_docstring(ast.parse(p.read_text())) is None]
    assert not undocumented, f"modules without a docstring: {undocumented}"


def test_the_diagnosis_decision_reads_in_one_sitting():
    # The rule that decides what the diagnosis adds is one module of under 400 lines; how
    # its options are fitted (fitting/_refits.py) and the record handling
    # (fitting/_diagnose.py) live elsewhere.
    n = len((ROOT / "fitting" / "_select.py").read_text().splitlines())
    assert n < 400, f"fitting/_select.py has {n} lines"


def test_examples_live_outside_the_packages():
    # A worked example is a script with a __main__ block; such scripts live in examples/.
    scripts = [str(p.relative_to(ROOT)) for p in _sources(*PACKAGES)
               if '__name__ == "__main__"' in p.read_text() and p.name != "__main__.py"]
    assert not scripts, f"scripts inside the library packages: {scripts}"
    assert (ROOT / "examples" / "tribometer.py").is_file()


def test_the_console_command_lives_in_the_top_layer():
    text = (ROOT / "pyproject.toml").read_text()
    assert 'jaxfric = "fitting.cli:main"' in text
    run = subprocess.run([sys.executable, "-m", "fitting.cli", "--help"], cwd=ROOT,
                         capture_output=True, text=True)
    assert run.returncode == 0 and "usage: jaxfric" in run.stdout, run.stderr


def test_every_program_is_compiled_with_jaxfrics_options():
    # One place decides how programs are compiled (jaxfric._compile.jit); a bare jax.jit
    # or equinox.filter_jit would compile without jaxfric's compiler options.
    bare = {}
    for p in _sources(*PACKAGES):
        if p.name == "_compile.py":
            continue
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.Attribute) and node.attr in ("jit", "filter_jit") and \
                    isinstance(node.value, ast.Name) and node.value.id in ("jax", "eqx"):
                bare.setdefault(str(p.relative_to(ROOT)), []).append(node.lineno)
    assert not bare, f"compiled without jaxfric._compile.jit: {bare}"


def test_the_command_line_starts_without_the_heaviest_imports():
    """Every command pays its imports before any work: the command line and both packages
    load without scipy.stats (whose distributions cost more than half a second; the
    chi-square quantiles the fits need come from scipy.special) and without matplotlib
    (imported by the commands that plot, when they plot)."""
    code = ("import sys, fitting.cli.main, jaxfric; "
            "print(sorted(m for m in ('scipy.stats', 'matplotlib') if m in sys.modules))")
    run = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                         text=True)
    assert run.returncode == 0 and run.stdout.strip() == "[]", run.stdout + run.stderr
