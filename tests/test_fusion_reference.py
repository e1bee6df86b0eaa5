"""The own accelerometer reference's floor from its bias, (R1) of :mod:`sensor.fusion_reference`
(``reference_accelerometer_bias``).

* With the linear tyres of (T2) ``σ_r`` is ``G·u·σ_a`` (1e-12 relative); with the brush tyre of (T4) it is the
  closed-form secant ``1.5·G·u·μg·|(1 − η₋)^(1/3) − (1 − η₊)^(1/3)|`` (1e-9 relative), and finite where the demand
  passes the friction.
* In the filter on a straight at zero reading σ_k is ``σ_r`` (1e-12 relative), where without the setting it is
  ``tractor_slip``: the floor's ``σ_0`` is replaced, not added to.
* Unset, the floor's added variance is (T3)'s ``σ_m²`` to the bit.
* Out of range, or without the ``trailer_lateral_acceleration`` reference, it is refused naming the field.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from pydantic import ValidationError

from scenarios.config import ConfigError, load_scenario
from sensor.fusion import FusedVisoOt, FusionNoise
from sensor.fusion_reference import OwnReference
from tests.test_fusion import CAMERA, DT, PARAMS, tractor_signals
from vehicle_model.parameters import GRAVITY

OWN = "trailer_lateral_acceleration"
SIGMA_A = 0.1 / math.sqrt(3.0)
"""A bias uniform within ±0.1 m/s² (sensor/datasheet.py's limit for the MEMS lateral accelerometer) [m/s²]."""


def test_r1_through_the_linear_tyres_is_g_u_sigma() -> None:
    reference = OwnReference(PARAMS, 1, FusionNoise(kinematic_rear_point=OWN, reference_accelerometer_bias=SIGMA_A))
    for speed, lateral in ((4.0, 0.0), (3.9, 0.8), (10.0, -2.0)):
        expected = reference.gradient * speed * SIGMA_A
        assert reference.bias_std(speed, lateral) == pytest.approx(expected, rel=1e-12)
        floor = reference.floor_variance(speed, lateral)
        assert floor == pytest.approx(expected**2 - reference.noise.tractor_slip**2, rel=1e-12)


def test_r1_through_the_brush_tyre_is_the_closed_form_secant() -> None:
    mu = 0.1
    noise = FusionNoise(kinematic_rear_point=OWN, reference_road_friction=mu, reference_accelerometer_bias=SIGMA_A)
    reference = OwnReference(PARAMS, 1, noise)
    speed, lateral = 3.9, 0.8  # the ice roundabout's steady turn: η = 0.82
    low, high = (lateral - SIGMA_A) / (mu * GRAVITY), (lateral + SIGMA_A) / (mu * GRAVITY)
    # (T4)'s demand term G·u·f·(1 + k(η)) = G·u·μg·3·(1 − (1 − η)^(1/3)) for 0 < η < 1
    expected = 1.5 * reference.gradient * speed * mu * GRAVITY * abs((1 - low) ** (1 / 3) - (1 - high) ** (1 / 3))
    assert high < 1.0
    assert reference.bias_std(speed, lateral) == pytest.approx(expected, rel=1e-9)
    assert expected > 2.5 * reference.gradient * speed * SIGMA_A  # steeper than the linear tyres there
    near = reference.bias_std(speed, 0.95 * mu * GRAVITY)  # the bias's +1σ passes the friction
    assert math.isfinite(near) and near > expected


def test_the_filters_kinematic_std_on_a_straight_is_r1_in_place_of_tractor_slip() -> None:
    speed = 4.0
    stds = {}
    for name, bias in (("without", None), ("with", SIGMA_A)):
        noise = FusionNoise(kinematic_rear_point=OWN, reference_accelerometer_bias=bias)
        fused = FusedVisoOt(PARAMS, CAMERA, noise)
        for tick in range(5):
            signals = replace(
                tractor_signals(speed, 0.0, 0.0, "lateral_acceleration", 0.0), unit_lateral_acceleration=0.0
            )
            fused.propagate(tick, DT, 0.0, speed, None, signals)
        stds[name] = fused.kinematic_std
    gradient = OwnReference(PARAMS, 1, FusionNoise()).gradient
    assert stds["without"] == pytest.approx(FusionNoise().tractor_slip, rel=1e-12)
    assert stds["with"] == pytest.approx(gradient * speed * SIGMA_A, rel=1e-12)


def test_unset_the_floor_is_the_residual_to_the_bit() -> None:
    reference = OwnReference(PARAMS, 1, FusionNoise(kinematic_rear_point=OWN, reference_friction=0.1))
    for speed, lateral in ((0.0, 0.0), (3.9, 0.8), (12.0, -1.7)):
        assert reference.floor_variance(speed, lateral) == reference.residual_std(speed, lateral) ** 2
    assert np.isclose(reference.bias_std(3.9, 0.8), 0.0)


def test_out_of_range_or_without_the_reference_it_is_refused_naming_the_field() -> None:
    for value in (0.0, 1.5):
        with pytest.raises(ValidationError, match="reference_accelerometer_bias"):
            FusionNoise(reference_accelerometer_bias=value)
    with pytest.raises(ConfigError, match=r"fusion\.side_rig\.reference_accelerometer_bias = 0\.05"):
        load_scenario("roundabout-3", {"vehicle": "lst", "fusion.side_rig.reference_accelerometer_bias": 0.05})
    on = {
        "signals.trailer_lateral_acceleration": {},
        "fusion.side_rig.kinematic_rear_point": OWN,
        "fusion.side_rig.reference_accelerometer_bias": 0.05,
    }
    assert load_scenario("roundabout-3", {"vehicle": "lst", **on}).fusion.side_rig.reference_accelerometer_bias == 0.05
