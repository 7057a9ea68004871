import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from solver.spec.errors import ExprError
from solver.spec.expr import parse, shape_of

q1, q2 = sp.symbols("q1 q2", real=True)
m2, l1, alpha = sp.symbols("m2 l1 alpha", positive=True)
NAMES = {"q1": q1, "q2": q2, "m2": m2, "l1": l1, "alpha": alpha}


@pytest.mark.parametrize("text, want", [
    ("m2*l1^2", m2 * l1**2),
    ("m2*l1**2", m2 * l1**2),
    ("-2^2", -4),
    ("2^3^2", 512),
    ("sin(q1 + pi/4)", sp.sin(q1 + sp.pi / 4)),
    ("atan2(q2, q1)", sp.atan2(q2, q1)),
    ("sqrt(l1)/2 - 0.5", sp.sqrt(l1) / 2 - sp.Rational(1, 2)),
    ("1e-3*alpha", alpha / 1000),
    ("cos(alpha)^2 + sin(alpha)^2", sp.cos(alpha)**2 + sp.sin(alpha)**2),
])
def test_accepts_plain_math(text, want):
    assert sp.simplify(parse(text, NAMES) - want) == 0


def test_lists_and_matrices():
    v = parse("[[m2, 0], [0, l1*q1]]", NAMES)
    assert shape_of(v) == (2, 2) and v[1][1] == l1 * q1
    assert parse("2*[q1, q2]", NAMES) == [2 * q1, 2 * q2]


@pytest.mark.parametrize("text, fragment", [
    ("__import__('os')", "unexpected character"),
    ("q1.real", "attribute access"),
    ("lambda x: x", "unexpected character"),
    ("m2l1", "unknown name 'm2l1'"),
    ("m2 l1", "missing operator"),
    ("9^9^9^9", "exponent too large"),
    ("2^1000", "exponent too large"),
    ("(10^99)^99", "too large"),
    ("foo(q1)", "unknown function"),
    ("sin(q1", "expected ')'"),
    ("", "empty expression"),
    ("q1 = 2", "no '='"),
    ("\\sin q_1", "plain math"),
    ("(" * 200 + "1" + ")" * 200, "nested too deeply"),
    ("x" * 30000, "too long"),
])
def test_rejects_with_clear_message(text, fragment):
    with pytest.raises(ExprError) as exc:
        parse(text, NAMES)
    assert fragment in str(exc.value)


def test_error_points_at_column():
    with pytest.raises(ExprError) as exc:
        parse("m2*l1 + mm2", NAMES)
    assert exc.value.col == 9 and "did you mean m2" in str(exc.value)


@settings(max_examples=300, deadline=None)
@given(st.text(alphabet="q12ml+-*/^()[], .sincopt_e9x'\"", max_size=60))
def test_fuzz_never_crashes(text):
    """Any text either parses or raises ExprError: never another exception, never eval."""
    try:
        parse(text, NAMES)
    except ExprError:
        pass
