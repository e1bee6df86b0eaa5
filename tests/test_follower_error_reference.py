"""The follower's own error in a following unit's reference while its tyres scrub, (C3) of sensor/fusion_coupling.py
(``fusion.side_rig.coupling_follower_limit``).

On a hand-made frame: below the setting's demand (or without it) the covariance is (C2)'s to the bit; at or above it
``inflate`` adds exactly the follower's off-tracking variance to the lead's lateral variance and ``refuse`` gives no
measurement, counted under its reason; a bad setting is refused naming the field, before any work (exit 2). The
counts reach ``metrics.json`` beside the lead unit's figures, in the recorded replay's shape; a run without a
reference has no such key.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from pydantic import ValidationError
from typer.testing import CliRunner

from scenarios.cli import app
from scenarios.config import ConfigError, load_scenario
from scenarios.configuration.sections import FusionConfig
from scenarios.loop.estimators import FusedVisoOtEstimator
from scenarios.loop.following_camera import filter_scrub, following_camera, reference_counts
from scenarios.recorded.following import coupling_summary
from scenarios.run.metrics import COUPLING_REFERENCE, coupling_reference_reports, with_coupling_references
from scenarios.run.runner import run_scenario
from sensor.camera import StereoRig
from sensor.fusion_coupling import FOLLOWER_SCRUBBING, FOLLOWER_UNKNOWN, follower_limited
from sensor.fusion_noise import FollowerLimit, FusionNoise, SideRigFusion
from vehicle_model.presets import VEHICLE_PRESETS

R_C = np.array([[4e-6, 1e-7, 2e-7], [1e-7, 9e-6, 3e-7], [2e-7, 3e-7, 1e-6]])  # a (C2) covariance [m², m·rad, rad²]


def _assert_lateral_widened_by(r: np.ndarray, sigma: float) -> None:
    """``r`` is ``R_C`` with ``sigma²`` added to its lateral entry (to 1e-18 m²) and every other entry unchanged."""
    expected = R_C.copy()
    expected[1, 1] += sigma**2
    np.testing.assert_allclose(r, expected, rtol=0.0, atol=1e-18)
    np.testing.assert_array_equal(np.delete(np.delete(r, 1, 0), 1, 1), np.delete(np.delete(R_C, 1, 0), 1, 1))


def test_below_the_demand_or_without_the_setting_the_covariance_is_c2s() -> None:
    """No setting, a demand below the setting's or not known (NaN): ``R_c`` itself, no reason."""
    limit = FollowerLimit(action="inflate", demand=0.5)
    for setting, demand in ((None, 1.0), (limit, 0.49), (limit, math.nan)):
        r, reason = follower_limited(R_C, setting, demand, 0.05)
        assert reason is None
        np.testing.assert_array_equal(r, R_C)


def test_inflate_adds_the_followers_variance_on_the_lateral_axis() -> None:
    """At the demand and above: ``R_c + σ_f²·e_y·e_yᵀ`` exactly (σ_f = 0.05 m adds 2.5e-3 m² to the yy entry only,
    to 1e-18 m²); the input is not changed; a follower without an estimate (σ_f NaN) is refused."""
    limit = FollowerLimit(action="inflate", demand=0.5)
    before = R_C.copy()
    for demand in (0.5, 1.0):
        r, reason = follower_limited(R_C, limit, demand, 0.05)
        assert reason is None
        _assert_lateral_widened_by(r, 0.05)
    np.testing.assert_array_equal(R_C, before)
    assert follower_limited(R_C, limit, 1.0, math.nan) == (None, FOLLOWER_SCRUBBING)


def test_refuse_gives_no_measurement_with_its_reason() -> None:
    """``refuse`` at the demand: no covariance, the reason ``follower scrubbing``; below it the frame is taken."""
    limit = FollowerLimit(action="refuse", demand=0.8)
    assert follower_limited(R_C, limit, 0.8, 0.05) == (None, FOLLOWER_SCRUBBING)
    r, reason = follower_limited(R_C, limit, 0.79, 0.05)
    assert reason is None and r is R_C


def test_below_inflate_widens_every_frame_under_the_demand() -> None:
    """(C3') ``below: inflate``: under the demand ``R_c + σ_f²·e_y·e_yᵀ`` exactly (to 1e-18 m², nothing elsewhere),
    at or above it the action's (refuse); a follower without a std refused under its own reason; a demand not known
    (NaN) taken as (C2) gives it. ``below: take`` is the default."""
    assert FollowerLimit(action="refuse", demand=0.5).below == "take"
    limit = FollowerLimit(action="refuse", demand=0.5, below="inflate")
    for demand in (0.0, 0.3, 0.49):
        r, reason = follower_limited(R_C, limit, demand, 0.05)
        assert reason is None
        _assert_lateral_widened_by(r, 0.05)
    assert follower_limited(R_C, limit, 0.5, 0.05) == (None, FOLLOWER_SCRUBBING)
    assert follower_limited(R_C, limit, 0.2, math.nan) == (None, FOLLOWER_UNKNOWN)
    r, reason = follower_limited(R_C, limit, math.nan, 0.05)
    assert reason is None and r is R_C
    with pytest.raises(ValidationError, match="below"):
        FollowerLimit(action="refuse", demand=0.5, below="drop")


def _following(limit: FollowerLimit | None, demand: float, follower_std: float):
    """A B-double's lead reference from its rear unit's rear camera, with one valid frame released on tick 5 after
    one on tick 0, and a follower filter at ``demand`` and ``follower_std``."""
    params = VEHICLE_PRESETS["au-b-double"]()
    rig = StereoRig.from_degrees(psi_c2v_deg=180.0, lateral=0.0, unit=2)
    camera_in_trailer = rig.camera_in_trailer("left", params)
    motion = np.eye(4)
    motion[2, 3] = -0.5  # the rear camera looks back: moving forward is along −Z_c
    frame = SimpleNamespace(valid=True, vo=SimpleNamespace(camera_motion=motion, covariance=np.eye(6) * 1e-6))
    camera = SimpleNamespace(camera_in_trailer=camera_in_trailer, released=[])
    follower = SimpleNamespace(
        filter=SimpleNamespace(
            frame_scrub_demand=demand, std=follower_std, state=np.zeros(12), covariance=np.eye(12) * 1e-8
        )
    )
    noise = FusionNoise(side_rig=SIDE.replace(coupling_follower_limit=limit)).for_camera((0.0, 1.0))
    following = following_camera(params, 1, {"viso_ot3": camera, "viso_ot_fused3": follower}, noise, "planar")
    measured = {"articulation": np.array([0.1]), "rear_articulation": np.array([0.05])}
    for tick in (0, 5):
        camera.released = [SimpleNamespace(tick=tick, frame=frame)]
        following.observe(tick, measured)
    return following, following.take(5)


SIDE = SideRigFusion(coupling_reference=True)


def test_the_loops_reference_applies_it_frame_by_frame() -> None:
    """In the loop's reference: off, the measurement at a scrubbing follower is (C2)'s; ``inflate`` the same
    increment with σ_f² more lateral variance (to 1e-15 m²); ``refuse`` no measurement and one refusal counted."""
    plain, taken = _following(None, 1.0, 0.04)
    assert taken is not None and plain.refused == {}
    _, inflated = _following(FollowerLimit(action="inflate", demand=0.5), 1.0, 0.04)
    np.testing.assert_array_equal(inflated.increment, taken.increment)
    expected = taken.covariance.copy()
    expected[1, 1] += 0.04**2
    np.testing.assert_allclose(inflated.covariance, expected, rtol=0.0, atol=1e-15)
    _, calm = _following(FollowerLimit(action="refuse", demand=0.5), 0.2, 0.04)
    np.testing.assert_array_equal(calm.covariance, _following(None, 0.2, 0.04)[1].covariance)
    _, widened = _following(FollowerLimit(action="refuse", demand=0.5, below="inflate"), 0.2, 0.04)
    np.testing.assert_allclose(widened.covariance, _following(None, 0.2, 0.04)[1].covariance + np.diag([0, 0.04**2, 0]))
    refusing, none = _following(FollowerLimit(action="refuse", demand=0.5), 1.0, 0.04)
    assert none is None and refusing.refused == {FOLLOWER_SCRUBBING: 1} and refusing.measurements == 0
    assert all(math.isnan(v) for v in filter_scrub(None))


def test_the_setting_is_off_by_default_and_the_references_not_the_filters() -> None:
    """Unset in a run's defaults; not among the settings the filter takes."""
    assert FusionConfig().side_rig.coupling_follower_limit is None
    side = SIDE.replace(coupling_follower_limit=FollowerLimit(action="refuse", demand=0.5))
    assert "coupling_follower_limit" not in side.given()


def test_a_bad_setting_is_refused_naming_the_field(tmp_path: Path) -> None:
    """A demand outside (0, 1] or an unknown action: refused naming the field, by the model, the scenario loader and
    the CLI (exit 2, nothing written)."""
    for bad in (
        {"action": "refuse", "demand": 0.0},
        {"action": "refuse", "demand": 1.5},
        {"action": "drop", "demand": 1},
    ):
        with pytest.raises(ValidationError, match="coupling_follower_limit"):
            FusionConfig(side_rig={"coupling_follower_limit": bad})
    field = "fusion.side_rig.coupling_follower_limit"
    with pytest.raises(ConfigError, match=re.escape(field)):
        load_scenario("roundabout-3", {f"{field}.action": "refuse", f"{field}.demand": 2.0})
    config = load_scenario("roundabout-3", {f"{field}.action": "refuse", f"{field}.demand": 0.5})
    assert config.fusion.side_rig.coupling_follower_limit == FollowerLimit(action="refuse", demand=0.5)
    args = ["run", "roundabout-3", "--out", str(tmp_path / "run")]
    result = CliRunner().invoke(app, [*args, "--set", f"{field}.action=refuse", "--set", f"{field}.demand=2"])
    assert result.exit_code == 2, result.output
    assert field in result.output
    assert not (tmp_path / "run").exists()


def _unit_metrics() -> dict:
    """The part of a B-double run's metrics the counts go beside: the first towed unit's and unit 3's figures."""
    return {"offtracking": {"estimators": {"viso_ot_fused": {"rms_error": 0.1}}, "units": {"3": {"estimators": {}}}}}


def test_the_counts_reach_the_metrics_beside_the_lead_units_figures() -> None:
    """One frame refused at a scrubbing follower: its fused filter reports 0 measurements and 1 refusal under
    ``follower scrubbing``, placed in ``offtracking`` (the first towed unit's) or ``offtracking.units["3"]`` by
    the report's key, kept whole through a rebuilt report, in the recorded replay's shape."""
    refusing, _ = _following(FollowerLimit(action="refuse", demand=0.5), 1.0, 0.04)
    taking, _ = _following(FollowerLimit(action="refuse", demand=0.5), 0.2, 0.04)
    params = VEHICLE_PRESETS["au-b-double"]()
    noise = FusionNoise(side_rig=SIDE).for_camera((0.0, 1.0))
    lead = FusedVisoOtEstimator(params, refusing.camera, noise, 1, refusing)
    expected = {"measurements": 0, "refused": {FOLLOWER_SCRUBBING: 1}}
    assert lead.report() == {COUPLING_REFERENCE: expected}
    assert reference_counts(taking) == {"measurements": 1, "refused": {}}
    metrics = with_coupling_references(_unit_metrics(), {"viso_ot_fused": lead.report(), "viso_ot": {"render": 1.0}})
    assert metrics["offtracking"][COUPLING_REFERENCE] == expected
    assert COUPLING_REFERENCE not in metrics["offtracking"]["units"]["3"]
    assert COUPLING_REFERENCE not in metrics["offtracking"]["estimators"]["viso_ot_fused"]
    further = with_coupling_references(_unit_metrics(), {"viso_ot_fused3": lead.report()})
    assert further["offtracking"]["units"]["3"][COUPLING_REFERENCE] == expected
    assert COUPLING_REFERENCE not in further["offtracking"]
    assert coupling_reference_reports(further) == {"viso_ot_fused3": {COUPLING_REFERENCE: expected}}
    recorded = SimpleNamespace(
        fused=SimpleNamespace(noise=noise, coupling_updates=0, coupling_rejected=0),
        reference=SimpleNamespace(follower=3, matched=2, following=refusing),
    )
    summary = coupling_summary(recorded)
    assert summary is not None and {k: summary[k] for k in expected} == expected


def test_without_a_reference_nothing_is_added(tmp_path: Path) -> None:
    """A fused filter without a reference reports nothing and the metrics are unchanged; a short single-trailer
    model-only run's ``metrics.json`` has no ``coupling_reference`` anywhere."""
    refusing, _ = _following(None, 1.0, 0.04)
    params = VEHICLE_PRESETS["au-b-double"]()
    alone = FusedVisoOtEstimator(params, refusing.camera, FusionNoise().for_camera((0.0, 1.0)))
    assert alone.report() == {}
    assert with_coupling_references(_unit_metrics(), {"viso_ot_fused": {}, "viso_ot_fused3": {}}) == _unit_metrics()
    run_scenario(load_scenario("roundabout-3", {"duration_s": 1.0}), tmp_path / "run", plots=False)
    assert COUPLING_REFERENCE not in (tmp_path / "run" / "metrics.json").read_text()
