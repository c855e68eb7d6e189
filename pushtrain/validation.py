"""Turn pydantic validation errors into (where, value, what is allowed) lines for users.

Scenario files and sweep specs share this: every problem is reported at once with its path
(``train.mass[1]``), union branches that were not meant are dropped (a per-trailer field that
takes a number or a list reports only the branch matching what was written), and a value that
fits no branch gets one line.

Numbers are strict: a TOML boolean (``n = true``) or string (``n = "3"``) is not a number and is
refused, naming the field (models set ``strict=True``; :data:`Integer` and :func:`no_bool` are
the two places where strict pydantic needs help).
"""

from __future__ import annotations

from typing import Annotated

from pydantic import BeforeValidator, Field

from pushtrain.errors import FieldErrors

__all__ = ["field_errors", "read_toml", "validate_model", "clipped", "clip_text",
           "MAX_SHOWN_CHARS", "Integer", "no_bool", "PositiveFloat", "NonNegFloat", "FiniteFloat"]

PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
"""A finite number > 0."""
NonNegFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]
"""A finite number >= 0."""
FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
"""A finite number."""


def _whole(value):
    """A float that is a whole number (a sweep's ``range`` makes 3.0) as that int; anything
    else unchanged for the strict int check (which refuses booleans, strings, 2.5)."""
    if type(value) is float and value.is_integer():
        return int(value)
    return value


Integer = Annotated[int, BeforeValidator(_whole)]
"""An integer field of a strict model: ints and whole floats (3.0), never a bool or a string."""


def no_bool(allowed: str) -> BeforeValidator:
    """Before-validator for a ``Literal`` of integers (``allowed`` says which, e.g. "0 or 1"):
    strict pydantic still takes ``true`` for 1 there (``True == 1`` in Python); refuse it."""

    def check(value):
        if isinstance(value, bool):
            raise ValueError(f"{allowed}, not the boolean {str(value).lower()}")
        return value

    return BeforeValidator(check)


def _type_message(err) -> str | None:
    """What is allowed, for a number or boolean field given the wrong TOML type."""
    value, kind = err.get("input"), err["type"]
    if kind not in ("int_type", "float_type", "bool_type"):
        return None
    want = {"int_type": "an integer", "float_type": "a number",
            "bool_type": "true or false"}[kind]
    if isinstance(value, bool):
        return f"{want}, not the boolean {str(value).lower()}"
    if isinstance(value, str):
        return f"{want}, not a string: write it without quotes"
    if kind == "int_type" and isinstance(value, float):
        return f"{want} (a whole number), not {value!r}"
    if kind == "bool_type" and isinstance(value, (int, float)):
        return f"{want}, not the number {value!r}"
    return None


MAX_SHOWN_CHARS = 200
"""Longest value or quoted text [characters] a message shows; the rest is counted, not shown."""


class _Clipped:
    """Stands for a value whose repr is too long to show: its repr is the clipped text."""

    __slots__ = ("text",)

    def __init__(self, text: str):
        self.text = text

    def __repr__(self) -> str:
        return self.text


def clip_text(text: str, limit: int = MAX_SHOWN_CHARS) -> str:
    """``text`` cut to ``limit`` characters, saying how many were left out."""
    text = str(text)
    if len(text) <= limit:
        return text
    return f"{text[:limit]}... ({len(text) - limit} more characters)"


def clipped(value, limit: int = MAX_SHOWN_CHARS):
    """``value`` itself if its repr has at most ``limit`` characters, else a stand-in whose repr
    is the first ``limit`` of them and how many were left out (for (where, value, allowed)
    problems: a message stays a few lines however large the bad value is)."""
    try:
        text = repr(value)
    except RecursionError:
        return _Clipped(f"<a {type(value).__name__} nested too deeply to show>")
    return value if len(text) <= limit else _Clipped(clip_text(text, limit))


def _is_branch(part) -> bool:
    """A pydantic union-branch tag in an error location (not a field name)."""
    return isinstance(part, str) and (
        part in ("float", "int", "str", "bool", "none", "constrained-float", "constrained-int")
        or part.startswith(("list[", "function-", "literal[", "union["))
    )


def _where(loc) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif not _is_branch(part):
            out += ("." if out else "") + str(part)
    return out or "(top level)"


def _wrong_branch(err) -> bool:
    """For a value that may be a number or a list: is this the error of the branch not taken?"""
    loc = err["loc"]
    tags = [k for k, part in enumerate(loc) if _is_branch(part)]
    if not tags:
        return False
    branch = loc[tags[0]]
    is_list = isinstance(err.get("input"), list)
    if branch.startswith("list["):
        inside = any(isinstance(part, int) for part in loc[tags[0] + 1:])
        return not inside and not is_list
    if branch in ("float", "int", "constrained-float", "constrained-int"):
        return is_list
    return False


def field_errors(exc) -> list[tuple[str, object, str]]:
    """The problems of a pydantic ``ValidationError``, one line per field."""
    lines, index = [], {}
    for err in exc.errors():
        inner = (err.get("ctx") or {}).get("error")
        if isinstance(inner, FieldErrors):
            lines += inner.errors
            continue
        if _wrong_branch(err):
            continue
        where = _where(err["loc"])
        if err["type"] == "extra_forbidden":
            allowed = "unknown key (check the spelling)"
        else:
            allowed = _type_message(err) or err["msg"].removeprefix("Value error, ")
        if where in index:  # the same value failed several branches: one line
            k = index[where]
            if allowed not in lines[k][2]:
                lines[k] = (where, lines[k][1], lines[k][2] + "; or " + allowed)
        else:
            index[where] = len(lines)
            lines.append((where, err.get("input"), allowed))
    return lines


def _toml_problem(text: str, message: str) -> tuple:
    """(where, value, allowed) of a TOML syntax error: its line and that line's text, so a key
    given twice ("Cannot overwrite a value") is named."""
    import re

    found = re.search(r"\(at line (\d+), column \d+\)", message)
    if found is None:
        return ("(syntax)", None, f"not valid TOML: {message}")
    number = int(found.group(1))
    lines = text.splitlines()
    shown = clip_text(lines[number - 1].strip(), 80) if 0 < number <= len(lines) else None
    if "overwrite" in message or "declare" in message:
        message += " (a key or a table given twice: each once)"
    return (f"(syntax) line {number}", shown, f"not valid TOML: {message}")


def read_toml(path, error_cls) -> dict:
    """The TOML document at ``path`` (UTF-8) with ``name`` defaulting to the file's stem.

    A file that cannot be read, decoded or parsed raises
    ``error_cls(source, [(where, value, allowed)])``.
    """
    import tomllib
    from pathlib import Path

    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise error_cls(str(path), [("(file)", str(path),
                                     f"cannot be read: {exc.strerror}")]) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise error_cls(str(path), [(f"(encoding) line {line}", raw[exc.start:exc.end],
                                     "TOML files must be UTF-8 text")]) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error_cls(str(path), [_toml_problem(text, str(exc))]) from None
    except RecursionError:
        raise error_cls(str(path), [("(syntax)", None,
                                     "not valid TOML: nested too deeply")]) from None
    data.setdefault("name", path.stem)
    return data


def validate_model(model, data: dict, source: str, error_cls):
    """``model.model_validate(data)``; a pydantic ``ValidationError`` becomes
    ``error_cls(source, [(where, value, allowed), ...])`` with every problem at once."""
    from pydantic import ValidationError

    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise error_cls(source, field_errors(exc)) from None
