"""The configuration reference, rendered from :mod:`egs_bench.slam.config`: the docs site's
page (``docs/gen/config_reference.py``) and ``egs-bench config-reference``.

One table per group of :data:`~egs_bench.slam.config.GROUPS`: each field's type, default, its
value in every preset of :data:`~egs_bench.slam.config.PRESETS`, its range
(:func:`~egs_bench.slam.config.ranges`) or choices, and the comment written beside it in the
source (the field's documentation). :func:`render` takes a method's group classes too, so a
component's own config (``SlamComponents.config_classes``) is listed the same way; without
them the page ends with the fields that the components of every registered method add
(:func:`registered_component_classes`, entry points included).
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import io
import textwrap
import tokenize
import typing
from collections.abc import Mapping
from typing import Any, Literal

from tabulate import tabulate

from egs_bench.errors import ConfigError
from egs_bench.slam import config


def field_docs(cls: type) -> dict[str, str]:
    """Each field of a config dataclass -> its comment: the comment lines right above the
    field and the comment at the end of its line, joined (``""`` when it has none). Fields
    inherited from a base dataclass keep the base's comment; a class whose source cannot be
    read (defined interactively) documents none of its own."""
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if dataclasses.is_dataclass(klass):
            docs.update(_own_field_docs(klass))
    return {f.name: docs.get(f.name, "") for f in dataclasses.fields(cls)}


def _own_field_docs(cls: type) -> dict[str, str]:
    """:func:`field_docs` of the fields written in ``cls``'s own body."""
    try:
        source = textwrap.dedent(inspect.getsource(cls))
    except (OSError, TypeError):
        return {}
    comments: dict[int, str] = {}
    code_lines: set[int] = set()
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            comments[tok.start[0]] = tok.string.lstrip("#").strip()
        elif tok.type not in (tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT,
                              tokenize.ENDMARKER):
            code_lines.add(tok.start[0])
    body = ast.parse(source).body[0]
    assert isinstance(body, ast.ClassDef)
    docs: dict[str, str] = {}
    for node in body.body:
        if not (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)):
            continue
        above: list[str] = []
        line = node.lineno - 1
        while line in comments and line not in code_lines:  # a comment block of its own
            above.insert(0, comments[line])
            line -= 1
        trailing = [comments[n] for n in range(node.lineno, (node.end_lineno or node.lineno) + 1)
                    if n in comments]
        docs[node.target.id] = " ".join(above + trailing)
    return docs


def type_name(kind: Any) -> str:
    """``float``, ``int | None``, ``str`` (a ``Literal``'s choices go to their own column)."""
    if typing.get_origin(kind) is Literal:
        return "str"
    args = typing.get_args(kind)
    if args:
        return " \\| ".join(type_name(arg) for arg in args)
    return "None" if kind is type(None) else kind.__name__


def allowed_values(key: str, kind: Any,
                   ranges: Mapping[str, config.Bounds] = config.RANGES) -> str:
    """The range of a number field, the choices of a ``Literal``, or ``""``."""
    choices = [arg for arg in typing.get_args(kind) if arg is not type(None)]
    literal = next((c for c in choices if typing.get_origin(c) is Literal), None)
    if typing.get_origin(kind) is Literal:
        literal = kind
    if literal is not None:
        return ", ".join(f"`{choice}`" for choice in typing.get_args(literal))
    bounds = ranges.get(key)
    if bounds is None:
        return ""
    text = bounds.describe()
    if type(None) in typing.get_args(kind):
        text += f"; `null`: {bounds.null}" if bounds.null else "; or `null`"
    return text


def value_text(value: Any) -> str:
    """A value as YAML writes it in ``config.yaml`` / ``--set`` takes it."""
    if value is None:
        return "`null`"
    if isinstance(value, bool):
        return f"`{str(value).lower()}`"
    if isinstance(value, float):
        return f"`{value:.6g}`"
    return f"`{value}`"


def group_table(group: str, presets: dict[str, config.SlamConfig],
                cls: type | None = None) -> str:
    """The Markdown table of one group (``cls``: its config class, default the built-in one;
    ``presets`` hold that class in the group)."""
    cls = cls or config.GROUPS[group]
    ranges = config.ranges({**config.GROUPS, group: cls})
    hints = typing.get_type_hints(cls)
    docs = field_docs(cls)
    rows = []
    for f in dataclasses.fields(cls):
        default = getattr(cls(), f.name)
        key = f"{group}.{f.name}"
        values = [value_text(getattr(getattr(p, group), f.name)) for p in presets.values()]
        default_text = value_text(default)
        # a preset's value that differs from the field's default is the point of the preset
        values = [v if v == default_text else f"**{v}**" for v in values]
        rows.append([f"`{f.name}`", type_name(hints[f.name]), default_text, *values,
                     allowed_values(key, hints[f.name], ranges), docs[f.name].replace("|", "\\|")])
    headers = ["field", "type", "default", *presets, "range / choices", "doc"]
    return tabulate(rows, headers=headers, tablefmt="github", disable_numparse=True)


def render(classes: Mapping[str, type] | None = None, method: str | None = None) -> str:
    """The whole page (Markdown). ``classes``: the group classes of ``method``, whose
    components declare their own config; None: the built-in groups, then the fields the
    components of each registered method add (:func:`components_section`)."""
    groups = {**config.GROUPS, **(classes or {})}
    presets = {name: make().with_groups(groups) for name, make in config.PRESETS.items()}
    parts = [
        "# Configuration reference" + (f" of method `{method}`" if method else ""),
        "",
        "Generated from `egs_bench/slam/config.py`"
        + (f" and the components of `{method}`." if method else " when the site is built."),
        "",
        "Set a field with `egs-bench run --set GROUP.FIELD=VALUE` (or the field name alone where "
        "it is unique, e.g. `--set lambda_d=0.05`), in a sweep file's `set:` mapping, or in "
        "Python with `SlamConfig.replace`. The run folder's `config.yaml` stores the resolved "
        "values, nested by group. Preset columns show each preset's value; bold values differ "
        "from the field's default.",
        "",
    ]
    for group, cls in groups.items():
        parts += [f"## `{group}`", "", " ".join((cls.__doc__ or "").split()), "",
                  group_table(group, presets, cls), ""]
    if classes is None:
        parts += [components_section(registered_component_classes())]
    return "\n".join(parts)


def registered_component_classes() -> dict[str, dict[str, type] | str]:
    """Each registered method (built-in, registered, entry point) whose components declare
    their own config -> its group classes (:meth:`ConfiguredSlamMethod.config_classes`), or
    why it could not be loaded (a broken plug-in must not break the page)."""
    from egs_bench.runs.registry import available_methods, get_method
    from egs_bench.slam.methods import ConfiguredSlamMethod

    out: dict[str, dict[str, type] | str] = {}
    for name in available_methods():
        try:
            found = get_method(name)
        except ConfigError as exc:
            out[name] = str(exc)
            continue
        if isinstance(found, ConfiguredSlamMethod) and found.config_classes() != config.GROUPS:
            out[name] = found.config_classes()
    return out


def components_section(methods: Mapping[str, Mapping[str, type] | str]) -> str:
    """The page's section on the fields that methods' components add to the groups: per
    method, a table of those fields (``group.field``, type, default, range, doc)."""
    parts = ["## Components' own settings", "",
             "Fields that the components of a registered method add to a group (set them the "
             "same way; `egs-bench config-reference --method NAME` prints the whole reference "
             "of one method).", ""]
    if not methods:
        parts += ["No registered method's components add a field.", ""]
    for name, classes in methods.items():
        parts += [f"### `{name}`", ""]
        if isinstance(classes, str):
            parts += [f"Not loaded: {classes}", ""]
            continue
        rows = []
        ranges = config.ranges(classes)
        for group, cls in classes.items():
            built_in = {f.name for f in dataclasses.fields(config.GROUPS[group])}
            hints, docs = typing.get_type_hints(cls), field_docs(cls)
            for f in dataclasses.fields(cls):
                if f.name in built_in:
                    continue
                key = f"{group}.{f.name}"
                rows.append([f"`{key}`", type_name(hints[f.name]),
                             value_text(getattr(cls(), f.name)),
                             allowed_values(key, hints[f.name], ranges),
                             docs[f.name].replace("|", "\\|")])
        parts += [tabulate(rows, headers=["field", "type", "default", "range / choices", "doc"],
                           tablefmt="github", disable_numparse=True), ""]
    return "\n".join(parts)


def method_reference(method: str | None = None) -> str:
    """The page for ``method`` (a registered name or ``module:attribute``): every group with
    the fields its components add; None: the site's page (:func:`render`).

    Raises:
        ConfigError: an unknown method, or one not configured by a ``SlamConfig``.
    """
    if method is None:
        return render()
    from egs_bench.runs.registry import get_method
    from egs_bench.slam.methods import ConfiguredSlamMethod

    found = get_method(method)
    if not isinstance(found, ConfiguredSlamMethod):
        raise ConfigError(f"method {found.name!r} is not configured by a SlamConfig: it has no "
                          "configuration reference")
    return render(found.config_classes(), found.name)
