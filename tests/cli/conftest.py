"""Fixtures shared by the command-line tests."""

import pytest

from fitting.cli.main import main


@pytest.fixture
def run(capsys):
    """``run(*argv) -> (exit code, stdout, stderr)`` of the command line in this process."""
    def _run(*argv):
        rc = main([str(a) for a in argv])
        out, err = capsys.readouterr()
        return rc, out, err
    return _run
