"""What every pipeline's options dataclass shares: a validated copy with some fields set."""

from __future__ import annotations

import dataclasses


class Options:
    """Base of a pipeline's options dataclass: ``validate`` (the subclass's: ValueError / TypeError
    naming the first field that is wrong or does not apply) and ``replace``."""

    def validate(self) -> None:
        """ValueError / TypeError naming the first field that is wrong or does not apply."""
        raise NotImplementedError

    def replace(self, **options):
        """A validated copy with the named options (fields) set."""
        out = dataclasses.replace(self, **options)
        out.validate()
        return out
