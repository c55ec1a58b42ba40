"""The command reference page, rendered from the CLI application (:mod:`egs_bench.cli`).

Walks the click command tree typer builds (``typer.main.get_command``): the program's own
options, then every command (and the commands of any sub-group) with its help text, usage
line and a table of its arguments and options (type, default, help).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import typer
from tabulate import tabulate
from typer._click import Command, Context

from egs_bench.cli.app import PANELS, click_metavar, shown_opts

PROG = "egs-bench"


def walk(command: Command, ctx: Context) -> Iterator[tuple[Command, Context]]:
    """``command`` and every command below it (depth first, in registration order), each with
    its context; hidden commands are left out."""
    yield command, ctx
    for name, sub in getattr(command, "commands", {}).items():
        if not sub.hidden:
            yield from walk(sub, Context(sub, info_name=name, parent=ctx,
                                         **sub.context_settings))


def _cell(text: str) -> str:
    """Text fit for a Markdown table cell."""
    return " ".join(text.split()).replace("|", "\\|")


def _flags(param: Any) -> str:
    """The option's names as ``--help`` shows them (deprecated spellings left out)."""
    return ", ".join(f"`{opt}`" for opt in [*shown_opts(param), *param.secondary_opts])


def _type(param: Any, ctx: Context) -> str:
    """The value's name as ``--help`` shows it (``[auto|paper|cpu]``, ``INTEGER RANGE``), with
    the range; ``flag`` for a flag."""
    if param.param_type_name == "option" and param.is_flag:
        return "flag"
    metavar = param.metavar or click_metavar(param, ctx)
    bounds = []
    if getattr(param, "min", None) is not None:
        bounds.append(f">= {param.min}")
    if getattr(param, "max", None) is not None:
        bounds.append(f"<= {param.max}")
    text = metavar
    if bounds:
        text = text.replace(" RANGE", "") + ", " + ", ".join(bounds)
    return f"`{text}`" + (", repeatable" if param.multiple else "")


def _default(param: Any) -> str:
    if param.required:
        return "required"
    value = param.default
    if value is None or value == [] or value == ():
        return ""
    if isinstance(value, bool):
        return "on" if value else "off"
    return f"`{value}`"


def params_table(command: Command, ctx: Context) -> str:
    """The Markdown table of a command's arguments and options ("" when it has none)."""
    rows = []
    params: list[Any] = command.get_params(ctx)  # typer's options and arguments
    for param in params:
        if getattr(param, "hidden", False):
            continue
        name = (f"`{param.name.upper()}`" if param.param_type_name == "argument"
                else _flags(param))
        rows.append([name, _type(param, ctx), _default(param),
                     _cell(getattr(param, "help", None) or "")])
    if not rows:
        return ""
    return tabulate(rows, headers=["argument / option", "type", "default", "help"],
                    tablefmt="github", disable_numparse=True)


def command_section(command: Command, ctx: Context) -> str:
    """The Markdown section of one command: heading, help, usage, parameters."""
    path = ctx.command_path
    depth = min(1 + max(path.count(" "), 1), 4)  # the program and its commands: level 2
    help_text = (command.help or "").strip()
    usage = command.get_usage(ctx).removeprefix("Usage: ")
    parts = [f"{'#' * depth} `{path}`", "", help_text, "", "```", usage, "```", "",
             params_table(command, ctx), ""]
    return "\n".join(parts)


def panels_index(root: Command, prog: str) -> list[str]:
    """The commands by the top-level help's panels (:data:`egs_bench.cli.app.PANELS`), each a
    link to its section; empty for an application without those commands."""
    names = set(getattr(root, "commands", {}))
    lines = []
    for panel, commands in PANELS.items():
        links = [f"[`{name}`](#{prog}-{name})" for name in commands if name in names]
        if links:
            lines.append(f"- **{panel}**: {', '.join(links)}")
    return [*lines, ""] if lines else []


def render(app: typer.Typer, prog: str = PROG) -> str:
    """The whole page (Markdown) for the typer application ``app``."""
    root = typer.main.get_command(app)
    ctx = Context(root, info_name=prog, **root.context_settings)
    sections = [command_section(cmd, sub) for cmd, sub in walk(root, ctx)]
    intro = [
        "# Command reference",
        "",
        f"Generated from the `{prog}` command-line application when the site is built: each "
        "command's help text and every argument and option with its type, default and "
        f"help, as `{prog} COMMAND --help` prints them.",
        "",
        *panels_index(root, prog),
    ]
    return "\n".join(intro + sections)


def egs_bench_app() -> typer.Typer:
    """The ``egs-bench`` application with every command registered."""
    from egs_bench.cli import _register_commands
    from egs_bench.cli.app import app

    _register_commands()
    return app
