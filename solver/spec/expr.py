"""The one expression parser of robosolve: plain math text -> sympy, by an allow-list.

Grammar (precedence low to high)::

    expr    := term (('+' | '-') term)*
    term    := unary (('*' | '/') unary)*
    unary   := ('+' | '-') unary | power
    power   := primary (('^' | '**') unary)?          # right associative: 2^3^2 = 2^9
    primary := NUMBER | NAME | NAME '(' expr (',' expr)* ')' | '(' expr ')' | '[' expr (',' expr)* ']'

Names resolve only through the table the caller gives (parameters, coordinates, abbreviations) plus the
constant ``pi`` and the functions in :data:`FUNCTIONS`. Nothing is ever evaluated by Python: no ``eval``,
no ``sympify`` of raw text, no attribute access. Lists (``[a, b]``, ``[[a, b], [c, d]]``) come back as
nested Python lists of sympy expressions.
"""
from __future__ import annotations

import difflib
import re
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Union

import sympy as sp

from solver.spec.errors import ExprError

MAX_LENGTH = 20_000
MAX_DEPTH = 60
MAX_EXPONENT = 100
MAX_LIST = 400
MAX_DEGREE = 1000      # polynomial degree an expression may reach once expanded
MAX_DIGITS = 5000      # decimal digits of the integers it may produce
MAXDECIMAL_EXP = 300  # 1e300 is the largest power of ten a number may carry

FUNCTIONS: dict[str, tuple[Callable[..., sp.Expr], int]] = {
    "sin": (sp.sin, 1), "cos": (sp.cos, 1), "tan": (sp.tan, 1), "cot": (sp.cot, 1),
    "asin": (sp.asin, 1), "acos": (sp.acos, 1), "atan": (sp.atan, 1), "atan2": (sp.atan2, 2),
    "sinh": (sp.sinh, 1), "cosh": (sp.cosh, 1), "tanh": (sp.tanh, 1),
    "exp": (sp.exp, 1), "log": (sp.log, 1), "ln": (sp.log, 1), "sqrt": (sp.sqrt, 1),
    "abs": (sp.Abs, 1), "sign": (sp.sign, 1),
}
CONSTANTS: dict[str, sp.Expr] = {"pi": sp.pi}
GREEK = (
    "alpha beta gamma delta epsilon zeta eta theta iota kappa lambda mu nu xi omicron rho sigma tau "
    "upsilon phi chi psi omega Gamma Delta Theta Lambda Xi Pi Sigma Upsilon Phi Psi Omega"
).split()

Parsed = Union[sp.Expr, list]

_TOKEN = re.compile(
    r"\s*(?:(?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)|(?P<name>[A-Za-z_][A-Za-z0-9_]*)|(?P<op>\*\*|[-+*/^(),\[\]]))"
)


@dataclass
class Token:
    kind: str  # num | name | op | end
    text: str
    col: int  # 1-based


def tokenize(text: str) -> list[Token]:
    """Split ``text`` into tokens; anything outside the grammar's alphabet is an error at its column."""
    tokens: list[Token] = []
    pos = 0
    while pos < len(text):
        if text[pos:].strip() == "":
            break
        m = _TOKEN.match(text, pos)
        if not m:
            bad = text[pos:].lstrip()[0]
            col = len(text) - len(text[pos:].lstrip()) + 1
            hint = {
                ".": "attribute access is not allowed; write plain math",
                "=": "an expression has no '='; give the value only",
                "{": "use [ ] for lists and matrices, ( ) for grouping",
                "\\": "write plain math here (sin(q1), not \\sin q_1)",
            }.get(bad, "allowed: numbers, names, + - * / ^ **, ( ), [ ] and ','")
            raise ExprError(f"unexpected character {bad!r}", text, col, hint)
        kind = m.lastgroup or "op"
        tokens.append(Token(kind, m.group(kind), m.start(kind) + 1))
        pos = m.end()
    tokens.append(Token("end", "", len(text) + 1))
    return tokens


class Parser:
    """Recursive-descent parser over :func:`tokenize`'s tokens, resolving names through ``names``."""

    def __init__(self, text: str, names: Mapping[str, sp.Expr], allow_lists: bool = True) -> None:
        if len(text) > MAX_LENGTH:
            raise ExprError(f"expression too long ({len(text)} characters, limit {MAX_LENGTH})", "", 0,
                            "split it with abbreviations (where:)")
        self.text = text
        self.names = names
        self.allow_lists = allow_lists
        self.tokens = tokenize(text)
        self.i = 0
        self.depth = 0

    # -- helpers -----------------------------------------------------------------------------------
    @property
    def tok(self) -> Token:
        return self.tokens[self.i]

    def error(self, message: str, tok: Token | None = None, hint: str | None = None) -> ExprError:
        tok = tok or self.tok
        return ExprError(message, self.text, tok.col, hint)

    def expect(self, op: str) -> Token:
        if self.tok.kind == "op" and self.tok.text == op:
            t = self.tok
            self.i += 1
            return t
        t = self.tok
        if op in ")]," and (t.kind in ("name", "num") or (t.kind == "op" and t.text in "([")):
            raise self.error(f"missing operator before {t.text!r}", t, "write products with '*', e.g. m2*l1 or 2*q1")
        found = "end of text" if t.kind == "end" else repr(t.text)
        raise self.error(f"expected {op!r}, found {found}", hint="check that brackets are balanced")

    def at_op(self, *ops: str) -> bool:
        return self.tok.kind == "op" and self.tok.text in ops

    def enter(self) -> None:
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise self.error(f"expression nested too deeply (limit {MAX_DEPTH})", hint="simplify the expression")

    # -- grammar -------------------------------------------------------------------------------------
    def parse(self) -> Parsed:
        if self.tok.kind == "end":
            raise self.error("empty expression", hint="write a value, e.g. 0 or m1*l1")
        value = self.expr()
        if self.tok.kind != "end":
            t = self.tok
            if t.kind in ("name", "num") or (t.kind == "op" and t.text in "(["):
                raise self.error(f"missing operator before {t.text!r}", t,
                                 "write products with '*', e.g. m2*l1 or 2*q1")
            raise self.error(f"unexpected {t.text!r}", t, "check brackets and operators")
        return value

    def expr(self) -> Parsed:
        self.enter()
        left = self.term()
        while self.at_op("+", "-"):
            op = self.tok
            self.i += 1
            right = self.term()
            left = self.arith(op, left, right)
        self.depth -= 1
        return left

    def term(self) -> Parsed:
        left = self.unary()
        while self.at_op("*", "/"):
            op = self.tok
            self.i += 1
            right = self.unary()
            left = self.arith(op, left, right)
        return left

    def unary(self) -> Parsed:
        if self.at_op("-", "+"):
            op = self.tok
            self.i += 1
            self.enter()
            value = self.unary()
            self.depth -= 1
            if isinstance(value, list):
                raise self.error("a sign cannot apply to a list", op)
            return -value if op.text == "-" else value
        return self.power()

    def power(self) -> Parsed:
        base = self.primary()
        if self.at_op("^", "**"):
            op = self.tok
            self.i += 1
            self.enter()
            exponent = self.unary()
            self.depth -= 1
            if isinstance(base, list) or isinstance(exponent, list):
                raise self.error("powers of lists are not defined", op)
            if exponent.is_number:
                if not exponent.is_real or abs(float(exponent)) > MAX_EXPONENT:
                    raise self.error(f"exponent too large (|exponent| <= {MAX_EXPONENT})", op)
            if base.is_number and exponent.is_number and base.is_real and base != 0:
                digits = abs(float(exponent)) * abs(float(sp.log(abs(base), 10).evalf(5)))
                if digits > MAX_DIGITS:
                    raise self.error(f"number too large (more than {MAX_DIGITS} digits)", op)
            value = sp.Pow(base, exponent)
            check_magnitude(value, {}, lambda msg: self.error(msg, op, "simplify the expression"))
            return value
        return base

    def primary(self) -> Parsed:
        t = self.tok
        if t.kind == "num":
            self.i += 1
            return number(t.text, lambda msg: self.error(msg, t, "write a number of at most 30 digits, "
                                                                 f"with an exponent within ±{MAXDECIMAL_EXP}"))
        if t.kind == "name":
            self.i += 1
            if self.at_op("("):
                return self.call(t)
            return self.name(t)
        if self.at_op("("):
            self.i += 1
            self.enter()
            value = self.expr()
            self.depth -= 1
            self.expect(")")
            return value
        if self.at_op("["):
            if not self.allow_lists:
                raise self.error("a list is not expected here", t, "give a single expression")
            self.i += 1
            self.enter()
            items = [self.expr()]
            while self.at_op(","):
                self.i += 1
                items.append(self.expr())
                if len(items) > MAX_LIST:
                    raise self.error(f"list too long (limit {MAX_LIST})", t)
            self.depth -= 1
            self.expect("]")
            return items
        if t.kind == "end":
            raise self.error("expression ends too early", t, "complete the expression or balance brackets")
        raise self.error(f"unexpected {t.text!r}", t)

    def call(self, t: Token) -> sp.Expr:
        if t.text not in FUNCTIONS:
            close = difflib.get_close_matches(t.text, FUNCTIONS, n=1)
            hint = f"did you mean {close[0]}(...)?" if close else \
                f"known functions: {', '.join(sorted(FUNCTIONS))}; for a product write {t.text}*(...)"
            raise self.error(f"unknown function {t.text!r}", t, hint)
        fn, arity = FUNCTIONS[t.text]
        self.expect("(")
        self.enter()
        args = [self.expr()]
        while self.at_op(","):
            self.i += 1
            args.append(self.expr())
        self.depth -= 1
        self.expect(")")
        if len(args) != arity:
            raise self.error(f"{t.text} takes {arity} argument(s), got {len(args)}", t)
        if any(isinstance(a, list) for a in args):
            raise self.error(f"{t.text} of a list is not defined", t)
        return fn(*args)

    def name(self, t: Token) -> sp.Expr:
        if t.text in self.names:
            return self.names[t.text]
        if t.text in CONSTANTS:
            return CONSTANTS[t.text]
        if t.text in FUNCTIONS:
            raise self.error(f"{t.text} is a function: write {t.text}(...)", t)
        parts = split_product(t.text, self.names)
        if parts:
            raise self.error(f"unknown name {t.text!r}: a product without '*'?", t,
                             f"products need '*': write {'*'.join(parts)}")
        close = difflib.get_close_matches(t.text, list(self.names) + list(CONSTANTS), n=3)
        hint = f"did you mean {' or '.join(close)}?" if close else "declare it under symbols: (with its meaning)"
        if not close and re.fullmatch(r"[A-Za-z]+\d*[A-Za-z]+\d*", t.text):
            hint += "; a product needs '*' (m2*l1, not m2l1)"
        raise self.error(f"unknown name {t.text!r}", t, hint)

    def arith(self, op: Token, left: Parsed, right: Parsed) -> Parsed:
        if isinstance(left, list) or isinstance(right, list):
            if op.text == "*" and (isinstance(left, list) != isinstance(right, list)):
                scalar, lst = (left, right) if isinstance(right, list) else (right, left)
                return _scale(lst, scalar)
            if op.text in "+-" and isinstance(left, list) and isinstance(right, list):
                return _combine(left, right, op.text == "-", lambda: self.error("lists of different shapes", op))
            raise self.error(f"'{op.text}' is not defined between these operands (lists)", op)
        if op.text == "+":
            return left + right
        if op.text == "-":
            return left - right
        if op.text == "*":
            return left * right
        if right == 0:
            raise self.error("division by zero", op)
        return left / right


_NUMBER = re.compile(r"(\d*)(?:\.(\d*))?(?:[eE]([+-]?\d+))?\Z")


def number(text: str, fail: Callable[[str], Exception]) -> sp.Expr:
    """A decimal literal as an exact sympy number (1.5 -> 3/2, 2e-3 -> 1/500), refusing more than 30 digits or a
    decimal exponent beyond ±MAXDECIMAL_EXP (1e999999999 would take hours to build exactly)."""
    m = _NUMBER.match(text)
    if not m:
        raise fail(f"not a number: {text!r}")
    whole, frac, exp = m.group(1), m.group(2) or "", m.group(3)
    if len((whole + frac).lstrip("0")) > 30:
        raise fail("number too long (more than 30 digits)")
    if exp is not None and (len(exp.lstrip("+-")) > 4 or abs(int(exp)) > MAXDECIMAL_EXP):
        raise fail("number out of range")
    if frac == "" and exp is None:
        return sp.Integer(whole)
    value = sp.Rational(int(whole + frac or "0"), 10 ** len(frac))
    return value * sp.Integer(10) ** int(exp) if exp is not None else value


Magnitude = tuple[int, int]  # (polynomial degree, decimal digits of the integers), upper bounds


def magnitude(e: sp.Expr, env: Mapping[sp.Symbol, Magnitude], memo: dict | None = None) -> Magnitude:
    """Upper bounds of the degree and of the integer digits that expanding ``e`` can produce, with each symbol of
    ``env`` (an abbreviation) standing for an expression of the given magnitude. Cheap: never expands."""
    memo = {} if memo is None else memo
    hit = memo.get(e)
    if hit is not None:
        return hit
    if e.is_Integer:
        out = (0, int(abs(int(e.p)).bit_length() * 0.302) + 1)
    elif e.is_Rational:
        out = (0, int((abs(int(e.p)).bit_length() + int(e.q).bit_length()) * 0.302) + 2)
    elif e.is_Symbol:
        out = env.get(e, (1, 0))  # type: ignore[arg-type]
    elif e.is_Number or not e.args:
        out = (0, 20)
    else:
        parts = [magnitude(a, env, memo) for a in e.args]
        if e.is_Add:
            out = (max(p[0] for p in parts), max(p[1] for p in parts) + len(parts).bit_length())
        elif e.is_Mul:
            out = (sum(p[0] for p in parts), sum(p[1] for p in parts))
        elif e.is_Pow and e.exp.is_Integer:
            k = abs(int(e.exp))
            out = (parts[0][0] * k, parts[0][1] * k)
        else:  # functions and other powers: an atom of degree 1, its own numbers inside
            out = (max(1, max(p[0] for p in parts)), max(p[1] for p in parts))
    memo[e] = out
    return out


def check_magnitude(e: sp.Expr, env: Mapping[sp.Symbol, Magnitude], fail: Callable[[str], Exception]) -> Magnitude:
    """``magnitude(e, env)``, raising ``fail(message)`` beyond MAX_DEGREE or MAX_DIGITS."""
    deg, digits = magnitude(e, env)
    if deg > MAX_DEGREE:
        raise fail(f"expression of too high degree once expanded (more than {MAX_DEGREE})")
    if digits > MAX_DIGITS:
        raise fail(f"number too large once expanded (more than {MAX_DIGITS} digits)")
    return deg, digits


def split_product(text: str, names: Mapping[str, sp.Expr]) -> list[str] | None:
    """``text`` as a concatenation of two or more known names (m2l1 -> [m2, l1]), or None."""
    if len(text) > 40:
        return None
    known = set(names) | set(CONSTANTS)
    best: dict[int, list[str]] = {0: []}
    for i in range(len(text)):
        if i not in best:
            continue
        for j in range(i + 1, len(text) + 1):
            if text[i:j] in known and j not in best:
                best[j] = best[i] + [text[i:j]]
    out = best.get(len(text))
    return out if out and len(out) > 1 else None


def _scale(lst: list, k: sp.Expr) -> list:
    return [_scale(x, k) if isinstance(x, list) else k * x for x in lst]


def _combine(a: list, b: list, minus: bool, err: Callable[[], ExprError]) -> list:
    if len(a) != len(b):
        raise err()
    out = []
    for x, y in zip(a, b):
        if isinstance(x, list) and isinstance(y, list):
            out.append(_combine(x, y, minus, err))
        elif isinstance(x, list) or isinstance(y, list):
            raise err()
        else:
            out.append(x - y if minus else x + y)
    return out


def parse(text: str | int | float, names: Mapping[str, sp.Expr], allow_lists: bool = True) -> Parsed:
    """Parse plain math ``text`` into a sympy expression (or nested lists of them)."""
    if isinstance(text, bool):
        raise ExprError("expected an expression, got a boolean", str(text), 0)
    if isinstance(text, int):
        if abs(text).bit_length() > 100:
            raise ExprError("number too long (more than 30 digits)", "", 0, "write a number of at most 30 digits")
        return sp.Integer(text)
    if isinstance(text, float):
        if text != text or text in (float("inf"), float("-inf")):
            raise ExprError(f"not a finite number: {text}", "", 0, "write a number such as 0.5 or 1e-3")
        return number(repr(abs(text)), lambda msg: ExprError(msg, "", 0)) * (-1 if text < 0 else 1)
    if not isinstance(text, str):
        raise ExprError(f"expected an expression (text), got {type(text).__name__}", "", 0)
    return Parser(text, names, allow_lists).parse()


def parse_scalar(text: str | int | float, names: Mapping[str, sp.Expr]) -> sp.Expr:
    """Parse a single scalar expression (lists refused)."""
    return parse(text, names, allow_lists=False)  # type: ignore[return-value]


def expand_abbreviations(value: Parsed, subs: Mapping[sp.Symbol, sp.Expr], check_only: bool = False) -> Parsed:
    """``value`` (or nested lists of them) with abbreviation symbols replaced by their definitions, repeatedly
    (an abbreviation may use earlier ones). Raises ExprError, before expanding, when the result would be too
    large (a chain a2 = a1^100, a3 = a2^100, ...); ``check_only``: only that check."""
    if isinstance(value, list):
        return [expand_abbreviations(v, subs, check_only) for v in value]
    if not (getattr(value, "free_symbols", set()) & set(subs)):
        return value
    used, todo = set(), list(value.free_symbols & set(subs))
    while todo:  # the abbreviations the value needs, directly or through others
        s = todo.pop()
        if s not in used:
            used.add(s)
            todo += list(subs[s].free_symbols & set(subs))
    env: dict[sp.Symbol, Magnitude] = {}
    for _ in range(len(used) + 1):  # in dependency order: each in terms of the ones known so far
        for s in used:
            if s not in env and not (subs[s].free_symbols & set(subs)) - set(env):
                env[s] = check_magnitude(subs[s], env, _too_large)
    check_magnitude(value, env, _too_large)
    if check_only:
        return value
    for _ in range(len(subs) + 1):
        if not (getattr(value, "free_symbols", set()) & set(subs)):
            break
        value = value.xreplace(subs)
    return value


def _too_large(message: str) -> ExprError:
    return ExprError(message, "", 0, "abbreviations expand to this; simplify them")


def shape_of(value: Parsed) -> tuple[int, ...]:
    """Shape of a parsed value: () scalar, (n,) list, (n, m) list of equal-length lists, ..."""
    if not isinstance(value, list):
        return ()
    inner = {shape_of(v) for v in value}
    if len(inner) != 1:
        return (len(value), -1)
    return (len(value), *inner.pop())


def to_matrix(value: Parsed, text: str = "") -> sp.Matrix:
    """A parsed list as a sympy Matrix: [a, b] is a column, [[a, b], [c, d]] a 2x2 matrix."""
    shape = shape_of(value)
    if shape == () :
        return sp.Matrix([[value]])
    if len(shape) == 1:
        return sp.Matrix(value)
    if len(shape) == 2 and shape[1] >= 0:
        return sp.Matrix(value)
    raise ExprError(f"not a vector or matrix (shape {shape})", text, 0, "rows must have equal length")


DECIMAL = re.compile(r"[+-]?(\d+\.\d*|\.\d+|\d+(\.\d*)?[eE][+-]?\d+)")


def as_written(raw: Any, value: sp.Expr) -> Any:
    """A number of the spec as the user wrote it, for the report: a decimal literal (0.3333, -1.5e-3) as its text
    (the template prints it) instead of the exact rational it was read as (3333/10000); any other entry (an
    integer, a fraction, an expression) as its value."""
    if isinstance(raw, float):
        return repr(raw)
    if isinstance(raw, str) and DECIMAL.fullmatch(raw.strip()):
        return raw.strip()
    return value
