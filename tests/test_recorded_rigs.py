"""``offtrack estimate --rigs``: a B-double recorded with one stereo rig per towed unit, each unit estimated.

A short B-double drive into a 30 m roundabout (25 km/h, 3 s, unsteered) is exported twice with ``export_kitti``:
a left-looking side rig on the lead trailer (the trailer behind it and the tractor drawn in the scene) and a rear
rig on the rear trailer, small images (672 × 196 px), each with a signals file of its unit written from the
simulation (the rear one: the tractor's, both articulations, the rear trailer's gyro and wheel speed).
``offtrack estimate --rigs`` on the two folders gives each unit's VISO-OT and fused series; each is checked against
the simulation's own true off-tracking of that unit (the run's ``offtracking_truth`` and ``offtracking_truth3``, not
the recording's reference), so a rig put on the wrong unit, the wrong coupling or the wrong follow point would fail.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from scenarios.cli import app
from scenarios.config import FusionConfig, load_scenario
from scenarios.export.kitti import export_kitti
from scenarios.loop.trailer_steer import UnsteeredTrailer, trailer_axles
from scenarios.recorded.estimate import estimate_recording
from scenarios.recorded.rigs import estimate_rigs, load_rigs
from scenarios.run.drive import simulate
from scenarios.setup.build import build_scenario
from sensor.camera import StereoRig
from vehicle_model.geometry import ChainPose, unit_frame

pytestmark = pytest.mark.rendering

B_DOUBLE = Path(__file__).parent / "data" / "combinations" / "b-double.yaml"
OVERRIDES = {
    "path.radius": 30.0,
    "path.entry_length": 1.0,
    "speed.cornering_kmh": 25.0,
    "camera.latency_s": 0.0,
    "duration_s": 3.0,
    "feedback": "none",
}
SIDE = {"unit": 1, "recording": "lead", "psi_c2v_deg": 270.0, "lever_arm_m": [-4.0, 1.3, 2.5]}


def _vehicle() -> dict:
    return {"name": "b-double", **yaml.safe_load(B_DOUBLE.read_text(encoding="utf-8"))}


def _rigs_file(folder: Path, rigs: list[dict], name: str = "rigs.yaml") -> Path:
    path = folder / name
    path.write_text(yaml.safe_dump({"vehicle": _vehicle(), "rigs": rigs}), encoding="utf-8")
    return path


def _signals(path: Path, cols: dict, params: object, unit: int) -> None:
    """The signals beside the rig on towed unit ``unit``, from the simulation's columns (times on the frames' clock:
    the first camera frame at 0 s)."""
    t = np.asarray(cols["time"]) - float(np.asarray(cols["time"])[np.argmax(np.asarray(cols["camera_frame"]) > 0.5)])
    table = {"time_s": t, "speed_m_s": cols["u"], "yaw_rate_rad_s": cols["r1"], "articulation_rad": cols["gamma"]}
    if unit == 2:
        pose = ChainPose(*(np.asarray(cols[k]) for k in ("X", "Y", "psi1")), (cols["gamma"], cols["gamma2"]))
        coupling, heading = unit_frame(params, pose, 2)
        velocity = np.gradient(coupling, t, axis=0)  # the unit's longitudinal speed: that of any point on its axis
        table["articulation2_rad"] = cols["gamma2"]
        table["trailer_yaw_rate_rad_s"] = cols["r3"]
        table["trailer_speed_m_s"] = velocity[:, 0] * np.cos(heading) + velocity[:, 1] * np.sin(heading)
    pd.DataFrame({k: np.asarray(v, dtype=float) for k, v in table.items()}).to_csv(path, index=False)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> SimpleNamespace:
    """The two rigs' KITTI folders, the rigs file, the estimate's directory and the simulation's columns."""
    tmp = tmp_path_factory.mktemp("rigs")
    config = load_scenario("roundabout-3", {"vehicle": _vehicle(), **OVERRIDES})
    params = config.vehicle_params()
    size = {"width": 672, "height": 196}
    side = StereoRig(**size, station=-4.0, lateral=1.3, mount_height=2.5, psi_c2v=math.radians(270.0), unit=1)
    rear = StereoRig(**size, station=None, mount_height=3.0, psi_c2v=math.pi, unit=2)
    export_kitti(config, tmp / "lead", rig=side)  # the two exports' world built once (world_for_scenario keeps it)
    export_kitti(config, tmp / "rear", rig=rear)
    setup = build_scenario(config)
    outcome, cols = simulate(setup, UnsteeredTrailer(trailer_axles(setup)))
    assert outcome.status == "completed"
    frames = np.flatnonzero(np.asarray(cols["camera_frame"]) > 0.5)
    _signals(tmp / "lead.csv", cols, params, unit=1)
    _signals(tmp / "rear.csv", cols, params, unit=2)
    rear_arm = [float(params.trailers[1].rear_x), 0.0, 3.0]
    rear_rig = {"unit": 2, "recording": "rear", "psi_c2v_deg": 180.0, "lever_arm_m": rear_arm, "signals": "rear.csv"}
    rigs = _rigs_file(tmp, [{**SIDE, "signals": "lead.csv"}, rear_rig])
    out = tmp / "estimate"
    result = CliRunner().invoke(app, ["estimate", "--rigs", str(rigs), "--out", str(out), "--no-plots"])
    assert result.exit_code == 0, result.output
    return SimpleNamespace(tmp=tmp, out=out, output=result.output, cols=cols, frames=frames, rigs=rigs)


@pytest.mark.parametrize(("unit", "truth"), [(2, "offtracking_truth"), (3, "offtracking_truth3")])
def test_each_units_camera_estimate_follows_that_units_true_offtracking(
    recorded: SimpleNamespace, unit: int, truth: str
) -> None:
    series = pd.read_parquet(recorded.out / f"unit{unit}" / "timeseries.parquet")
    series = series[series["camera_frame"] > 0.5]  # the frames' rows (the signals add rows between them)
    true = np.asarray(recorded.cols[truth])[recorded.frames]
    assert len(series) == len(true)
    # the reference from the rig's exported camera poses is the simulation's own truth of that unit (within 3 mm)
    reference = series["offtracking_truth"].to_numpy()
    assert np.isfinite(reference).sum() >= 10 and np.nanmax(np.abs(reference - true)) < 3e-3
    estimate = series["offtracking_viso_ot"].to_numpy()
    error = (estimate - true)[np.isfinite(estimate) & np.isfinite(true)]
    assert error.size >= 10
    # the targets on small images: ≤ 0.10 m RMS, ≤ 0.15 m max (measured 0.05 / 0.09 m)
    assert float(np.sqrt(np.mean(error**2))) <= 0.10 and float(np.max(np.abs(error))) <= 0.15
    assert abs(float(np.nanmax(np.abs(true)))) > 0.05  # the unit off-tracks: the check is not of zeros
    fused = series["offtracking_viso_ot_fused"].to_numpy()
    std = series["offtracking_viso_ot_fused_std"].to_numpy()
    ok = np.isfinite(fused) & np.isfinite(true)
    assert ok.sum() >= 10
    # the unit's own fused filter on its signals: within the same targets, and its std a finite positive number
    assert float(np.sqrt(np.mean((fused - true)[ok] ** 2))) <= 0.10 and float(np.max(np.abs(fused - true)[ok])) <= 0.15
    assert np.all(std[ok] > 0.0)


def test_the_directory_holds_every_units_metrics_and_the_synchronisation(recorded: SimpleNamespace) -> None:
    summary = json.loads((recorded.out / "metrics.json").read_text())
    assert summary["status"] == "completed" and set(summary["units"]) == {"2", "3"}
    for key, unit in summary["units"].items():
        assert unit["run"] == f"unit{key}" and unit["rig_unit"] == int(key) - 1
        assert unit["offtracking"]["estimators"]["viso_ot"]["rms_error"] <= 0.10
        own = json.loads((recorded.out / unit["run"] / "metrics.json").read_text())
        assert own["offtracking"] == unit["offtracking"]
    assert summary["synchronisation"]["span_s"] == pytest.approx([0.0, 3.0])
    assert "unit 3 (unit3/): completed" in recorded.output
    record = yaml.safe_load((recorded.out / "unit3" / "recording.yaml").read_text())
    assert record["rig_file"]["unit"] == 2 and record["rig"] is None


def test_the_side_rigs_filter_takes_the_rear_rig_as_its_reference_as_a_run_does(
    recorded: SimpleNamespace, tmp_path: Path
) -> None:
    """The lead trailer's side rig takes the rear trailer's rear rig through the couplings (a run's
    ``fusion.side_rig.coupling_reference``, on by default): the rear rig's frames meet the lead's on every frame and
    the filter uses their measurements; with the setting off, the same recording gives a different estimate."""
    lead = json.loads((recorded.out / "unit2" / "metrics.json").read_text())["coupling_reference"]
    assert lead["follower_unit"] == 2 and lead["frames_matched"] == len(recorded.frames)
    assert lead["measurements"] >= len(recorded.frames) - 2 and lead["updates"] > len(recorded.frames) // 2
    assert "coupling_reference" not in json.loads((recorded.out / "unit3" / "metrics.json").read_text())  # a rear rig
    rigs = load_rigs(recorded.rigs)
    side = next(inputs for inputs in rigs.units if inputs.rig.unit == 1)
    off = FusionConfig(side_rig={"coupling_reference": False})
    metrics = estimate_recording(side, tmp_path, plots=False, fusion=off)  # the lead alone, its own filter
    assert "coupling_reference" not in metrics
    with_reference = pd.read_parquet(recorded.out / "unit2" / "timeseries.parquet")["offtracking_viso_ot_fused"]
    alone = pd.read_parquet(tmp_path / "timeseries.parquet")["offtracking_viso_ot_fused"]
    both = np.isfinite(with_reference) & np.isfinite(alone)
    assert both.sum() >= 10
    # the reference moves the estimate (by more than 1 mm somewhere): it is not ignored
    assert float(np.max(np.abs(with_reference[both] - alone[both]))) > 1e-3


def test_a_missing_rear_rig_frame_leaves_the_side_rig_its_own_frames_there(
    recorded: SimpleNamespace, tmp_path: Path
) -> None:
    """A frame of the rear rig not recorded: the lead takes no reference over it nor over the frame after it (which
    spans the gap, so it does not start at the lead's anchor), and every other frame's as before."""
    for name in ("lead", "rear", "lead.csv", "rear.csv", "rigs.yaml"):
        copy = shutil.copytree if (recorded.tmp / name).is_dir() else shutil.copy
        copy(recorded.tmp / name, tmp_path / name)
    for sub in ("image_0", "image_1"):
        (tmp_path / "rear" / sub / "000015.png").unlink()
    summary = estimate_rigs(load_rigs(tmp_path / "rigs.yaml"), tmp_path / "out", plots=False)
    assert summary["status"] == "completed"
    full = json.loads((recorded.out / "unit2" / "metrics.json").read_text())["coupling_reference"]
    gap = json.loads((tmp_path / "out" / "unit2" / "metrics.json").read_text())["coupling_reference"]
    assert gap["frames_matched"] == full["frames_matched"] - 1 and gap["measurements"] == full["measurements"] - 1
    # the frame after the gap is measured but not at the lead's anchor: the filter takes neither, refusing none
    assert gap["updates"] + gap["rejected"] == full["updates"] + full["rejected"] - 2


def _refused(*args: str) -> str:
    result = CliRunner().invoke(app, ["estimate", *args])
    assert result.exit_code == 2, result.output
    return result.output


def test_rigs_that_share_no_instant_are_refused_before_any_work(recorded: SimpleNamespace, tmp_path: Path) -> None:
    late = tmp_path / "late"
    shutil.copytree(recorded.tmp / "rear", late)
    times = np.loadtxt(late / "times.txt") + 100.0  # the rear rig's clock 100 s on: no frame beside the lead's
    (late / "times.txt").write_text("".join(f"{t:.6f}\n" for t in times))
    shutil.copytree(recorded.tmp / "lead", tmp_path / "lead")
    arm = [-11.0, 0.0, 3.0]
    rigs = _rigs_file(tmp_path, [SIDE, {"unit": 2, "recording": "late", "psi_c2v_deg": 180.0, "lever_arm_m": arm}])
    output = _refused("--rigs", str(rigs), "--out", str(tmp_path / "out"))
    assert "synchronised" in output and not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("rigs", "says"),
    [
        ([SIDE, SIDE], "unit 1 given twice"),
        ([{**SIDE, "unit": 3}], "unit = 3"),
        ([{**SIDE, "unit": 2, "signals": "signals.csv"}], "signals"),
        ([{**SIDE, "vehicle": "lst"}], "vehicle"),
        ([{**SIDE, "unit": [1]}], "unit"),
        ([], "rigs"),
    ],
)
def test_a_rigs_file_that_cannot_work_is_refused_naming_the_field(
    recorded: SimpleNamespace, tmp_path: Path, rigs: list[dict], says: str
) -> None:
    shutil.copytree(recorded.tmp / "lead", tmp_path / "lead")
    (tmp_path / "signals.csv").write_text("time_s,speed_m_s,yaw_rate_deg_s,articulation_deg\n0,7,0,0\n3,7,0,0\n")
    if rigs and rigs[0].get("unit") == 2:
        rigs = [{**rigs[0], "lever_arm_m": [-10.0, 1.3, 2.5]}]
    output = _refused("--rigs", str(_rigs_file(tmp_path, rigs)), "--out", str(tmp_path / "out"))
    assert says in output


def test_rigs_and_a_recording_are_refused_together(recorded: SimpleNamespace) -> None:
    assert "not with --rigs" in _refused(str(recorded.tmp / "lead"), "--rigs", str(recorded.rigs))


def test_a_longer_combinations_export_draws_the_other_units(tmp_path: Path) -> None:
    """A forward-looking rig on the rear trailer, 1.5 m behind the lead trailer's rear: its exported image is that
    trailer's body where the same camera poses rendered without the units see the road and the scenery."""
    import cv2

    from scenarios.camera.build import lighting_from_config, stereo_camera
    from scenarios.export.kitti import combination_poses

    config = load_scenario("roundabout-3", {"vehicle": _vehicle(), **OVERRIDES, "duration_s": 0.5})
    rig = StereoRig(width=96, height=48, station=-3.0, mount_height=2.0, psi_c2v=0.0, unit=2)
    export_kitti(config, tmp_path / "k", rig=rig, max_frames=1)
    drawn = cv2.imread(str(tmp_path / "k" / "image_0" / "000000.png"), cv2.IMREAD_GRAYSCALE).astype(float)
    setup = build_scenario(config)
    _, cols = simulate(setup, UnsteeredTrailer(trailer_axles(setup)))
    pose = combination_poses(setup.params, cols, np.flatnonzero(np.asarray(cols["camera_frame"]) > 0.5)[:1])
    left, right = (rig.camera_in_world(setup.params, pose, which)[0] for which in ("left", "right"))
    camera = stereo_camera(setup, ideal=True, rig=rig, lighting=lighting_from_config(config))
    bare, _ = camera.develop(camera.render_poses(left, right, 0), 0)
    centre = (slice(12, 36), slice(24, 72))
    difference = np.abs(drawn - bare.astype(float))
    assert np.mean(difference[centre]) > 10.0, np.mean(difference[centre])  # grey levels: another picture there
    assert np.median(difference[:, :8]) < 1.0  # and the same road and sky at the image's edge
