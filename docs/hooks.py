"""mkdocs hook: the command line page shows the ``--help`` of the installed parser, so the
documented options are always the real ones."""

import argparse
import contextlib
import io


MARKER = "<!-- jaxfric-help -->"


def _help(parser: argparse.ArgumentParser) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        parser.print_help()
    return out.getvalue()


def on_page_markdown(markdown, page, config, files):
    if MARKER not in markdown:
        return markdown
    from fitting.cli.main import build_parser

    parser = build_parser()
    parts = ["```text", "$ jaxfric --help", _help(parser).rstrip(), "```"]
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, p in sub.choices.items():
        parts += ["", f"## jaxfric {name}", "", "```text", f"$ jaxfric {name} --help",
                  _help(p).rstrip(), "```"]
    return markdown.replace(MARKER, "\n".join(parts))
