"""The typer application object, global options and the consoles, shared by the command
modules."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import typer
from rich.console import Console
from typer._click import Context
from typer._click.exceptions import BadParameter, NoArgsIsHelpError, UsageError
from typer.core import TyperGroup

from egs_bench import installed_version
from egs_bench.errors import ConfigError


@dataclass
class GlobalOptions:
    debug: bool = False


OPTIONS = GlobalOptions()

#: the largest ``--seed`` (numpy's legacy and most simulators' seeds are 32-bit)
SEED_MAX = 2**32 - 1

# Every message names paths, sequence names and values the tool did not write, and rich would
# read `[red]` or `[/x]` in them as markup (raising MarkupError or eating text) and `:smile:`
# as an emoji. So no console of the CLI interprets its strings; styling is given as
# rich.text.Text spans instead of markup.
out = Console(markup=False, emoji=False, highlight=False, soft_wrap=True)
err = Console(stderr=True, markup=False, emoji=False, highlight=False, soft_wrap=True)


class CommandLineUsageError(ConfigError):
    """An option or argument typer refused (unknown, missing, of the wrong type, out of range);
    reported like every other error, as one line with exit code 2."""


@contextmanager
def _one_line_usage_errors() -> Iterator[None]:
    try:
        yield
    except NoArgsIsHelpError:
        raise  # typer shows the help for a bare `egs-bench`
    except UsageError as exc:
        where = f" (see {exc.ctx.command_path} --help)" if exc.ctx is not None else ""
        one_line = " ".join(exc.format_message().split())  # "Choose from:" lists one per line
        raise CommandLineUsageError(f"{one_line}{where}") from exc


def _refusing_non_finite(callback: Callable[..., Any] | None) -> Callable[..., Any]:
    """An option callback that refuses NaN and infinities, then runs ``callback``."""

    def check(ctx: Context, param: Any, value: Any) -> Any:
        if isinstance(value, float) and not math.isfinite(value):
            raise BadParameter(f"{value} is not a finite number", ctx=ctx, param=param)
        return callback(ctx, param, value) if callback is not None else value

    return check


_COMPLETION_OPTIONS = ("--show-completion", "--install-completion")
_SHELLS = ("bash", "zsh", "fish", "powershell", "pwsh")


def _naming_shell(callback: Callable[..., Any] | None, shell: str | None
                  ) -> Callable[..., Any]:
    """A completion option's callback that receives ``shell`` (a name) instead of the flag's
    True when the command line named one."""

    def call(ctx: Context, param: Any, value: Any) -> Any:
        if callback is None:
            return value
        return callback(ctx, param, shell if value and shell else value)

    return call


class EgsBenchGroup(TyperGroup):
    """The command group: usage errors become one-line :class:`ConfigError`\\ s (typer would
    print a usage block and a framed panel), and no number option of any command accepts NaN
    or an infinity (float parsing takes "nan" and "inf", and no range check refuses NaN)."""

    def __init__(self, **attrs: Any) -> None:
        super().__init__(**attrs)
        for command in self.commands.values():
            for param in command.params:
                if getattr(getattr(param, "type_descriptor", None), "annotation", None) is float:
                    param.callback = _refusing_non_finite(param.callback)

    def make_context(self, info_name: str | None, args: list[str],
                     parent: Context | None = None, **extra: Any) -> Context:
        args = self._take_completion_shell(list(args))
        with _one_line_usage_errors():
            return super().make_context(info_name, args, parent=parent, **extra)

    def _take_completion_shell(self, args: list[str]) -> list[str]:
        """``--show-completion zsh`` / ``--install-completion zsh``: typer's options are flags
        that detect the shell, so the shell named after them was ignored (the bash script was
        printed for zsh). The name is taken out of ``args`` and handed to typer's callback,
        which uses a shell given as text."""
        flags = [p for p in self.params if p.name in ("show_completion", "install_completion")
                 and getattr(p, "is_flag", False)]  # not flags: typer takes the shell itself
        shell = None
        for i, arg in enumerate(args[:-1]):
            if flags and arg in _COMPLETION_OPTIONS and args[i + 1] in _SHELLS:
                shell = args.pop(i + 1)
                break
        for param in flags:
            callback = getattr(param, "_egs_bench_shell_free", param.callback)
            param._egs_bench_shell_free = callback  # type: ignore[attr-defined]
            param.callback = _naming_shell(callback, shell)
        return args

    def invoke(self, ctx: Context) -> Any:
        with _one_line_usage_errors():  # the command's own options are parsed in here
            return super().invoke(ctx)


app = typer.Typer(
    name="egs-bench",
    cls=EgsBenchGroup,
    # plain help: rich mode reads help texts as markup (eating "[default: ...]") and shows
    # flags as "<bool>"; plain help shows flags bare and choices as <a|b|c>
    rich_markup_mode=None,
    help="Event + RGB-D Gaussian Splatting SLAM toolkit: make data, run methods, score them.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    # --install-completion / --show-completion [SHELL]: typer's completion scripts call the
    # console script back with _EGS_BENCH_COMPLETE set, which click answers before any command
    add_completion=True,
    context_settings={"help_option_names": ["-h", "--help"]},
)


def _print_version(value: bool) -> None:
    if value:
        out.print(f"egs-bench {installed_version()}")
        raise typer.Exit()


@app.callback()
def _global(
    debug: bool = typer.Option(
        False, "--debug", help="Show full Python tracebacks instead of one-line error messages."
    ),
    _version: bool = typer.Option(
        False, "--version", callback=_print_version, is_eager=True,
        help="Show the installed egs-bench version and exit."
    ),
) -> None:
    """Event + RGB-D Gaussian Splatting SLAM toolkit: make data, run methods, score them."""
    OPTIONS.debug = debug


def comma_list(text: str, option: str) -> list[str]:
    """The non-empty items of a comma-separated option value; at least one is required.

    Raises:
        ConfigError: the value lists nothing (e.g. ``--metrics ,``).
    """
    items = [item.strip() for item in text.split(",") if item.strip()]
    if not items:
        raise ConfigError(f"{option} lists nothing (got {text!r}); give comma-separated names")
    return items
