"""The configuration reference page of the docs site (``reference/config.md``): rendered by
:mod:`egs_bench.slam.config_reference`, which ``egs-bench config-reference`` prints too."""

from __future__ import annotations

from egs_bench.slam.config_reference import (
    allowed_values,
    components_section,
    field_docs,
    group_table,
    registered_component_classes,
    render,
    type_name,
    value_text,
)

__all__ = ["allowed_values", "components_section", "field_docs", "group_table",
           "registered_component_classes", "render", "type_name", "value_text"]
