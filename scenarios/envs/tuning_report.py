"""What ``offtrack tune`` shows and writes: the gains with their units, the tables, and the gains as a run's config.

A run takes controller gains as ``controller.kp``, ``controller.ki`` and ``controller.kd`` [rad/m, rad/m², rad;
per metre travelled], the same for every steered unit, or as ``controller.unit_gains``, one ``{kp, ki, kd}`` per
steered towed unit front to rear: on the command line as ``--set`` (:func:`set_options`), or in a scenario file's
``controller:`` section. One steered unit is written with ``kp``/``ki``/``kd``, more with ``unit_gains``. A
scenario file is a whole scenario (there is no file of overrides alone), so the gains are written as the scenario
they were tuned on with its ``controller:`` section set (:func:`gains_config`): ``offtrack run
DIR/tuned_gains.yaml`` runs it, and the ``--set`` line applies the gains to any other scenario of that vehicle.
"""

from __future__ import annotations

import shlex
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd
from rich.markup import escape
from rich.table import Table

from controller.path_following_config import PathFollowingGains

from ..config import ScenarioConfig, validate_config
from ..run.files import write_atomic
from ..run.results import config_yaml
from ..run.summary import MISSING, number
from .tuning import TuningResult

__all__ = [
    "GAIN_UNITS",
    "TUNING_FILES",
    "comparison_frame",
    "gains_config",
    "gains_table",
    "held_out_table",
    "set_options",
    "trials_frame",
    "write_trials",
    "write_tuning",
]

GAIN_UNITS: dict[str, str] = {"kp": "rad/m", "ki": "rad/m²", "kd": "rad"}
"""Units of the gains (per metre travelled), as the configuration's ``controller`` section takes them."""

TUNING_FILES: dict[str, str] = {
    "trials": "trials.csv",
    "comparison": "comparison.csv",
    "comparison_md": "comparison.md",
    "gains": "tuned_gains.yaml",
}
"""The files :func:`write_tuning` writes, by what they hold."""


def _sets(gains: PathFollowingGains | Sequence[PathFollowingGains]) -> tuple[PathFollowingGains, ...]:
    return (gains,) if isinstance(gains, PathFollowingGains) else tuple(gains)


def _controller_fields(gains: PathFollowingGains | Sequence[PathFollowingGains]) -> dict[str, Any]:
    """The ``controller`` fields giving a run ``gains``: ``kp``/``ki``/``kd`` for one set, ``unit_gains`` for more."""
    sets = _sets(gains)
    if len(sets) == 1:
        return {**{name: float(getattr(sets[0], name)) for name in GAIN_UNITS}, "unit_gains": None}
    return {
        **dict.fromkeys(GAIN_UNITS),
        "unit_gains": [{name: float(getattr(g, name)) for name in GAIN_UNITS} for g in sets],
    }


def set_options(gains: PathFollowingGains | Sequence[PathFollowingGains]) -> str:
    """The ``--set`` options that give a run ``gains`` (full precision: the run gets exactly these numbers).

    Parameters
    ----------
    gains
        One set (every steered unit), or one per steered towed unit, front to rear.

    Returns
    -------
    str
        ``--set controller.kp=… --set controller.ki=… --set controller.kd=…`` for one set; for more,
        ``--set 'controller.unit_gains=[{kp: …, ki: …, kd: …}, …]'`` (quoted for a POSIX shell).
    """
    sets = _sets(gains)
    if len(sets) == 1:
        return " ".join(f"--set controller.{name}={float(getattr(sets[0], name))!r}" for name in GAIN_UNITS)
    items = ", ".join(
        "{" + ", ".join(f"{name}: {float(getattr(g, name))!r}" for name in GAIN_UNITS) + "}" for g in sets
    )
    return "--set " + shlex.quote(f"controller.unit_gains=[{items}]")


def gains_config(base: ScenarioConfig, gains: PathFollowingGains | Sequence[PathFollowingGains]) -> ScenarioConfig:
    """``base`` with its controller driven by ``gains``.

    Parameters
    ----------
    base
        The scenario the gains are for.
    gains
        One set, or one per steered towed unit front to rear [rad/m, rad/m², rad].

    Returns
    -------
    ScenarioConfig
        Validated; its ``controller`` section holds ``kp``, ``ki`` and ``kd`` (one set) or ``unit_gains``.
    """
    data = base.model_dump(mode="json")
    data["controller"].update(_controller_fields(gains))
    return validate_config(data)


def trials_frame(result: TuningResult | list[dict[str, Any]]) -> pd.DataFrame:
    """One row per trial: ``trial``, the gains with their units in the column names, ``train_cost``, ``state``
    (of a result, or of its :attr:`~scenarios.envs.tuning.TuningResult.trial_rows` alone)."""
    trial_rows = result if isinstance(result, list) else result.trial_rows
    names = [
        k for k in (trial_rows[0] if trial_rows else dict.fromkeys(GAIN_UNITS)) if k.rsplit("_", 1)[-1] in GAIN_UNITS
    ]
    columns = ["trial", *(f"{n} [{GAIN_UNITS[n.rsplit('_', 1)[-1]]}]" for n in names), "train_cost", "state"]
    rows = [
        [r["trial"], *(r[n] for n in names), r["train_cost"], r["state"]]
        for r in trial_rows  # a result made without them (an older one) gives an empty table
    ]
    return pd.DataFrame(rows, columns=columns)


def write_trials(trial_rows: list[dict[str, Any]], out_dir: Path) -> Path:
    """Write the trials of a stopped tuning (``trials.csv`` alone) into ``out_dir``; return its path."""
    path = Path(out_dir) / TUNING_FILES["trials"]
    write_atomic(path, trials_frame(trial_rows).to_csv(index=False))
    return path


def comparison_frame(result: TuningResult) -> pd.DataFrame:
    """The held-out comparison, a row per condition and gains (designed, tuned), units in the column names."""
    rows = []
    for row in result.held_out:
        for which in ("designed", "tuned"):
            r = row[which]
            rows.append(
                {
                    "condition": row["condition"],
                    "gains": which,
                    "rms_offtracking [m]": r["rms_offtracking"],
                    "max_offtracking [m]": r["max_offtracking"],
                    **{
                        f"{key} [m]": value
                        for key, value in r.items()
                        if key.startswith("unit") and key.endswith("_offtracking")
                    },
                    "saturated_fraction": r["saturated_fraction"],
                    "cost": r["cost"],
                    "status": r["status"],
                }
            )
    return pd.DataFrame(rows)


def write_tuning(result: TuningResult, out_dir: Path, base: ScenarioConfig) -> dict[str, Path]:
    """Write the trials, the comparison and the tuned gains into ``out_dir``.

    Parameters
    ----------
    result
        What :func:`scenarios.envs.tuning.tune_gains` found.
    out_dir
        An existing directory.
    base
        The scenario the gains were tuned on: ``tuned_gains.yaml`` is this scenario with the tuned gains.

    Returns
    -------
    dict of str to Path
        The files written, by the keys of :data:`TUNING_FILES`.
    """
    paths = {key: Path(out_dir) / name for key, name in TUNING_FILES.items()}
    write_atomic(paths["trials"], trials_frame(result).to_csv(index=False))
    write_atomic(paths["comparison"], comparison_frame(result).to_csv(index=False))
    write_atomic(paths["comparison_md"], result.table() + "\n")
    units = ", ".join(str(u) for u in result.units)
    header = (
        f"# Scenario {base.name} with the gains offtrack tune found for steered unit(s) {units} (controller.kp "
        "[rad/m], ki [rad/m²], kd [rad]; unit_gains: one set per steered unit, front to rear).\n"
        f"# From the held-out roads, {result.advice()[-1]}\n"
        f"# Run it with: offtrack run {paths['gains']}\n"
        f"# Or give another scenario of this vehicle these gains with: {set_options(result.tuned)}\n"
    )
    write_atomic(paths["gains"], header + config_yaml(gains_config(base, result.tuned)))
    return paths


def gains_table(result: TuningResult) -> Table:
    """The designed and the tuned gains with their units, as a rich table."""
    view = Table(title="gains (per metre travelled)")
    view.add_column("gain")
    view.add_column("unit")
    view.add_column("designed (exact)", justify="right")
    view.add_column("tuned", justify="right")
    for vehicle_unit, designed, tuned in zip(result.units, result.designed, result.tuned, strict=True):
        for name, unit in GAIN_UNITS.items():
            view.add_row(
                f"unit {vehicle_unit} {name}",
                unit,
                repr(float(getattr(designed, name))),
                number(getattr(tuned, name), ".4f"),
            )
    view.add_row("training cost", "", number(result.train_cost_designed, ".5f"), number(result.train_cost_tuned, ".5f"))
    return view


def held_out_table(result: TuningResult) -> Table:
    """The held-out comparison as a rich table whose condition column wraps, so that it fits the terminal.

    The status column is shown only when a run did not complete.
    """
    statuses = [str(row[which]["status"]) for row in result.held_out for which in ("designed", "tuned")]
    with_status = any(status != "completed" for status in statuses)
    view = Table(title="held-out conditions (outside the training ranges)")
    view.add_column("condition", min_width=10)
    view.add_column("gains", no_wrap=True)
    further = result.further_units()
    headers = ["e_tr RMS\n[mm]", "e_tr max\n[mm]", *(f"unit {k}\nRMS\n[mm]" for k in further)]
    for header in (*headers, "satu-\nrated\n[%]", "cost"):
        view.add_column(escape(header), justify="right")
    if with_status:
        view.add_column("status")
    for row in result.held_out:
        for which in ("designed", "tuned"):
            r: dict[str, Any] = row[which]
            cells = [
                escape(row["condition"]) if which == "designed" else "",
                which,
                _scaled(r["rms_offtracking"], 1e3, ".1f"),
                _scaled(r["max_offtracking"], 1e3, ".1f"),
                *(_scaled(r.get(f"unit{k}_rms_offtracking"), 1e3, ".1f") for k in further),
                _scaled(r["saturated_fraction"], 1e2, ".0f"),
                number(r["cost"], ".4f"),
            ]
            view.add_row(*cells, *([escape(str(r["status"]))] if with_status else []))
        view.add_section()
    return view


def _scaled(value: Any, factor: float, spec: str) -> str:
    """``value·factor`` formatted, or :data:`~scenarios.run.summary.MISSING`."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return MISSING
    return number(value * factor, spec)
