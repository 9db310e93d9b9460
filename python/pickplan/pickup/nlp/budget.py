"""The wall-clock budget of one ``routed.plan_routed`` call (issue 37's ``--time-limit``): when it is
spent, and the time limit each native run of the call is given. The native runs keep their own
budget within a call (cpp/src/pickup/run_limits.hpp)."""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Optional

from pickplan.pickup.nlp import planner

# The share of a time budget kept back for what the planner does not control: the process waiting
# for a core or a garbage collection (behind layout, two benchmark processes on two cores: a call
# whose CPU stayed within 2 s ended 12 ms past it, 44 ms of its wall time spent off the CPU). 2 %:
# at 1 %, on a host running a fifth slower than usual, one cluttered call of 100 ended 1.8 ms past
# 2 s, the freeing of its results after the last run taking up to 7 ms (session 35).
SCHEDULER_SHARE = 0.02


class Budget:
    """The call's wall-clock budget: spent when a native run stopped for it (a native run stops
    before an iteration that would end past the deadline, so it may stop a little early) or when
    less time is left than the shortest Ipopt iteration of a native call so far, on average over
    the call (a call started then would end past the deadline: its start-up and first iteration
    take about that long). The whole of the quickest call was the measure before: one stage-1 run
    that ended at its iteration limit after 1.25 s then spent a 2 s budget at 1.3 s (headings 92;
    13 behind and 14 cluttered budgets ended so between 1.0 and 1.85 s)."""

    def __init__(self, time_limit: float):
        self.deadline = time.monotonic() + (1 - SCHEDULER_SHARE) * time_limit if time_limit > 0 else None
        self.cut = False
        self.quickest = 0.0
        # The longest stretch of Python work between a native call's return and the next call (the
        # plan's dense checks, the next seed): a native run is given the time left less this, so the
        # same work after the last run still ends by the deadline (cut runs' plans returned 2-3 ms late).
        self.reserve = 0.0
        # The most a native call ran past the time it was given (an iteration longer than the
        # longest before it; on a loaded machine a cluttered call ended 3 ms past the deadline).
        self.late = 0.0
        self.given = math.inf
        self.returned: Optional[float] = None

    def left(self) -> float:
        return math.inf if self.deadline is None else self.deadline - time.monotonic()

    def spent(self) -> bool:
        return self.cut or (self.deadline is not None and time.monotonic() >= self.spent_at())

    def spent_at(self) -> Optional[float]:
        """The time.monotonic() instant from which the budget is spent unless a run is cut first
        (None: no budget), also for work that checks a clock itself: the route search."""
        return None if self.deadline is None else self.deadline - (self.quickest + self.reserve + self.late)

    def settings(self, settings: planner.PlannerSettings) -> planner.PlannerSettings:
        if self.deadline is None:
            return settings
        if self.returned is not None:
            self.reserve = max(self.reserve, time.monotonic() - self.returned)
        self.given = max(1e-3, self.left() - self.reserve - self.late)
        return replace(settings, time_limit=self.given)

    def note(self, status, seconds: float, iterations: int = 1) -> None:
        """A native call's status (SolveStatus or the native enum; time_limit spends the budget),
        wall time and Ipopt iterations."""
        self.returned = time.monotonic()
        if self.deadline is not None:
            self.late = max(self.late, seconds - self.given)
        if not isinstance(status, planner.SolveStatus):
            status = planner.SolveStatus.from_native(status)
        if status is planner.SolveStatus.time_limit:
            self.cut = True
        else:
            step = seconds / max(1, iterations)
            self.quickest = min(self.quickest, step) if self.quickest > 0 else step
