"""The test oracle of Algorithm 2's loop: the loop in Python, step by step as the paper writes it,
with the selection policies of ``pickplan.omg.selection`` (the research reference). The library
plans with the native loop (``omg.native_loop``); tests/python/test_omg_native_loop.py checks that
both plan the same (goals chosen at every iteration, trajectories to 1e-9).

>>> result = ReferencePlanner(None, scene, settings, world=world).plan(grasps=grasps)
"""

from __future__ import annotations

from typing import Tuple

import numpy as np

from pickplan.omg.chomp import cubic_initialization
from pickplan.omg.goals import GoalSet
from pickplan.omg.planner import LoopInputs, OMGPlanner, PlanResult, PlanStatus, _clock
from pickplan.omg.selection import CostKind


class ReferencePlanner(OMGPlanner):
    """``OMGPlanner`` with Algorithm 2's loop in Python (everything around the loop is the library's)."""

    def _optimize(self, world, q0, gs: GoalSet, timings: dict) -> PlanResult:
        return _Optimization(self.settings, world, q0, GoalBook(gs, world.robot), timings).run()


class GoalBook:
    """The goal set as the planner changes it: the first time C-Space ISF moves a goal, its refined
    copy joins the set; later refinements update that copy in place. Goals ISF cannot improve (no
    decrease found, beyond ``isf_max_shift`` from their input grasp, or their shifted approach past a joint
    limit) are left alone."""

    def __init__(self, gs: GoalSet, robot):
        self.robot = robot
        self.initial_goals = np.array(gs.goals)  # the IK goal set as built, before any refinement
        self.goals = list(gs.goals)
        self.tails = list(gs.tails)
        self.origin = list(gs.grasp_index)  # input grasp of each goal
        self.origin_goal = list(range(len(gs)))  # goal-set goal each goal came from (refined copies: their source)
        self.refined_copy: dict = {}  # goal index -> index of its refined copy
        self.stalled: set = set()  # goals ISF leaves alone
        self.grasp_hand: dict = {}  # hand position at an input goal, made when ISF first refines it
        self.tail_length = gs.tails.shape[1]

    def __len__(self) -> int:
        return len(self.goals)

    def on_goal(self, xi, g: int) -> bool:
        """The tail sits on goal g's tail (after a projection step: to round-off)."""
        return bool(np.abs(xi[-self.tail_length :] - self.tails[g]).max() <= 1e-9)

    def is_refined(self, g: int) -> bool:
        return g in self.refined_copy.values()

    def refine(self, g: int, refiner, steps: int, max_shift: float) -> Tuple[int, bool]:
        """ISF steps on goal g; returns the goal to follow (g or its refined copy) and whether that
        copy is new (a selection policy then grows by one goal)."""
        q_ref, _ = refiner.refine(self.goals[g], steps)
        hand_link = self.robot.hand_link
        source = self.origin_goal[g]
        if source not in self.grasp_hand:
            self.grasp_hand[source] = self.robot.link_pose(self.goals[source], hand_link)[:3, 3]
        shift = np.linalg.norm(self.robot.link_pose(q_ref, hand_link)[:3, 3] - self.grasp_hand[source])
        if np.abs(q_ref - self.goals[g]).max() == 0 or shift > max_shift:
            self.stalled.add(g)  # deterministic: refine would give the same again
            return g, False
        shifted = self.tails[g] + (q_ref - self.goals[g])  # keep the approach's shape
        if np.any(shifted < self.robot.lower_limits) or np.any(shifted > self.robot.upper_limits):
            self.stalled.add(g)  # a pinned approach past a joint limit could never be executed
            return g, False
        if self.is_refined(g):  # already a refined goal: update in place
            self.goals[g], self.tails[g] = q_ref, shifted
            return g, False
        if g in self.refined_copy:
            k = self.refined_copy[g]
            self.goals[k], self.tails[k] = q_ref, shifted
            return k, False
        self.goals.append(q_ref)
        self.tails.append(shifted)
        self.origin.append(self.origin[g])
        self.origin_goal.append(g)
        self.refined_copy[g] = len(self.goals) - 1
        return len(self.goals) - 1, True


class _Optimization:
    """The loop of Algorithm 2 over a non-empty goal set; ``timings`` accumulates its phases."""

    def __init__(self, settings, world, q0: np.ndarray, book: GoalBook, timings: dict):
        self.settings, self.world, self.q0, self.book, self.timings = settings, world, q0, book, timings
        parts = LoopInputs.of(settings, world, book.tail_length)
        self.chomp, self.metric_settings, self.refiner, self.policy = (
            parts.chomp,
            parts.metric_settings,
            parts.refiner,
            parts.policy,
        )
        self.ws = self.chomp.workspace()

    def estimates(self, xi, i: int) -> np.ndarray:
        """Normalized cost of each goal for the trajectory xi at iteration i."""
        s, goals = self.settings, np.array(self.book.goals)
        if self.policy.cost_kind is CostKind.distance:  # Proj: distance of the free end point to each goal
            _, grad = self.chomp.problem.objective(xi, self.q0, i)
            free_end = xi[-1] - s.chomp.step_size * self.chomp.problem.solve_A(grad)[-1]
            c = np.linalg.norm(goals - free_end, axis=1)
        else:
            c = self.chomp.problem.goal_costs(
                xi, self.q0, i, s.iterations, goals, s.cost_time_stride, s.cost_point_stride, self.ws
            )
        norm = np.linalg.norm(c)
        return c / norm if norm > 0 else c

    def _timed(self, phase: str, fn, *args):
        clock = _clock(self.settings)
        t = clock()
        out = fn(*args)
        self.timings[phase] += clock() - t
        return out

    def _select(self, c) -> Tuple[int, np.ndarray]:
        """The policy's update and its choice: (goal, p)."""
        p = self.policy.update(c)
        return self.policy.select(), p

    def _refine(self, g: int) -> int:
        g, added = self.book.refine(g, self.refiner, self.settings.isf_steps, self.settings.isf_max_shift)
        if added:
            self.policy.add_goal()
        return g

    def _succeeds(self, xi, g: int, iterations: int):
        """The trajectory that would be returned (its tail on goal g) and its metrics when it succeeds."""
        book, q0 = self.book, self.q0
        cand = xi if book.on_goal(xi, g) else self.chomp.step(xi.copy(), q0, book.tails[g], iterations, self.ws)[0]
        metrics = self.chomp.metrics(cand, q0, self.metric_settings)
        return (cand, metrics) if metrics.success else (None, None)

    def run(self) -> PlanResult:
        s, book, q0, chomp, ws = self.settings, self.book, self.q0, self.chomp, self.ws
        xi = cubic_initialization(q0, book.goals[0], s.chomp.n)
        c0 = self._timed("costs", self.estimates, xi, 0)
        self.policy.reset(len(book), s.iterations, c0)
        g = int(np.argmin(c0))  # the initial goal: best by the initial estimate (as Fixed)
        xi = cubic_initialization(q0, book.goals[g], s.chomp.n)
        xi[-book.tail_length :] = book.tails[g]
        history = {
            "objective": [],
            "goal": [],
            "p": [],
            "costs": [],
            "switches": 0,
            "initial_grasp": int(book.origin[g]),
        }
        iterations, metrics = 0, None
        for i in range(s.iterations):
            iterations = i + 1
            xi, info = self._timed("chomp", chomp.step, xi, q0, book.tails[g], i, ws)
            history["objective"].append(info.before.total)
            c = self._timed("costs", self.estimates, xi, i + 1)
            history["costs"].append(c)
            g_next, p = self._timed("selection", self._select, c)
            if self.refiner is not None and g_next not in book.stalled:
                g_next = self._timed("isf", self._refine, g_next)
            history["switches"] += int(g_next != g)
            history["goal"].append(g_next)
            history["p"].append(p.copy())
            # On a switch the tail is left where it is: the next CHOMP-Proj step's offset term
            # (eq. 7, -A^-1 C^T (C A^-1 C^T)^-1 b) moves the whole trajectory smoothly onto the new
            # goal; overwriting the tail instead would leave a jump before it for CHOMP to undo.
            g = g_next
            if s.pre_terminate and iterations >= s.min_iterations and iterations % s.check_every == 0:
                cand, metrics = self._timed("metrics", self._succeeds, xi, g, iterations)
                if cand is not None:
                    xi = cand
                    break
        if not book.on_goal(xi, g):  # the last selection (a switch or a refined goal): project onto it
            xi, _ = chomp.step(xi, q0, book.tails[g], iterations, ws)
        return self._result(xi, g, iterations, metrics, history)

    def _result(self, xi, g: int, iterations: int, metrics, history: dict) -> PlanResult:
        clock = _clock(self.settings)
        t = clock()
        if metrics is None:
            metrics = self.chomp.metrics(xi, self.q0, self.metric_settings)
        refiner = self.refiner
        grasp_cost = float(refiner.cost(xi[-1])[0].total) if refiner is not None else float("nan")
        self.timings["metrics"] += clock() - t
        robot = self.world.robot
        return PlanResult(
            PlanStatus.of(metrics),
            np.vstack([self.q0, xi]),
            xi[-1].copy(),
            int(self.book.origin[g]),
            robot.link_pose(xi[-1], robot.hand_link),
            self.book.is_refined(g),
            metrics,
            grasp_cost,
            len(self.book),
            iterations,
            history,
            self.timings,
            goal_set=self.book.initial_goals.copy(),
            goal_source=int(self.book.origin_goal[g]),
        )
