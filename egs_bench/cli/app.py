"""The typer application object, global options and the consoles, shared by the command
modules."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import typer
from rich.console import Console
from typer._click import Context
from typer._click.exceptions import BadParameter, NoArgsIsHelpError, UsageError
from typer.core import TyperArgument, TyperGroup, TyperOption

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


# ------------------------------------------------------------------ the CLI's one convention
# (docs/design.md §10): every output is -o/--out, progress is switched off with --quiet,
# values are shown as click shows them, and the top-level help lists commands by panel.

#: old spellings that still work for one version, hidden from the help; using one prints a
#: deprecation line naming the new spelling
DEPRECATED_OPTIONS = {"--output": "-o/--out", "--no-progress": "--quiet"}

#: the one progress switch of every command that shows progress (``--no-progress``: the old
#: spelling of some commands)
QUIET = typer.Option(False, "--quiet", "--no-progress", help="No progress display.")

#: the help of a -o/--out option that a deprecated positional argument may still stand for
OUT_REQUIRED = "(required)"


def output_path(out: Path | None, positional: Path | None, command: str) -> Path:
    """The output path of a command whose output was once a positional argument: ``-o/--out``,
    else the positional one (with a deprecation line).

    Raises:
        ConfigError: neither is given, or both are.
    """
    if out is not None and positional is not None:
        raise ConfigError(f"the output is given twice ({positional} and -o {out}); give it "
                          f"once, as -o/--out (see egs-bench {command} --help)")
    if positional is not None:
        err.print(f"warning: the output as a positional argument is deprecated and will be "
                  f"removed in the next version; use -o/--out {positional}")
        return positional
    if out is None:
        raise ConfigError(f"Missing option '-o' / '--out' (see egs-bench {command} --help)")
    return out


#: the top-level help's panels, in the order shown, and the commands in each
PANELS: dict[str, tuple[str, ...]] = {
    "Sequences": ("info", "show", "make-synthetic", "list-scenes", "make-eventreplica",
                  "import-recording", "make-calib", "recording-presets", "import-enslam",
                  "export"),
    "SLAM runs": ("run", "list", "list-methods", "config-reference", "demo", "import-run"),
    "Evaluation and reports": ("eval", "ate", "rpe", "compare-images", "leaderboard", "plot",
                               "report", "figure", "paper-tables"),
    "Experiments": ("sweep", "regress"),
    "Gaussian maps": ("render-map", "export-map", "render-demo"),
    "Setup": ("warm-up",),
}

_CLICK_TYPE_NAMES = {"str": "TEXT", "int": "INTEGER", "float": "FLOAT", "bool": "BOOLEAN",
                     "path": "PATH", "Path": "PATH", "datetime": "DATETIME"}


def click_metavar(param: Any, ctx: Context) -> str:
    """The value's name as click shows it: ``TEXT``, ``PATH``, ``INTEGER RANGE``, ``[a|b|c]``
    (typer would show ``<str>``, ``<path>``, ``<int range>``, ``<a|b|c>``, ``<list[Path]>``)."""
    label = TyperOption.display_type(param, ctx).removeprefix("<").removesuffix(">")
    if label.startswith("list[") and label.endswith("]"):  # repeatable: the element's name
        label = label[len("list["):-1]
    if "|" in label:
        return f"[{label}]"
    if label.endswith(" range"):
        base = label.removesuffix(" range")
        return f"{_CLICK_TYPE_NAMES.get(base, base.upper())} RANGE"
    return _CLICK_TYPE_NAMES.get(label, label.upper())


def shown_opts(param: Any) -> list[str]:
    """An option's names as the help shows them: without the deprecated spellings."""
    return [o for o in param.opts if o not in DEPRECATED_OPTIONS]


class _ClickStyleOption(TyperOption):
    """An option shown as ``-o, --out PATH``, deprecated spellings left out."""

    def display_type_rich(self, ctx: Context) -> str | None:
        return self.metavar if self.metavar is not None else click_metavar(self, ctx)

    def get_help_record(self, ctx: Context) -> tuple[str, str] | None:
        all_opts = self.opts
        self.opts = shown_opts(self) or all_opts
        try:
            return super().get_help_record(ctx)
        finally:
            self.opts = all_opts


class _ClickStyleArgument(TyperArgument):
    """An argument shown by its name in capitals (``SOURCE``, ``RUN_DIRS...``), as click
    shows it, and left out of the usage line when hidden."""

    def display_type_rich(self, ctx: Context) -> str | None:
        return None

    @property
    def display_name_raw(self) -> str:
        return self.metavar if self.metavar is not None else (self.name or "").upper()

    def _usage_display_name(self) -> str:
        name = self.display_name_raw + ("..." if self.nargs != 1 else "")
        return name if self.required else f"[{name}]"

    def get_usage_pieces(self, ctx: Context) -> list[str]:
        return [] if self.hidden else [self._usage_display_name()]


def _deprecation_lines(command: Any, args: list[str]) -> list[str]:
    """A line for each deprecated option name of ``command`` found in ``args``."""
    names = {o for p in command.params for o in getattr(p, "opts", ())}
    lines = []
    for arg in args:
        if arg == "--":
            break
        name = arg.split("=", 1)[0]
        if name in DEPRECATED_OPTIONS and name in names:
            lines.append(f"warning: {name} is deprecated and will be removed in the next "
                         f"version; use {DEPRECATED_OPTIONS[name]}")
    return lines


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
    print a usage block and a framed panel), no number option of any command accepts NaN
    or an infinity (float parsing takes "nan" and "inf", and no range check refuses NaN), and
    the help follows the one convention above (click-style value names, panels, deprecated
    spellings hidden and announced)."""

    def __init__(self, **attrs: Any) -> None:
        super().__init__(**attrs)
        panel_of = {name: panel for panel, names in PANELS.items() for name in names}
        for name, command in self.commands.items():
            if not isinstance(getattr(command, "rich_help_panel", None), str):  # typer: a Default
                cast(Any, command).rich_help_panel = panel_of.get(name)
            for param in command.params:
                if getattr(getattr(param, "type_descriptor", None), "annotation", None) is float:
                    param.callback = _refusing_non_finite(param.callback)
                if type(param) is TyperOption:
                    param.__class__ = _ClickStyleOption
                elif type(param) is TyperArgument:
                    param.__class__ = _ClickStyleArgument

    def format_commands(self, ctx: Context, formatter: Any) -> None:
        """The commands under their panel's heading (:data:`PANELS`), a panel at a time."""
        commands = [(name, cmd) for name in self.list_commands(ctx)
                    if (cmd := self.get_command(ctx, name)) is not None and not cmd.hidden]
        if not commands:
            return
        limit = formatter.width - 6 - max(len(name) for name, _ in commands)

        def panel(cmd: Any) -> str | None:
            name = getattr(cmd, "rich_help_panel", None)
            return name if name in PANELS else None

        for heading in [*PANELS, None]:
            rows = [(name, cmd.get_short_help_str(limit)) for name, cmd in commands
                    if panel(cmd) == heading]
            if rows:
                with formatter.section(heading or "Other commands"):
                    formatter.write_dl(rows)

    def resolve_command(self, ctx: Context, args: list[str]) -> Any:
        name, command, rest = super().resolve_command(ctx, args)
        if command is not None and not ctx.resilient_parsing:
            for line in _deprecation_lines(command, rest):
                err.print(line)
        return name, command, rest

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


def counted(n: int, noun: str) -> str:
    """``"1 run"``, ``"3 runs"``: a count and its noun in the number it needs."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def comma_list(text: str, option: str) -> list[str]:
    """The non-empty items of a comma-separated option value; at least one is required.

    Raises:
        ConfigError: the value lists nothing (e.g. ``--metrics ,``).
    """
    items = [item.strip() for item in text.split(",") if item.strip()]
    if not items:
        raise ConfigError(f"{option} lists nothing (got {text!r}); give comma-separated names")
    return items
