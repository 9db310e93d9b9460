"""Inverse kinematics settings: the native damped-least-squares IK (``_core.IkSolver``: one descent, then a
spread of seeds), its options as enums, its defaults written once in the C++ struct."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

from pickplan import _core
from pickplan.core.settings import Option, native_defaults, to_native


class IkTask(Option):
    pose = "pose"
    position = "position"


class IkRotationError(Option):
    angle_axis = "angle_axis"
    sine_axis = "sine_axis"


class IkDamping(Option):
    adaptive = "adaptive"
    fixed = "fixed"


class IkStepNorm(Option):
    max_abs = "max_abs"
    euclidean = "euclidean"


@dataclass(frozen=True)
@native_defaults(_core.IkSettings)
class IkSettings:
    """Mirror of the native ``IkSettings`` (one damped-least-squares descent's settings, then the
    spread of seeds); ``to_native`` sets the per-joint weights."""

    task: IkTask
    rotation_error: IkRotationError
    max_iterations: int
    position_tolerance: float
    rotation_tolerance: float
    damping_schedule: IkDamping
    damping: float
    damping_decrease: float
    damping_increase: float
    min_damping: float
    max_damping: float
    min_relative_decrease: float
    max_stalled_iterations: int  # descents stopped after this many steps without decrease (0: never)
    max_step: float
    step_norm: IkStepNorm
    limit_margin: float
    num_seeds: int
    seed: int
    duplicate_tolerance: float

    def to_native(self, active: Sequence[bool]) -> "_core.IkSettings":
        """The native settings; joints not ``active`` are frozen (weight 0)."""
        return to_native(self, _core.IkSettings, weights=[1.0 if a else 0.0 for a in active])
