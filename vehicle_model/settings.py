"""Settings declared once: the validated, frozen base of every group of settings in offtrack.

A group of settings — the path-following controller's (:class:`controller.path_following_config.
PathFollowingConfig`), the visual odometry's (:class:`sensor.vo.config.VOConfig`), the fused filter's noise model
(:class:`sensor.fusion.FusionNoise`), an on-board signal's (:class:`sensor.signals.ChannelSpec`), and every section
of the scenario schema (:mod:`scenarios.config`) — is a :class:`Settings`: a pydantic model whose fields carry their
type, their allowed range and the reason for it. It refuses unknown fields and non-finite numbers (also inside
tuples and optional fields) and cannot be changed once made (:meth:`Settings.replace` makes a validated copy). A bad
value raises pydantic's ``ValidationError`` (a ``ValueError``) naming the field, the value and the range; the
scenario schema reports the same fields with their dotted names and reasons. The schema embeds these groups (or
converts to one in a single method), so every range is written in one place.
"""

from __future__ import annotations

from typing import Annotated, Any, Self

from pydantic import BaseModel, BeforeValidator, ConfigDict, Strict

__all__ = ["Count", "Flag", "Real", "Settings"]


def _flag(value: Any) -> bool:
    if isinstance(value, bool):
        return value
    if isinstance(value, int) and value in (0, 1):
        return bool(value)
    raise ValueError("must be a bool (or 0/1)")


def _real(value: Any) -> Any:
    if isinstance(value, bool):
        raise ValueError("must be a finite number, not a bool")
    return value


Flag = Annotated[bool, BeforeValidator(_flag)]
"""A switch: ``True``/``False`` or ``1``/``0`` (a C library's flags), nothing else."""
Count = Annotated[int, Strict()]
"""A whole number given as an int (not a float, not a bool)."""
Real = Annotated[float, BeforeValidator(_real)]
"""A finite number (an int is taken; a bool is not)."""


class Settings(BaseModel):
    """A group of settings: unknown fields refused, frozen, every number finite (module docstring)."""

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True, allow_inf_nan=False)

    def replace(self, **changes: Any) -> Self:
        """A validated copy with ``changes``."""
        return type(self).model_validate({**{name: getattr(self, name) for name in type(self).model_fields}, **changes})
