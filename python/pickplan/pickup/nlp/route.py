"""Layout-aware seeds of pick-up on the move (issue 37): car-like routes of the base from its start,
through a grasp pose from which the arm reaches the part, to its goal, fitted by the NLP's
polynomials as stage-1 seeds.

A route is two Dubins paths (shortest paths of bounded curvature, Dubins 1957) with the turning
radius v_max / w_max of the base: along it at the speed limit the yaw rate is at most its limit, and
the heading is the path's tangent (no lateral motion: the non-holonomic constraint). Either leg may
be driven backwards (the Dubins path of the reversed headings), which is Reeds-Shepp's freedom at
the grasp pose only. The grasp poses lie on the middle of the grasping annulus, in reach and clear
of the obstacles, heading along the annulus (so the base stays in it while the arm grasps); the
candidates are the shortest collision-free route on each side of the part and in each sense round
it (left / right, clockwise / anticlockwise), ranked by length. Where obstacles block every two-leg
route of a class, a blocked leg goes through a via pose beside an obstacle, heading round it
(``via_poses``, ``clear_leg``): a detour a lattice search would find, from a handful of Dubins pairs.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Optional

import numpy as np

from pickplan.pickup.nlp.feasibility import BaseGeometry

GRASP_ANGLES = 24  # grasp poses tried round the part
STEP = 0.05  # m between route samples
FIT_SAMPLES = 80  # samples of a route the polynomials are fitted to
SPEED_SHARE = 0.9  # seeds time the fitted polynomial to this share of the speed and yaw-rate limits
WAYPOINT_WEIGHT = 30.0  # weight of the grasp pose and the goal in the fit
# Where the fitted path slows below this share of its median speed (round a cusp), the seed heads
# as the route does: the fitted tangent is noise there.
SLOW_SHARE = 0.3
# Via poses (clutter where no two-leg route clears): per obstacle disk, VIA_ANGLES poses round it
# VIA_CLEARANCE beyond the margin; per blocked class, its VIA_OPTIONS shortest routes are tried with
# each blocked leg through the pair of legs via one pose, of the VIA_TRIES shortest pairs.
VIA_ANGLES = 8
VIA_CLEARANCE = 0.1  # m
VIA_OPTIONS = 3
VIA_TRIES = 12
# A base path reverses where its speed along its heading falls below -REVERSE_SHARE of its peak
# speed (the share keeps a path that only creeps through zero, a solver's rounding, forwards).
REVERSE_SHARE = 0.05


def _mod2pi(a: float) -> float:
    return a % (2 * math.pi)


def dubins_words(q0, q1, rho: float) -> list:
    """Every feasible Dubins word from pose q0 to pose q1 (x, y, heading) with turning radius rho:
    (word, (t, p, q)) with t, p, q the segment lengths divided by rho (Shkel and Lumelsky's form)."""
    dx, dy = q1[0] - q0[0], q1[1] - q0[1]
    d = math.hypot(dx, dy) / rho
    th = math.atan2(dy, dx) if d > 1e-12 else 0.0
    a, b = _mod2pi(q0[2] - th), _mod2pi(q1[2] - th)
    sa, sb, ca, cb, cab = math.sin(a), math.sin(b), math.cos(a), math.cos(b), math.cos(a - b)
    out = []
    p2 = 2 + d * d - 2 * cab + 2 * d * (sa - sb)
    if p2 >= 0:
        t1 = math.atan2(cb - ca, d + sa - sb)
        out.append(("LSL", (_mod2pi(t1 - a), math.sqrt(p2), _mod2pi(b - t1))))
    p2 = 2 + d * d - 2 * cab + 2 * d * (sb - sa)
    if p2 >= 0:
        t1 = math.atan2(ca - cb, d - sa + sb)
        out.append(("RSR", (_mod2pi(a - t1), math.sqrt(p2), _mod2pi(t1 - b))))
    p2 = -2 + d * d + 2 * cab + 2 * d * (sa + sb)
    if p2 >= 0:
        p = math.sqrt(p2)
        t0 = math.atan2(-ca - cb, d + sa + sb) - math.atan2(-2.0, p)
        out.append(("LSR", (_mod2pi(t0 - a), p, _mod2pi(t0 - b))))
    p2 = -2 + d * d + 2 * cab - 2 * d * (sa + sb)
    if p2 >= 0:
        p = math.sqrt(p2)
        t0 = math.atan2(ca + cb, d - sa - sb) - math.atan2(2.0, p)
        out.append(("RSL", (_mod2pi(a - t0), p, _mod2pi(b - t0))))
    c = (6 - d * d + 2 * cab + 2 * d * (sa - sb)) / 8
    if abs(c) <= 1:
        p = _mod2pi(2 * math.pi - math.acos(c))
        t = _mod2pi(a - math.atan2(ca - cb, d - sa + sb) + p / 2)
        out.append(("RLR", (t, p, _mod2pi(a - b - t + p))))
    c = (6 - d * d + 2 * cab + 2 * d * (sb - sa)) / 8
    if abs(c) <= 1:
        p = _mod2pi(2 * math.pi - math.acos(c))
        t = _mod2pi(-a - math.atan2(ca - cb, d + sa - sb) + p / 2)
        out.append(("LRL", (t, p, _mod2pi(b - a - t + p))))
    return out


def dubins_shortest(q0, q1, rho: float) -> tuple:
    """(word, (t, p, q), length in metres) of the shortest Dubins path."""
    word, seg = min(dubins_words(q0, q1, rho), key=lambda w: sum(w[1]))
    return word, seg, rho * sum(seg)


def sample_dubins(q0, word: str, seg, rho: float, step: float = STEP) -> np.ndarray:
    """Poses (n, 3) along a Dubins path every ``step`` metres or less, both ends included."""
    out = [np.asarray(q0, float)[None, :]]
    x, y, h = (float(v) for v in q0)
    for kind, length in zip(word, seg):
        n = max(1, int(math.ceil(length * rho / step)))
        u = length * np.arange(1, n + 1) / n
        if kind == "S":
            p = np.stack([x + rho * u * math.cos(h), y + rho * u * math.sin(h), np.full(n, h)], axis=1)
        elif kind == "L":
            p = np.stack(
                [x + rho * (np.sin(h + u) - math.sin(h)), y + rho * (math.cos(h) - np.cos(h + u)), h + u], axis=1
            )
        else:
            p = np.stack(
                [x + rho * (math.sin(h) - np.sin(h - u)), y + rho * (np.cos(h - u) - math.cos(h)), h - u], axis=1
            )
        out.append(p)
        x, y, h = p[-1]
    return np.concatenate(out)


@dataclass(frozen=True)
class Route:
    """A base route: poses (x, y, vehicle heading) by arc length, the grasp pose's sample, and per
    sample whether the base drives forwards (+1) or backwards (-1)."""

    poses: np.ndarray
    s: np.ndarray  # arc length at each sample (m)
    grasp_index: int
    direction: np.ndarray
    label: str

    @property
    def length(self) -> float:
        return float(self.s[-1])


@dataclass(frozen=True)
class Leg:
    """A Dubins path from pose ``start`` driven forwards (sign +1) or backwards (-1)."""

    start: tuple
    word: str
    seg: tuple
    sign: int
    length: float

    def poses(self, rho: float) -> np.ndarray:
        flip = 0.0 if self.sign > 0 else math.pi
        p = sample_dubins((self.start[0], self.start[1], self.start[2] + flip), self.word, self.seg, rho)
        p[:, 2] -= flip
        return p


def _leg(a, b, rho: float, sign: int) -> Leg:
    """The shortest leg from pose a to pose b driven forwards (+1) or backwards (-1)."""
    flip = 0.0 if sign > 0 else math.pi
    word, seg, length = dubins_shortest((a[0], a[1], a[2] + flip), (b[0], b[1], b[2] + flip), rho)
    return Leg(tuple(a), word, seg, sign, length)


def _build(geo: BaseGeometry, legs: list, grasp_leg: int, rho: float, label: str) -> Route:
    """The route of consecutive legs from the start to the goal; the grasp pose ends leg ``grasp_leg``."""
    parts, dirs, grasp_index = [], [], 0
    for k, leg in enumerate(legs):
        p = leg.poses(rho)
        if parts:
            p = p[1:]
        parts.append(p)
        dirs.append(np.full(len(p), leg.sign))
        if k == grasp_leg:
            grasp_index = sum(len(q) for q in parts) - 1
    poses = np.concatenate(parts)
    poses[:, 2] = geo.start[2] + np.unwrap(poses[:, 2] - geo.start[2])
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(poses[:, :2], axis=0), axis=1))])
    return Route(poses, s, grasp_index, np.concatenate(dirs), label)


def via_poses(geo: BaseGeometry, margin: float, rho: float) -> list:
    """Poses beside each obstacle disk, heading round it either way, clear by ``margin``: a leg through
    one turns round the disk on an arc of radius rho about a centre beyond the disk's, so the arc
    holds the disk inside and stays clear of it near the via pose."""
    out = []
    for cx, cy, r in geo.disks:
        ring = r + margin + VIA_CLEARANCE
        for a in np.linspace(0.0, 2 * math.pi, VIA_ANGLES, endpoint=False):
            p = (cx + ring * math.cos(a), cy + ring * math.sin(a))
            if geo.free(p, margin)[0]:
                out += [(p[0], p[1], a + math.pi / 2), (p[0], p[1], a - math.pi / 2)]
    return out


def clear_leg(geo: BaseGeometry, a, b, rho: float, sign: int, vias: list, margin: float) -> Optional[list]:
    """[leg] from pose a to pose b clear by ``margin``, or [leg, leg] through one via pose (the shortest
    such pair whose legs clear, of the VIA_TRIES shortest by length); None when neither clears."""
    direct = _leg(a, b, rho, sign)
    if geo.free(direct.poses(rho)[:, :2], margin).all():
        return [direct]
    pairs = sorted(
        ((l1.length + l2.length, l1, l2) for v in vias for l1, l2 in [(_leg(a, v, rho, sign), _leg(v, b, rho, sign))]),
        key=lambda o: o[0],
    )
    for _, l1, l2 in pairs[:VIA_TRIES]:
        if geo.free(l1.poses(rho)[:, :2], margin).all() and geo.free(l2.poses(rho)[:, :2], margin).all():
            return [l1, l2]
    return None


def grasp_poses(geo: BaseGeometry, margin: float) -> list:
    """(x, y, heading, side, sense) on the middle of the annulus, in reach and clear by ``margin``;
    side: +1 left of the start-goal line, -1 right; sense: +1 anticlockwise round the part."""
    r = 0.5 * (geo.r_min + geo.r_max)
    line = geo.goal[:2] - geo.start[:2]
    out = []
    for a in np.linspace(0.0, 2 * math.pi, GRASP_ANGLES, endpoint=False):
        p = geo.part_xy + r * np.array([math.cos(a), math.sin(a)])
        if not (np.linalg.norm(p - geo.grasp_xy) <= geo.reach_xy and geo.free(p, margin)[0]):
            continue
        side = 1 if line[0] * (p[1] - geo.start[1]) - line[1] * (p[0] - geo.start[0]) >= 0 else -1
        for sense in (1, -1):
            out.append((p[0], p[1], a + sense * math.pi / 2, side, sense))
    return out


def candidate_routes(geo: BaseGeometry, count: int = 3, margin: float = 0.05, deadline: Optional[float] = None) -> list:
    """Up to ``count`` routes, shortest first: per (side, sense) the shortest route whose samples
    clear the obstacles by ``margin``; the best per class, then the classes by length. The search
    (up to 0.2 s in clutter, where many routes collide) stops at ``deadline`` (time.monotonic())
    with the routes found by then."""
    rho = geo.v_max / geo.w_max
    per_class = {}
    for gx, gy, h, side, sense in grasp_poses(geo, margin):
        g = (gx, gy, h)
        firsts = [_leg(geo.start, g, rho, d) for d in (1, -1)]
        seconds = [_leg(g, geo.goal, rho, d) for d in (1, -1)]
        for a in firsts:
            for b in seconds:
                per_class.setdefault((side, sense), []).append((a.length + b.length, g, (a, b)))
    best, blocked = [], []
    late = lambda: deadline is not None and time.monotonic() >= deadline  # noqa: E731
    for key, options in per_class.items():
        label = f"{'left' if key[0] > 0 else 'right'}/{'anticlockwise' if key[1] > 0 else 'clockwise'}"
        options.sort(key=lambda o: o[0])
        for length, g, legs in options:
            if late():
                return sorted(best, key=lambda r: r.length)[:count]
            route = _build(geo, list(legs), 0, rho, label)
            if geo.free(route.poses[:, :2], margin).all():
                best.append(route)
                break
        else:
            blocked.append((label, options))
    # A class no two-leg route clears (clutter between the start, the part and the goal): its
    # VIA_OPTIONS shortest options with each blocked leg through a via pose beside an obstacle.
    vias = via_poses(geo, margin, rho) if blocked else []
    for label, options in blocked:
        for length, g, (a, b) in options[:VIA_OPTIONS]:
            if late():
                return sorted(best, key=lambda r: r.length)[:count]
            first = clear_leg(geo, geo.start, g, rho, a.sign, vias, margin)
            second = clear_leg(geo, g, geo.goal, rho, b.sign, vias, margin) if first else None
            if second:
                best.append(_build(geo, first + second, len(first) - 1, rho, f"{label} via"))
                break
    return sorted(best, key=lambda r: r.length)[:count]


def _degrees(settings, dof: int) -> list:
    """The polynomial degrees of a solve (native resolved_degrees: 5 for the first six DOFs, 3 after)."""
    return list(settings.degrees) if len(settings.degrees) else [5 if i < 6 else 3 for i in range(dof)]


def reverses(x: np.ndarray, degrees, samples: int = 201) -> bool:
    """Whether the base path of the NLP variables ``x`` (monomial coefficients in s = t / T, the
    base polynomials first, at ``degrees``) drives backwards: its speed along its heading, x' cos(theta)
    + y' sin(theta), below -REVERSE_SHARE of its peak somewhere."""
    offsets = np.concatenate([[0], np.cumsum(np.asarray(degrees[:3]) + 1)])
    cx, cy, ct = (np.asarray(x[offsets[i] : offsets[i + 1]], float)[::-1] for i in range(3))
    u = np.linspace(0.0, 1.0, samples)
    theta = np.polyval(ct, u)
    forward = np.polyval(np.polyder(cx), u) * np.cos(theta) + np.polyval(np.polyder(cy), u) * np.sin(theta)
    peak = np.abs(forward).max()
    return bool(peak > 0 and forward.min() < -REVERSE_SHARE * peak)


def _fit(s, values, degree: int, first: float, weights) -> np.ndarray:
    """Monomial coefficients of a polynomial in s through values (weighted), with P(0) = first."""
    V = np.vander(s, degree + 1, increasing=True)[:, 1:] * weights[:, None]
    c, *_ = np.linalg.lstsq(V, (values - first) * weights, rcond=None)
    return np.concatenate([[first], c])


def route_times(route: Route) -> np.ndarray:
    """The seed's normalised time (0 to 1) at each route sample: constant speed, except that the base
    comes to rest at each cusp (where the route turns from forwards to backwards or back), slowing at
    a constant rate over the whole of the shorter leg beside it and speeding up likewise after. A
    polynomial fitted to a cusp driven at constant speed rounds it with a sideways slide and a tangent
    that swings through pi, so its heading fits badly and stage 1 starts far from the non-holonomic
    rows; at rest there, the fitted path is smooth and its tangent follows the route."""
    s = route.s
    cusps = np.flatnonzero(np.diff(route.direction) != 0)
    bounds = np.concatenate([[0.0], s[cusps], [route.length]])
    mid = 0.5 * (s[1:] + s[:-1])
    speed = np.ones(len(mid))
    for k, c in enumerate(s[cusps]):
        ramp = max(min(bounds[k + 1] - bounds[k], bounds[k + 2] - bounds[k + 1]), 1e-9)
        speed = np.minimum(speed, np.sqrt(np.minimum(1.0, np.abs(mid - c) / ramp)))  # constant deceleration
    t = np.concatenate([[0.0], np.cumsum(np.diff(s) / np.maximum(speed, 1e-6))])
    return t / t[-1] if t[-1] > 0 else np.linspace(0.0, 1.0, len(s))


def route_seed(route: Route, geo: BaseGeometry, template: np.ndarray, settings, dof: int, stroke: float) -> np.ndarray:
    """The stage-1 seed of a route: ``template`` (a native heuristic seed: arm, S_g, S_c) with the
    base polynomials fitted to the route timed by ``route_times``, T set so the polynomial's peak
    speed and yaw rate are SPEED_SHARE of their limits, the grasp window round the grasp pose."""
    deg = _degrees(settings, dof)
    offsets = np.concatenate([[0], np.cumsum(np.asarray(deg) + 1)])
    x = np.array(template, float)
    nc = offsets[-1]
    if len(x) != nc + 5:
        raise ValueError(f"route_seed: the template has {len(x)} variables, expected {nc + 5}")
    times = route_times(route)
    idx = np.unique(np.searchsorted(times, np.linspace(0.0, 1.0, FIT_SAMPLES)).clip(0, len(times) - 1))
    idx = np.union1d(idx, [route.grasp_index, len(times) - 1])
    s = times[idx]
    w = np.ones(len(idx))
    w[idx == route.grasp_index] = w[-1] = WAYPOINT_WEIGHT
    coeffs = [_fit(s, route.poses[idx, i], deg[i], geo.start[i], w) for i in range(2)]
    # The heading: the fitted path's own tangent (+ pi where the route drives backwards), so the
    # seed meets the non-holonomic rows as well as its path allows; the route's heading where the
    # fitted path nearly stops (below SLOW_SHARE of its median speed: round a cusp), as its tangent
    # is noise there.
    dx, dy = (np.polyval(np.polyder(c[::-1]), s) for c in coeffs)
    tangent = np.arctan2(dy, dx) + np.where(route.direction[idx] < 0, math.pi, 0.0)
    speed = np.hypot(dx, dy)
    slow = speed <= SLOW_SHARE * np.median(speed)
    tangent[slow] = route.poses[idx, 2][slow]
    heading = geo.start[2] + np.unwrap(np.concatenate([[0.0], tangent[1:] - geo.start[2]]))
    heading = route.poses[idx, 2] + np.remainder(heading - route.poses[idx, 2] + math.pi, 2 * math.pi) - math.pi
    coeffs.append(_fit(s, heading, deg[2], geo.start[2], w))
    for i, c in enumerate(coeffs):
        x[offsets[i] : offsets[i + 1]] = c
    u = np.linspace(0.0, 1.0, 201)
    d = [np.polyval(np.polyder(c[::-1]), u) for c in coeffs]
    window = stroke / x[nc + 4]
    T = max(
        geo.t_min,
        2 * window,
        np.hypot(d[0], d[1]).max() / (SPEED_SHARE * geo.v_max),
        np.abs(d[2]).max() / (SPEED_SHARE * geo.w_max),
    )
    half = 0.5 * window / T
    s1 = float(np.clip(times[route.grasp_index] - half, 0.0, 1.0 - 2 * half))
    x[nc], x[nc + 1], x[nc + 2] = s1, min(1.0, s1 + 2 * half), T
    return x
