
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from solver.grading.latex_in import latex_to_plain, looks_like_latex, parse_latex
from solver.spec.errors import ExprError
from solver.spec.expr import MAX_LENGTH

NAMES = {n: sp.Symbol(n) for n in (
    "m1 m2 l1 l2 d1 d2 I1 I2 q1 q2 q3 dq1 dq2 dq3 ddq1 ddq2 ddq3 g0 dc3 theta1 alpha I2x").split()}
S = NAMES
m1, m2, l1, l2, d1, d2, I1, q1, q2, q3 = (S[n] for n in "m1 m2 l1 l2 d1 d2 I1 q1 q2 q3".split())
dq1, dq2, ddq1 = S["dq1"], S["dq2"], S["ddq1"]

# how sympy's latex() should print each name (for the round trip)
SYMBOL_LATEX = {
    "m1": "m_{1}", "m2": "m_{2}", "l1": "l_{1}", "l2": "l_{2}", "d1": "d_{1}", "d2": "d_{2}",
    "I1": "I_{1}", "I2": "I_{2}", "q1": "q_{1}", "q2": "q_{2}", "q3": "q_{3}",
    "dq1": r"\dot{q}_{1}", "dq2": r"\dot{q}_{2}", "dq3": r"\dot{q}_{3}",
    "ddq1": r"\ddot{q}_{1}", "ddq2": r"\ddot{q}_{2}", "ddq3": r"\ddot{q}_{3}",
    "g0": "g_{0}", "dc3": "d_{c3}", "theta1": r"\theta_{1}", "alpha": r"\alpha", "I2x": "I_{2x}",
}


def same(a, b) -> bool:
    return sp.simplify(a - b) == 0


@pytest.mark.parametrize("text, want", [
    (r"$\dot q_1^2 \sin q_2$", dq1**2 * sp.sin(q2)),
    (r"2 m_2 l_1 d_2 \cos(q_2)", 2 * m2 * l1 * d2 * sp.cos(q2)),
    (r"\frac{1}{2} m_1 d_1^2 \dot{q}_1^{2}", m1 * d1**2 * dq1**2 / 2),
    (r"\sin^2 q_1 + \cos^2 q_1", 1),
    (r"\cos^{2}(q_1)", sp.cos(q1)**2),
    ("c_{12}", sp.cos(q1 + q2)),
    ("c_{23}", sp.cos(q2 + q3)),
    ("s_2 c_2", sp.sin(q2) * sp.cos(q2)),
    ("s_1", sp.sin(q1)),
    (r"\sin\left(q_1+q_2\right)", sp.sin(q1 + q2)),
    (r"\sin{q_1}", sp.sin(q1)),
    (r"\sin\bigl(q_1\bigr)", sp.sin(q1)),
    (r"\sin(q_1)^2", sp.sin(q1)**2),
    ("(m_1+m_2)(l_1+l_2)", (m1 + m2) * (l1 + l2)),
    (r"2\sin q_1 \cos q_1", sp.sin(2 * q1)),
    (r"\sin q_1 \dot q_2", sp.sin(q1) * dq2),
    (r"\cos 2q_1", sp.cos(2 * q1)),
    (r"\theta_1", S["theta1"]),
    (r"\alpha^2", S["alpha"]**2),
    (r"\sqrt{l_1^2+l_2^2}", sp.sqrt(l1**2 + l2**2)),
    (r"\sqrt[3]{q_1}", sp.cbrt(q1)),
    ("I_{2x}", S["I2x"]),
    ("d_{c3}", S["dc3"]),
    ("dc3 + g0", S["dc3"] + S["g0"]),
    ("m2 l1", m2 * l1),
    (r"\dot{q_1} + \dot q_{1} + \dot{q}_1", 3 * dq1),
    (r"\ddot q_1", ddq1),
    (r"\ell_1 \cdot l_2 \times 2", 2 * l1 * l2),
    (r"\pi/2 - q_1", sp.pi / 2 - q1),
    (r"e^{q_1} + e^{-1}", sp.exp(q1) + sp.exp(-1)),
    (r"q_1^{10} + q_2^{-1}", q1**10 + 1 / q2),
    (r"\dfrac{m_1}{2} + \tfrac12 g_0", m1 / 2 + S["g0"] / 2),
    (r"\left[ m_1 + m_2 \right] g_0", (m1 + m2) * S["g0"]),
    (r"{m_1 + m_2}^2", (m1 + m2)**2),
    (r"\left| q_1 \right| + |q_2|", sp.Abs(q1) + sp.Abs(q2)),
    (r"\arctan(q_1) + \operatorname{atan2}(q_2, q_1)", sp.atan(q1) + sp.atan2(q2, q1)),
    (r"\ln q_1 + \exp(q_2)", sp.log(q1) + sp.exp(q2)),
    (r"m_1\,g_0\;l_1\quad q_1~q_2", m1 * S["g0"] * l1 * q1 * q2),
    (r"\[ 2.5 m_1 \]", sp.Rational(5, 2) * m1),
    (r"\( m_1 \)", m1),
    ("$$ m_1 $$", m1),
    (r"  $ -m_1 \dot q_1 $  ", -m1 * dq1),
    (r"\sin^2 q_1 \dot q_1", sp.sin(q1)**2 * dq1),
    (r"2 m_2 l_1 \dot q_1", 2 * m2 * l1 * dq1),
    (r"\sin 2q_1^2", sp.sin(2 * q1**2)),
])
def test_translates(text, want):
    assert same(parse_latex(text, NAMES), want)


@pytest.mark.parametrize("text, plain", [
    (r"2 m_2 l_1 \dot q_1", "2*m2*l1*dq1"),
    (r"\sin q_1 \dot q_2", "sin(q1)*dq2"),
    (r"\cos 2q_1", "cos(2*q1)"),
    (r"\sin^2 q_1", "sin(q1)^2"),
    (r"\frac{a}{b}", "((a)/(b))"),
    (r"2\sin q_1", "2*sin(q1)"),
    ("(a+b)(c+d)", "(a+b)*(c+d)"),
    (r"\begin{pmatrix} a & b \\ c & d \end{pmatrix}", "[[a, b], [c, d]]"),
])
def test_plain_text(text, plain):
    assert latex_to_plain(text, {"a", "b", "c", "d", *NAMES}) == plain


def test_matrices():
    M = parse_latex(r"\begin{pmatrix} I_1 + m_2 q_2^2 & m_2 l_1 \\ m_2 l_1 & m_2 \end{pmatrix}", NAMES)
    assert len(M) == 2 and all(len(r) == 2 for r in M)
    assert same(M[0][0], I1 + m2 * q2**2) and M[0][1] == m2 * l1 and M[1][0] == m2 * l1 and M[1][1] == m2
    assert parse_latex(r"\begin{bmatrix} q_1 \\ \dot q_2 \end{bmatrix}", NAMES) == [q1, dq2]
    assert parse_latex(r"\begin{bmatrix} q_1 \\ q_2 \\  \end{bmatrix}", NAMES) == [q1, q2]  # trailing \\
    assert parse_latex(r"\begin{bmatrix} q_1 & q_2\end{bmatrix}^T", NAMES) == [q1, q2]
    assert parse_latex(r"\begin{bmatrix} q_1 & q_2\end{bmatrix}", NAMES) == [[q1, q2]]
    assert parse_latex(r"\begin{matrix} q_1 \\ q_2 \end{matrix}^{T}", NAMES) == [[q1, q2]]
    assert parse_latex(r"\begin{Bmatrix} 1 & 2 \\ 3 & 4 \end{Bmatrix}^\top", NAMES) == [[1, 3], [2, 4]]
    assert parse_latex(r"2 \begin{pmatrix} m_1 \\ 0 \end{pmatrix}", NAMES) == [2 * m1, 0]


def test_latex_names_first():
    names = dict(NAMES, d_c3=sp.Symbol("d_c3"), l=sp.Symbol("l"))
    spell = {r"d_{c3}": "dc3", r"\ell_1": "l1", r"I_{2x}": "I2x", r"\mathrm{g}": "g0"}
    assert parse_latex("d_{c3}", names, spell) == S["dc3"]
    assert parse_latex("d_ { c 3 }", names, spell) == S["dc3"]          # whitespace is ignored
    assert parse_latex("d_{c3}", names) == S["dc3"]                     # generic rule: dc3 before d_c3
    assert parse_latex(r"\ell_{1} + \mathrm{g}", names, spell) == l1 + S["g0"]
    assert parse_latex("x_1", names, {"x_{1}": "q1"}) == q1              # x_1 and x_{1} alike
    assert parse_latex(r"\dot x_1", names, {"x_{1}": "q1"}) == dq1       # \dot + the plain name
    assert parse_latex(r"\dot{q}_1", names, {r"\dot q_{1}": "ddq1"}) == ddq1  # a dotted spelling
    assert parse_latex(r"\ell", names) == sp.Symbol("l")


def test_name_candidates_and_fallbacks():
    names = {"d_c3": sp.Symbol("d_c3"), "I2xx": sp.Symbol("I2xx"), "ell2": sp.Symbol("ell2")}
    assert latex_to_plain("d_{c3}", names) == "d_c3"
    assert latex_to_plain("I_{2,xx}", names) == "I2xx"
    assert latex_to_plain(r"\ell_2", names) == "ell2"   # no l2: \ell stays ell
    assert latex_to_plain("d_{c4}", names) == "dc4"     # unknown: base+sub, the plain parser reports it
    assert latex_to_plain(r"\theta_{1}", names) == "theta1"


def test_trig_shorthand_rules():
    assert latex_to_plain("c_{12}", NAMES) == "cos(q1+q2)"
    assert latex_to_plain("c_{12}", NAMES, trig_shorthand=False) == "c12"
    assert latex_to_plain("c_4", NAMES) == "c4"                      # no q4: not a shorthand
    assert latex_to_plain("C_1", NAMES) == "C1"                      # only lowercase s and c
    names = dict(NAMES, c1=sp.Symbol("c1"))
    assert latex_to_plain("c_1", names) == "c1"                      # a known name wins


@pytest.mark.parametrize("text, fragment, col", [
    ("m2l1", "ambiguous product", 1),
    ("2 ml", "ambiguous product", 3),
    (r"\input{x}", "unsupported LaTeX command", 1),
    (r"m_1 + \def\x{1}", "unsupported LaTeX command", 7),
    (r"$\newcommand{\a}{1}$", "unsupported LaTeX command", 2),
    (r"\foo", "unsupported LaTeX command", 1),
    (r"\begin{vmatrix} a & b \\ c & d \end{vmatrix}", "unsupported LaTeX command", 1),
    (r"\begin{align} a \end{align}", "unsupported LaTeX command", 1),
    (r"\frac{1}{", "never closed", 9),
    (r"\left( q_1 + q_2", "never closed", 1),
    (r"\left( q_1 + q_2 \right]", "closed by", 24),
    (r"m_1 + (q_1", "never closed", 7),
    (r"m_1 + q_1)", "unmatched ')'", 10),
    (r"m_1}", "unmatched '}'", 4),
    (r"q_1 & q_2", "outside a matrix", 5),
    (r"\begin{pmatrix} a & b \\ c \end{pmatrix}", "different lengths", 1),
    (r"\begin{pmatrix} q_1 & \end{pmatrix}", "empty matrix entry", 23),
    (r"\begin{pmatrix} q_1", "never closed", 1),
    ("q_12", "ambiguous subscript", 2),
    ("q^-1", "negative exponent", 3),
    (r"q_1^2^3", "double superscript", 6),
    (r"\sin^{-1} q_1", "ambiguous inverse", 5),
    (r"\sin", "needs an argument", 1),
    ("q_1 = 2", "unexpected character '='", 5),
    ("$q_1", "unbalanced '$'", 1),
    ("{" * 10000, "nested too deeply", 61),
    ("", "empty expression", 0),
    ("$ $", "empty expression", 0),
], ids=lambda v: repr(v)[:40])
def test_rejects_with_column(text, fragment, col):
    with pytest.raises(ExprError) as exc:
        parse_latex(text, NAMES)
    assert fragment in str(exc.value)
    if col is not None:
        assert exc.value.col == col


@pytest.mark.parametrize("text", [
    "{" * 10000, r"\frac{" * 3000, r"\frac{" * 10000, r"\sin" * 4000 + " q_1", "(" * 10000, r"\left(" * 3000,
    "q_1^{" * 3000, r"\sqrt{" * 3000, "-" * 10000 + "q_1", r"\dot{" * 3000,
], ids=lambda v: repr(v)[:20])
def test_deep_nesting_fails_fast(text):
    with pytest.raises(ExprError, match="too deeply|too long"):
        parse_latex(text, NAMES)


def test_ambiguous_product_hint():
    with pytest.raises(ExprError) as exc:
        parse_latex("m2l1", NAMES)
    assert "ambiguous" in exc.value.message and "m2*l1" in exc.value.message
    assert exc.value.hint == r"write m_2 l_1 or m_2 \cdot l_1"


def test_plain_parser_errors_say_how_it_was_read():
    with pytest.raises(ExprError) as exc:
        parse_latex("x_1", NAMES)
    assert "unknown name 'x1'" in exc.value.message and "read as: x1" in exc.value.message
    assert exc.value.text == "x_1"
    with pytest.raises(ExprError) as exc:
        parse_latex(r"\sin q_1 \cdot", NAMES)
    assert "read as: sin(q1)*" in exc.value.message


def test_huge_input_fails_fast():
    with pytest.raises(ExprError, match="too long"):
        parse_latex("x" * 1_000_000, NAMES)
    with pytest.raises(ExprError, match="too long"):
        parse_latex("{" * (MAX_LENGTH + 1), NAMES)


def test_looks_like_latex():
    assert looks_like_latex(r"\sin q_1") and looks_like_latex("$x$") and looks_like_latex("m_2")
    assert looks_like_latex("{x}") and looks_like_latex(" x$")
    assert not looks_like_latex("m2*l1*sin(q1)")


FRAGMENTS = [
    "\\", "{", "}", "^", "_", "$", "&", "\\\\", " ", "+", "-", "*", "/", ",", ".", "|", "(", ")", "[", "]",
    "q", "m", "l", "c", "s", "e", "T", "1", "2", "3", "\\frac", "\\sin", "\\cos", "\\sqrt", "\\dot", "\\ddot",
    "\\left(", "\\right)", "\\left|", "\\right|", "\\cdot", "\\alpha", "\\ell", "\\pi", "\\theta",
    "\\begin{pmatrix}", "\\end{pmatrix}", "\\begin{vmatrix}", "\\operatorname{atan2}", "\\mathrm", "\\,", "~",
]
random_text = st.one_of(
    st.text(max_size=60),
    st.text(alphabet="\\{}^_$&()[]|+-*/.,=~ qmlcse123T", max_size=60),
    st.lists(st.sampled_from(FRAGMENTS), max_size=40).map("".join),
)


@settings(max_examples=100, deadline=None)
@given(random_text)
def test_random_text_only_expr_errors(text):
    try:
        parse_latex(text, NAMES)
    except ExprError:
        pass


SYMBOLS = [sp.Symbol(n) for n in SYMBOL_LATEX]
SYMBOL_NAMES = {sp.Symbol(n): v for n, v in SYMBOL_LATEX.items()}
leaves = st.one_of(st.sampled_from(SYMBOLS), st.integers(-5, 5).map(sp.Integer))


def _extend(children):
    pairs = st.tuples(children, children)
    return st.one_of(
        pairs.map(lambda p: p[0] + p[1]),
        pairs.map(lambda p: p[0] - p[1]),
        pairs.map(lambda p: p[0] * p[1]),
        st.tuples(children, st.integers(1, 3)).map(lambda p: p[0] ** p[1]),
    )


expressions = st.recursive(leaves, _extend, max_leaves=8)


@settings(max_examples=100, deadline=None)
@given(expressions)
def test_round_trip_of_sympy_latex(e):
    text = sp.latex(e, symbol_names=SYMBOL_NAMES)
    assert sp.expand(parse_latex(text, NAMES) - e) == 0, text


@settings(max_examples=100, deadline=None)
@given(expressions, st.integers(2, 5), st.sampled_from([sp.sin, sp.cos]))
def test_round_trip_with_fractions_and_trig(e, k, fn):
    e = fn(e) * e / k
    text = sp.latex(e, symbol_names=SYMBOL_NAMES)
    assert sp.expand(parse_latex(text, NAMES) - e) == 0, text
