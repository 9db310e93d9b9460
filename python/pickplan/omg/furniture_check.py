"""The success test among furniture (a shelf, a bin, a cabinet): the robot's clearance from the furniture and
the other objects measured exactly, in place of the paper's padded body points.

The paper's test (Sec. IV-A) holds 20 body points per link 5 cm from everything: on a tabletop a plan keeps
far more than that, but a hand that reaches into a cabinet or under a shelf's board passes within a few
centimetres of it and of the target's neighbours by necessity, and the padding then decides both ways wrongly
(plans 0.2-6.9 mm clear that lift in PyBullet fail it; a link's hull passed 2.3 cm into a cabinet's top
between its points). Here the links' convex hulls (as PyBullet takes them: ``CheckerKind.surroundings``) are
measured against the furniture and the objects but the target by FCL on the test's own dense steps: the
transit (as the paper's test bounds it: up to the waypoint before the pre-grasp) keeps the approach's clearance (``MetricSettings.tail_clearance``, what it keeps
from the target among furniture), the approach into the grasp touches nothing. The target and the table are
judged as before (body points; the target's transit clearance exactly as well, ``planner``), and so is
smoothness. A tabletop (no furniture) keeps the paper's test.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from pickplan import _core
from pickplan.omg.world import CheckerKind, World


def surroundings_mask(world) -> int:
    """The bits of the furniture (the scene's obstacles) and the objects but the target in the world's SDF."""
    names = [o.name for o in world.scene.obstacles] + [o.name for o in world.scene.objects if o.name != world.target]
    return sum(1 << world.sdf.index(name) for name in names)


def furniture_distances(world, trajectory: np.ndarray, steps: int) -> np.ndarray:
    """(steps,) the least signed distance (m) of the links' hulls from the furniture and the objects but the
    target at each of the success test's dense steps of ``trajectory`` ((n + 1, dof), the start first)."""
    dense = _core.interpolate(trajectory[0], trajectory[1:], steps)
    return world.checker(CheckerKind.surroundings).min_distance_batch(dense)


def transit_steps(n: int, tail_length: int, steps: int) -> np.ndarray:
    """(steps,) whether each dense step lies on the transit as the paper's test splits it (``tail_start`` of the
    native metrics): before the waypoint ahead of the pre-grasp, from which the approach's clearance applies."""
    end = (n - tail_length) / n * (steps - 1) if tail_length > 0 else steps
    return np.arange(steps) < end


def furniture_clear(world, trajectory: np.ndarray, tail_length: int, metric_settings) -> tuple:
    """(clear, least distance): whether the transit of ``trajectory`` keeps ``tail_clearance`` from the
    furniture and the objects but the target and its approach touches neither, and the least distance."""
    d = furniture_distances(world, trajectory, metric_settings.steps)
    transit = transit_steps(len(trajectory) - 1, tail_length, metric_settings.steps)
    need = np.where(transit, metric_settings.tail_clearance, 0.0)
    return bool(np.all(d > need)), float(d.min())


def judged_among_furniture(
    chomp, world, q0: np.ndarray, xi: np.ndarray, tail_length: int, metric_settings, least: Optional[float] = None
):
    """(metrics, least exact distance) of a plan among furniture: the native test with the furniture and the
    objects but the target left out of its body points (their ``min_clearance`` and ``collision`` then read
    the cap and the table alone), then the exact check (``furniture_clear``); a plan failing it is marked in
    collision. ``least``: the plan's least distance where the exact check already passed it (``LoopCheck``)."""
    native = chomp.native_metric_settings(metric_settings, extra_exclude=surroundings_mask(world))
    metrics = chomp.problem.metrics(xi, q0, native)
    if least is not None:
        return metrics, least
    clear, least = furniture_clear(world, np.vstack([q0, xi]), tail_length, metric_settings)
    return (metrics if clear else _core.marked_in_collision(metrics)), least


class LoopCheck:
    """What Algorithm 2's loop stops early on among furniture (``native_loop.run_native``'s ``exact``: the
    metrics without the objects of ``mask``, and this test of a plan (n, dof)): the exact checks the plan is
    judged by afterwards (``furniture_clear``; the transit's clearance from the target, where asked). With the
    padded body points in its place the loop ran most furnished plans to the horizon and returned the last
    iterate, though an earlier one passed the exact test (the 5 cabinet plans refused on 100 scenes). The
    measures of the plan it accepts are kept (``measured``): the loop returns that plan, judged without
    measuring it again."""

    def __init__(self, world, q0: np.ndarray, tail_length: int, metric_settings):
        self.world, self.q0, self.tail_length, self.settings = world, q0, tail_length, metric_settings
        self.mask = surroundings_mask(world)
        self._accepted = None  # (plan, least distance from the surroundings, from the target or None)

    def __call__(self, xi: np.ndarray) -> bool:
        trajectory = np.vstack([self.q0, xi])
        clear, least = furniture_clear(self.world, trajectory, self.tail_length, self.settings)
        need = self.settings.transit_target_clearance
        if not clear:
            return False
        target = None
        if need > -np.inf:
            target = transit_target_distance(self.world, trajectory, self.tail_length, self.settings.steps)
            if target < need:
                return False
        self._accepted = (np.array(xi), least, target)
        return True

    def measured(self, xi: np.ndarray) -> Optional[tuple]:
        """(least distance from the surroundings, from the target or None) of ``xi`` if it is the plan the
        check accepted last, else None."""
        a = self._accepted
        return a[1:] if a is not None and np.array_equal(a[0], xi) else None


def exact_furniture(world) -> bool:
    """Whether plans in ``world`` are judged by ``judged_among_furniture`` (a world with furniture)."""
    return isinstance(world, World) and bool(world.scene.obstacles)


def pregrasps_clear_of_furniture(world, tails: np.ndarray, clearance: float) -> np.ndarray:
    """(G,) whether each pre-grasp (``tails[:, 0]``) keeps ``clearance`` (the transit's) from the furniture and
    the objects but the target."""
    if len(tails) == 0:
        return np.zeros(0, bool)
    d = world.checker(CheckerKind.surroundings).min_distance_batch(np.asarray(tails[:, 0], float))
    return d > clearance


def transit_target_distance(world: World, trajectory: np.ndarray, tail_length: int, steps: int) -> float:
    """The least distance (m, FCL on the meshes) of the robot from the target over the transit of a
    ``trajectory`` ((n + 1, dof), the start first) interpolated as the success test does (``steps`` over the
    whole), up to its pre-grasp (the first of the last ``tail_length`` waypoints)."""
    n = len(trajectory) - 1
    end = n - tail_length + 1  # the pre-grasp's row
    dense = _core.interpolate(trajectory[0], trajectory[1:], steps)  # the success test's own steps
    transit = np.linspace(0.0, n, steps) <= end
    return float(world.checker(CheckerKind.target).min_distance_batch(dense[transit]).min())
