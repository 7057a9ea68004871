r"""LaTeX answers -> the plain syntax of :mod:`solver.spec.expr`: a translator, never an evaluator.

The LaTeX is tokenized and rewritten into plain text (``2*m2*l1*dq1``), which the one allow-list parser
:func:`solver.expr.parse` then reads. Accepted subset (anything else is an :class:`ExprError` whose column
points into the original text):

* the whole answer may be wrapped in ``$..$``, ``$$..$$``, ``\[..\]`` or ``\(..\)``;
* numbers; symbols with subscripts ``m_2``, ``I_{2x}``, ``d_{c3}`` (tried as ``dc3``, ``d_c3``, without
  commas; ``latex_names`` spellings first); plain tokens that are known names (``m2``, ``dc3``);
  ``\dot``/``\ddot`` (``\dot q_1`` -> ``dq1``); Greek letters (``\theta_1``, ``\ell_1`` -> ``l1``), ``\pi``,
  ``e^{x}``; the trig shorthand ``s_1``, ``c_{12}`` -> ``sin(q1)``, ``cos(q1+q2)``;
* ``+ - * / ,``, ``\cdot``, ``\times``, ``\div`` and products by juxtaposition (``2 m_2 l_1``);
* ``^`` powers, ``\frac``/``\dfrac``/``\tfrac``/``\cfrac``, ``\sqrt{x}``, ``\sqrt[n]{x}``;
* ``\sin \cos \tan \cot \arcsin \arccos \arctan \sinh \cosh \tanh \exp \log \ln`` (also
  ``\operatorname{atan2}`` and the plain words ``sin``, ...) with ``(..)``, ``\left(..\right)``, ``{..}`` or
  one unbracketed atom (``\cos 2q_1``), and ``\sin^2 x`` meaning ``sin(x)^2``;
* grouping ``( ) [ ] { } \{ \}``, ``\left( \right)`` (also ``[``, ``\{``, ``|``), ``\bigl(`` etc., ``|x|``;
* ``pmatrix``, ``bmatrix``, ``Bmatrix`` and ``matrix`` environments, with ``^T`` to transpose;
* spacing (``\, \; \: \! \quad \qquad ~``), ``\displaystyle`` are separators.

A run of letters that is not a known name (``m2l1``) is refused as an ambiguous product rather than split.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Collection, Mapping

import sympy as sp

from solver.spec.errors import ExprError
from solver.spec.expr import CONSTANTS, FUNCTIONS, GREEK, MAX_DEPTH, MAX_LENGTH, Parsed, parse

__all__ = ["latex_to_plain", "parse_latex", "looks_like_latex"]

_IGNORED = {"\\,", "\\;", "\\:", "\\!", "\\ ", "\\quad", "\\qquad", "\\enspace", "\\thinspace", "\\medspace",
            "\\thickspace", "\\displaystyle", "\\textstyle"} | {
    f"\\{size}{side}" for size in ("big", "Big", "bigg", "Bigg") for side in ("", "l", "r", "m")}
_FUNC_CMDS = {f"\\{f}": f for f in ("sin", "cos", "tan", "cot", "sinh", "cosh", "tanh", "exp", "log", "ln")} | {
    "\\arcsin": "asin", "\\arccos": "acos", "\\arctan": "atan"}
_FUNC_LATEX = {plain: cmd for cmd, plain in _FUNC_CMDS.items()}
_NO_INVERSE_POWER = {"sin", "cos", "tan", "cot", "sinh", "cosh", "tanh"}
_GREEK_CMDS: dict[str, list[str]] = {f"\\{g}": [g] for g in GREEK} | {
    "\\varphi": ["phi"], "\\vartheta": ["theta"], "\\varepsilon": ["epsilon"], "\\ell": ["l", "ell"],
    "\\pi": ["pi"]}
_WORD_CMDS = {"\\mathrm", "\\operatorname", "\\text", "\\textrm", "\\mathit"}
_FRACS = {"\\frac", "\\dfrac", "\\tfrac", "\\cfrac"}
_DOTS = {"\\dot": "d", "\\ddot": "dd"}
_MATRIX_ENVS = {"pmatrix", "bmatrix", "Bmatrix", "matrix"}
_LEFT = {"(": ")", "[": "]", "\\{": "\\}", "|": "|", "\\lvert": "\\rvert", "\\vert": "\\vert"}
_TIMES = {"\\cdot": "*", "\\times": "*", "\\ast": "*", "\\div": "/"}
_TRANSPOSE = {"T", "\\top", "\\intercal"}
_CHARS = set("+-*/^_(){}[]&,|.")
_CLOSE_CHARS = set("})]&")
_CLOSE_CMDS = {"\\}", "\\right", "\\end", "\\rvert", "\\\\"}
_CHAR_HINTS = {
    "=": "give only the value, without '='",
    "'": "write time derivatives as \\dot q_1",
    "$": "math delimiters $...$ must enclose the whole answer",
    "%": "LaTeX comments are not allowed",
}
_SIMPLE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*|\d+(?:\.\d*)?|\.\d+")


@dataclass(frozen=True)
class Tok:
    """A LaTeX token: kind is letter | digit | char | cmd | end; pos is the 0-based offset in the original text."""

    kind: str
    text: str
    pos: int
    space: bool = False  # whitespace or a spacing command precedes it


@dataclass
class _Piece:
    """A translated operand: plain text, or a matrix (kept as rows of cells until rendered), plus a power."""

    text: str = ""
    matrix: list[list[str]] | None = None
    power: str | None = None

    def render(self) -> str:
        text = self.text if self.matrix is None else _render_matrix(self.matrix)
        return text if self.power is None else f"{text}^{self.power}"


# -- helpers ------------------------------------------------------------------------------------------
def _is_char(t: Tok, c: str) -> bool:
    return t.kind == "char" and t.text == c


def _is_cmd(t: Tok, c: str) -> bool:
    return t.kind == "cmd" and t.text == c


def _is_wrapped(s: str) -> bool:
    """True if ``s`` is one parenthesized group, e.g. ``(a+b)`` but not ``(a)+(b)``."""
    if not (s.startswith("(") and s.endswith(")")):
        return False
    depth = 0
    for k, ch in enumerate(s):
        depth += ch == "("
        depth -= ch == ")"
        if depth == 0:
            return k == len(s) - 1
    return False


def _wrap(s: str) -> str:
    return s if _SIMPLE.fullmatch(s) or _is_wrapped(s) else f"({s})"


def _unwrap(s: str) -> str:
    return s[1:-1] if _is_wrapped(s) else s


def _render_matrix(rows: list[list[str]]) -> str:
    if len(rows) > 1 and all(len(r) == 1 for r in rows):
        return "[" + ", ".join(r[0] for r in rows) + "]"
    return "[" + ", ".join("[" + ", ".join(r) + "]" for r in rows) + "]"


def _candidates(base: str, sub: str | None) -> list[str]:
    """Plain spellings of base_sub, most likely first: dc3, d_c3, then without commas."""
    if sub is None:
        return [base]
    bare = sub.replace(",", "")
    out = [base + sub, f"{base}_{sub}", base + bare, f"{base}_{bare}", f"{base}_{sub.replace(',', '_')}"]
    return list(dict.fromkeys(out))


def _latex_symbol(piece: str) -> str:
    """m2 -> m_2, m12 -> m_{12}, m -> m (for hints)."""
    head, tail = piece[0], piece[1:]
    return head if not tail else f"{head}_{tail}" if len(tail) == 1 else f"{head}_{{{tail}}}"


# -- tokenizer ----------------------------------------------------------------------------------------
def _strip_delimiters(text: str) -> tuple[int, int]:
    """The span of ``text`` inside surrounding whitespace and one pair of math delimiters."""
    start, end = 0, len(text)
    while start < end and text[start].isspace():
        start += 1
    while end > start and text[end - 1].isspace():
        end -= 1
    for opening, closing in (("$$", "$$"), ("$", "$"), ("\\[", "\\]"), ("\\(", "\\)")):
        if end - start >= len(opening) + len(closing) and text.startswith(opening, start) \
                and text.endswith(closing, start, end):
            return start + len(opening), end - len(closing)
    if text.startswith("$", start, end) or text.endswith("$", start, end):
        col = start + 1 if text.startswith("$", start, end) else end
        raise ExprError("unbalanced '$'", text, col, "wrap the whole answer in $...$ or leave the $ out")
    return start, end


def _tokenize(text: str, start: int, end: int) -> list[Tok]:
    """Tokens of ``text[start:end]``; spacing commands only mark the next token's ``space``."""
    toks: list[Tok] = []
    i, space, depth = start, False, 0
    while i < end:
        ch = text[i]
        if ch.isspace() or ch == "~":
            space, i = True, i + 1
            continue
        if ch == "\\":
            j = i + 1
            if j >= end:
                raise ExprError("a lone backslash", text, i + 1, "remove it or complete the command")
            if text[j].isascii() and text[j].isalpha():
                while j < end and text[j].isascii() and text[j].isalpha():
                    j += 1
                name = text[i:j]
            else:
                name = "\\ " if text[j].isspace() else text[i:j + 1]
                j += 1
            if name in _IGNORED:
                space, i = True, j
                continue
            toks.append(Tok("cmd", name, i, space))
            space, i = False, j
            continue
        if ch.isascii() and ch.isalpha():
            kind = "letter"
        elif ch.isascii() and ch.isdigit():
            kind = "digit"
        elif ch in _CHARS:
            kind = "char"
            if ch == "{":
                depth += 1
                if depth > MAX_DEPTH:
                    raise ExprError(f"braces nested too deeply (limit {MAX_DEPTH})", text, i + 1,
                                    "simplify the expression")
            elif ch == "}":
                depth -= 1
        else:
            raise ExprError(f"unexpected character {ch!r}", text, i + 1,
                            _CHAR_HINTS.get(ch, "write LaTeX math: symbols, numbers, operators, \\frac, \\sin, ..."))
        toks.append(Tok(kind, ch, i, space))
        space, i = False, i + 1
    toks.append(Tok("end", "", end, space))
    return toks


def _normalize(toks: list[Tok], text: str) -> list[Tok]:
    """Brace the one-token arguments of ``_``, ``^``, ``\\dot``, ``\\ddot``: ``x_1`` -> ``x_{1}``."""
    out: list[Tok] = []
    i, n = 0, len(toks)
    while i < n:
        t = toks[i]
        out.append(t)
        i += 1
        takes_arg = (t.kind == "char" and t.text in "_^") or (t.kind == "cmd" and t.text in _DOTS)
        if not takes_arg or i >= n or toks[i].kind == "end" or _is_char(toks[i], "{"):
            continue
        a = toks[i]
        if t.text == "^" and _is_char(a, "-"):
            raise ExprError("a negative exponent needs braces", text, a.pos + 1, "write x^{-1}")
        nxt = toks[i + 1]
        if t.text in "_^" and a.kind == "digit" and nxt.kind == "digit" and not nxt.space:
            what, sym = ("subscript", "_") if t.text == "_" else ("exponent", "^")
            base = toks[i - 2].text if i >= 2 and toks[i - 2].kind in ("letter", "cmd") else "x"
            raise ExprError(f"ambiguous {what} '{sym}{a.text}{nxt.text}'", text, t.pos + 1,
                            f"write {base}{sym}{{{a.text}{nxt.text}}} or {base}{sym}{a.text} \\cdot {nxt.text}")
        out += [Tok("char", "{", a.pos, a.space), Tok(a.kind, a.text, a.pos), Tok("char", "}", a.pos)]
        i += 1
    return out


def _latex_keys(latex_names: Mapping[str, str] | None) -> dict[tuple[str, ...], str]:
    """latex_names with each spelling reduced to its normalized token texts (whitespace-insensitive)."""
    table: dict[tuple[str, ...], str] = {}
    for spelling, plain in (latex_names or {}).items():
        start, end = _strip_delimiters(spelling)
        toks = _normalize(_tokenize(spelling, start, end), spelling)
        table[tuple(t.text for t in toks if t.kind != "end")] = plain
    return table


# -- translator ---------------------------------------------------------------------------------------
class _Translator:
    """Recursive translator over normalized tokens; each method consumes one construct and returns plain text."""

    def __init__(self, text: str, toks: list[Tok], names: Collection[str], keys: dict[tuple[str, ...], str],
                 trig_shorthand: bool) -> None:
        self.text = text
        self.toks = toks
        self.names = names
        self.keys = keys
        self.trig = trig_shorthand
        self.i = 0
        self.depth = 0
        self.in_abs = False  # inside |...|: a '|' after an operand closes it

    # -- token helpers ---------------------------------------------------------------------------------
    @property
    def tok(self) -> Tok:
        return self.toks[self.i]

    def peek(self, k: int) -> Tok:
        return self.toks[min(self.i + k, len(self.toks) - 1)]

    def error(self, message: str, tok: Tok, hint: str | None = None) -> ExprError:
        return ExprError(message, self.text, tok.pos + 1, hint)

    def at(self, c: str) -> bool:
        return _is_char(self.tok, c)

    def close(self, closing: str, opener: Tok) -> None:
        """Consume ``closing`` (a char or a command) or explain which opener is left open."""
        t, opened = self.tok, opener.text
        if t.text == closing and t.kind in ("char", "cmd"):
            self.i += 1
            return
        if t.kind == "end":
            raise self.error(f"'{opened}' at column {opener.pos + 1} is never closed", opener,
                             f"add '{closing}' or check that brackets are balanced")
        raise self.error(f"expected '{closing}' to close '{opened}' from column {opener.pos + 1}, "
                         f"found '{t.text}'", t, "check that brackets are balanced")

    def is_closer(self, t: Tok, after_operand: bool) -> bool:
        return (t.kind == "end" or (t.kind == "char" and t.text in _CLOSE_CHARS)
                or (t.kind == "cmd" and t.text in _CLOSE_CMDS)
                or (self.in_abs and after_operand and _is_char(t, "|")))

    def starts_atom(self) -> bool:
        t = self.tok
        if t.kind in ("letter", "digit"):
            return True
        if t.kind == "char":
            return t.text in "([{|."
        return t.kind == "cmd" and t.text not in _CLOSE_CMDS and t.text not in _TIMES

    def word_at(self, i: int) -> tuple[str, int]:
        """The run of letters and digits (no space inside) starting at token ``i``, and the index after it."""
        j = i
        while self.toks[j].kind in ("letter", "digit") and (j == i or not self.toks[j].space):
            j += 1
        return "".join(t.text for t in self.toks[i:j]), j

    def braced_word_at(self, i: int) -> tuple[str, int] | None:
        """``{word}`` starting at token ``i``: the word and the index after ``}``, else None."""
        if not _is_char(self.toks[i], "{") or self.toks[i + 1].kind != "letter":
            return None
        word, j = self.word_at(i + 1)
        return (word, j + 1) if _is_char(self.toks[j], "}") else None

    def inner(self, opener: Tok, closing: str, abs_bars: bool = False) -> str:
        """Translate up to ``closing`` (consumed); ``|`` starts a fresh context inside any group."""
        saved, self.in_abs = self.in_abs, abs_bars
        text = self.seq()
        self.in_abs = saved
        self.close(closing, opener)
        return text

    # -- grammar ---------------------------------------------------------------------------------------
    def translate(self) -> str:
        out = self.seq()
        t = self.tok
        if t.kind != "end":
            raise self.stray(t)
        if not out:
            raise ExprError("empty expression", self.text, 0, "write a value, e.g. 0 or m_1 l_1")
        return out

    def stray(self, t: Tok) -> ExprError:
        messages = {
            "&": ("'&' outside a matrix", "use \\begin{pmatrix} a & b \\end{pmatrix}"),
            "\\\\": ("line break \\\\ outside a matrix", "use \\begin{pmatrix} a \\\\ b \\end{pmatrix}"),
            "\\right": ("\\right without \\left", "write \\left( ... \\right)"),
            "\\end": ("\\end without \\begin", None),
        }
        message, hint = messages.get(t.text, (f"unmatched '{t.text}'", "check that brackets are balanced"))
        return self.error(message, t, hint)

    def seq(self) -> str:
        """Operands and operators up to a closer; juxtaposed operands are multiplied."""
        out: list[str] = []
        operand = False
        while not self.is_closer(self.tok, operand):
            t = self.tok
            if t.kind == "char" and t.text in "+-*/,":
                out.append(", " if t.text == "," else t.text)
                operand, self.i = False, self.i + 1
                continue
            if t.kind == "cmd" and t.text in _TIMES:
                out.append(_TIMES[t.text])
                operand, self.i = False, self.i + 1
                continue
            piece = self.factor()
            if piece is None:
                continue
            if operand:
                out.append("*")
            out.append(piece.render())
            operand = True
        return "".join(out)

    def factor(self) -> _Piece | None:
        """An atom with its superscript (or ``^T`` after a matrix)."""
        piece = self.atom()
        if piece is None:
            if self.at("^") or self.at("_"):
                raise self.error("superscript or subscript without a base", self.tok, "put it after a symbol")
            return None
        had_power = piece.power is not None
        while True:
            t = self.tok
            if self.at("_"):
                raise self.error("unexpected subscript", t,
                                 "subscripts go on symbols, once: m_2, d_{c3}; write x_1^2, not x^2_1")
            if not self.at("^"):
                return piece
            if had_power:
                raise self.error("double superscript", t, "use braces, e.g. {x^2}^3")
            had_power = True
            self.i += 1
            if piece.matrix is not None and self.transpose_mark():
                piece.matrix = [list(r) for r in zip(*piece.matrix)]
            else:
                piece.power = self.exponent(t)

    def transpose_mark(self) -> bool:
        """Consume ``{T}`` (or ``{\\top}``) after ``^``."""
        t = self.peek(1)
        if self.at("{") and t.kind in ("letter", "cmd") and t.text in _TRANSPOSE and _is_char(self.peek(2), "}"):
            self.i += 3
            return True
        return False

    def exponent(self, caret: Tok) -> str:
        if not self.at("{"):
            raise self.error("'^' needs an exponent", caret, "write x^2 or x^{n+1}")
        opener = self.tok
        self.i += 1
        text = self.inner(opener, "}")
        if not text:
            raise self.error("empty exponent", caret, "write x^2 or x^{n+1}")
        return _wrap(text)

    def atom(self) -> _Piece | None:
        t = self.tok
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise self.error(f"expression nested too deeply (limit {MAX_DEPTH})", t, "simplify the expression")
        try:
            return self._atom(t)
        finally:
            self.depth -= 1

    def _atom(self, t: Tok) -> _Piece | None:
        if t.kind == "digit" or (_is_char(t, ".") and self.peek(1).kind == "digit"):
            return _Piece(self.number())
        if t.kind == "letter":
            word, after = self.word_at(self.i)
            if word in FUNCTIONS and word not in self.names:
                self.i = after
                return self.function(word, t)
            return self.symbol()
        if t.kind == "char":
            if t.text in "([":
                self.i += 1
                text = self.inner(t, ")" if t.text == "(" else "]")
                if not text:
                    raise self.error(f"empty {t.text}{')' if t.text == '(' else ']'}", t)
                return _Piece(_wrap(text))
            if t.text == "{":
                self.i += 1
                text = self.inner(t, "}")
                return _Piece(_wrap(text)) if text else None
            if t.text == "|":
                self.i += 1
                return self.abs_of(t, "|", True)
            raise self.error(f"unexpected '{t.text}'", t, "check operators and brackets")
        c = t.text
        if c in _FUNC_CMDS:
            self.i += 1
            return self.function(_FUNC_CMDS[c], t)
        if c in _GREEK_CMDS or c in _DOTS:
            return self.symbol()
        if c in _WORD_CMDS:
            found = self.braced_word_at(self.i + 1)
            if found is None:
                raise self.error(f"{c}{{...}} must hold one word of letters and digits", t)
            if found[0] in FUNCTIONS:
                self.i = found[1]
                return self.function(found[0], t)
            return self.symbol()
        if c in _FRACS:
            self.i += 1
            num = self.arg(t, "numerator")
            den = self.arg(t, "denominator")
            return _Piece(f"(({num})/({den}))")
        if c == "\\sqrt":
            return self.sqrt(t)
        if c == "\\left":
            return self.left(t)
        if c == "\\lvert":
            self.i += 1
            return self.abs_of(t, "\\rvert", False)
        if c == "\\{":
            self.i += 1
            text = self.inner(t, "\\}")
            if not text:
                raise self.error("empty \\{ \\}", t)
            return _Piece(_wrap(text))
        if c == "\\begin":
            return self.matrix(t)
        raise self.error(f"unsupported LaTeX command {c}", t,
                         "allowed: \\frac, \\sqrt, \\sin, \\cos, ..., \\dot, \\ddot, Greek letters, \\cdot, "
                         "\\left( \\right), pmatrix/bmatrix")

    def abs_of(self, opener: Tok, closing: str, bars: bool) -> _Piece:
        text = self.inner(opener, closing, abs_bars=bars)
        if not text:
            raise self.error("empty absolute value", opener)
        return _Piece(f"abs({text})")

    def number(self) -> str:
        digits: list[str] = []
        while self.tok.kind == "digit" and (not digits or not self.tok.space):
            digits.append(self.tok.text)
            self.i += 1
        nxt = self.peek(1)
        if self.at(".") and (not digits or not self.tok.space) and nxt.kind == "digit" and not nxt.space:
            digits.append(".")
            self.i += 1
            while self.tok.kind == "digit" and not self.tok.space:
                digits.append(self.tok.text)
                self.i += 1
        return "".join(digits)

    def arg(self, cmd: Tok, what: str) -> str:
        """A command argument: ``{...}`` or one token (``\\frac12``)."""
        a = self.tok
        if self.at("{"):
            self.i += 1
            text = self.inner(a, "}")
            if not text:
                raise self.error(f"empty {what} in {cmd.text}", a)
            return text
        if a.kind == "digit":
            self.i += 1
            return a.text
        if a.kind == "letter" or a.text in _GREEK_CMDS:
            self.i += 1
            if self.at("_") or self.at("^"):
                raise self.error(f"the {what} of {cmd.text} needs braces", a, f"write {cmd.text}{{...}}")
            alts = [a.text] if a.kind == "letter" else _GREEK_CMDS[a.text]
            return self.resolve(alts, None, "", a.kind == "letter", [((a.text,), "")], a)
        if a.kind == "end":
            raise self.error(f"{cmd.text} needs a {what}", cmd, f"write {cmd.text}{{...}}")
        raise self.error(f"{cmd.text} needs its {what} in braces", a, f"write {cmd.text}{{...}}")

    def sqrt(self, t: Tok) -> _Piece:
        self.i += 1
        index = None
        if self.at("["):
            opener = self.tok
            self.i += 1
            index = self.inner(opener, "]")
            if not index:
                raise self.error("empty root index", opener, "write \\sqrt[3]{x}")
        radicand = self.arg(t, "radicand")
        return _Piece(f"sqrt({radicand})" if index is None else f"(({radicand})^(1/({index})))")

    def left(self, t: Tok) -> _Piece:
        self.i += 1
        d = self.tok
        if d.kind not in ("char", "cmd") or d.text not in _LEFT:
            raise self.error("unsupported delimiter after \\left", d, "use \\left( \\right), \\left[ \\right] or "
                                                                      "\\left| \\right|")
        closing = _LEFT[d.text]
        self.i += 1
        saved, self.in_abs = self.in_abs, False
        text = self.seq()
        self.in_abs = saved
        r = self.tok
        if not _is_cmd(r, "\\right"):
            if r.kind == "end":
                raise self.error(f"\\left{d.text} at column {t.pos + 1} is never closed", t,
                                 f"add \\right{closing}")
            raise self.error(f"expected \\right{closing} to close \\left{d.text} from column {t.pos + 1}, "
                             f"found '{r.text}'", r, "check that brackets are balanced")
        self.i += 1
        c = self.tok
        if c.text != closing or c.kind not in ("char", "cmd"):
            raise self.error(f"\\left{d.text} is closed by \\right{c.text}", c, f"write \\right{closing}")
        self.i += 1
        if not text:
            raise self.error("empty \\left \\right group", t)
        return _Piece(f"abs({text})" if closing in ("|", "\\rvert", "\\vert") else _wrap(text))

    def function(self, name: str, t: Tok) -> _Piece:
        """``name`` already consumed: optional ``^power``, then the argument."""
        power = None
        if self.at("^"):
            caret = self.tok
            self.i += 1
            power = self.exponent(caret)
            if power == "(-1)" and name in _NO_INVERSE_POWER:
                raise self.error(f"ambiguous inverse: {t.text}^{{-1}}", caret,
                                 "write \\arcsin x (\\arccos, \\arctan) for an inverse, "
                                 f"or ({t.text} x)^{{-1}} for a reciprocal")
        if self.at("_"):
            raise self.error(f"a subscript on {name} is not supported", self.tok,
                             "for a logarithm to base b write \\frac{\\ln x}{\\ln b}")
        a = self.tok
        if (a.kind == "char" and a.text in "([{|") or (a.kind == "cmd" and a.text in ("\\left", "\\lvert", "\\{")):
            piece = self.atom()
            if piece is None:
                raise self.error(f"{name} needs an argument", a)
            arg = _unwrap(piece.text)
        else:
            parts: list[str] = []
            if a.kind == "digit" or (self.at(".") and self.peek(1).kind == "digit"):
                number = self.factor()
                if number is not None:
                    parts.append(number.render())
            if self.starts_atom() and self.tok.kind != "digit":
                rest = self.factor()
                if rest is not None:
                    parts.append(rest.render())
            if not parts:
                raise self.error(f"{t.text} needs an argument", t, f"write e.g. {t.text}(q_1)")
            arg = "*".join(parts)
        return _Piece(f"{name}({arg})", power=power)

    def symbol(self) -> _Piece:
        """A symbol with optional ``\\dot``/``\\ddot`` and subscript, resolved to a plain name."""
        first = self.tok
        prefix = _DOTS.get(first.text, "") if first.kind == "cmd" else ""
        if prefix:
            self.i += 1
            brace = self.tok
            if not self.at("{"):
                raise self.error(f"{first.text} needs a symbol", first, f"write {first.text} q_1")
            self.i += 1
            alts, letters, base = self.symbol_base(first)
            sub, sub_texts = self.subscript()
            self.close("}", brace)
            if sub is None:
                sub, sub_texts = self.subscript()
            elif self.at("_"):
                raise self.error("double subscript", self.tok, f"write {first.text}{{q}}_1")
            keys = [((first.text, "{") + base + ("}",) + sub_texts, ""),
                    ((first.text, "{") + base + sub_texts + ("}",), ""), (base + sub_texts, prefix)]
        else:
            alts, letters, base = self.symbol_base(first)
            sub, sub_texts = self.subscript()
            keys = [(base + sub_texts, "")]
        if not prefix and sub is None and alts == ["e"] and "e" not in self.names and base not in self.keys:
            if self.at("^"):  # Euler's number
                caret = self.tok
                self.i += 1
                return _Piece(f"exp({_unwrap(self.exponent(caret))})")
            return _Piece("exp(1)")
        return _Piece(self.resolve(alts, sub, prefix, letters, keys, first))

    def symbol_base(self, ctx: Tok) -> tuple[list[str], bool, tuple[str, ...]]:
        """The base of a symbol: (plain spellings to try, written as bare letters?, its token texts)."""
        t = self.tok
        if t.kind == "letter":
            word, after = self.word_at(self.i)
            texts = tuple(x.text for x in self.toks[self.i:after])
            self.i = after
            return [word], True, texts
        if t.kind == "cmd" and t.text in _GREEK_CMDS:
            self.i += 1
            digits = ""
            while t.text != "\\pi" and self.tok.kind == "digit" and not self.tok.space:  # \theta1 = theta1
                digits += self.tok.text
                self.i += 1
            return [a + digits for a in _GREEK_CMDS[t.text]], False, (t.text, *digits)
        if t.kind == "cmd" and t.text in _WORD_CMDS:
            found = self.braced_word_at(self.i + 1)
            if found is not None:
                texts = tuple(x.text for x in self.toks[self.i:found[1]])
                self.i = found[1]
                return [found[0]], False, texts
        raise self.error(f"{ctx.text} must be applied to a symbol", t, f"write {ctx.text} q_1")

    def subscript(self) -> tuple[str | None, tuple[str, ...]]:
        """``_{...}`` of letters, digits and commas: (its text, its token texts incl. ``_ { }``) or (None, ())."""
        if not self.at("_"):
            return None, ()
        under = self.tok
        self.i += 1
        brace = self.tok
        if not self.at("{"):
            raise self.error("'_' needs a subscript", under, "write m_2 or d_{c3}")
        self.i += 1
        start = self.i
        while self.tok.kind in ("letter", "digit") or self.at(","):
            self.i += 1
        if not self.at("}"):
            if self.tok.kind == "end":
                self.close("}", brace)
            raise self.error("unsupported subscript", self.tok, "subscripts may hold letters, digits and commas")
        texts = tuple(x.text for x in self.toks[start:self.i])
        self.i += 1
        if not texts:
            raise self.error("empty subscript", under, "write m_2 or d_{c3}")
        return "".join(texts), ("_", "{", *texts, "}")

    def resolve(self, alts: list[str], sub: str | None, prefix: str, letters: bool,
                keys: list[tuple[tuple[str, ...], str]], t: Tok) -> str:
        """Plain name for a symbol: latex_names, known names, trig shorthand, else ``base+sub``."""
        for key, pre in keys:
            if key in self.keys:
                return pre + self.keys[key]
        for base in alts:
            for cand in _candidates(base, sub):
                if prefix + cand in self.names:
                    return prefix + cand
        base = alts[-1]
        if (letters and self.trig and not prefix and base in ("s", "c") and sub is not None and sub.isdigit()
                and all(f"q{d}" in self.names for d in sub)):
            return f"{'sin' if base == 's' else 'cos'}({'+'.join('q' + d for d in sub)})"
        if (letters and base not in self.names and not re.fullmatch(r"[A-Za-z]\d*", base)
                and base not in GREEK and base not in CONSTANTS and base not in FUNCTIONS):
            pieces = re.findall(r"[A-Za-z]\d*", base)
            plain, latex = list(pieces), [_latex_symbol(p) for p in pieces]
            if sub is not None:
                plain[-1] += sub
                latex[-1] += f"_{{{sub}}}"
            word = base + (f"_{{{sub}}}" if sub is not None else "")
            hint = f"write {' '.join(latex)} or " + " \\cdot ".join(latex)
            fn = next((f for f in sorted(FUNCTIONS, key=len, reverse=True) if base.startswith(f)), None)
            if fn is not None and not prefix:  # sinq_1: a function without its backslash and space
                rest = base[len(fn):] + (f"_{{{sub}}}" if sub is not None else "")
                command = _FUNC_LATEX.get(fn, "\\operatorname{" + fn + "}")
                hint = f"write {command} {rest}"
            raise self.error(f"ambiguous product '{word}' (read as {'*'.join(plain)}): "
                             "a run of letters that is not a known name", t, hint)
        return prefix + base + (sub.replace(",", "") if sub else "")

    def matrix(self, t: Tok) -> _Piece:
        self.i += 1
        found = self.braced_word_at(self.i)
        if found is None:
            raise self.error("\\begin needs an environment name in braces", t, "write \\begin{pmatrix}")
        env, self.i = found
        if env not in _MATRIX_ENVS:
            hint = ("determinants are not supported; write the matrix with pmatrix or bmatrix"
                    if env in ("vmatrix", "Vmatrix") else "only pmatrix, bmatrix, Bmatrix and matrix are allowed")
            raise self.error(f"unsupported LaTeX command \\begin{{{env}}}", t, hint)
        rows: list[list[tuple[str, Tok]]] = [[]]
        saved, self.in_abs = self.in_abs, False
        while True:
            cell_tok = self.tok
            cell = self.seq()
            s = self.tok
            rows[-1].append((cell, cell_tok))
            self.i += 1
            if _is_char(s, "&"):
                continue
            if _is_cmd(s, "\\\\"):
                rows.append([])
                continue
            if _is_cmd(s, "\\end"):
                end = self.braced_word_at(self.i)
                if end is None or end[0] != env:
                    raise self.error(f"\\begin{{{env}}} at column {t.pos + 1} is closed by a different \\end",
                                     s, f"write \\end{{{env}}}")
                self.i = end[1]
                break
            if s.kind == "end":
                self.i -= 1
                raise self.error(f"\\begin{{{env}}} at column {t.pos + 1} is never closed", t,
                                 f"add \\end{{{env}}}")
            raise self.error(f"unexpected '{s.text}' in a matrix", s, "separate entries with & and rows with \\\\")
        self.in_abs = saved
        if len(rows) > 1 and len(rows[-1]) == 1 and not rows[-1][0][0]:
            rows.pop()  # a trailing \\ before \end
        for row in rows:
            for cell, cell_tok in row:
                if not cell:
                    raise self.error("empty matrix entry", cell_tok, "write 0 for a zero entry")
        if len({len(r) for r in rows}) != 1:
            raise self.error("matrix rows have different lengths", t, "give every row the same number of entries")
        return _Piece(matrix=[[cell for cell, _ in row] for row in rows])


# -- public API ---------------------------------------------------------------------------------------
def latex_to_plain(text: str, names: Collection[str], latex_names: Mapping[str, str] | None = None,
                   trig_shorthand: bool = True) -> str:
    """Translate a LaTeX answer into the plain syntax of :func:`solver.expr.parse` (explicit ``*``)."""
    if not isinstance(text, str):
        raise ExprError(f"expected LaTeX text, got {type(text).__name__}", "", 0)
    if len(text) > MAX_LENGTH:
        raise ExprError(f"expression too long ({len(text)} characters, limit {MAX_LENGTH})", "", 0,
                        "split it with abbreviations (where:)")
    start, end = _strip_delimiters(text)
    toks = _normalize(_tokenize(text, start, end), text)
    return _Translator(text, toks, names, _latex_keys(latex_names), trig_shorthand).translate()


def parse_latex(text: str, names: Mapping[str, sp.Expr], latex_names: Mapping[str, str] | None = None,
                trig_shorthand: bool = True) -> Parsed:
    """Parse a LaTeX answer: :func:`latex_to_plain`, then :func:`solver.expr.parse`.

    Errors of the plain parser are re-raised against the LaTeX text, saying how the answer was read.
    """
    plain = latex_to_plain(text, names, latex_names, trig_shorthand)
    try:
        return parse(plain, names)
    except ExprError as exc:
        shown = plain if len(plain) <= 200 else plain[:200] + "..."
        raise ExprError(f"{exc.message} (read as: {shown})", text, 0, exc.hint) from exc


def looks_like_latex(text: str) -> bool:
    """True if ``text`` is probably LaTeX rather than plain math (backslash, ``$``, ``_`` or ``{``)."""
    stripped = text.strip()
    return ("\\" in text or stripped.startswith("$") or stripped.endswith("$") or "_" in text
            or "{" in text)
