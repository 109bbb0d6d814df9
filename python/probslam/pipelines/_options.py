"""What every pipeline's options dataclass shares: its fields described once (``described``: doc,
unit, choices; help() and the command line's flags are made from it), a validated copy with some
fields set."""

from __future__ import annotations

import dataclasses
from typing import Any, Optional, Sequence


def described(default: Any, doc: str, unit: str = "", choices: Optional[Sequence[Any]] = None,
              type: Optional[type] = None):
    """A dataclass field with its description: ``doc`` (what it sets; other fields named as
    ``name``; "(None: X)" what None means), ``unit``, the ``choices`` of a field with a few values,
    the ``type`` of a value where the default (None) does not show it."""
    return dataclasses.field(default=default, metadata=dict(doc=doc, unit=unit, choices=choices, type=type))


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

    def validate(self) -> None:
        """ValueError / TypeError naming the first field that is wrong or does not apply."""
        raise NotImplementedError

    def replace(self, **options):
        """A validated copy with the named options (fields) set."""
        out = dataclasses.replace(self, **options)
        out.validate()
        return out
