"""LaTeX math from files, by an allow-list: the only way text of a spec, an exam file or a submission reaches LaTeX
or HTML (MathJax) as math.

Math text is tokenized into characters and control sequences. Letters, digits, spaces and the punctuation of
formulas pass; ``^ _ { } & \\\\`` pass with braces balanced; a control sequence passes only if it names a math
command of :data:`COMMANDS` (symbols, Greek letters, accents, fonts, fractions, delimiters) or, after ``\\begin``/
``\\end``, an environment of :data:`ENVIRONMENTS`. Everything else — ``\\input``, ``\\def``, ``\\catcode``,
``\\write``, ``\\csname``, ``#``, ``%``, ``$``, active characters, control characters — is refused: TeX is a
programming language that can read files and run commands.
"""
from __future__ import annotations

import re

MAX_MATH = 5_000  # characters of one formula

_GREEK = ("alpha beta gamma delta epsilon varepsilon zeta eta theta vartheta iota kappa lambda mu nu xi pi varpi "
          "rho varrho sigma varsigma tau upsilon phi varphi chi psi omega Gamma Delta Theta Lambda Xi Pi Sigma "
          "Upsilon Phi Psi Omega")
_SYMBOLS = ("ell hbar imath jmath infty nabla partial prime emptyset exists forall neg top bot angle "
            "cdot cdots ldots dots vdots ddots times div pm mp ast star circ bullet oplus otimes odot "
            "leq le geq ge neq ne approx equiv sim simeq cong propto ll gg subset subseteq supset supseteq in notin "
            "ni cup cap setminus wedge vee to mapsto rightarrow leftarrow Rightarrow Leftarrow leftrightarrow "
            "Leftrightarrow longrightarrow longmapsto uparrow downarrow iff implies perp parallel mid "
            "langle rangle lfloor rfloor lceil rceil lvert rvert lVert rVert vert Vert backslash colon "
            "quad qquad , ; : ! space enspace thinspace medspace")
_FUNCTIONS = ("sin cos tan cot sec csc arcsin arccos arctan sinh cosh tanh exp log ln det dim ker max min sup inf "
              "lim arg deg gcd Pr mod bmod pmod operatorname")
_STRUCTURE = ("frac dfrac tfrac sqrt sum prod int iint oint left right big Big bigg Bigg bigl bigr Bigl Bigr "
              "biggl biggr middle overline underline overbrace underbrace widehat widetilde hat tilde bar vec dot "
              "ddot dddot acute grave breve check mathring "
              "mathbf mathrm mathit mathsf mathtt mathcal mathbb mathfrak boldsymbol bm text textrm textbf textit "
              "mbox displaystyle textstyle scriptstyle limits nolimits stackrel overset underset substack "
              "begin end hline cr label nonumber notag tag phantom vphantom hphantom")
COMMANDS = frozenset((_GREEK + " " + _SYMBOLS + " " + _FUNCTIONS + " " + _STRUCTURE).split())
ENVIRONMENTS = frozenset("matrix pmatrix bmatrix Bmatrix vmatrix Vmatrix smallmatrix cases array aligned "
                         "gathered split".split())

_TOKEN = re.compile(r"\\([A-Za-z]+|.)|(.)", re.S)
_PLAIN = re.compile(r"[A-Za-z0-9 \t\n+\-*/=<>()\[\].,;:!?'|^_{}&@]")


def math_problem(tex: str) -> str | None:
    """Why ``tex`` (the inside of $...$) may not be used as math, or None when it may."""
    if len(tex) > MAX_MATH:
        return f"formula too long ({len(tex)} characters, at most {MAX_MATH})"
    if "^^" in tex:
        return "'^^' is not allowed in math (TeX reads ^^5c as a backslash)"
    depth = 0
    expect_env = False
    for m in _TOKEN.finditer(tex):
        name, ch = m.group(1), m.group(2)
        if name is not None:
            if name == "\\":
                continue  # a line break inside a matrix
            if len(name) == 1 and not name.isalpha():
                if name in ",;:! {}|_&%#$":
                    continue  # spacing, escaped braces and characters
                return f"'\\{name}' is not allowed in math"
            if name not in COMMANDS:
                return f"the command \\{name} is not allowed in math (allowed: symbols, Greek letters, \\frac, " \
                       f"\\sqrt, accents, fonts, matrices)"
            expect_env = name in ("begin", "end")
            continue
        if ch == "{":
            depth += 1
            if expect_env:
                env = re.match(r"\{([A-Za-z]+\*?)\}", tex[m.start():])
                if not env or env.group(1) not in ENVIRONMENTS:
                    return "only the environments " + ", ".join(sorted(ENVIRONMENTS)) + " are allowed in math"
            expect_env = False
        elif ch == "}":
            depth -= 1
            if depth < 0:
                return "unbalanced braces '}'"
        elif not _PLAIN.match(ch) and not (ch.isalpha() and ch.isprintable() and ord(ch) < 0x2000):
            return f"the character {ch!r} is not allowed in math"
        else:
            expect_env = False if not ch.isspace() else expect_env
    if depth:
        return "unbalanced braces '{'"
    return None


def safe_math(tex: str) -> str:
    """``tex`` when allowed (see :func:`math_problem`), else the text shown literally (\\text{...} of its
    printable characters, every special character dropped)."""
    if math_problem(tex) is None:
        return tex
    shown = re.sub(r"[^A-Za-z0-9 +\-*/=<>()\[\].,;:!?']", " ", tex)
    return "\\text{" + " ".join(shown.split())[:200] + "}"


_SEGMENT = re.compile(r"(\$\$.*?\$\$|\$[^$]*\$)", re.S)


def text_math_problem(text: str) -> str | None:
    """The first problem of a $...$ formula inside Markdown ``text``, or None."""
    for part in _SEGMENT.findall(str(text)):
        inner = part.strip("$")
        why = math_problem(inner)
        if why:
            return f"{why}: ${inner[:60]}$"
    return None
