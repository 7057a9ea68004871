"""Benchmark: grade a synthetic class of 300 submissions per problem; compare verdicts with sympy's own tests.

For each problem, 300 submissions are generated from the reference solution: correct answers, correct
alternatives (trig identities expanded, factored, LaTeX, rounded numbers), wrong answers (a sign flipped, a term
dropped, a factor 2, a wrong index) and invalid ones (ambiguous products, unbalanced brackets, 9^9^9^9). The
ground truth is known by construction. robosolve grades them with `grade_files` (both cores); then, on the same
(answer entry, reference entry) pairs, `sympy.simplify(a - b) == 0` and `a.equals(b)` (PrairieLearn's way) are
timed and their verdicts counted against the truth.

    python benchmarks/grading.py [--n 300] [--jobs 0] [--peer-pairs 150] [--peer-cap 5]
"""
from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import random
import sys
import tempfile
import time
from pathlib import Path

import sympy as sp

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from solver.grading.gradebook import grade_files  # noqa: E402
from solver.grading.grader import ItemSpec, prepare  # noqa: E402
from solver.spec import load_problem  # noqa: E402

PROBLEMS = {
    "3-dof dynamics (2016-09-12-ex1)": ("2016-09-12-ex1", ["B", "c", "g", "S"]),
    "redundancy (2019-04-29-midterm-ex5)": ("2019-04-29-midterm-ex5", ["J", "qdot_ps"]),
}
INVALID = ["m2l1*cos(q2)", "[[1, 2], [3", "9^9^9^9", "(" * 3000 + "q1" + ")" * 3000, "sin q1", "x" * 30000,
           "__import__('os')", "$\\frac{1}{$"]


def _alternative(e: sp.Expr, rng: random.Random, angles: list[sp.Symbol]) -> sp.Expr:
    """An equivalent but different-looking form of e (never evaluated as text: printed, then re-parsed)."""
    if e.is_number:
        return e
    choice = rng.randrange(4)
    if choice == 0:
        return sp.expand_trig(e)
    if choice == 1:
        return sp.expand(e)
    if choice == 2 and angles:
        x = rng.choice(angles)
        return e * (sp.sin(x) ** 2 + sp.cos(x) ** 2)
    return sp.factor_terms(e)


def _wrong(e: sp.Expr, rng: random.Random, angles: list[sp.Symbol]) -> sp.Expr:
    terms = sp.Add.make_args(sp.expand(e))
    choice = rng.randrange(3)
    if choice == 0 and len(terms) > 1:
        return e - rng.choice(terms)  # a term dropped
    if choice == 1 and e != 0:
        return -e
    return 2 * e + (angles[0] if angles else 1)


def _fmt(v: sp.Expr) -> str:
    return str(v)


def _value(ref_value, kind: str, truth: str, rng: random.Random,  # type: ignore[no-untyped-def]
           angles: list[sp.Symbol]) -> tuple[str, list[str]]:
    """The answer text and the truth of each of its entries."""
    if truth == "invalid":
        return rng.choice(INVALID), []
    if kind in ("matrix", "vector"):
        m = sp.Matrix(ref_value)
        entries = ["correct"] * len(m)
        if truth == "alternative":
            m = m.applyfunc(lambda x: _alternative(x, rng, angles))
        elif truth == "wrong":
            k = rng.choice([i for i in range(len(m)) if m[i] != 0] or [0])
            m[k] = _wrong(m[k], rng, angles)
            entries[k] = "incorrect"
        rows = [[_fmt(m[i, j]) for j in range(m.cols)] for i in range(m.rows)]
        return str([r[0] for r in rows] if m.cols == 1 else rows).replace("'", ""), entries
    e = sp.sympify(ref_value)
    if truth == "alternative":
        e = _alternative(e, rng, angles)
    elif truth == "wrong":
        e = _wrong(e, rng, angles)
    return _fmt(e), ["incorrect" if truth == "wrong" else "correct"]


def make_class(ref, items: list[str], n: int, folder: Path, seed: int = 7):  # type: ignore[no-untyped-def]
    """Write n submissions (JSON); return, per file and item, the truth (correct | incorrect | invalid) and the
    truth of each entry."""
    rng = random.Random(seed)
    angles = list(ref.problem.robot.q) if ref.problem.robot else []
    truth: dict[str, dict[str, tuple[str, list[str]]]] = {}
    for k in range(n):
        answers, t = {"student": f"s{k:03d}"}, {}
        for name in items:
            r = ref.results[name]
            kind = rng.choices(["correct", "alternative", "wrong", "invalid"], [3, 3, 3, 1])[0]
            answers[name], entries = _value(r.value, r.kind, kind, rng, angles)
            t[name] = ({"correct": "correct", "alternative": "correct", "wrong": "incorrect",
                        "invalid": "invalid"}[kind], entries)
        path = folder / f"s{k:03d}.json"
        path.write_text(json.dumps(answers))
        truth[str(path)] = t
    return truth


# ------------------------------------------------------------------------------------------------ peers
def _peer_worker(a: sp.Expr, b: sp.Expr, how: str, out) -> None:  # type: ignore[no-untyped-def]
    t = time.perf_counter()
    if how == "simplify":
        v = sp.simplify(a - b) == 0
    else:
        v = a.equals(b)
    out.put((v, time.perf_counter() - t))


def peer(a: sp.Expr, b: sp.Expr, how: str, cap: float) -> tuple[bool | None, float]:
    """(verdict, seconds) with a time cap (None: undecided or over the cap)."""
    ctx = mp.get_context("fork")
    q = ctx.Queue()
    p = ctx.Process(target=_peer_worker, args=(a, b, how, q))
    t = time.perf_counter()
    p.start()
    p.join(cap)
    if p.is_alive():
        p.terminate()
        return None, cap
    return (q.get() if not q.empty() else (None, time.perf_counter() - t))


def entry_pairs(ref, items, truth, limit: int, rng: random.Random):  # type: ignore[no-untyped-def]
    """Distinct (answer entry, reference entry, truth) of the readable answers, at most ``limit``."""
    from solver.grading.submission import answer_names, latex_spellings, load_submission, parse_answer
    pairs = {}
    for path, t in truth.items():
        sub = load_submission(Path(path))
        names, _, _ = answer_names(ref.problem, sub)
        for name in items:
            verdict, entries = t[name]
            if verdict == "invalid":
                continue
            got = parse_answer(sub.answers[name], names, latex_spellings(ref.problem))
            want = ref.results[name].value
            g, w = (list(sp.Matrix(got)), list(want)) if isinstance(want, sp.MatrixBase) else ([got], [want])
            for x, y, tr in zip(g, w, entries):
                pairs[(str(x), str(y))] = (x, y, tr)
    out = list(pairs.values())
    rng.shuffle(out)
    return out[:limit]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=300)
    ap.add_argument("--jobs", type=int, default=0)
    ap.add_argument("--peer-pairs", type=int, default=150)
    ap.add_argument("--peer-cap", type=float, default=5.0)
    args = ap.parse_args()
    for label, (pid, items) in PROBLEMS.items():
        path = ROOT / "problems" / f"{pid}.yaml"
        if not path.exists():
            print(f"{label}: {path.name} missing, skipped")
            continue
        t0 = time.perf_counter()
        ref = prepare(load_problem(path))
        ref.items = {k: ItemSpec(points=1) for k in items}
        t_ref = time.perf_counter() - t0
        with tempfile.TemporaryDirectory() as d:
            truth = make_class(ref, items, args.n, Path(d))
            t1 = time.perf_counter()
            reports = grade_files(ref, sorted(Path(d).iterdir()), jobs=args.jobs)
            t_grade = time.perf_counter() - t1
            wrong = undecided = 0
            for r in reports:
                for it in r["items"]:
                    want = truth[r["file"]][it["name"]][0]
                    undecided += it["verdict"] == "undecided"
                    wrong += it["verdict"] not in (want, "undecided")
            n_items = len(reports) * len(items)
            print(f"\n{label}: reference solved in {t_ref:.2f} s; {len(reports)} submissions x {len(items)} items "
                  f"graded in {t_grade:.2f} s ({len(reports) / t_grade:.1f} submissions/s, jobs={args.jobs or 'all cores'})")
            print(f"  robosolve verdicts: {n_items - wrong - undecided}/{n_items} as constructed, {wrong} wrong, "
                  f"{undecided} undecided")
            pairs = entry_pairs(ref, items, truth, args.peer_pairs, random.Random(1))
        print(f"  on {len(pairs)} distinct (answer entry, reference entry) pairs:")
        print(f"  {'method':<26}{'time [s]':>10}{'wrong':>8}{'undecided/timeout':>20}")
        from solver.grading.grader import entry_equiv
        t = time.perf_counter()
        ours = [entry_equiv(a, b, ItemSpec()).verdict for a, b, _ in pairs]
        t_ours = time.perf_counter() - t
        bad = sum(o not in (tr, "undecided") for o, (_, _, tr) in zip(ours, pairs))
        print(f"  {'robosolve':<26}{t_ours:>10.2f}{bad:>8}{ours.count('undecided'):>20}")
        for how in ("simplify", "equals"):
            t = time.perf_counter()
            res = [peer(a, b, how, args.peer_cap) for a, b, _ in pairs]
            el = time.perf_counter() - t
            bad = sum(v is not None and (("correct" if v else "incorrect") != tr) for (v, _), (_, _, tr) in
                      zip(res, pairs))
            und = sum(v is None for v, _ in res)
            name = "sympy simplify(a-b)==0" if how == "simplify" else "sympy a.equals(b)"
            print(f"  {name:<26}{el:>10.2f}{bad:>8}{und:>20}")


if __name__ == "__main__":
    main()
