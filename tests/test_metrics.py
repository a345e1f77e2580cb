"""The order / Richardson / GCI code recovers known orders and limits on non-uniform h."""

import numpy as np
import pytest

from pcverify.harness.judge.metrics import classify, field_errors, observed_order, richardson

# the lattice family's own spacings a = W / (n - 1): non-uniform refinement ratios 1.5, 1.33, 1.67, ...
H = 0.01 / (np.array([3, 4, 6, 8, 11]) - 1)


@pytest.mark.parametrize("p", [1.0, 2.0, 2.7])
def test_richardson_recovers_order_and_limit_on_nonuniform_h(p):
    limit, c = 0.3, 40.0
    phi = limit + c * H**p  # exact power law: the procedure must recover p and the limit to round-off
    r = richardson(H, phi)
    assert r.order == pytest.approx(p, rel=1e-8)
    assert r.extrapolated == pytest.approx(limit, rel=1e-9)
    assert r.kind == "monotonic"
    # GCI is 1.25 times the error estimate relative to the fine value (Celik's e_a / (r^p - 1)); with an exact
    # power law that estimate is exact, so the GCI is 1.25 times the true error of the fine value
    fine = phi[np.argmin(H)]
    true_rel = abs(fine - limit) / fine
    assert r.gci_fine == pytest.approx(1.25 * true_rel, rel=1e-6)


def test_richardson_with_higher_order_term_stays_close():
    # a second term of higher order perturbs the apparent order only slightly on fine grids
    phi = 1.0 + 5.0 * H**2 + 30.0 * H**3
    r = richardson(H, phi)
    assert abs(r.order - 2.0) < 0.15
    assert abs(r.extrapolated - 1.0) < abs(phi[-1] - 1.0)


def test_observed_order_least_squares():
    err = 3.0 * H**1.5
    p, c = observed_order(H, err)
    assert p == pytest.approx(1.5, rel=1e-10)
    assert c == pytest.approx(3.0, rel=1e-10)
    # the `finest` selector uses only the smallest h: a corrupted coarse point must not matter
    err2 = err.copy()
    err2[0] *= 10
    assert observed_order(H, err2, finest=3)[0] == pytest.approx(1.5, rel=1e-10)


def test_classification():
    assert classify([1.3, 1.1, 1.05]) == "monotonic"
    assert classify([1.3, 0.9, 1.1]) == "oscillatory"
    assert classify([1.0, 1.1, 1.4]) == "divergent"
    assert classify([1.0, 0.5, 1.5]) == "divergent"  # oscillating with growing amplitude
    phi_osc = 1.0 + (-1.0) ** np.arange(5) * H**2 * 10
    assert richardson(H, phi_osc).kind == "oscillatory"


def test_field_errors():
    e = field_errors(np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.0, 5.0]))
    assert e["linf"] == 2.0
    assert e["l2"] == pytest.approx(np.sqrt(4.0 / 3.0))


def test_degenerate_inputs_fail_clearly():
    with pytest.raises(ValueError, match="identical"):
        richardson(H[:3], np.ones(3))
    with pytest.raises(ValueError, match="two points"):
        observed_order(H[:1], np.ones(1))
