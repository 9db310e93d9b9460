"""The rho surface exists twice by design: in Python (part 1 fits it, RhoSurface) and in C++ (the NLP
constrains with it, RhoPoly). They must be one function: compare values and gradients at random
interior points of random surfaces, not only at the corners where Bernstein forms agree trivially."""

import numpy as np
import pytest

from pickplan import _core
from pickplan.pickup.metamodel.surface import RhoSurface
from pickplan.pickup.nlp.planner import rho_from_surface


@pytest.mark.parametrize("degrees", [(1, 1), (2, 3), (4, 4), (5, 2)])
def test_python_and_native_rho_agree_inside_the_domain(degrees):
    rng = np.random.default_rng(sum(degrees))
    coeffs = rng.uniform(0.0, 1.0, (degrees[0] + 1, degrees[1] + 1))
    sg_range, sc_range = (0.05, 1.25), (0.1, 0.6)
    py_surface = RhoSurface(coeffs, sg_range, sc_range)
    native = rho_from_surface(py_surface)
    assert isinstance(native, _core.RhoPoly)
    sg = rng.uniform(*sg_range, 200)
    sc = rng.uniform(*sc_range, 200)
    # strictly interior: no point within 1 % of an edge
    inside = (np.abs(sg - np.clip(sg, sg_range[0] + 0.012, sg_range[1] - 0.012)) == 0) & (
        np.abs(sc - np.clip(sc, sc_range[0] + 0.005, sc_range[1] - 0.005)) == 0
    )
    sg, sc = sg[inside], sc[inside]
    assert len(sg) > 150
    py_val = py_surface(sg, sc)
    py_grad = py_surface.gradient(sg, sc)
    for k in range(len(sg)):
        assert native.value(sg[k], sc[k]) == pytest.approx(py_val[k], abs=1e-12)
        np.testing.assert_allclose(np.asarray(native.gradient(sg[k], sc[k])), py_grad[:, k], atol=1e-10)


def test_the_gradient_both_sides_agree_with_finite_differences():
    rng = np.random.default_rng(7)
    surface = RhoSurface(rng.uniform(0, 1, (4, 3)), (0.1, 1.2), (0.15, 0.55))
    native = rho_from_surface(surface)
    h = 1e-6
    for sg, sc in rng.uniform((0.2, 0.2), (1.1, 0.5), (20, 2)):
        fd = np.array(
            [
                (native.value(sg + h, sc) - native.value(sg - h, sc)) / (2 * h),
                (native.value(sg, sc + h) - native.value(sg, sc - h)) / (2 * h),
            ]
        )
        np.testing.assert_allclose(np.asarray(native.gradient(sg, sc)), fd, atol=1e-6)
        np.testing.assert_allclose(surface.gradient(sg, sc), fd, atol=1e-6)
