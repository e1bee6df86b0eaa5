"""A case and its record: the picklable case spec and the JSON file each ended case leaves in ``OUT/cases/``.

Standard library only: a spawned sweep worker imports this before its thread limits are set.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..loop.ends import RunStatus
from ..run.files import jsonable
from ..run.json_output import strict_json

CASES_DIR = "cases"
"""Subdirectory of a sweep's output directory holding one JSON file per finished case."""


@dataclass(frozen=True)
class CaseSpec:
    """One case: a catalogue scenario, dotted overrides and labels for the table."""

    study: str
    scenario: str
    overrides: tuple[tuple[str, Any], ...]
    labels: tuple[tuple[str, Any], ...] = field(default_factory=tuple)

    @property
    def name(self) -> str:
        return "_".join(f"{k}-{v}" for k, v in self.labels).replace(" ", "").replace("/", "-")


@dataclass(frozen=True)
class CaseRecord:
    """What one case left in ``cases/<name>.json``.

    Attributes
    ----------
    name : str
        The case name (its file name without ``.json``).
    index : int
        Position of the case in the sweep (the table keeps this order).
    status : str
        ``done`` (the run function returned a row) or ``failed`` (it raised, its worker died, or the row it returned
        says its run failed).
    row : dict or None
        The table row (JSON types; NaN stored as null); None if the case raised or its worker died.
    error : dict or None
        ``type``, ``message`` and ``traceback`` of a failure.
    spec : dict
        The case spec (study, scenario, overrides, labels).
    fingerprint : str
        Hash of ``spec``: a finished case is skipped on resume only while its spec is unchanged.
    session : str
        Identifier of the sweep invocation that ran the case.
    wall_s : float
        Wall-clock time of the case in its worker [s].
    worker : dict
        ``host`` and ``pid`` of the process that ran it.
    finished_at : str
        ISO time stamp (UTC).
    """

    name: str
    index: int
    status: str
    row: dict[str, Any] | None
    error: dict[str, str] | None
    spec: dict[str, Any]
    fingerprint: str
    session: str
    wall_s: float
    worker: dict[str, Any]
    finished_at: str

    @property
    def ok(self) -> bool:
        """True if the case finished with a row."""
        return self.status == "done"

    def to_json(self) -> str:
        """The record as strict JSON (non-finite floats as null)."""
        return strict_json(dataclasses.asdict(self), indent=1)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> CaseRecord:
        """Rebuild a record from its JSON object."""
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in data.items() if k in names})

    def table_row(self) -> dict[str, Any]:
        """The row this case contributes to the table (if it failed: its labels or the row its run left, ``status``
        ``failed`` and ``error``)."""
        if self.ok and self.row is not None:
            return dict(self.row)
        error = self.error or {}
        row: dict[str, Any] = {k: v for k, v in self.spec.get("labels", [])}
        row.update({k: v for k, v in (self.row or {}).items() if k != "message"})
        row["status"] = RunStatus.FAILED
        row["error"] = f"{error.get('type', 'Error')}: {error.get('message', '')}".strip()
        return row


def case_path(out_dir: Path, name: str) -> Path:
    """The file of case ``name`` in the sweep directory ``out_dir``."""
    return Path(out_dir) / CASES_DIR / f"{name}.json"


def marker_path(out_dir: Path, name: str) -> Path:
    """The marker a worker leaves while it runs case ``name`` (who and since when; removed when the case ends)."""
    return Path(out_dir) / CASES_DIR / f".{name}.running"


def read_record(out_dir: Path, name: str) -> CaseRecord | None:
    """The record of case ``name``, or None if it has none (or an unreadable one)."""
    try:
        return CaseRecord.from_dict(json.loads(case_path(out_dir, name).read_text()))
    except (OSError, ValueError, TypeError):
        return None


def spec_dict(spec: CaseSpec) -> dict[str, Any]:
    """A case spec as a JSON object."""
    return jsonable(
        {
            "study": spec.study,
            "scenario": spec.scenario,
            "overrides": [list(kv) for kv in spec.overrides],
            "labels": [list(kv) for kv in spec.labels],
        }
    )


def fingerprint(spec: CaseSpec) -> str:
    """A short hash of the spec: a case is only skipped on resume while its spec is unchanged."""
    text = json.dumps(spec_dict(spec), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]
