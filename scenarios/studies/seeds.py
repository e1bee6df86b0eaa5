"""The seeds a study's cells run at (``offtrack study NAME --seeds SPEC``): parsed and checked before any work.

A study that takes seeds (:attr:`~scenarios.studies.registry.Study.takes_seeds`) runs each of its cells once per
seed given, the seed in every case's overrides and labels; without ``--seeds`` it runs at its own seed(s).
"""

from __future__ import annotations

from collections.abc import Sequence

from vehicle_model.errors import InputError

MAX_SEEDS = 64
"""Most seeds one ``--seeds`` may name: each multiplies the study's cases (the off-highway default subset's 8,
two of them rendered, become 512 at 64 seeds)."""

MAX_SEED = 2**32 - 1
"""Largest seed: the run configuration's ``seed`` range (numpy's)."""

ALLOWED = (
    f"non-negative integers up to {MAX_SEED} as 0-7, 0,1,5 or 3 (ranges and seeds joined by commas), each once, "
    f"at most {MAX_SEEDS} seeds"
)
"""What ``--seeds`` accepts, in the one line that refuses anything else."""


def parse_seeds(text: str) -> tuple[int, ...]:
    """The seeds of ``--seeds``: single seeds and inclusive ranges ``a-b`` (a ≤ b) joined by commas, in the order
    given.

    Parameters
    ----------
    text
        e.g. ``"0-7"``, ``"0,1,5"``, ``"3"`` or ``"0-3,8"``.

    Returns
    -------
    tuple of int
        Each seed once, in the order given.

    Raises
    ------
    InputError
        One line naming ``--seeds`` and :data:`ALLOWED`: an empty item, a value that is not a non-negative integer
        or exceeds :data:`MAX_SEED`, a range whose end is below its start, a seed named twice, or more than
        :data:`MAX_SEEDS` seeds.
    """
    seeds: list[int] = []
    items = [item.strip() for item in str(text).split(",")]
    for item in items:
        first, dash, last = item.partition("-")
        bounds = (first.strip(), last.strip()) if dash else (item,)
        if not all(bound.isascii() and bound.isdecimal() for bound in bounds):
            raise InputError(f"--seeds {text!r}: {item!r} is not a seed or a range; allowed: {ALLOWED}")
        low, high = int(bounds[0]), int(bounds[-1])
        if high > MAX_SEED:
            raise InputError(f"--seeds {text!r}: {high} is above {MAX_SEED}; allowed: {ALLOWED}")
        if high < low:
            raise InputError(f"--seeds {text!r}: the range {item!r} ends below its start; allowed: {ALLOWED}")
        if len(seeds) + high - low + 1 > MAX_SEEDS:
            raise InputError(f"--seeds {text!r}: more than {MAX_SEEDS} seeds; allowed: {ALLOWED}")
        seeds.extend(range(low, high + 1))
    repeated = sorted({seed for seed in seeds if seeds.count(seed) > 1})
    if repeated:
        named = ", ".join(str(seed) for seed in repeated)
        raise InputError(f"--seeds {text!r}: seed {named} named more than once; allowed: {ALLOWED}")
    return tuple(seeds)


def seeds_text(seeds: Sequence[int]) -> str:
    """``seeds`` written back compactly: runs of consecutive seeds as ``a-b``, the rest joined by commas
    (``(0, 1, 2, 3, 5)`` → ``0-3,5``)."""
    parts: list[str] = []
    values = [int(seed) for seed in seeds]
    start = 0
    for k in range(1, len(values) + 1):
        if k == len(values) or values[k] != values[k - 1] + 1:
            low, high = values[start], values[k - 1]
            parts.append(str(low) if low == high else f"{low}-{high}")
            start = k
    return ",".join(parts)
