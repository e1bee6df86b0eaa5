"""``offtrack estimate --rigs RIGS.yaml``: a recording with one stereo rig per towed unit, each unit estimated.

A combination that tows more than one unit carries a rig on each (docs/real_cameras.md): a side camera on a unit that
tows another (its rear view is the unit behind), a rear camera on the last. Each rig is recorded on its own — a
KITTI folder, a bag with its topics, or a video pair — and all of them on one clock (the vehicle's, as a logger
stamps every camera), so their frames are synchronised by their timestamps. The rigs file names the combination once
and lists the rigs; paths are relative to the file (YAML; degrees at this edge, metres)::

    vehicle: b-double.yaml          # a preset, a combination file or the combination, shared by every rig
    rigs:
      - unit: 1                     # the towed unit carrying the rig (1 the first, 2 the one it tows, …)
        recording: lead/            # KITTI folder, bag or left video, as offtrack estimate's RECORDING
        psi_c2v_deg: 90             # the rig file's fields (scenarios.recorded.rig), in the unit's own axes
        lever_arm_m: [-3.0, 1.3, 2.5]
        signals: lead.csv           # optional: the unit's signals (sensor.recordings.signals)
      - unit: 2
        recording: rear/
        psi_c2v_deg: 180
        lever_arm_m: [-14.1, 0.0, 3.0]

Each entry may also carry ``calibration``, ``calib``, ``right_video``, ``times``, ``left_topic``, ``right_topic``,
``pair_tolerance_s``, ``reference`` and ``reference_offtracking`` as ``offtrack estimate`` takes them. The rigs
are synchronised when their recordings overlap on the shared clock: frames of every rig inside one span of time;
rigs that share no instant are refused before any image is decoded, naming both spans.

:func:`estimate_rigs` runs :func:`.estimate.estimate_recording` on each rig — VISO-OT of its own unit
(:class:`sensor.viso_ot.VisoOtEstimator` with the unit's front coupling and follow point) and, with the rig's
signals, the unit's fused estimate (the first towed unit's also Cheng's zero-slip estimate; a unit behind it
:mod:`.unit_fusion`; a side rig's taking the rear rig of a unit behind as its reference, :mod:`.following`) —
each into ``unitK/`` (``K`` the vehicle unit, 2 the first towed unit, as a run's ``metrics.json`` numbers them), a
recorded run of its own that ``offtrack report`` and ``offtrack animate`` take. The directory's ``metrics.json``
holds each unit's off-tracking metrics and the synchronisation: the span every rig covers and each rig's first and
last frame on the clock.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from vehicle_model.errors import InputError

from ..config import FusionConfig
from ..loop.ends import RunStatus
from ..run.results import write_metrics
from ..yaml_input import MAX_BYTES, load_yaml
from .estimate import Progress, estimate_recording
from .following import FollowerTrace
from .inputs import EstimateInputs, resolve_inputs
from .rig import rig_from_fields

__all__ = ["RIG_INPUT_FIELDS", "RigsInputs", "estimate_rigs", "load_rigs"]

RIG_INPUT_FIELDS = {
    "recording": "recording",
    "calibration": "calibration",
    "calib": "calib",
    "right_video": "right_video",
    "times": "times",
    "signals": "signals",
    "reference": "reference",
    "reference_offtracking": "reference_offtracking",
}
"""A rig entry's file fields and the :func:`.inputs.resolve_inputs` argument each is (paths, relative to the file)."""
_TEXT_FIELDS = {"left_topic": "left_topic", "right_topic": "right_topic", "pair_tolerance_s": "pair_tolerance"}


@dataclass
class RigsInputs:
    """The rigs of a recording, each checked, in the order of the file.

    Attributes
    ----------
    source : str
        The rigs file.
    units : list of EstimateInputs
        Each rig's inputs (:class:`.inputs.EstimateInputs`; its ``rig.unit`` the towed unit carrying it).
    span : (float, float)
        The span of time every rig's recording covers, on the shared clock [s].
    """

    source: str
    units: list[EstimateInputs]
    span: tuple[float, float]


def _entry_inputs(
    entry: Any, index: int, vehicle: Any, folder: Path, source: str, options: dict[str, Any]
) -> EstimateInputs:
    """One rig entry's inputs, checked (paths relative to ``folder``)."""
    where = f"{source}: rigs[{index}]"
    if not isinstance(entry, dict):
        raise InputError(f"{where}: not a mapping; allowed: unit, recording, psi_c2v_deg, lever_arm_m, …")
    entry = dict(entry)
    if "vehicle" in entry:
        raise InputError(f"{where}: vehicle: named once for every rig, at the file's top level")
    paths = {arg: entry.pop(key) for key, arg in RIG_INPUT_FIELDS.items() if key in entry}
    texts = {arg: entry.pop(key) for key, arg in _TEXT_FIELDS.items() if key in entry}
    if "recording" not in paths:
        raise InputError(f"{where}: recording: missing; allowed: a KITTI folder, a bag or a left video")
    for arg, value in paths.items():
        if not isinstance(value, str) or not value:
            raise InputError(f"{where}: {arg}: {value!r}; allowed: a path (relative to the rigs file)")
    rig = rig_from_fields({"vehicle": vehicle, **entry}, where)
    resolved = {arg: (folder / value) for arg, value in paths.items()}
    return resolve_inputs(resolved.pop("recording"), rig=rig, **resolved, **texts, **options)


def _span(units: list[EstimateInputs], source: str) -> tuple[float, float]:
    """The span every rig's frames cover on the shared clock (module notes); refused when it is empty."""
    spans = [
        (u.recording.t0 + float(u.recording.times[0]), u.recording.t0 + float(u.recording.times[-1])) for u in units
    ]
    start, end = max(s for s, _ in spans), min(e for _, e in spans)
    if not start <= end:
        first = int(np.argmax([s for s, _ in spans]))
        last = int(np.argmin([e for _, e in spans]))
        raise InputError(
            f"{source}: rigs[{first}] starts at {spans[first][0]:.6g} s after rigs[{last}] ends at "
            f"{spans[last][1]:.6g} s; allowed: recordings on one clock sharing a span of time (synchronised rigs)"
        )
    return start, end


def load_rigs(path: Path, **options: Any) -> RigsInputs:
    """Read and check a rigs file (module notes); ``options`` go to every rig's :func:`.inputs.resolve_inputs`
    (``refinement``, ``seed``, ``rear_point``, ``zero_slip_grade``, ``use_folder_poses``).

    Raises
    ------
    InputError
        The file is missing or not YAML within bounds; no rig, a unit twice, an entry's field unknown or out of
        range, a recording or file not usable, or rigs that share no span of time — one line naming the field.
    """
    path = Path(path)
    source = f"--rigs {path}"
    if not path.is_file():
        raise InputError(f"{source}: not found; allowed: a rigs YAML file (vehicle, rigs: a list of rigs)")
    raw = path.read_bytes()
    if len(raw) > MAX_BYTES:
        raise InputError(f"{source}: {len(raw)} bytes; allowed: at most {MAX_BYTES}")
    data = load_yaml(raw, f"rigs file {path}")
    if not isinstance(data, dict) or set(data) - {"vehicle", "rigs"}:
        extra = sorted(set(data) - {"vehicle", "rigs"}) if isinstance(data, dict) else []
        raise InputError(f"{source}: {', '.join(extra) or 'not a mapping'}; allowed: vehicle and rigs")
    rigs = data.get("rigs")
    if not isinstance(rigs, list) or not rigs:
        raise InputError(f"{source}: rigs: {rigs!r}; allowed: a list of one rig or more, each with its unit")
    units = [entry.get("unit", 1) if isinstance(entry, dict) else None for entry in rigs]
    twice = sorted({u for u in units if isinstance(u, int) and units.count(u) > 1})
    if twice:
        raise InputError(f"{source}: rigs: unit {twice[0]} given twice; allowed: one rig per towed unit")
    vehicle = data.get("vehicle", "reference")
    if isinstance(vehicle, str) and vehicle.endswith((".yaml", ".yml")) and not Path(vehicle).is_absolute():
        vehicle = str(path.parent / vehicle)
    inputs = [_entry_inputs(entry, i, vehicle, path.parent, source, options) for i, entry in enumerate(rigs)]
    return RigsInputs(str(path), inputs, _span(inputs, source))


def unit_dir_name(towed_unit: int) -> str:
    """The sub-directory of the rig on towed unit ``towed_unit``: ``unitK``, ``K`` its vehicle unit (2 the first)."""
    return f"unit{towed_unit + 1}"


def estimate_rigs(
    rigs: RigsInputs,
    run_dir: Path,
    *,
    plots: bool = True,
    progress: Progress | None = None,
    fusion: FusionConfig | None = None,
) -> dict[str, Any]:
    """Estimate every rig's unit into ``run_dir/unitK`` and write ``run_dir/metrics.json`` (module notes); return it.

    The rearmost unit first: a unit's frames and fused filter are kept (:class:`.following.FollowerTrace`) for the
    units ahead of it, whose side rig's filter takes them as a run's does (:mod:`.following`). ``progress(frames
    done, frames in all)`` counts the frames of every rig, in that order; ``fusion``: the fused filters' settings
    (a run's ``fusion``; default a run's defaults).
    """
    run_dir = Path(run_dir)
    total = sum(len(u.recording.times) for u in rigs.units)
    done = 0
    units: dict[str, Any] = {}
    clock: list[dict[str, Any]] = []
    status, message = RunStatus.COMPLETED, f"every rig's recording was processed to its end ({len(rigs.units)} rigs)"
    traces: dict[int, FollowerTrace] = {}
    for inputs in sorted(rigs.units, key=lambda u: -u.rig.unit):
        unit_dir = run_dir / unit_dir_name(inputs.rig.unit)
        unit_dir.mkdir(parents=True, exist_ok=False)

        def counted(frames: int, _: int, before: int = done) -> None:
            if progress is not None:
                progress(before + frames, total)

        trace = FollowerTrace(inputs)
        metrics = estimate_recording(
            inputs, unit_dir, plots=plots, progress=counted, fusion=fusion, followers=dict(traces), trace=trace
        )
        traces[inputs.rig.unit] = trace
        done += len(inputs.recording.times)
        key = str(inputs.rig.unit + 1)
        units[key] = {
            "run": unit_dir.name,
            "rig_unit": inputs.rig.unit,
            "status": metrics.get("status"),
            "offtracking": metrics.get("offtracking"),
            "camera": metrics.get("camera"),
            "verdict": metrics.get("verdict"),
        }
        times = inputs.recording.t0 + inputs.recording.times
        clock.append(
            {"unit": int(key), "frames": len(times), "first_frame_s": float(times[0]), "last_frame_s": float(times[-1])}
        )
        if metrics.get("status") != RunStatus.COMPLETED and status == RunStatus.COMPLETED:
            status, message = metrics.get("status", RunStatus.FAILED), f"{unit_dir.name}: {metrics.get('message')}"
    order = [u.rig.unit + 1 for u in rigs.units]  # the file's order
    units = {key: units[key] for key in sorted(units, key=lambda k: order.index(int(k)))}
    clock.sort(key=lambda entry: order.index(entry["unit"]))
    summary = {
        "scenario": f"recording rigs {Path(rigs.source).name}",
        "status": status,
        "message": message,
        "units": units,
        "synchronisation": {"span_s": list(rigs.span), "rigs": clock},
    }
    write_metrics(run_dir, summary)
    return summary


def rigs_lines(summary: dict[str, Any]) -> list[str]:
    """One line per unit of :func:`estimate_rigs`' summary: its VISO-OT error against the reference, if any."""
    lines = []
    for key, unit in summary["units"].items():
        estimators = ((unit.get("offtracking") or {}).get("estimators")) or {}
        errors = ", ".join(
            f"{name} {values['rms_error']:.3f} m RMS error"
            for name, values in estimators.items()
            if isinstance(values, dict) and values.get("rms_error") is not None
        )
        lines.append(f"unit {key} ({unit['run']}/): {unit['status']}" + (f"; {errors}" if errors else ""))
    span = summary["synchronisation"]["span_s"]
    lines.append(f"rigs synchronised over {span[0]:.3f}–{span[1]:.3f} s of the shared clock")
    return lines
