"""The ``controller.mpc`` section: the receding-horizon MPC of ``controller.law: mpc``, each field with its unit and
range and the reason for the range beside it."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from controller.receding_horizon import HorizonSettings
from vehicle_model.settings import Settings

__all__ = ["MpcConfig"]


class MpcConfig(Settings):
    """The receding-horizon MPC of ``controller.law: mpc`` (``controller.receding_horizon``), SI units."""

    horizon_s: float = Field(
        2.0,
        gt=0.0,
        le=10.0,
        description="[s] time the plan looks ahead; beyond 10 s the tractor's inputs held at their present values "
        "say nothing of where it goes",
    )
    nodes: int = Field(
        10, ge=2, le=50, description="intervals in the horizon; 50 makes each tick's NLP as large as a whole-path one"
    )
    rk4_step_s: float = Field(
        0.05,
        gt=0.0,
        le=0.2,
        description="[s] largest RK4 step of the plan's model inside an interval; above 0.2 s RK4 leaves its "
        "stability region for the tyres' relaxation",
    )
    replan_ticks: int = Field(
        1,
        ge=1,
        le=50,
        description="solve every this many control ticks, the last plan's steer applied in between; 50 ticks is a "
        "second at the default 50 Hz",
    )
    max_iter: int = Field(50, ge=1, le=3000, description="Ipopt's iterations per solve before it falls back")
    max_solve_cpu_s: float = Field(
        5.0,
        gt=0.0,
        le=600.0,
        description="[s] CPU time of one solve before it falls back to the last plan's move; ten minutes for one "
        "tick is no controller",
    )

    tractor_prediction: Literal["held", "driver"] = Field(
        "held",
        description="the tractor's steer over the horizon: held at its present value, or driver (the driver's own "
        "law run on the plan's model along its path; the drive force and the surface stay held)",
    )
    warm_start: Literal["primal", "primal_dual"] = Field(
        "primal",
        description="each solve's start: primal (the last plan shifted to the present, its states by the model) or "
        "primal_dual (that and the last successful solve's multipliers, with Ipopt's warm-start options; a primal "
        "start after a failed or capped solve)",
    )

    def settings(self) -> HorizonSettings:
        """The MPC's own settings."""
        return HorizonSettings(
            horizon=self.horizon_s,
            nodes=self.nodes,
            step=self.rk4_step_s,
            max_iter=self.max_iter,
            max_solve_time=self.max_solve_cpu_s,
            tractor_prediction=self.tractor_prediction,
            warm_start=self.warm_start,
        )
