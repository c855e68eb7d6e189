"""Settings written once: a library config's fields say how they appear in a scenario file.

A library config is a frozen dataclass (SI units, radians). A field that a scenario file sets is
declared with :func:`setting` (or :func:`angle_setting` for an angle, which the file gives in
degrees under the field's name plus ``_deg``). From that one declaration:

- :func:`file_section` builds the scenario's pydantic section (keys, types, constraints and
  defaults), so the file's default *is* the library's default;
- :func:`config_values` turns a validated section back into the config's keyword arguments
  (degrees to radians, lists to tuples), so no field is copied by hand.

The default of an angle is written once, in degrees, and the library's default is
``math.radians`` of it: the very number a file's value would give.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from pydantic import create_model

__all__ = ["FileKey", "angle_setting", "config_values", "file_keys", "file_section", "setting"]


@dataclasses.dataclass(frozen=True)
class FileKey:
    """How one library setting appears in a scenario file.

    Attributes
    ----------
    key : str
        The file's key (``joint_margin_deg`` for the field ``joint_margin``).
    annotation : object
        The pydantic type of the file's value (with its constraints).
    default : object
        The file's default, in the file's units (degrees for an angle).
    degrees : bool
        The file gives degrees, the library takes radians.
    part : str or None
        The file section that holds it, when not the config's own (e.g. ``"robot"`` for the
        controller's speed limits).
    """

    key: str
    annotation: Any
    default: Any
    degrees: bool = False
    part: str | None = None

    def to_library(self, value):
        """The library's value of the file's ``value`` (radians of degrees; a list becomes a
        tuple, since configs are frozen)."""
        if value is None:
            return None
        if isinstance(value, list):
            return tuple(math.radians(v) if self.degrees else v for v in value)
        return math.radians(value) if self.degrees else value


_META = "pushtrain.file"


def setting(default, annotation, *, part: str | None = None, key: str | None = None):
    """A dataclass field the scenario file sets under the same name (or ``key``), with
    ``annotation`` (its pydantic type and constraints) and the same ``default``; ``part``: the
    file section that holds it, if not the config's own."""
    return dataclasses.field(default=default,
                             metadata={_META: (annotation, False, default, part, key)})


def angle_setting(default_deg, annotation, *, part: str | None = None, key: str | None = None):
    """A dataclass field for an angle [rad] that the file gives in degrees as ``NAME_deg`` (or
    ``key``; ``annotation`` constrains the degrees); the default is written in degrees, the
    field's default is its radians (None stays None)."""
    default = None if default_deg is None else math.radians(default_deg)
    return dataclasses.field(default=default,
                             metadata={_META: (annotation, True, default_deg, part, key)})


def file_keys(config_class, part: str | None = None) -> dict[str, FileKey]:
    """{field name: :class:`FileKey`} of every field of ``config_class`` that the file section
    ``part`` sets (None: the config's own section)."""
    out = {}
    for f in dataclasses.fields(config_class):
        meta = f.metadata.get(_META)
        if meta is None or meta[3] != part:
            continue
        annotation, degrees, default, _, key = meta
        key = key or f.name + ("_deg" if degrees else "")
        out[f.name] = FileKey(key, annotation, default, degrees, part)
    return out


def file_section(config_class, name: str, base, extra: dict | None = None,
                 part: str | None = None, also: tuple = ()):
    """The pydantic model of a scenario section holding ``config_class``'s file settings of
    ``part`` (on ``base``, the scenario's strict model), those of the ``(config class, part)``
    pairs in ``also`` (a section that feeds two configs), plus the section's ``extra`` fields
    that belong to no library config ({key: (annotation, default)})."""
    fields: dict = {}
    for cls, of in ((config_class, part), *also):
        for k in file_keys(cls, of).values():
            if k.key in fields:
                raise TypeError(f"{name}.{k.key} is set by two configs")
            fields[k.key] = (k.annotation, k.default)
    for key in extra or {}:
        if key in fields:
            raise TypeError(f"{name}.{key} is both a {config_class.__name__} setting and extra")
    fields.update(extra or {})
    model = create_model(name, __base__=base, **fields)
    model.__doc__ = (f"The scenario's settings of :class:`{config_class.__module__}."
                     f"{config_class.__qualname__}` (generated from its fields).")
    return model


def config_values(config_class, section, part: str | None = None) -> dict:
    """``config_class``'s keyword arguments from a validated ``section`` (every file setting of
    ``part``)."""
    return {name: k.to_library(getattr(section, k.key))
            for name, k in file_keys(config_class, part).items()}
