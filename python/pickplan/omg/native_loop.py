"""Algorithm 2's loop in native code (``_core.run_omg_loop``): the CHOMP-Proj steps, the goal-cost
estimates, the selection policy's update (``_core.SelectionPolicy``: the rules of ``omg.selection``,
which stays the research reference the native policies are tested against), C-Space ISF on the
selected goal, pre-termination and the dense success test, all with the GIL released and no round
trip through Python per iteration. The same loop in Python, the oracle the native one is tested
against, is tests/python/omg_reference_loop.py.
"""

from __future__ import annotations

import time

import numpy as np

from pickplan import _core
from pickplan.core.settings import Option
from pickplan.omg.chomp import cubic_blend
from pickplan.omg.selection import EXP, MirrorDescent, Selection, SelectionPolicy


class StageClock(Option):
    """What the planner's stage timings read."""

    wall = "wall"  # time.perf_counter / steady_clock
    thread_cpu = "thread_cpu"  # the planning thread's CPU time (a shared machine's load does not count)

    def timer(self):
        """The timer this clock reads (looked up per call: a bench may replace perf_counter)."""
        return time.thread_time if self is StageClock.thread_cpu else time.perf_counter


def native_selection(policy) -> "_core.SelectionSettings":
    """The native settings of a policy: a ``Selection`` (or its spelling) or a ``SelectionPolicy``
    instance (its EXP rate and MD exponents and shift carried over)."""
    out = _core.SelectionSettings()
    if isinstance(policy, SelectionPolicy):
        out.kind = getattr(_core.SelectionKind, Selection.parse(policy.name).name)
        if isinstance(policy, EXP) and policy.fixed_eta is not None:
            if not policy.fixed_eta > 0:
                raise ValueError(f"EXP: the native policy needs a rate > 0, got {policy.fixed_eta!r}")
            out.exp_eta = float(policy.fixed_eta)
        if isinstance(policy, MirrorDescent):
            out.md_exponents = [int(k) for k in policy.exponents]
            if policy.shift_setting is not None:
                out.md_shift = float(policy.shift_setting)
        return out
    out.kind = getattr(_core.SelectionKind, Selection.parse(policy, "selection policy").name)
    return out


def native_policy(policy) -> "_core.SelectionPolicy":
    """A fresh native policy with the rules (and parameters) of ``policy`` (see ``native_selection``)."""
    return _core.SelectionPolicy(native_selection(policy))


def loop_settings(settings, policy, metrics: "_core.MetricSettings") -> "_core.OmgLoopSettings":
    """The native loop's settings from ``OMGSettings`` and its (fresh) policy."""
    out = _core.OmgLoopSettings()
    out.selection = native_selection(policy)
    for name in (
        "iterations",
        "isf_steps",
        "isf_max_shift",
        "cost_time_stride",
        "cost_point_stride",
        "pre_terminate",
        "min_iterations",
        "check_every",
    ):
        setattr(out, name, getattr(settings, name))
    out.metrics = metrics
    out.clock = getattr(_core.StageClock, StageClock.parse(settings.clock, "stage clock").name)
    return out


def run_native(
    chomp, refiner, robot, q0, goals, tails, grasp_index, settings, policy, metric_settings, warm=None, exact=None
) -> dict:
    """Algorithm 2's loop over a goal set (``goals``, their approach ``tails`` and the input grasp
    each came from) with ``chomp`` (its problem), ``refiner`` (a ``GraspRefiner`` or None) for
    ``robot``; returns ``_core.run_omg_loop``'s ``OmgLoopResult`` (xi, goal, metrics, history, seconds per stage, ...).
    ``warm``: (initial trajectory (n, dof), its goal index or -1[, one cost per goal for the selection to start
    from, or None: estimated]) to start from a previous plan. ``exact``: (the SDF bits the metrics leave out, a
    test of a plan (n, dof) -> bool): the loop stops early only on a plan that passes the metrics without those
    objects and the test (the exact test among furniture, ``omg.furniture_check``); None: the metrics alone."""
    extra, check = (0, None) if exact is None else exact
    native = loop_settings(settings, policy, chomp.native_metric_settings(metric_settings, extra_exclude=extra))
    initial, initial_goal, costs = (
        (None, -1, None)
        if warm is None
        else (
            np.asarray(warm[0], dtype=float),
            int(warm[1]),
            None if len(warm) < 3 or warm[2] is None else np.asarray(warm[2], dtype=float),
        )
    )
    return _core.run_omg_loop(
        chomp.problem,
        None if refiner is None else refiner._native,
        robot.hand_link,
        np.asarray(q0, dtype=float),
        np.asarray(goals),
        np.asarray(tails),
        np.asarray(grasp_index),
        cubic_blend(chomp.settings.n),
        native,
        initial=initial,
        initial_goal=initial_goal,
        initial_costs=costs,
        check=check,
    )
