"""The one form of an options object: a frozen pydantic model with one-line errors.

Every options object of the package (:class:`~laser_corners.DetectorParams`,
:class:`~laser_corners.matching.MatchOptions`, the evaluation configs, ...) derives from
:class:`Options`, so they all

* reject unknown fields and wrong values with one :class:`~laser_corners.errors.InvalidParamsError`
  line naming the field and the allowed range (``MatchOptions.k_nearest: input should be
  greater than or equal to 1, got 0``);
* are frozen (a changed copy comes from :meth:`Options.with_overrides`);
* take the same vocabulary from a YAML/TOML mapping (:meth:`Options.from_mapping`) and from
  ``key=value`` strings (:meth:`Options.with_overrides`, the CLI's ``--set``); a nested
  options field is reached with a dotted key (``match.max_distance=0.5``).
"""

from __future__ import annotations

import types
import typing
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Annotated, Any, ClassVar

import tomllib
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from laser_corners.errors import InvalidParamsError

__all__ = ["MountValue", "Options", "read_config", "unknown_keys"]

MountValue = Annotated[float, Field(allow_inf_nan=False, ge=-1000.0, le=1000.0)]
"""One number of a base -> laser mount ``(x, y, yaw)``: finite, within a kilometre (radian)."""


class Options(BaseModel):
    """Base of the package's options objects (frozen, ``extra="forbid"``, one-line errors).

    Class attributes a subclass may set: ``title`` (prefix of field names in messages, e.g.
    ``"MatchOptions"``; empty: the bare field name), ``what`` (what a field is called in
    messages, "parameter" by default), ``tuple_hints`` (tuple field -> the accepted form of
    its value, for messages) and ``section`` (the table of a config file that holds these
    options).
    """

    model_config = ConfigDict(frozen=True, extra="forbid", validate_default=True)

    title: ClassVar[str] = ""
    what: ClassVar[str] = "parameter"
    tuple_hints: ClassVar[dict[str, str]] = {}
    section: ClassVar[str] = ""

    def __init__(self, **data: Any) -> None:
        try:
            super().__init__(**data)
        except ValidationError as exc:
            raise InvalidParamsError(one_line(exc, type(self))) from None

    def __setattr__(self, name: str, value: Any) -> None:
        raise InvalidParamsError(
            f"{type(self).__name__} is frozen: cannot set {name!r}; make a changed copy with "
            f".with_overrides({{{name!r}: ...}})"
        )

    def __delattr__(self, name: str) -> None:
        self.__setattr__(name, None)

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], source: str = "parameters") -> Any:
        """Build from a mapping such as a parsed YAML/TOML document (``source`` names it in
        messages). A top-level table named ``section`` (e.g. ``detector``), if present, is
        used, so one config file can hold several sections."""
        if not isinstance(data, Mapping):
            raise InvalidParamsError(f"{source}: expected a mapping of {cls.what} names to values")
        if cls.section and isinstance(data.get(cls.section), Mapping):
            data = data[cls.section]
        try:
            return cls(**dict(data))
        except InvalidParamsError as exc:
            raise InvalidParamsError(f"{source}: {exc}") from None

    @classmethod
    def from_file(cls, path: str | Path) -> Any:
        """Load from a ``.yaml``/``.yml`` or ``.toml`` file (see :meth:`from_mapping`)."""
        return cls.from_mapping(read_config(path, cls.what), source=str(path))

    def to_yaml(self) -> str:
        """The options as a YAML document (the format :meth:`from_file` reads)."""
        return yaml.safe_dump(self.model_dump(mode="json"), sort_keys=False)

    def with_overrides(self, assignments: Iterable[str] | Mapping[str, Any]) -> Any:
        """A validated copy with fields replaced.

        Parameters
        ----------
        assignments : iterable of ``"key=value"`` strings, or a mapping
            Values in strings are parsed as YAML (``[0.1, 0.2]``, ``6``, ``true``); tuple
            fields also take comma-separated values (``0.1,0.2``). A dotted key
            (``match.k_nearest=2``) reaches a nested options field.
        """
        updates = parse_assignments(type(self), assignments)
        return type(self)(**_merged(self, updates))


def read_config(path: str | Path, what: str = "parameter") -> Any:
    """The parsed document of a ``.yaml``/``.yml`` or ``.toml`` file (an empty YAML file:
    ``{}``).

    Raises
    ------
    InvalidParamsError
        One line naming the file: unreadable (``cannot read <what>s``) or not valid YAML/TOML.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InvalidParamsError(f"{path}: cannot read {what}s ({exc.strerror})") from None
    try:
        if path.suffix.lower() == ".toml":
            return tomllib.loads(text)
        return yaml.safe_load(text) or {}
    except (yaml.YAMLError, tomllib.TOMLDecodeError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InvalidParamsError(f"{path}: not valid YAML/TOML: {first}") from None


def parse_assignments(
    cls: type[Options], assignments: Iterable[str] | Mapping[str, Any]
) -> dict[str, Any]:
    """``key=value`` strings (or a mapping) as a mapping of field -> value, keys checked."""
    if isinstance(assignments, Mapping):
        items = list(assignments.items())
    else:
        items = []
        for item in assignments:
            key, sep, raw = str(item).partition("=")
            key = key.strip()
            if not sep or not key:
                raise InvalidParamsError(f"override {item!r} is not of the form key=value")
            try:
                items.append((key, yaml.safe_load(raw)))
            except yaml.YAMLError:
                raise InvalidParamsError(f"override {item!r}: value is not valid") from None
    updates: dict[str, Any] = {}
    for key, value in items:
        head, _, rest = str(key).partition(".")
        field = cls.model_fields.get(head)
        nested = _options_type(field.annotation) if field is not None else None
        if field is None or (rest and nested is None):
            raise InvalidParamsError(unknown_keys(cls, [key]))
        if rest:
            assert nested is not None
            updates.setdefault(head, {}).update(parse_assignments(nested, {rest: value}))
        else:
            updates[head] = _as_tuple(cls, head, value) if _is_tuple(field.annotation) else value
    return updates


def _merged(options: Options, updates: Mapping[str, Any]) -> dict[str, Any]:
    """The fields of ``options`` with ``updates``; nested updates are merged into a copy of
    the nested options (so they are validated by their own class)."""
    merged = {name: getattr(options, name) for name in type(options).model_fields}
    for key, value in updates.items():
        current = merged[key]
        if isinstance(value, dict) and isinstance(current, Options):
            try:
                merged[key] = type(current)(**_merged(current, value))
            except InvalidParamsError as exc:  # as a YAML table says it: ``icp: ...``
                raise InvalidParamsError(f"{key}: {exc}") from None
        else:
            merged[key] = value
    return merged


def _options_type(annotation: Any) -> type[Options] | None:
    """The :class:`Options` class of a (possibly optional) nested field, else None."""
    for arg in (annotation, *typing.get_args(annotation)):
        if isinstance(arg, type) and issubclass(arg, Options):
            return arg
    return None


def _is_tuple(annotation: Any) -> bool:
    args = typing.get_args(annotation) if isinstance(annotation, types.UnionType) else ()
    return any(typing.get_origin(a) is tuple for a in (annotation, *args))


def _as_tuple(cls: type[Options], key: str, value: Any) -> Any:
    """A tuple field's value: comma-separated values or one value -> a tuple."""
    if isinstance(value, str):
        parts = value.strip("[]() ").split(",")
        try:
            return tuple(yaml.safe_load(part) for part in parts if part.strip())
        except yaml.YAMLError:
            hint = cls.tuple_hints.get(key, "comma-separated values")
            raise InvalidParamsError(f"{key}: expected {hint}, got {value!r}") from None
    if isinstance(value, list | tuple) or value is None:
        return value
    return (value,)


def unknown_keys(cls: type[Options], keys: Iterable[str]) -> str:
    """The one message of unknown keys: ``unknown <what> 'x'; known: a, b, ...`` (the
    :attr:`Options.what` and fields of ``cls``), for :meth:`Options.with_overrides`, the
    constructor and :meth:`Options.from_mapping` alike."""
    names = ", ".join(repr(k) + _grouped_hint(cls, str(k)) for k in keys)
    return f"unknown {cls.what} {names}; known: {', '.join(cls.model_fields)}"


def _grouped_hint(cls: type[Options], key: str) -> str:
    """`` (now 'loop.radius')`` for a flat name ``loop_radius`` whose group ``loop`` (a nested
    options field of ``cls``) has the field ``radius``, else ""."""
    for head, field in cls.model_fields.items():
        nested = _options_type(field.annotation)
        rest = key.removeprefix(f"{head}_")
        if nested is not None and rest != key and rest in nested.model_fields:
            return f" (now '{head}.{rest}')"
    return ""


def _group_message(cls: type[Options], loc: list[str]) -> str | None:
    """The message for a plain value given to the group at ``loc`` (``smooth=false``): its
    dotted names, else None when ``loc`` is not a nested options field."""
    owner, key = _owner(cls, loc)
    field = owner.model_fields.get(key)
    nested = _options_type(field.annotation) if field is not None else None
    if nested is None:
        return None
    names = ", ".join(f"{key}.{k}" for k in nested.model_fields)
    return f"a group of {cls.what}s: set one by its dotted name ({names}) or the table {key}:"


def _owner(cls: type[Options], loc: list[str]) -> tuple[type[Options], str]:
    """The options class that holds the unknown key at ``loc`` (nested options fields are
    followed) and the key as that class names it."""
    for i, name in enumerate(loc[:-1]):
        field = cls.model_fields.get(name)
        nested = _options_type(field.annotation) if field is not None else None
        if nested is None:
            return cls, ".".join(loc[i:])
        cls = nested
    return cls, loc[-1]


def one_line(exc: ValidationError, cls: type[Options]) -> str:
    """A pydantic validation error as one line: ``field: message, got value; ...``; unknown
    fields first, as :func:`unknown_keys` says them."""
    unknown: dict[type[Options], list[str]] = {}
    parts = []
    for error in exc.errors():
        loc = [str(p) for p in error.get("loc", ()) if not isinstance(p, int)]
        kind = error.get("type", "")
        if kind == "extra_forbidden" and loc:
            owner, key = _owner(cls, loc)
            unknown.setdefault(owner, []).append(key)
            continue
        field = ".".join(loc)
        where = f"{cls.title}.{field}" if cls.title and field else field or cls.title
        message = str(error.get("msg", "invalid")).removeprefix("Value error, ")
        group = _group_message(cls, loc) if kind == "model_type" and loc else None
        if group is not None:
            message = f"{group}, got {error.get('input')!r}"
        elif loc and loc[0] in cls.tuple_hints and kind != "value_error":
            message = f"expected {cls.tuple_hints[loc[0]]} ({message})"
            where = loc[0]
        elif kind not in ("value_error", "missing", "extra_forbidden") and "input" in error:
            message = f"{message[:1].lower()}{message[1:]}, got {error['input']!r}"
        parts.append(f"{where}: {message}" if where else message)  # message names the key
    first = [unknown_keys(owner, keys) for owner, keys in unknown.items()]
    return "; ".join(dict.fromkeys([*first, *parts]))
