"""The parts that are picked up on the move and their grasping strategies.

A part is a rigid body built from primitive shapes (boxes, cylinders) in its own frame P,
whose origin lies on the table surface under the part. A grasping strategy Gamma_g is the
pose of the gripper's tool centre point (TCP) in P at the moment t' when grasping ends,
together with the approach direction n_g (Sec. III-A of the paper). In simulation the
gripper always moves along its own +x axis (parallel to the finger pads), so n_g is fixed in
the gripper frame and the strategy reduces to the TCP pose in P.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

# Palm bottom sits this far above the part's top at t'; the TCP is 25 mm below the palm.
PALM_CLEARANCE = 0.008
TCP_BELOW_PALM = 0.025


@dataclass(frozen=True)
class Shape:
    """One primitive of a part. kind: 'box' (size = full extents x, y, z), 'cylinder'
    (size = (radius, height)) or 'mesh' (size = the convex hull's vertices, the only shape of its
    part; see mesh_part.py); pos is the shape centre (a mesh: its centre of mass) in the part frame."""

    kind: str
    size: tuple
    pos: tuple


@dataclass(frozen=True)
class GraspStrategy:
    """TCP pose at t' in the part frame: position (x, y, z) and yaw of the gripper about z
    (the gripper's closing axis is its y axis), plus the part width between the pads."""

    tcp_xyz: tuple
    tcp_yaw: float
    grasp_width: float

    def approach_direction_in_part(self) -> np.ndarray:
        """n_g expressed in the part frame (unit vector in the table plane)."""
        return np.array([math.cos(self.tcp_yaw), math.sin(self.tcp_yaw), 0.0])


@dataclass(frozen=True)
class Part:
    name: str
    shapes: tuple
    mass: float
    height: float
    strategy: GraspStrategy
    lateral_friction: float = 0.6
    description: str = ""
    # Radius, about the strategy's grasp point, of a circle containing the footprint.
    footprint_radius: float = field(default=0.0)
    # Success never drops when the fingers close faster (the paper's observation for its parts).
    # Measured per part by extensive sampling (bench/PICKUP.md): it holds for the box, not for
    # the cylinder, which faster fingers knock aside. Only where it holds may the meta-model
    # label poses for free from the lower S_c boundary and keep rho monotone in S_c.
    closing_monotone: bool = True


def grasp_height(height: float) -> float:
    """TCP height at t' for a part of this height (the palm just above its top)."""
    return height + PALM_CLEARANCE - TCP_BELOW_PALM


def _footprint_radius(shapes, center_xy) -> float:
    r = 0.0
    cx, cy = center_xy
    for s in shapes:
        if s.kind == "box":
            hx, hy = s.size[0] / 2, s.size[1] / 2
            for sx in (-1, 1):
                for sy in (-1, 1):
                    r = max(r, math.hypot(s.pos[0] + sx * hx - cx, s.pos[1] + sy * hy - cy))
        else:
            r = max(r, math.hypot(s.pos[0] - cx, s.pos[1] - cy) + s.size[0])
    return r


def _make_part(name, shapes, mass, height, tcp_xy, tcp_yaw, width, description, closing_monotone=True) -> Part:
    strategy = GraspStrategy((tcp_xy[0], tcp_xy[1], grasp_height(height)), tcp_yaw, width)
    return Part(
        name=name,
        shapes=tuple(shapes),
        mass=mass,
        height=height,
        strategy=strategy,
        description=description,
        footprint_radius=_footprint_radius(shapes, tcp_xy),
        closing_monotone=closing_monotone,
    )


def make_box() -> Part:
    # 35 x 60 x 50 mm block grasped across its 35 mm side; the gripper approaches along the
    # part's -y axis (TCP yaw 90 deg), so the long side runs along the pads.
    h = 0.05
    return _make_part(
        "box",
        [Shape("box", (0.035, 0.06, h), (0.0, 0.0, h / 2))],
        mass=0.15,
        height=h,
        tcp_xy=(0.0, 0.0),
        tcp_yaw=math.pi / 2,
        width=0.035,
        description="35x60x50 mm block, grasped across 35 mm, approach along its long side",
    )


def make_cylinder() -> Part:
    # Upright cylinder r = 20 mm, h = 60 mm, grasped across its diameter.
    h = 0.06
    return _make_part(
        "cylinder",
        [Shape("cylinder", (0.02, h), (0.0, 0.0, h / 2))],
        mass=0.15,
        height=h,
        tcp_xy=(0.0, 0.0),
        tcp_yaw=0.0,
        width=0.04,
        description="upright cylinder r=20 mm h=60 mm, grasped across the diameter",
        closing_monotone=False,
    )


def make_l_bracket() -> Part:
    # L-shaped bracket standing on the table: a 70 x 15 mm arm along x and a 15 x 40 mm arm
    # at its +x end pointing +y, extruded 50 mm. Grasped across the long arm's 15 mm
    # thickness, 10 mm behind its centre, so the short arm (and most of the mass asymmetry)
    # lies ahead of the gripper and is never swept by the fingers.
    h = 0.05
    shapes = [
        Shape("box", (0.07, 0.015, h), (0.0, 0.0, h / 2)),
        Shape("box", (0.015, 0.04, h), (0.0275, 0.0275, h / 2)),
    ]
    return _make_part(
        "l_bracket",
        shapes,
        mass=0.10,
        height=h,
        tcp_xy=(-0.01, 0.0),
        tcp_yaw=0.0,
        width=0.015,
        description="L-bracket 70x40 mm, 15 mm thick, 50 mm tall, grasped on the long arm",
    )


PARTS = {"box": make_box, "cylinder": make_cylinder, "l_bracket": make_l_bracket}


def get_part(name_or_part) -> Part:
    """Return a Part given its name (one of PARTS) or a Part instance."""
    if isinstance(name_or_part, Part):
        return name_or_part
    try:
        return PARTS[name_or_part]()
    except KeyError:
        raise ValueError(f"unknown part {name_or_part!r}; expected one of {sorted(PARTS)}") from None
