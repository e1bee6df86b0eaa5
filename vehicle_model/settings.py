"""Settings declared once: the validated, frozen base of every group of settings in offtrack.

A group of settings — the path-following controller's (:class:`controller.path_following_config.
PathFollowingConfig`), the visual odometry's (:class:`sensor.vo.config.VOConfig`), the fused filter's noise model
(:class:`sensor.fusion.FusionNoise`), an on-board signal's (:class:`sensor.signals.ChannelSpec`), and every section
of the scenario schema (:mod:`scenarios.config`) — is a :class:`Settings`: a pydantic model whose fields carry their
type, their allowed range and the reason for it. It refuses unknown fields, non-finite numbers (also inside
tuples and optional fields) and ``true``/``false`` given for a number (:func:`no_bool_for_a_number`; pydantic
alone reads ``true`` as 1), and cannot be changed once made (:meth:`Settings.replace` makes a validated copy). A bad
value raises pydantic's ``ValidationError`` (a ``ValueError``) naming the field, the value and the range; the
scenario schema reports the same fields with their dotted names and reasons. The schema embeds these groups (or
converts to one in a single method), so every range is written in one place.
"""

from __future__ import annotations

import typing
from typing import Annotated, Any, Self

from pydantic import BaseModel, BeforeValidator, ConfigDict, Strict, ValidationInfo, field_validator
from pydantic_core import PydanticCustomError

__all__ = ["BOOL_FOR_A_NUMBER", "Count", "Flag", "Real", "Settings", "no_bool_for_a_number"]

BOOL_FOR_A_NUMBER = "bool_for_a_number"
"""The error type of ``true``/``false`` given for a number (:func:`no_bool_for_a_number`)."""


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


def _admits(annotation: Any, kinds: tuple[Any, ...]) -> bool:
    """Whether a field of type ``annotation`` is (or holds, in a union, tuple or ``Annotated``) one of ``kinds``."""
    if annotation in kinds or (bool in kinds and isinstance(annotation, bool)):  # bool: also Literal[True]
        return True
    return any(_admits(arg, kinds) for arg in typing.get_args(annotation))


def no_bool_for_a_number(model: type[BaseModel], value: Any, field: str | None) -> Any:
    """``value`` for ``model``'s ``field``, refused if it is ``true``/``false`` (or a list holding one) and the field
    is not a switch: pydantic would read ``true`` as the number 1 (a 1 kg trailer, a μ of 1.0).

    Raises
    ------
    pydantic_core.PydanticCustomError
        Of type :data:`BOOL_FOR_A_NUMBER`: the value is a bool and the field takes a number but no bool.
    """
    holds_bool = isinstance(value, bool) or (
        isinstance(value, list | tuple) and any(isinstance(v, bool) for v in value)
    )
    if not holds_bool or field not in model.model_fields:
        return value
    annotation = model.model_fields[field].annotation
    if _admits(annotation, (int, float)) and not _admits(annotation, (bool, Any)):
        raise PydanticCustomError(BOOL_FOR_A_NUMBER, "must be a number, not true/false")
    return value


class Settings(BaseModel):
    """A group of settings: unknown fields refused, frozen, every number finite and given as a number (module
    docstring)."""

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True, allow_inf_nan=False)

    @field_validator("*", mode="before")
    @classmethod
    def _strict_numbers(cls, value: Any, info: ValidationInfo) -> Any:
        return no_bool_for_a_number(cls, value, info.field_name)

    def replace(self, **changes: Any) -> Self:
        """A validated copy with ``changes``."""
        return type(self).model_validate({**{name: getattr(self, name) for name in type(self).model_fields}, **changes})
