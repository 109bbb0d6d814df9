"""What every pipeline's options dataclass shares: its fields described once (``described``: doc,
unit, choices; help() and the command line's flags are made from it), groups of fields that are an
options object of their own (``described_group``: a library class such as ``FastSlamOptions``, set
as a whole or by a dict of its fields, as the bound options classes' groups are), a validated copy
with some fields set."""

from __future__ import annotations

import dataclasses
import re
from typing import Any, Mapping, Optional, Sequence, Tuple


def described(default: Any, doc: str, unit: str = "", choices: Optional[Sequence[Any]] = None,
              type: Optional[type] = None):
    """A dataclass field with its description: ``doc`` (what it sets; other fields named as
    ``name``; "(None: X)" what None means), ``unit``, the ``choices`` of a field with a few values,
    the ``type`` of a value where the default (None) does not show it."""
    return dataclasses.field(default=default, metadata=dict(doc=doc, unit=unit, choices=choices, type=type))


def described_group(cls: type, doc: str):
    """A dataclass field holding an options object of class ``cls`` (its default ``cls()``): given
    as one, or as a dict of its fields (``{"num_particles": 50}``), its fields reached by dotted
    path (``fastslam.num_particles``) in sweeps and on the command line."""
    return dataclasses.field(default_factory=cls, metadata=dict(doc=doc, unit="", choices=None, type=cls, group=True))


def option_names(options: Any) -> Tuple[str, ...]:
    """The field names of an options object: a dataclass's fields, a bound options class's
    ``as_dict`` keys."""
    if dataclasses.is_dataclass(options):
        return tuple(f.name for f in dataclasses.fields(options))
    return tuple(options.as_dict())


def group_fields(options) -> Sequence[str]:
    """The names of the fields of a pipeline's options dataclass that are groups (``described_group``)."""
    return [f.name for f in dataclasses.fields(options) if f.metadata.get("group")]


class Options:
    """Base of a pipeline's options dataclass: ``validate`` (the subclass's: ValueError / TypeError
    naming the first field that is wrong or does not apply) and ``replace``; its described fields
    are listed in its docstring as "name (unit): doc", as the bound options classes list theirs."""

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        fields = [(name, f.metadata) for name, f in vars(cls).items()
                  if isinstance(f, dataclasses.Field) and "doc" in f.metadata]
        if fields:
            lines = [f"    {name}" + (f" ({m['unit']})" if m["unit"] else "") + f": {m['doc']}\n" for name, m in fields]
            cls.__doc__ = (cls.__doc__ or "").rstrip() + "\n\n    Fields:\n" + "".join(lines)

    def __post_init__(self) -> None:
        # A group given as a dict of its fields: the group's defaults with them set.
        for name in group_fields(self):
            value = getattr(self, name)
            if isinstance(value, Mapping):
                setattr(self, name, _set_group(type(self).__dataclass_fields__[name].default_factory(), name, value))

    def validate(self) -> None:
        """ValueError / TypeError naming the first field that is wrong or does not apply."""
        raise NotImplementedError

    def replace(self, **options):
        """A validated copy with the named options (fields) set; a group (``described_group``) given
        as a dict has the fields it names set, the others kept. The copy's groups are its own."""
        groups = group_fields(self)
        for name in groups:
            value = options.get(name, getattr(self, name))
            options[name] = (_set_group(getattr(self, name), name, value) if isinstance(value, Mapping)
                             else _copy(value))
        out = dataclasses.replace(self, **options)
        out.validate()
        return out


def _copy(group):
    """A copy of an options object (a bound class's ``copy``, a dataclass's), anything else as it is."""
    if hasattr(group, "copy"):
        return group.copy()
    return dataclasses.replace(group) if dataclasses.is_dataclass(group) else group


def _set_group(group, name: str, values: Mapping):
    """``group.replace(**values)``, its errors naming the field's path (``fastslam.num_particles``)."""
    try:
        return group.replace(**values)
    except (TypeError, ValueError) as exc:
        raise type(exc)(group_message(name, str(exc), values)) from None


def group_message(name: str, message: str, fields=()) -> str:
    """A group's error message naming the field's path: ``name.field ...`` when it starts with one
    of the group's field names (``fields``), else ``name: ...``."""
    if message.startswith(f"{name}."):
        return message
    if any(re.match(rf"{re.escape(str(f))}\b(?!\.)", message) for f in fields):
        return f"{name}.{message}"
    return f"{name}: {message}"
