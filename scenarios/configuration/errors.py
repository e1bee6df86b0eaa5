"""The configuration's input error and the "did you mean" of its messages."""

from __future__ import annotations

import difflib
from typing import Any

from vehicle_model.errors import InputError


class ConfigError(InputError):
    """An invalid scenario configuration; the message lists every bad field with its allowed range."""


def did_you_mean(word: str, choices: Any, prefix: str = "") -> str:
    """``"; did you mean 'a' or 'b'?"`` naming the valid ``choices`` nearest to ``word``, or ``""`` if none is near.

    Parameters
    ----------
    word : str
        What was given.
    choices : iterable of str
        The valid names.
    prefix : str
        Put before each name shown (a section's dotted name and a dot).

    Returns
    -------
    str
        The suggestion, to append to an error message; empty when no choice is close
        (:func:`difflib.get_close_matches`).
    """
    near = [repr(prefix + n) for n in difflib.get_close_matches(word, sorted(set(choices)), n=3, cutoff=0.6)]
    if not near:
        return ""
    named = near[0] if len(near) == 1 else f"{', '.join(near[:-1])} or {near[-1]}"
    return f"; did you mean {named}?"
