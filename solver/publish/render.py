"""Rendering: Jinja2 templates (Markdown, LaTeX) and JSON. Solvers never format text; templates do."""
from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path
from typing import Any, Callable

import jinja2
import sympy as sp
from sympy.printing.latex import LatexPrinter
from sympy.printing.str import StrPrinter

from solver.math.nounits import without_units
from solver.publish.termorder import ordered_terms, printing_order
from solver.publish.texprint import DirectLatex, negative
from solver.publish.textprint import OutsideText, text
from solver.results import Result, Solution
from solver.spec.expr import DECIMAL
from solver.spec.texmath import safe_math
from solver.spec.problem import Problem

FORMATS = ("md", "tex", "json")


def templates_dir() -> Path:
    """The shipped templates: inside the installed package, else the repository's top-level templates/."""
    package = Path(__file__).resolve().parents[1]  # solver/
    for cand in (package / "templates", package.parent / "templates"):
        if cand.is_dir():
            return cand
    raise FileNotFoundError("robosolve templates not found")


class _Memo:
    """A sympy printer that prints each compound subexpression once: a model's results share most of their
    subexpressions (the same coefficient sums in B, the C_k, c, S and the model). The text of a subexpression does
    not depend on where it stands (parentheses are added by the caller), only on the printer's settings, of which
    "order" is changed while printing: it is part of the key. Floats, whose equal values may print with other
    precisions, are not memoized."""

    _MEMO_LIMIT = 200_000
    _memo_on = False

    def doprint(self, expr: Any) -> str:  # type: ignore[override]
        outer = self._memo_on
        try:
            self._memo_on = isinstance(expr, (sp.Basic, sp.MatrixBase)) and not has_float(expr)
            return super().doprint(expr)  # type: ignore[misc]
        finally:
            self._memo_on = outer

    def _as_ordered_terms(self, expr: Any, order: Any = None) -> list:  # type: ignore[override]
        """The terms of a sum in printing order, computed once for the text and the LaTeX printer alike (sympy's
        as_ordered_terms evaluates every coefficient numerically to sort them)."""
        order = order or self.order  # type: ignore[attr-defined]
        if order in ("old", "none"):
            return super()._as_ordered_terms(expr, order=order)  # type: ignore[misc]
        if not self._memo_on:
            return ordered_terms(expr, order)
        return list(printing_order(expr, order))

    def _print(self, expr: Any, **kwargs: Any) -> str:  # type: ignore[override]
        if kwargs or not self._memo_on or not isinstance(expr, sp.Basic) or expr.is_Atom:
            return super()._print(expr, **kwargs)  # type: ignore[misc]
        memo = self.__dict__.setdefault("_memo", {})
        key = (expr, self._settings.get("order"))  # type: ignore[attr-defined]
        hit = memo.get(key)
        if hit is None:
            if len(memo) > self._MEMO_LIMIT:
                memo.clear()
            hit = memo[key] = super()._print(expr)  # type: ignore[misc]
        return hit


class _Str(_Memo, StrPrinter):
    """sympy's str() (the JSON text), memoized."""


_STR = _Str()


def _text(e: sp.Basic) -> str:
    """str(e): directly where :func:`solver.publish.textprint.text` prints it, else by the memoized printer."""
    try:
        return text(e)
    except OutsideText:
        return _STR.doprint(e)


class _Printer(_Memo, LatexPrinter):
    """LaTeX printer writing products as a teacher does: m_2 l_1 q_2 \\dot q_1 \\cos q_2 (parameters, coordinates,
    velocities, accelerations, then functions)."""

    def __init__(self, names: dict[sp.Symbol, str], rank: dict[sp.Symbol, int]) -> None:
        super().__init__({"symbol_names": names, "fold_short_frac": False, "fold_func_brackets": True})
        self.rank = rank
        self._keys: dict[sp.Expr, tuple] = {}

    def _factor_key(self, f: sp.Expr) -> tuple:
        key = self._keys.get(f)
        if key is None:
            key = self._keys[f] = self._factor_key_of(f)
        return key

    def _factor_key_of(self, f: sp.Expr) -> tuple:
        base = f.as_base_exp()[0]
        if f.is_number:
            return (0, "")
        if base.is_Symbol:
            return (1 + self.rank.get(base, 0), base.name)
        if isinstance(base, (sp.sin, sp.cos)):
            return (6, _text(f))
        if isinstance(base, sp.Add):
            return (1.5, _text(f))
        return (5, _text(f))

    direct: DirectLatex | None = None  # the direct printer of plain subexpressions (set by Latex)

    def _print(self, expr: Any, **kwargs: Any) -> str:  # type: ignore[override]
        d = self.direct
        if d is not None and not kwargs and isinstance(expr, sp.Basic) and not expr.is_Atom and _plain(expr):
            order = self._settings["order"]
            if d.takes(expr, order):
                return d.tex(expr, order)
        return super()._print(expr, **kwargs)

    def _needs_mul_brackets(self, expr: sp.Expr, first: bool = False, last: bool = False) -> bool:
        """sympy's rule, decided directly for plain expressions (no Mod, integral, sum or product to look for
        inside): a sum, a negative number, and a product with a minus sign after the first factor."""
        if not _plain(expr):
            return super()._needs_mul_brackets(expr, first, last)
        if expr.is_Mul:
            return not first and expr.could_extract_minus_sign()
        return bool(expr.is_Add or (expr.is_Rational and expr.p < 0))

    def _needs_add_brackets(self, expr: sp.Expr) -> bool:
        """sympy's rule, directly for plain expressions: a sum."""
        return bool(expr.is_Add) if _plain(expr) else super()._needs_add_brackets(expr)

    def _print_Pow(self, expr: sp.Expr) -> str:
        """An even power of a sum that would print with a leading minus, (−D + 2d)², as (D − 2d)²."""
        b, e = expr.as_base_exp()
        if b.is_Add and e.is_Integer and e > 0 and e.is_even and self._print(b).startswith("-") \
                and not self._print(-b).startswith("-"):
            expr = sp.Pow(-b, e, evaluate=False)
        return super()._print_Pow(expr)

    def _print_Mul(self, expr: sp.Expr) -> str:
        coeff, rest = expr.as_coeff_Mul()
        factors = sp.Mul.make_args(rest)
        if len(factors) < 2 or any(f.is_Pow and f.exp.is_negative for f in factors):
            return super()._print_Mul(expr)
        ordered = sorted(factors, key=self._factor_key)
        body = sp.Mul(*ordered, evaluate=False)
        old = self._settings["order"]
        self._settings["order"] = "none"
        try:
            if coeff == 1:
                return super()._print_Mul(body)
            if coeff == -1:
                return "- " + super()._print_Mul(body)
            return super()._print_Mul(sp.Mul(coeff, body, evaluate=False))
        finally:
            self._settings["order"] = old


_PLAIN: dict[sp.Basic, bool] = {}
_FLOATS: dict[sp.Basic, bool] = {}


def _plain(e: sp.Basic) -> bool:
    """Whether ``e`` is made of sums, products, powers, sin, cos, symbols and rationals only (memoized)."""
    if e.is_Atom:
        return bool(e.is_Symbol or e.is_Rational)
    hit = _PLAIN.get(e)
    if hit is None:
        if len(_PLAIN) > 200_000:
            _PLAIN.clear()
        hit = _PLAIN[e] = type(e) in (sp.Add, sp.Mul, sp.Pow, sp.sin, sp.cos) and all(_plain(a) for a in e.args)
    return hit


def has_float(e: Any) -> bool:
    """``e.has(sp.Float)`` for an expression or a matrix, memoized by subtree."""
    if isinstance(e, sp.MatrixBase):
        return any(has_float(x) for x in e)
    if e.is_Atom:
        return bool(e.is_Float)
    hit = _FLOATS.get(e)
    if hit is None:
        if len(_FLOATS) > 200_000:
            _FLOATS.clear()
        hit = _FLOATS[e] = any(has_float(a) for a in e.args if isinstance(a, sp.Basic))
    return hit


class Latex:
    """sympy -> LaTeX with the problem's symbol names (q̇ as \\dot q, m2 as m_{2}, ...)."""

    def __init__(self, names: dict[sp.Symbol, str], rank: dict[sp.Symbol, int] | None = None,
                 width: int | None = None) -> None:
        names = {s: safe_math(tex) for s, tex in names.items()}
        self.names = names
        self.printer = _Printer(names, rank or {})
        self.printer.direct = DirectLatex(self.printer)
        self._symbols: dict[sp.Symbol, str] = {}
        self.width = width  # reports: a matrix wider than this many characters gets its long entries broken
        self._printed: dict[sp.Basic, str] = {}  # (the report prints an entry again to measure and to break it)
        self._fast_memo: dict[sp.Basic, str] = {}  # compound subexpressions of long expressions, printed by fast

    def fast(self, e: sp.Expr, memo: dict | None = None) -> str:
        """LaTeX of a long polynomial-like expression (sums, products, powers, sin/cos, numbers, symbols) printed
        directly, terms in stored order; with ``memo`` (an expression without floats) each compound subexpression
        once (the entries of B a share the numerators of a)."""
        if memo is None or e.is_Atom:
            return self._fast(e, memo)
        hit = memo.get(e)
        if hit is None:
            hit = memo[e] = self._fast(e, memo)
        return hit

    def _fast(self, e: sp.Expr, memo: dict | None) -> str:
        if e.is_Symbol:
            if e not in self._symbols:
                self._symbols[e] = self.printer.doprint(e)
            return self._symbols[e]
        if e.is_Rational:
            if e.q == 1:
                return str(e.p)
            return f"{'-' if e.p < 0 else ''}\\frac{{{abs(e.p)}}}{{{e.q}}}"
        if e.is_Add:
            out = ""
            for k, a in enumerate(e.args):
                neg = negative(a)
                body = self.fast(-a if neg else a, memo)
                out += ("- " if neg else "") + body if k == 0 else (" - " if neg else " + ") + body
            return out
        if e.is_Mul:
            coeff, rest = e.as_coeff_Mul()
            factors = sp.Mul.make_args(rest)
            parts = []
            for f in factors:
                s = self.fast(f, memo)
                parts.append(f"\\left({s}\\right)" if f.is_Add else s)
            body = " ".join(parts)
            if coeff == 1:
                return body
            if coeff == -1:
                return "- " + body
            if coeff.is_Rational and coeff.q != 1:
                return f"{'-' if coeff < 0 else ''}\\frac{{{abs(coeff.p)}}}{{{coeff.q}}} {body}"
            return f"{self.fast(coeff, memo)} {body}"
        if e.is_Pow and e.exp.is_Integer and e.exp > 0:
            base = self.fast(e.base, memo)
            if not (e.base.is_Symbol or e.base.is_Integer and e.base > 0):
                base = f"\\left({base}\\right)"
            return f"{base}^{{{e.exp}}}"
        if isinstance(e, (sp.sin, sp.cos)):
            return f"\\{type(e).__name__}{{\\left({self.fast(e.args[0], memo)}\\right)}}"
        return self.printer.doprint(e)

    def __call__(self, value: Any) -> str:
        if isinstance(value, bool):
            return "\\text{true}" if value else "\\text{false}"
        if isinstance(value, (list, tuple)):
            return ",\\quad ".join(self(v) for v in value)
        if isinstance(value, sp.MatrixBase):
            cells = [[self(value[i, j]) for j in range(value.shape[1])] for i in range(value.shape[0])]
            if self.width is not None and value.shape[0] * value.shape[1]:
                cells = self._fit(value, cells, self.width)
            body = " \\\\ ".join(" & ".join(row) for row in cells)
            return f"\\begin{{bmatrix}} {body} \\end{{bmatrix}}"
        if isinstance(value, (int, float)):
            value = sp.sympify(value)
        if isinstance(value, sp.Basic):
            hit = self._printed.get(value)
            if hit is None:
                hit = self._printed[value] = self._expr(value)
            return hit
        return str(value)

    def _expr(self, value: sp.Basic) -> str:
        if value.is_Float:
            return number(value)
        floats = value.atoms(sp.Float) if has_float(value) else set()
        if floats:
            value = value.xreplace({f: sp.Float(f, 4) for f in floats})
        if is_large(value):  # terms as stored, by a direct printer: sympy's costs minutes on such sums
            return self.fast(value, None if floats else self._fast_memo)
        return self.printer.doprint(value)  # (plain subexpressions: by its direct printer)

    def _fit(self, M: sp.MatrixBase, cells: list[list[str]], width: int) -> list[list[str]]:
        """The cells of a matrix whose rows are wider than ``width`` characters: the narrow columns as they are,
        the long entries of the others broken into lines (:func:`cell_lines`) within an equal share of the rest."""
        cols = M.shape[1]
        if matrix_width(cells) <= width:
            return cells
        widths = [max(printed_width(row[j]) for row in cells) for j in range(cols)]
        room = width - 4 * (cols - 1)  # (column separation)
        narrow = [w for w in widths if w <= room / cols]
        budget = max(16, (room - sum(narrow)) // (cols - len(narrow)))
        return [[cell_lines(M[i, j], c, self, budget) if printed_width(c) > budget else c
                 for j, c in enumerate(row)] for i, row in enumerate(cells)]


LARGE_PRINT = 4000  # nodes: larger expressions are printed with their terms in stored order (text and LaTeX)
LARGE_TEXT = 1000  # the same for the JSON text (sympy syntax, for programs) past this many nodes


def is_large(value: Any, limit: int = LARGE_PRINT) -> bool:
    """Whether a sympy expression has more than ``limit`` nodes (as sympy's preorder traversal counts them)."""
    return isinstance(value, sp.Basic) and tree_size(value) > limit


_SIZES: dict[sp.Basic, int] = {}  # expression -> its number of nodes (the results of a problem share subtrees)


def tree_size(e: sp.Basic) -> int:
    """The number of nodes of the tree of ``e`` (each occurrence of a repeated subtree counted), 1 + Σ over its
    args, memoized by subtree: linear in the distinct subtrees, however often they recur."""
    n = _SIZES.get(e)
    if n is None:
        n = 1 + sum(tree_size(a) for a in e.args) if e.args else 1
        if len(_SIZES) > 200_000:
            _SIZES.clear()
        _SIZES[e] = n
    return n


_TEX_SPECIAL = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "#": r"\#", "_": r"\_", "{": r"\{",
                "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}", "$": r"\$"}


def latex_text(text: str) -> str:
    """Plain text made safe for LaTeX."""
    return "".join(_TEX_SPECIAL.get(ch, ch) for ch in str(text))


def _math(segment: str) -> str:
    """A $...$ or $$...$$ segment with its formula through the allow-list (solver.spec.texmath)."""
    fence = "$$" if segment.startswith("$$") and len(segment) >= 4 else "$"
    return fence + safe_math(segment[len(fence):len(segment) - len(fence)]) + fence


def md_math(text: str) -> str:
    """Markdown text with every formula through the allow-list (what Markdown reports print from a spec)."""
    return "".join(_math(p) if k % 2 else p for k, p in enumerate(re.split(r"(\$\$.*?\$\$|\$[^$]*\$)", str(text))))


def _one_line_math(text: str) -> str:
    """``text`` with the line breaks inside $$...$$ (and $...$) displays turned into spaces, so that a formula
    written over several lines stays one formula."""
    return re.sub(r"\$\$.*?\$\$|\$[^$]*\$", lambda m: " ".join(m.group(0).split("\n")), str(text), flags=re.S)


_ITEM = re.compile(r"\s*[-*] ")


def _joined_items(lines: list[str]) -> list[str]:
    """Lines with each list item whole: an indented line under an item ('- b) ... can be executed' then
    '  separately, ...') continues it, as in Markdown."""
    out: list[str] = []
    for line in lines:
        if out and line[:1].isspace() and line.strip() and not _ITEM.match(line) and _ITEM.match(out[-1]):
            out[-1] += " " + line.strip()
        else:
            out.append(line)
    return out


def md2tex(text: str) -> str:
    """Markdown with $...$ math to LaTeX: math kept, **bold**/*italic*, '- ' lists (items over several indented
    lines), text escaped."""
    out_lines, in_list = [], False
    for line in _joined_items(_one_line_math(text).strip().splitlines()):
        item = _ITEM.match(line)
        if item and not in_list:
            out_lines.append("\\begin{itemize}")
            in_list = True
        elif not item and in_list:
            out_lines.append("\\end{itemize}")
            in_list = False
        body = line[item.end():] if item else line
        parts = re.split(r"(\$\$.*?\$\$|\$[^$]*\$)", body)
        conv = []
        for k, part in enumerate(parts):
            if k % 2:
                conv.append(_math(part))
            else:
                t = latex_text(part)
                t = re.sub(r"\*\*(.+?)\*\*", r"\\textbf{\1}", t)
                t = re.sub(r"\*(.+?)\*", r"\\emph{\1}", t)
                conv.append(t)
        out_lines.append(("\\item " if item else "") + "".join(conv))
    if in_list:
        out_lines.append("\\end{itemize}")
    return "\n".join(out_lines)


def _img(alt_escaped: str, src: str) -> str:
    """An <img> with both attributes quoted; the source only a relative path or an http(s) address."""
    import html as _html
    src = _html.unescape(src)
    if re.match(r"[A-Za-z][A-Za-z0-9+.-]*:", src) and not re.match(r"https?://", src):
        src = ""
    alt = _html.escape(_html.unescape(alt_escaped), quote=True)
    return f'<img alt="{alt}" src="{_html.escape(src, quote=True)}">'


def md2html(text: str) -> str:
    """The Markdown of robosolve's templates to HTML (headings, paragraphs, lists, tables, images, **bold**,
    *italic*), math ($...$, $$...$$) left for MathJax, everything else HTML-escaped."""
    import html as _html

    def inline(t: str) -> str:
        maths: list[str] = []   # math set aside (as \0k\0) while the emphasis is found: "*torque $g_1$.*"

        def aside(m: re.Match) -> str:
            maths.append(m.group(0))
            return f"\0{len(maths) - 1}\0"
        p = _html.escape(re.sub(r"\$\$.*?\$\$|\$[^$]*\$", aside, t.replace("\0", "")), quote=False)
        p = re.sub(r"!\[([^\]]*)\]\(([^)\s]+)\)", lambda m: _img(m.group(1), m.group(2)), p)
        p = re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", p)
        p = re.sub(r"(?<![\w*\\])\*(?!\s)(.+?)(?<![\s\\])\*(?![\w*])", r"<em>\1</em>", p)
        p = re.sub(r"`([^`]+)`", r"<code>\1</code>", p).replace("\\*", "*")
        return re.sub(r"\0(\d+)\0", lambda m: _html.escape(_math(maths[int(m.group(1))]), quote=False), p)

    blocks = re.split(r"\n\s*\n", _one_line_math(text).strip())
    html_out = []
    for block in blocks:
        lines = _joined_items(block.splitlines())
        head = re.match(r"(#{1,6}) (.*)", block)
        image = re.fullmatch(r"!\[(.*)\]\(([^)\s]+)\)", block.strip(), re.S)
        if image:  # a figure on its own line (its caption may hold math, so before the math split)
            html_out.append(f"<p>{_img(_html.escape(image.group(1).replace('$', ''), quote=False), image.group(2))}</p>")
        elif head and len(lines) == 1:
            n = len(head.group(1))
            html_out.append(f"<h{n}>{inline(head.group(2))}</h{n}>")
        elif all(_ITEM.match(ln) for ln in lines):
            items = "".join("<li>" + inline(ln[_ITEM.match(ln).end():]) + "</li>" for ln in lines)
            html_out.append(f"<ul>{items}</ul>")
        elif all(ln.strip().startswith("|") for ln in lines) and len(lines) >= 2:
            rows = [[c.strip() for c in ln.strip().strip("|").split("|")] for ln in lines]
            body = [r for r in rows if not all(re.fullmatch(r":?-+:?", c) for c in r)]
            cells = ["<tr>" + "".join(f"<{'th' if i == 0 else 'td'}>{inline(c)}</{'th' if i == 0 else 'td'}>"
                                      for c in r) + "</tr>" for i, r in enumerate(body)]
            html_out.append("<table>" + "".join(cells) + "</table>")
        else:
            html_out.append(f"<p>{inline(block)}</p>")
    return "\n".join(html_out)


def join_terms(parts: list[str]) -> str:
    """LaTeX terms joined as a sum: 'a', '- b', 'c' -> 'a - b + c'."""
    if not parts:
        return "0"
    out = parts[0]
    for p in parts[1:]:
        out += f" {p}" if p.lstrip().startswith("-") else f" + {p}"
    return out


def visible_length(tex: str) -> int:
    """Rough printed width of a LaTeX formula in characters (commands and braces do not print)."""
    t = re.sub(r"\\(left|right|,|;|!|quad|qquad)", "", tex)
    t = re.sub(r"\\(sin|cos|tan|cot|exp|log|ln)\b", "xxx", t)
    t = re.sub(r"\\[A-Za-z]+", "x", t)
    return len(re.sub(r"[{}^_\s]", "", t))


def printed_width(tex: str) -> int:
    """:func:`visible_length` with each fraction as wide as the wider of its numerator and denominator (they are
    stacked, not side by side)."""
    width, i = 0, 0
    while (k := tex.find("\\frac{", i)) >= 0:
        a = _closing(tex, k + 5)
        b = _closing(tex, a + 1) if a + 1 < len(tex) and tex[a + 1] == "{" else -1
        if a < 0 or b < 0:
            break
        width += visible_length(tex[i:k]) + max(printed_width(tex[k + 6:a]), printed_width(tex[a + 2:b]))
        i = b + 1
    return width + visible_length(tex[i:])


def formula_width(tex: str) -> int:
    """:func:`printed_width` with each bmatrix as wide as its widest cells (:func:`matrix_width`), not as all its
    entries in a row."""
    width, i = 0, 0
    while (k := tex.find("\\begin{bmatrix}", i)) >= 0:
        end = tex.find("\\end{bmatrix}", k)
        if end < 0:
            break
        rows = [r.split("&") for r in tex[k + 15:end].split("\\\\")]
        cols = max(len(r) for r in rows)
        cells = [r + [""] * (cols - len(r)) for r in rows]
        width += printed_width(tex[i:k]) + matrix_width(cells) + 2
        i = end + 13
    return width + printed_width(tex[i:])


def value_width(value: Any, tex: Callable[[Any], str]) -> int:
    """The printed width of ``value`` in LaTeX: a matrix by its columns (:func:`matrix_width`), anything else by
    :func:`printed_width`."""
    if isinstance(value, sp.MatrixBase) and value.rows * value.cols:
        return matrix_width([[tex(value[i, j]) for j in range(value.cols)] for i in range(value.rows)])
    return printed_width(tex(value))


def matrix_width(cells: list[list[str]]) -> int:
    """The printed width of a matrix of LaTeX cells: its columns' widest cells (:func:`printed_width`) and the
    separation between columns."""
    cols = len(cells[0])
    return sum(max(printed_width(row[j]) for row in cells) for j in range(cols)) + 4 * (cols - 1)


def _closing(tex: str, j: int) -> int:
    """The index of the brace closing the one at ``j`` (-1 when unbalanced)."""
    depth = 0
    for k in range(j, len(tex)):
        if tex[k] == "{" and tex[k - 1] != "\\":
            depth += 1
        elif tex[k] == "}" and tex[k - 1] != "\\":
            depth -= 1
            if depth == 0:
                return k
    return -1


def display(parts: list[str], rhs: str = "", width: int = 70, lhs: str = "", wrap: tuple[str, str] = ("", ""),
            punct: str = "") -> str:
    """A displayed ``lhs = wrap[0] Σ parts wrap[1] = rhs`` that breaks into lines (multline*) at the + and - of
    the sum when wider than ``width`` characters (``wrap`` must then be breakable, e.g. \\Big( ... \\Big))."""
    lines = _group(parts, width, visible_length(lhs) + visible_length(wrap[0]))
    head = f"{lhs} = " if lhs else ""
    tail = (f" = {rhs}" if rhs else "") + punct
    if len(lines) == 1:
        return f"\\[{head}{wrap[0]}{join_terms(parts)}{wrap[1]}{tail}\\]"
    body = _line_texts(lines)
    body[0] = head + wrap[0] + body[0]
    body[-1] += wrap[1]
    return "\\begin{multline*}\n" + " \\\\\n".join(body) + tail + "\n\\end{multline*}"


def _group(parts: list[str], width: int, start: int = 0) -> list[list[str]]:
    """The terms ``parts`` of a sum in lines of at most ``width`` characters (the first already ``start`` wide:
    left with none when it is long, a third of the line (a long (1/d)\\Big(), and its first term would overfill
    it)."""
    lines: list[list[str]] = [[]]
    size = start
    for p in parts:
        w = visible_length(p) + 3
        if (lines[-1] or (start > width // 3 and len(lines) == 1 and len(parts) > 1 and w <= width)) \
                and size + w > width:
            lines.append([])
            size = 0
        lines[-1].append(p)
        size += w
    return lines


def _line_texts(lines: list[list[str]]) -> list[str]:
    """Each line of a broken sum as LaTeX, the lines after the first starting with their sign."""
    body = []
    for k, ln in enumerate(lines):
        text = join_terms(ln) if ln else ""
        if any(lines[:k]) and not text.lstrip().startswith("-"):
            text = "+ " + text
        body.append(text)
    return body


def top_level_terms(tex: str) -> list[str]:
    """Split a printed LaTeX sum at its top-level + and - signs: 'a + b \\left(c - d\\right) - e' ->
    ['a', 'b \\left(c - d\\right)', '- e']."""
    parts, depth, start = [], 0, 0
    for m in _TOKENS.finditer(tex):  # (only the tokens that matter, not every character)
        tok = m.group()
        if tok in ("\\left", "{"):
            depth += 1
        elif tok in ("\\right", "}"):
            depth -= 1
        elif depth == 0 and m.start() > 0:
            i = m.start() + 1  # the sign, between two spaces
            parts.append(tex[start:i].strip())
            start = i + (1 if tok[1] == "+" else 0)
    parts.append(tex[start:].strip())
    return [p for p in parts if p]


_TOKENS = re.compile(r"\\left|\\right|[{}]| [+-](?= )")


def term_parts(t: Any, tex: Callable[[Any], str], width: int = 70) -> list[str]:
    """One term of a displayed sum as parts :func:`display` can put on several lines: [tex(t)] when it fits in
    ``width``; otherwise, for t = ± r·A/d with A a sum (the largest factor of the numerator that is one),
    ['± \\frac{r}{d}\\Big(a_1', 'a_2', ..., 'a_m\\Big)'] (or 'r \\Big(...' without d): a single fraction or
    product is one box TeX cannot break, and overflows the page."""
    text = tex(t)
    if not isinstance(t, sp.Expr) or visible_length(text) <= width:
        return [text]
    neg = t.could_extract_minus_sign()
    n, d = sp.fraction(-t if neg else t)
    factors = list(sp.Mul.make_args(n))
    sums = [f for f in factors if f.is_Add]
    if not sums:
        return [text]
    big = max(sums, key=lambda f: visible_length(tex(f)))
    factors.remove(big)
    inner = top_level_terms(tex(big))
    if len(inner) < 2 or max(map(visible_length, inner)) > UNBREAKABLE:
        return [text]
    inner = _split_terms(big, inner, tex, width)  # (a term of A itself wider than the page: broken the same way)
    rest = sp.Mul(*factors)
    head = (f"\\frac{{{tex(rest)}}}{{{tex(d)}}}" if d != 1 else "" if rest == 1
            else f"\\left({tex(rest)}\\right)" if rest.is_Add else tex(rest))
    if visible_length(head) > width:  # the factor before A overfills the line already: breaking A cannot help
        return [text]
    inner[0] = ("- " if neg else "") + head + "\\Big(" + inner[0]
    inner[-1] += "\\Big)"
    return inner


DISPLAY_LHS = 6  # a matrix of cells up to the width fits the line with a left-hand side of this many characters
# (calibrated on the library's compiled reports: 76 characters in all fit; 80, 83 and 87 ran 8-50 pt past the margin)


def equation(value: Any, lhs: str, entry: str, tex: Callable[[Any], str], punct: str = "",
             width: int = 70) -> str:
    """A displayed ``lhs = value``; a matrix or vector too wide for the page is written entry by entry
    (``entry``_{ij} = ..., zero entries and the lower triangle of a symmetric matrix left out), each long entry
    broken into lines; one whose entries share a long denominator Δ as (1/Δ) N, Δ written once
    (:func:`common_denominator`)."""
    if not isinstance(value, sp.MatrixBase):
        return _broken(lhs, tex(value), punct, width, value, tex)
    cells = [[tex(value[i, j]) for j in range(value.cols)] for i in range(value.rows)]
    if _fits(cells, lhs, width):
        return f"\\[{lhs} = {tex(value)}{punct}\\]"
    over = common_denominator(value, tex, width)
    if over is not None:
        d, N = over
        cells = [[tex(N[i, j]) for j in range(N.cols)] for i in range(N.rows)]
        head = f"{lhs} = \\frac{{1}}{{\\Delta}}"
        if _fits(cells, head, width):
            return "\n".join([f"\\[{head}\\,{tex(N)}, \\quad\\text{{with}}\\]",
                              _broken("\\Delta", tex(d), punct, width, d, tex)])
        return "\n".join([f"\\[{head}\\begin{{bmatrix}} n_{{{_ij(N)}}} \\end{{bmatrix}}, \\quad\\text{{with}}\\]",
                          _broken("\\Delta", tex(d), "", width, d, tex)] + _entries(N, "n", cells, tex, punct, width))
    head = f"\\[{lhs} = \\begin{{bmatrix}} {entry}_{{{_ij(value)}}} \\end{{bmatrix}}, \\quad\\text{{with}}\\]"
    return "\n".join([head] + _entries(value, entry, cells, tex, punct, width))


def _ij(value: sp.MatrixBase) -> str:
    return "ij" if value.cols > 1 else "i"


def _fits(cells: list[list[str]], lhs: str, width: int) -> bool:
    """Whether a matrix of LaTeX ``cells`` fits the line, after ``lhs``."""
    widest = max(sum(printed_width(c) + 6 for c in row) for row in cells)  # + column separation
    return widest <= width and widest + formula_width(lhs) <= width + DISPLAY_LHS


def _entries(value: sp.MatrixBase, entry: str, cells: list[list[str]], tex: Callable[[Any], str], punct: str,
             width: int) -> list[str]:
    """The lines ``entry``_{ij} = ... of a matrix written entry by entry, then its zero entries in one sentence."""
    symmetric = value.rows == value.cols and value == value.T
    out = []
    for i in range(value.rows):
        for j in range(value.cols):
            if value[i, j] == 0 or (symmetric and j < i):
                continue
            idx = f"{i + 1}{j + 1}" if value.cols > 1 else f"{i + 1}"
            out.append(_broken(f"{entry}_{{{idx}}}", cells[i][j], "", width, value[i, j], tex))
    zeros = [f"{entry}_{{{i + 1}{j + 1}}}" if value.cols > 1 else f"{entry}_{{{i + 1}}}"
             for i in range(value.rows) for j in range(value.cols) if value[i, j] == 0 and not (symmetric and j < i)]
    if zeros:
        out.append("and $" + " = ".join(zeros) + " = 0$" + (punct or "."))
    elif punct:
        out[-1] = out[-1].replace("\\]", f"{punct}\\]") if out[-1].endswith("\\]") else out[-1]
    return out


def common_denominator(value: sp.MatrixBase, tex: Callable[[Any], str],
                       width: int) -> tuple[sp.Expr, sp.MatrixBase] | None:
    """(Δ, N) with value = N / Δ when at least two entries are non-zero and every one is a quotient n_ij / Δ over
    the same denominator (up to its sign), printed wider than a third of the line (a short one reads well in each
    entry); None otherwise, or when the matrix's own symbols print as Δ or n."""
    nums: dict[tuple[int, int], sp.Expr] = {}
    d = None
    for i in range(value.rows):
        for j in range(value.cols):
            if value[i, j] == 0:
                continue
            n, den = sp.fraction(value[i, j])
            if den == 1:
                return None
            if d is None:
                d = den
            elif den != d:
                if den != -d:
                    return None
                n = -n
            nums[(i, j)] = n
    if d is None or len(nums) < 2 or printed_width(tex(d)) <= width // 3:
        return None
    names = {tex(s) for s in value.free_symbols}
    if "\\Delta" in names or any(t == "n" or t.startswith("n_") for t in names):
        return None
    return d, sp.Matrix(value.rows, value.cols, lambda i, j: nums.get((i, j), 0))


def equations(items: list, tex: Callable[[Any], str], sep: str = ", \\qquad ", punct: str = "",
              width: int = 70) -> str:
    """Several ``lhs = value`` (items: (lhs, value, entry); value None: lhs is written as it is) in one display,
    joined by ``sep``, when they fit on a line; otherwise each on its own, a wide matrix entry by entry
    (:func:`equation`)."""
    size = 4 * (len(items) - 1)
    for lhs, value, _ in items:
        size += visible_length(lhs) + 3 + (value_width(value, tex) if value is not None else 0)
    if size <= width:
        return "\\[" + sep.join(lhs if value is None else f"{lhs} = {tex(value)}" for lhs, value, _ in items) \
            + punct + "\\]"
    out = []
    for k, (lhs, value, entry) in enumerate(items):
        end = punct if k == len(items) - 1 else ","
        out.append(f"\\[{lhs}{end}\\]" if value is None else equation(value, lhs, entry, tex, end, width))
    return "\n".join(out)


def _broken(lhs: str, text: str, punct: str, width: int, value: Any = None,
            tex: Callable[[Any], str] | None = None) -> str:
    """``lhs = text`` broken at the top-level signs when wider than ``width``; a long quotient n/d (``value``) as
    (1/d)(n) with n broken (a single fraction cannot be broken), or, when d itself is long, as n over d with each
    on its own lines (:func:`stacked`)."""
    parts = top_level_terms(text)
    if max(map(visible_length, parts)) > UNBREAKABLE:  # a line TeX cannot even measure: one (overfull) line
        return f"\\[{lhs} = {text}{punct}\\]"
    if tex is not None and isinstance(value, sp.Add) and max(map(visible_length, parts)) > width:
        return display(_split_terms(value, parts, tex, width), "", width, lhs=lhs, punct=punct)
    if tex is not None and isinstance(value, sp.Expr) and printed_width(text) > width:  # (a fraction: stacked)
        n, d = sp.fraction(value)
        if d != 1 and printed_width(tex(d)) > width // 2:  # a long denominator: n over d, each on lines
            frac = stacked_quotient(n, d, tex, width)
            if frac is not None:
                return f"\\[{lhs} = {frac}{punct}\\]"
        if d != 1 and n.is_Add:
            num = top_level_terms(tex(n))
            if max(map(visible_length, num)) <= UNBREAKABLE:
                num = _split_terms(n, num, tex, width)  # (a term of n wider than the page: broken itself)
                return display(num, "", width, lhs=lhs, punct=punct,
                               wrap=(f"\\frac{{1}}{{{tex(d)}}}\\Big(", "\\Big)"))
        if len(parts) == 1:  # a product r·A with A a long sum: r\Big(a₁ + … + a_m\Big) over lines
            parts = term_parts(value, tex, width)
    return display(parts, "", width, lhs=lhs, punct=punct)


def _split_terms(value: sp.Add, parts: list[str], tex: Callable[[Any], str], width: int) -> list[str]:
    """The printed terms ``parts`` of the sum ``value``, each one wider than ``width`` broken by
    :func:`term_parts`."""
    printed = {}  # each term of the sum as it is printed in it
    for t in value.args:
        printed[tex(t)] = t
        if t.could_extract_minus_sign():
            printed["- " + tex(-t)] = t
    return [q for p in parts for q in (term_parts(printed[p], tex, width) if p in printed else [p])]


def cell_lines(value: Any, text: str, tex: Callable[[Any], str], width: int) -> str:
    """A matrix entry printed ``text`` wider than ``width``, on several lines within one cell: a quotient n/d as
    n over d, each broken at the top-level signs of its sum (:func:`stacked`); a sum broken at its signs (long
    terms ± r·A as r (a₁ + … + a_m), :func:`term_parts`); ``text`` itself when it cannot be broken."""
    if not isinstance(value, sp.Expr):
        return text
    neg = value.could_extract_minus_sign()
    n, d = sp.fraction(-value if neg else value)
    if d != 1:
        frac = stacked_quotient(n, d, tex, width)
        return text if frac is None else ("- " if neg else "") + frac
    return stacked(value, tex, width, top=True) or text


def stacked_quotient(n: sp.Expr, d: sp.Expr, tex: Callable[[Any], str], width: int) -> str | None:
    """\\frac{n}{d} with n and d each on lines when wider than ``width`` (:func:`stacked`); None when neither
    needs it."""
    num, den = stacked(n, tex, width), stacked(d, tex, width)
    if num is None and den is None:
        return None
    return f"\\frac{{{num or tex(n)}}}{{{den or tex(d)}}}"


def stacked(e: sp.Expr, tex: Callable[[Any], str], width: int, top: bool = False) -> str | None:
    """``e`` on lines of at most ``width`` characters (aligned; ``top``: aligned at its first line) when it is
    wider: a sum at its top-level signs, a product r·A (A its widest sum factor) as r (A on lines); None when it
    fits or cannot be broken."""
    text = tex(e)
    if printed_width(text) <= width:
        return None
    if e.is_Mul:
        sums = [f for f in sp.Mul.make_args(e) if f.is_Add]
        if not sums:
            return None
        big = max(sums, key=lambda f: visible_length(tex(f)))
        inner = stacked(big, tex, width)
        if inner is None:
            return None
        rest = e / big
        head = "- " if rest == -1 else "" if rest == 1 else tex(rest) + " "
        return head + "\\left(" + inner + "\\right)"
    if not e.is_Add:
        return None
    parts = top_level_terms(text)
    if max(map(visible_length, parts)) > UNBREAKABLE:
        return None
    lines = _group(_split_terms(e, parts, tex, max(width, TERM_WIDTH)), width)
    if len(lines) < 2:
        return None
    return ("\\begin{aligned}[t] & " if top else "\\begin{aligned} & ") + " \\\\ & \\quad ".join(
        _line_texts(lines)) + " \\end{aligned}"


UNBREAKABLE = 2000  # printed characters of one term past which a multline line would exceed TeX's dimensions
TERM_WIDTH = 30  # characters: a term of a matrix entry is broken itself (r (a₁ + … + a_m)) only when wider
MATRIX_WIDTH = 64  # characters (printed_width, about 6.4 pt each at 11 pt) of a matrix row in a report, past which
#                   its long entries are broken into lines: the page (471 pt) less the left-hand side


def number(value: Any, digits: int = 4) -> str:
    """A number with ``digits`` significant figures."""
    try:
        x = float(sp.N(value))
    except (TypeError, ValueError):
        return str(value)
    return f"{x:.{digits}g}"


def ranks(problem: Problem) -> dict[sp.Symbol, int]:
    """Printing rank of symbols: parameters 0, coordinates 1, velocities 2, accelerations 3."""
    out: dict[sp.Symbol, int] = {}
    if problem.robot:
        for k, group in enumerate((problem.robot.q, problem.robot.dq, problem.robot.ddq), 1):
            out.update({s: k for s in group})
    return out


class _CompiledTemplates(jinja2.BytecodeCache):
    """Compiled templates kept across environments and processes (compiling the report templates costs more than
    rendering them): in memory, and in Jinja2's per-user cache folder (created 0700 and checked to be the user's;
    entries are checked against the template's source, so an edited template is compiled again). The key has
    the environment's syntax options and filter names, on which the compiled code depends."""

    def __init__(self) -> None:
        self.memory: dict[str, bytes] = {}
        self.disk: jinja2.FileSystemBytecodeCache | None = None
        try:
            self.disk = jinja2.FileSystemBytecodeCache()
        except (OSError, RuntimeError):  # no safe per-user folder: memory only
            self.disk = None

    def get_bucket(self, environment: jinja2.Environment, name: str, filename: str | None,
                   source: str) -> jinja2.bccache.Bucket:
        e = environment
        setup = repr((e.block_start_string, e.variable_start_string, e.comment_start_string, e.trim_blocks,
                      e.lstrip_blocks, e.keep_trailing_newline, e.autoescape, sorted(e.filters), sorted(e.tests)))
        key = self.get_cache_key(f"{name}\0{setup}", filename)
        bucket = jinja2.bccache.Bucket(environment, key, self.get_source_checksum(source))
        self.load_bytecode(bucket)
        return bucket

    def load_bytecode(self, bucket: jinja2.bccache.Bucket) -> None:
        data = self.memory.get(bucket.key)
        if data is not None:
            bucket.bytecode_from_string(data)
        if bucket.code is None and self.disk is not None:
            try:
                self.disk.load_bytecode(bucket)
            except Exception:  # an unreadable or stale entry: compile again
                bucket.reset()

    def dump_bytecode(self, bucket: jinja2.bccache.Bucket) -> None:
        self.memory[bucket.key] = bucket.bytecode_to_string()
        if self.disk is not None:
            try:
                self.disk.dump_bytecode(bucket)
            except OSError:
                pass


_COMPILED = _CompiledTemplates()


def template_env(subdir: str, custom: Path | None = None, autoescape: bool = False) -> jinja2.Environment:
    """Jinja2 environment over templates/<subdir>/, a user's <custom>/<subdir>/ first. LaTeX templates (tex,
    latex) use << >>, <% %> and <# #> so that braces stay LaTeX's. Filters every template may use: points,
    latex_text, md2tex, md2html."""
    dirs = [str(p / subdir) for p in ([custom] if custom else []) + [templates_dir()]]
    opts: dict[str, Any] = dict(loader=jinja2.FileSystemLoader(dirs), undefined=jinja2.StrictUndefined,
                                trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True,
                                autoescape=autoescape, bytecode_cache=_COMPILED)
    if subdir in ("tex", "latex"):
        opts.update(block_start_string="<%", block_end_string="%>", variable_start_string="<<",
                    variable_end_string=">>", comment_start_string="<#", comment_end_string="#>")
    env = jinja2.Environment(**opts)
    env.filters.update(points=lambda x: f"{x:g}", latex_text=latex_text, md2tex=md2tex, md2html=md2html,
                       md_math=md_math, md_stars=md_stars)
    return env


def md_stars(text: str) -> str:
    """``*`` outside ``$...$`` escaped (``\\*``), so that text put between ``*...*`` ("A*: ...") stays one
    emphasis in Markdown and :func:`md2html`."""
    parts = re.split(r"(\$\$.*?\$\$|\$[^$]*\$)", text)
    return "".join(p if k % 2 else p.replace("*", "\\*") for k, p in enumerate(parts))


def written(x: Any, tex: Callable[[Any], str]) -> str:
    """A spec number for the report: a decimal literal kept as the user wrote it (``solver.spec.expr.as_written``),
    1.5e-3 as 1.5 \\cdot 10^{-3}; anything else through
    ``tex``."""
    if not isinstance(x, str):
        return tex(x)
    if not DECIMAL.fullmatch(x):   # the allow-list: no other text from a spec reaches LaTeX
        raise ValueError(f"not a decimal literal: {x[:40]!r}")
    mantissa, _, exponent = x.lower().partition("e")
    return mantissa + (f" \\cdot 10^{{{int(exponent)}}}" if exponent else "")


def approx(value: Any, digits: int = 5) -> Any:
    """value.evalf(digits) with its whole floats written as integers: 2 q̇₁, not 2.0 q̇₁."""
    out = value.evalf(digits) if hasattr(value, "evalf") else value
    if not isinstance(out, (sp.Basic, sp.MatrixBase)):
        return out
    return out.xreplace({f: sp.Integer(int(f)) for f in out.atoms(sp.Float) if float(f).is_integer()})


INLINE_WIDTH = 44  # printed characters of a formula in a sentence (a line holds about 80), past which it is displayed
INLINE_MATRIX_WIDTH = 24  # the same for a matrix of several rows (tall, and never broken across lines)


def inline(value: Any, lhs: str, tex: Callable[[Any], str], fmt: str, punct: str = "", entry: str = "",
           width: int = INLINE_WIDTH) -> str:
    """``$lhs = value$punct`` in a sentence; in LaTeX, displayed by :func:`equation` (broken into lines, a matrix
    entry by entry as ``entry``_ij: by default lhs without its arguments) when wider than ``width`` printed
    characters (a matrix by its columns, a fraction by its wider line; a matrix of several rows past
    INLINE_MATRIX_WIDTH), which the line could not hold. Markdown keeps it inline (its viewers wrap)."""
    text = tex(value)
    if fmt == "tex":
        if isinstance(value, sp.MatrixBase) and value.rows > 1 and value.cols:
            width = min(width, INLINE_MATRIX_WIDTH)
        if visible_length(lhs) + 3 + value_width(value, tex) > width:
            name = entry or "{" + re.sub(r"\(.*?\)", "", lhs.split("=")[0]).strip() + "}"
            return equation(value, lhs, name, tex, punct)
    return f"${lhs} = {text}${punct}"


def _env(fmt: str, custom: Path | None, names: dict[sp.Symbol, str],
         rank: dict[sp.Symbol, int] | None = None) -> jinja2.Environment:
    """The report environment of one problem: :func:`template_env` plus its symbols' LaTeX printing."""
    env = template_env(fmt, custom)
    env.filters["tex"] = Latex(names, rank, width=MATRIX_WIDTH)
    env.filters["num"] = number
    env.filters["terms"] = lambda terms: join_terms([env.filters["tex"](t) for t in terms if t != 0])
    env.filters["display"] = lambda terms, rhs="", lhs="", wrap=("", ""), punct="": display(
        [p for t in terms if t != 0 for p in term_parts(t, env.filters["tex"])], rhs, lhs=lhs, wrap=tuple(wrap),
        punct=punct)
    env.filters["width"] = visible_length
    env.filters["printed"] = formula_width
    env.filters["written"] = lambda x: written(x, env.filters["tex"])
    env.filters["equation"] = lambda value, lhs, entry, punct="": equation(value, lhs, entry, env.filters["tex"],
                                                                          punct)
    env.filters["equations"] = lambda items, sep=", \\qquad ", punct="": equations(items, env.filters["tex"], sep,
                                                                                    punct)
    env.filters["approx"] = approx
    env.filters["inline"] = lambda value, lhs, punct="", entry="": inline(value, lhs, env.filters["tex"], fmt, punct,
                                                                          entry)
    env.globals["sp"] = sp
    return env


def render(problem: Problem, solutions: list[Solution], fmt: str, fragment: bool = False,
           template_dir: Path | None = None, assets: dict[str, str] | None = None, details: bool = False) -> str:
    """The report of ``problem`` in ``fmt`` (md | tex | json); ``details``: JSON with the intermediate results
    (per-body quantities) and the steps' expressions."""
    with without_units():  # results computed on demand by the templates may simplify
        if fmt == "json":
            data = to_json(problem, solutions, details)
            try:
                return json.dumps(data, indent=2, ensure_ascii=False, allow_nan=False) + "\n"
            except ValueError:  # ±∞, NaN: strings "inf", "-inf", "nan" (JSON has no such numbers)
                return json.dumps(_finite(data), indent=2, ensure_ascii=False, allow_nan=False) + "\n"
        env = _env(fmt, template_dir, problem.latex_names, ranks(problem))
        page = env.get_template(f"page.{fmt}.j2")
        return page.render(problem=problem, solutions=solutions, fragment=fragment, assets=assets or {},
                           symbols=[(problem.symbols[k], v) for k, v in problem.meanings.items()])


def render_template(problem: Problem, name: str, fmt: str, template_dir: Path | None = None, **ctx: Any) -> str:
    """Render template ``name`` (of format ``fmt``) with ``problem``'s symbol printing, e.g. the solutions
    part of a handout."""
    env = _env(fmt, template_dir, problem.latex_names, ranks(problem))
    with without_units():
        return env.get_template(name).render(problem=problem, **ctx)


def latex_printer(problem: Problem) -> Latex:
    """The LaTeX printer of ``problem``'s symbols (as used in its reports and JSON)."""
    return Latex(problem.latex_names, ranks(problem))


# ------------------------------------------------------------------------------------------------- JSON
def _expr_str(value: Any) -> str:
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_expr_str(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_expr_str(k)}: {_expr_str(v)}" for k, v in value.items()) + "}"
    if isinstance(value, sp.MatrixBase) and value.rows and value.cols:  # str(M), entry by entry
        rows = ", ".join("[" + ", ".join(_expr_str(x) for x in value.row(i)) + "]" for i in range(value.rows))
        return f"Matrix([{rows}])"
    if is_large(value, LARGE_TEXT):
        return _fast_str(value, None if has_float(value) else _FAST_TEXT)
    if isinstance(value, sp.Basic):
        return _text(value)
    return str(value)


_FAST_TEXT: dict[sp.Basic, str] = {}  # compound subexpression -> its _fast_str (expressions without floats)


def _fast_str(e: Any, memo: dict | None = None) -> str:
    """sympy-readable text of a long expression printed directly (terms in stored order): parse_expr reads it
    back to the same expression. With ``memo`` (an expression without floats, whose equal values may print with
    other precisions) each compound subexpression is printed once: the entries of B a share the numerators of a."""
    if memo is None or e.is_Atom:
        return _fast_text(e, memo)
    hit = memo.get(e)
    if hit is None:
        if len(memo) > 200_000:
            memo.clear()
        hit = memo[e] = _fast_text(e, memo)
    return hit


def _fast_text(e: Any, memo: dict | None) -> str:
    if e.is_Symbol or e.is_Integer:
        return str(e)
    if e.is_Rational:
        return f"({e.p}/{e.q})"
    if e.is_Add:
        out = ""
        for k, a in enumerate(e.args):
            neg = negative(a)
            body = _fast_str(-a if neg else a, memo)
            out += ("-" if neg else "") + body if k == 0 else (" - " if neg else " + ") + body
        return out
    if e.is_Mul:
        coeff, rest = e.as_coeff_Mul()
        parts = [f"({_fast_str(f, memo)})" if f.is_Add else _fast_str(f, memo) for f in sp.Mul.make_args(rest)]
        body = "*".join(parts)
        if coeff == 1:
            return body
        if coeff == -1:
            return "-" + body
        return f"{_fast_str(coeff, memo)}*{body}"
    if e.is_Pow:
        base, ex = _fast_str(e.base, memo), _fast_str(e.exp, memo)
        if not (e.base.is_Symbol or (e.base.is_Integer and e.base > 0)):
            base = f"({base})"
        if not (e.exp.is_Integer and e.exp > 0):
            ex = f"({ex})"
        return f"{base}**{ex}"
    if isinstance(e, sp.Function):
        return f"{type(e).__name__}({', '.join(_fast_str(a, memo) for a in e.args)})"
    return str(e)


def _finite(obj: Any) -> Any:
    """JSON data with every non-finite float written as the string "inf", "-inf" or "nan" (float() reads them)."""
    if isinstance(obj, float) and not math.isfinite(obj):
        return "nan" if obj != obj else ("inf" if obj > 0 else "-inf")
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


def _numeric(value: Any) -> Any:
    """Numbers (nested lists for matrices) where the value is fully numeric, else None."""
    try:
        if isinstance(value, bool):
            return value
        if isinstance(value, sp.MatrixBase):
            rows = [[_numeric(value[i, j]) for j in range(value.shape[1])] for i in range(value.shape[0])]
            if any(x is None for r in rows for x in r):
                return None
            return [r[0] for r in rows] if value.shape[1] == 1 else rows
        if isinstance(value, (list, tuple)):
            out = [_numeric(v) for v in value]
            return None if any(x is None for x in out) else out
        if isinstance(value, (int, float)):
            return value
        if isinstance(value, sp.Basic) and value.is_number:
            c = complex(sp.N(value))
            return c.real if abs(c.imag) < 1e-12 else [c.real, c.imag]
    except (TypeError, ValueError):
        return None
    return None


def result_json(r: Result, latex: Latex) -> dict[str, Any]:
    out: dict[str, Any] = {"kind": r.kind, "expr": _expr_str(r.value), "latex": latex(r.value)}
    num = _numeric(r.value)
    if num is not None:
        out["value"] = num
    return out


class _Steps:
    """Step data to JSON, each expression written once: a value that is a result of the report is written as
    {"result": NAME}, other sympy values (with ``details`` only) as {"expr", "latex"}, once per object."""

    def __init__(self, latex: Latex, refs: dict[Any, str], details: bool) -> None:
        self.latex, self.refs, self.details = latex, refs, details
        self.seen: dict[int, Any] = {}

    def __call__(self, obj: Any) -> Any:
        if _referable(obj):
            key = _ref_key(obj)
            if key is not None and key in self.refs:
                return {"result": self.refs[key]}
        if isinstance(obj, (str, int, float, bool)) or obj is None:
            return obj
        if not self.details:  # only references to results and plain data
            if isinstance(obj, (list, tuple)) and all(isinstance(v, (str, int, float, bool)) for v in obj):
                return list(obj)
            return _SKIP
        if isinstance(obj, (sp.Basic, sp.MatrixBase)):
            if id(obj) not in self.seen:
                self.seen[id(obj)] = {"expr": str(obj), "latex": self.latex(obj)}
            return self.seen[id(obj)]
        if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
            return self._dict({f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)
                               if f.metadata.get("json", True)})  # (a printing aid, not data: json=False)
        if isinstance(obj, dict):
            return self._dict(obj)
        if isinstance(obj, (list, tuple)):
            return [x for x in (self(v) for v in obj) if x is not _SKIP]
        if isinstance(obj, (set, frozenset)):  # in a fixed order (a set's own order changes from run to run)
            return [x for x in (self(v) for v in sorted(obj, key=str)) if x is not _SKIP]
        if type(obj).__str__ is object.__str__ and type(obj).__repr__ is object.__repr__:
            return _SKIP  # a helper object (a template's lazy view): nothing readable to write
        return str(obj)

    def _dict(self, d: dict) -> dict:
        out = {str(k): self(v) for k, v in d.items()}
        return {k: v for k, v in out.items() if v is not _SKIP}


_SKIP = object()


def _ref_key(value: Any) -> Any:
    """A hashable key equal for equal values (a result is referred to by value: identity would depend on which
    objects sympy's caches happen to share, and change the JSON from run to run); None when not hashable."""
    if isinstance(value, sp.MatrixBase):
        return ("matrix", value.shape, tuple(value))
    if isinstance(value, (list, tuple)):
        keys = tuple(_ref_key(v) if _referable(v) else v for v in value)
        try:
            hash(keys)
        except TypeError:
            return None
        return ("list", keys)
    return value if isinstance(value, sp.Basic) else None


def _referable(value: Any) -> bool:
    """A value written by reference when it is a result: a matrix, a list or a compound expression (atoms such
    as 0 are shared objects in sympy)."""
    return isinstance(value, (sp.MatrixBase, list, tuple)) or (isinstance(value, sp.Basic) and not value.is_Atom)


def to_json(problem: Problem, solutions: list[Solution], details: bool = False) -> dict[str, Any]:
    """{"id", "title", "results": {NAME: {kind, expr, latex, value?}}, "steps": [{ask, step, data}]}: the results
    of the asks, each printed once as text and LaTeX; intermediate results (``Result.detail``: per-body energies,
    ...) and the steps' own expressions only with ``details``. Step data refer to results by name."""
    latex = Latex(problem.latex_names, ranks(problem))
    results: dict[str, Any] = {}
    refs: dict[Any, str] = {}
    own: list[dict[Any, str]] = []   # a step names its own ask's result, else the first ask's with that value
    for sol in solutions:
        own.append({})
        for name, r in sol.results.items():
            if r.detail and not details:
                continue
            results[name] = result_json(r, latex)
            key = _ref_key(r.value) if _referable(r.value) else None
            if key is not None:
                own[-1].setdefault(key, name)
                refs.setdefault(key, name)
    plain = _Steps(latex, refs, details)
    steps: list[Any] = []
    for sol, mine in zip(solutions, own):
        plain.refs = {**refs, **mine}
        for st in sol.steps:
            data = plain._dict({k: v for k, v in st.data.items() if k not in ("robot",)})
            steps.append({"ask": sol.kind, "step": st.name, "data": data})
    return {"id": problem.id, "title": problem.title, "results": results, "steps": steps}
