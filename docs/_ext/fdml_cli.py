"""``.. fdml-cli::``: the command-line reference, generated from :func:`fdml.cli.build_parser`.

The directive walks the argparse parser (the top-level options, then every registered command
in ``fdml.cli.COMMANDS`` order) and renders each command's usage, description and options, so
the reference can never drift from the parser.
"""

from __future__ import annotations

import argparse

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.util.docutils import SphinxDirective


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The command name -> parser map of a parser's subparsers action (empty if none)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _help_of(parser: argparse.ArgumentParser, name: str) -> str:
    """The one-line help a parent parser gives for its command ``name``."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                if choice.dest == name:
                    return choice.help or ""
    return ""


def _escape(text: str) -> str:
    """Text safe for reStructuredText inline use."""
    return text.replace("\\", "\\\\").replace("*", "\\*").replace("`", "\\`").replace("|", "\\|")


def _option_lines(parser: argparse.ArgumentParser) -> list[str]:
    """A definition list of a parser's arguments: invocation, then help with the default."""
    fmt = parser._get_formatter()
    lines: list[str] = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction) or action.help == argparse.SUPPRESS:
            continue
        invocation = fmt._format_action_invocation(action)
        text = fmt._expand_help(action) if action.help else ""
        lines += [f"``{invocation}``", f"    {_escape(' '.join(text.split())) or '(no description)'}", ""]
    return lines


def _parser_lines(parser: argparse.ArgumentParser, title: str, underline: str, summary: str) -> list[str]:
    """reST for one parser: a section with its usage, description, epilog and arguments."""
    usage = parser.format_usage().replace("usage: ", "", 1).rstrip()
    lines = [title, underline * len(title), ""]
    if summary:
        lines += [_escape(summary), ""]
    lines += [".. code-block:: text", ""] + [f"   {u}" for u in usage.splitlines()] + [""]
    for block in (parser.description, parser.epilog):
        if block:
            lines += [".. code-block:: text", ""] + [f"   {b}" for b in block.splitlines()] + [""]
    return lines + _option_lines(parser)


class FdmlCli(SphinxDirective):
    """Render the whole ``fdml`` command line from its parser."""

    has_content = False

    def run(self) -> list[nodes.Node]:
        """Build the nodes: the top-level parser, then one section per command."""
        from fdml.cli import build_parser

        parser = build_parser()
        lines = _parser_lines(parser, "fdml", "-", "")
        for name, sub in _subparsers(parser).items():
            lines += _parser_lines(sub, f"fdml {name}", "-", _help_of(parser, name))
            for inner_name, inner in _subparsers(sub).items():
                lines += _parser_lines(inner, f"fdml {name} {inner_name}", "~", _help_of(sub, inner_name))
        container = nodes.section()
        container.document = self.state.document
        self.state.nested_parse(
            StringList(lines, source="fdml.cli.build_parser"), self.content_offset, container, match_titles=True
        )
        return list(container.children)


def setup(app):
    """Register the ``fdml-cli`` directive."""
    app.add_directive("fdml-cli", FdmlCli)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
