"""Parsed YAML checked against a typed schema before pydrake's loader reads
it (`yaml_load_typed`): an unknown key or a value of the wrong type is
refused with an InputError that names the field, dotted from the top, where
the loader's own message would not say which section it is in."""

import dataclasses as dc
import typing

from regrasp_drake.errors import InputError, field_error, quote
from regrasp_drake.input_files import Tagged


def check_schema(value, schema, field: str) -> None:
    """Checks parsed YAML `value` against the type `schema` (a dataclass,
    float, int, str or list of them) before pydrake's loader reads it: an
    unknown key or a value of the wrong type raises the InputError that
    names the field (dotted from the top, `field` being this value's).
    Drake's structs (MultibodyPlantConfig, the directives) are checked
    likewise; what this does not know (a tagged value, a union, a mapping
    of names) is left to pydrake's loader."""
    if isinstance(value, Tagged):
        return
    hints = _fields(schema)
    if hints is not None:
        if not isinstance(value, dict):
            raise field_error(field or "the scenario", value,
                              "a mapping of field: value")
        for key, item in value.items():
            if key not in hints:
                shown = (key if isinstance(key, str) and len(key) <= 64
                         else quote(key))
                name = f"{field}.{shown}" if field else shown
                raise InputError(
                    f"{name}: unknown field, expected one of "
                    f"{', '.join(hints)}")
            name = f"{field}.{key}" if field else str(key)
            check_schema(item, hints[key], name)
    elif typing.get_origin(schema) is list:
        (inner,) = typing.get_args(schema)
        if not isinstance(value, list):
            raise field_error(field, value, _type_name(schema))
        for i, item in enumerate(value):
            check_schema(item, inner, f"{field}[{i}]")
    elif typing.get_origin(schema) is typing.Union:
        kinds = [k for k in typing.get_args(schema) if k is not type(None)]
        if value is not None and len(kinds) == 1:
            check_schema(value, kinds[0], field)
    elif schema in (float, int, str, bool) and not _is_a(value, schema):
        raise field_error(field, value, _type_name(schema))


def _fields(schema) -> dict | None:
    """The fields (name -> type) of a dataclass or of a pydrake struct, or
    None for another type."""
    if dc.is_dataclass(schema):
        return typing.get_type_hints(schema)
    if isinstance(schema, type) and hasattr(schema, "__fields__"):
        return {f.name: f.type for f in schema.__fields__}
    return None


def _is_a(value, kind) -> bool:
    if isinstance(value, bool):  # YAML's true/false is no number
        return kind is bool
    if kind is float:
        return isinstance(value, (int, float))
    return isinstance(value, kind)


def _type_name(kind, plural: bool = False) -> str:
    """'a number', 'a list of numbers', 'a list of lists of numbers', …"""
    if typing.get_origin(kind) is list:
        (inner,) = typing.get_args(kind)
        return (("lists" if plural else "a list") + " of "
                + _type_name(inner, plural=True))
    names = {float: ("a number", "numbers"), int: ("an integer", "integers"),
             str: ("a string", "strings"), bool: ("true or false", "booleans")}
    if _fields(kind) is not None:
        return ("mappings of field: value" if plural
                else "a mapping of field: value")
    return names.get(kind, (str(kind), str(kind)))[plural]
