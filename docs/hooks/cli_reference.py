"""The CLI reference page, generated from ``ami_xr.app.cli.build_parser`` (issue 24).

Used two ways:

* as a MkDocs hook (``hooks:`` in ``mkdocs.yml``): ``on_files`` adds the generated page
  ``cli-reference.md`` to the site, so the reference cannot drift from the parsers;
* as a script: ``python docs/hooks/cli_reference.py`` prints the same Markdown.

Each subcommand's section is its ``--help`` text exactly as ``ami-xr <command> --help`` prints
it, rendered at a fixed width of 100 columns so the page does not depend on the terminal.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Iterator

WIDTH = "100"
PAGE = "cli-reference.md"


def _subcommands(
    parser: argparse.ArgumentParser, prefix: str
) -> Iterator[tuple[str, argparse.ArgumentParser]]:
    """Yield (command line, parser) for the parser and every subcommand below it, in order."""
    yield prefix, parser
    for action in parser._actions:  # argparse keeps subparsers only here
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _subcommands(sub, f"{prefix} {name}")


def render() -> str:
    """Return the Markdown of the CLI reference: one section per (sub)command with its --help."""
    from ami_xr.app.cli import build_parser

    saved = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = WIDTH  # argparse wraps help text to the terminal width
    try:
        parser = build_parser()
        sections = [(name, sub.format_help()) for name, sub in _subcommands(parser, "ami-xr")]
    finally:
        if saved is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = saved
    lines = [
        "# Command-line reference",
        "",
        "Generated from the argument parsers (`ami_xr.app.cli.build_parser`) when the site is",
        "built: each section is what `--help` prints for that command. The rules every command",
        "follows (outputs checked first, one-line errors, exit codes) are in",
        "[Command line](cli.md).",
        "",
    ]
    for name, text in sections:
        lines += [f"## `{name}`", "", "```text", text.rstrip("\n"), "```", ""]
    return "\n".join(lines)


def on_files(files, config):
    """MkDocs hook: add the generated page to the site's files."""
    from mkdocs.structure.files import File

    files.append(File.generated(config, PAGE, content=render()))
    return files


if __name__ == "__main__":
    print(render())
