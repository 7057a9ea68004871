"""Benchmark: the dynamic model as a user gets it, robosolve vs sympy.physics.mechanics and roboticstoolbox.

Robots (symbolic lengths, offsets, centres of mass, masses and inertias): planar 2R..6R in a vertical plane, a
spatial 3R (anthropomorphic), a PUMA-like arm with its real offsets (a2, a3, d3, d4), a six-joint arm with the
same DH table and generic centres of mass and diagonal inertias. Each robot is one DH description from which the
robosolve spec and the peers' models are built.

robosolve: `load` (the spec), `solve` (B, Christoffel symbols, c, S with the skew check, g, the model, per-body
energies), `output` (`--format json`), in one process; `cli` is the whole `robosolve solve FILE -f json` process.
Peers, each raw and followed by the simplification that makes them readable (`trigsimp` of every entry of the
mass matrix, `trigsimp(expand(.))` of the forcing / torque):
  - `lagrange`: sympy.physics.mechanics LagrangesMethod (mass matrix and forcing),
  - `kane`: sympy.physics.mechanics KanesMethod (u = q̇; mass matrix and forcing),
  - `rne`: roboticstoolbox-python's symbolic recursive Newton-Euler `DHRobot.rne` (run with the Python of
    --rtb-python, default .venv-bench/bin/python beside this repository, when it has roboticstoolbox).
Times are CPU seconds (the machine is shared; wall times vary with its load), the fastest of --repeat runs
of robosolve, its CLI and each raw peer, interleaved so that a slow phase of the machine hits all alike; every
run is a separate process capped at --cap wall seconds, whose imports are frozen (gc.freeze, as `robosolve
solve` does) before its clock starts. All models are evaluated at --points random states and parameter values;
`agree` is the largest relative difference of the torques from robosolve's.

    python benchmarks/dynamics.py [--robots 2R,3R,4R,S3R,PUMA] [--cap 60] [--peers lagrange,kane,rne] [--points 3]
                                  [--repeat 3]
    python benchmarks/dynamics.py --robots all --cap 300
"""
from __future__ import annotations

import argparse
import gc
import json
import os
import random
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
clock = time.process_time  # CPU seconds of the process: the machine is shared, wall times vary with its load
DEFAULT_ROBOTS = "2R,3R,4R,S3R,PUMA"
ALL_ROBOTS = "2R,3R,4R,5R,6R,S3R,PUMA,G6R"


# ------------------------------------------------------------------------------------------- descriptions
def describe(name: str) -> dict:
    """{rows: [(a, alpha, d, theta)], links: [(mass, com[3], inertia[3])], gravity: [3]} as strings, standard DH."""
    if name.endswith("R") and name[:-1].isdigit():
        n = int(name[:-1])
        rows = [(f"l{i}", "0", "0", f"q{i}") for i in range(1, n + 1)]
        links = [(f"m{i}", [f"d{i} - l{i}", "0", "0"], ["0", "0", f"I{i}"]) for i in range(1, n + 1)]
        return dict(rows=rows, links=links, gravity=["0", "-g0", "0"])
    if name == "S3R":
        rows = [("0", "pi/2", "d1", "q1"), ("a2", "0", "0", "q2"), ("a3", "0", "0", "q3")]
        links = [("m1", ["0", "0", "0"], ["I1xx", "I1yy", "I1zz"]),
                 ("m2", ["-a2/2", "0", "0"], ["I2xx", "I2yy", "I2zz"]),
                 ("m3", ["-a3/2", "0", "0"], ["I3xx", "I3yy", "I3zz"])]
        return dict(rows=rows, links=links, gravity=["0", "0", "-g0"])
    rows = [("0", "pi/2", "0", "q1"), ("a2", "0", "0", "q2"), ("a3", "-pi/2", "d3", "q3"),
            ("0", "pi/2", "d4", "q4"), ("0", "-pi/2", "0", "q5"), ("0", "0", "0", "q6")]
    inertia = [[f"I{i}xx", f"I{i}yy", f"I{i}zz"] for i in range(1, 7)]
    if name == "PUMA":  # centres of mass where the PUMA 560's are off the axes (Corke's model), symbolic
        coms = [["0", "0", "0"], ["r2x", "0", "r2z"], ["0", "r3y", "r3z"], ["0", "r4y", "0"], ["0", "0", "0"],
                ["0", "0", "r6z"]]
        inertia[0] = ["0", "I1yy", "0"]
    elif name == "G6R":
        coms = [[f"r{i}x", f"r{i}y", f"r{i}z"] for i in range(1, 7)]
    else:
        raise SystemExit(f"unknown robot {name}")
    links = [(f"m{i}", coms[i - 1], inertia[i - 1]) for i in range(1, 7)]
    return dict(rows=rows, links=links, gravity=["0", "0", "-g0"])


def parameters(desc: dict) -> list[str]:
    """Names of the parameters of a description, sorted (read as identifiers, without sympy: the robosolve worker
    writes its spec before its clock starts, and sympy's parser is not warmed up for it)."""
    import re
    names: set[str] = set()
    texts = [x for r in desc["rows"] for x in r] + desc["gravity"]
    texts += [x for m, c, i in desc["links"] for x in [m, *c, *i]]
    for t in texts:
        names |= set(re.findall(r"[A-Za-z_]\w*", t)) - {"pi", "sin", "cos"}
    return sorted(n for n in names if not (n.startswith("q") and n[1:].isdigit()))


def spec_text(name: str, desc: dict) -> str:
    """The robosolve spec of a description."""
    n = len(desc["rows"])
    out = [f"id: bench-{name}", f"title: benchmark robot {name}", "symbols:"]
    out += [f"  {p}: parameter {p}" for p in parameters(desc)]
    out += ["robot:", f"  joints: [{', '.join(['R'] * n)}]", f"  gravity: [{', '.join(desc['gravity'])}]", "  dh:",
            "    table:"]
    out += [f"      - {{a: {a}, alpha: {al}, d: {d}, theta: {th}}}" for a, al, d, th in desc["rows"]]
    out += ["    links:"]
    out += [f"      - {{mass: {m}, com: [{', '.join(c)}], inertia: [{', '.join(i)}]}}" for m, c, i in desc["links"]]
    out += ["asks:", "  - kind: dynamic_model", "    plots: false", ""]
    return "\n".join(out)


# ------------------------------------------------------------------------------------------------ workers
def _values(exprs, points: list[dict], alias: dict[str, str] | None = None) -> list[list[float]]:  # type: ignore[no-untyped-def]
    """Each expression at each point ({name: value}), by exact substitution of numbers (no compilation: fast on
    huge unsimplified expressions). Symbols, functions q(t) and their derivatives are matched by name (q1, dq1,
    ddq1); ``alias`` maps other names to those (u1 -> dq1)."""
    import sympy as sp
    from sympy.core.function import AppliedUndef
    exprs = list(exprs)
    atoms: set = set()
    for e in exprs:
        atoms |= e.free_symbols | e.atoms(sp.Derivative) | e.atoms(AppliedUndef)

    def name(a) -> str:  # type: ignore[no-untyped-def]
        if isinstance(a, sp.Derivative):
            order = sum(int(c) for _, c in a.variable_count)
            n = "d" * order + a.expr.func.__name__
        elif isinstance(a, AppliedUndef):
            n = a.func.__name__
        else:
            n = a.name
        return (alias or {}).get(n, n)
    out = []
    for p in points:
        subs = {a: sp.Float(p[name(a)], 30) for a in atoms if name(a) in p}
        out.append([float(sp.N(e.xreplace(subs))) for e in exprs])
    return out


def _emit(times: dict) -> None:
    """The timings first (a run stopped by its cap while evaluating still reports them)."""
    print(json.dumps(dict(times=times)), flush=True)


def work_robosolve(name: str, points: list[dict]) -> dict:
    sys.path.insert(0, str(ROOT))
    from solver.publish.render import render
    from solver.solve import solve_problem
    from solver.registry import load_all
    from solver.spec import load_problem_text
    load_all()  # the library's modules imported (the CLI column counts the imports)
    import sympy.tensor.tensor  # noqa: F401  sympy imports it at the first matrix sum; the peers' imports have it
    text = spec_text(name, describe(name))  # (the user's file: written before the clock starts)
    gc.freeze()  # what the imports made, out of the collector's sight (as `robosolve solve` does; every worker)
    t0 = clock()
    problem = load_problem_text(text)
    t1 = clock()
    sols = solve_problem(problem)
    t2 = clock()
    text = render(problem, sols, "json")
    t3 = clock()
    _emit(dict(load=t1 - t0, solve=t2 - t1, output=t3 - t2))
    return dict(values=_values(sols[0].results["model"].value, points), chars=len(text))


def _frames(desc: dict, q):  # type: ignore[no-untyped-def]
    """sympy.physics.mechanics frames, joint origins and mass centres of a DH description."""
    import sympy as sp
    from sympy.physics.mechanics import Point, ReferenceFrame
    N = ReferenceFrame("N")
    O = Point("O")
    O.set_vel(N, 0)
    frames, centres = [], []
    F, P = N, O
    for i, ((a, al, d, th), (m, c, I)) in enumerate(zip(desc["rows"], desc["links"])):
        theta = sp.sympify(th, locals={f"q{k + 1}": q[k] for k in range(len(q))})
        Fi = F.orientnew(f"F{i + 1}", "Body", (theta, sp.sympify(al), 0), "ZXZ")
        Pi = P.locatenew(f"O{i + 1}", sp.sympify(d) * F.z + sp.sympify(a) * Fi.x)
        r = [sp.sympify(x) for x in c]
        Ci = Pi.locatenew(f"C{i + 1}", r[0] * Fi.x + r[1] * Fi.y + r[2] * Fi.z)
        Ci.set_vel(N, Ci.pos_from(O).dt(N))
        frames.append(Fi)
        centres.append(Ci)
        F, P = Fi, Pi
    return N, O, frames, centres


def _simplify(M, f):  # type: ignore[no-untyped-def]
    import sympy as sp
    return M.applyfunc(sp.trigsimp), f.applyfunc(lambda e: sp.trigsimp(sp.expand(e)))


def work_mechanics(name: str, points: list[dict], method: str, simplify: bool) -> dict:
    import sympy as sp
    from sympy.physics.mechanics import (KanesMethod, LagrangesMethod, Lagrangian, RigidBody, dynamicsymbols,
                                         inertia)
    desc = describe(name)
    n = len(desc["rows"])
    gc.freeze()
    t0 = clock()
    q = dynamicsymbols(f"q1:{n + 1}")
    N, O, frames, centres = _frames(desc, q)
    gvec = sum((sp.sympify(x) * e for x, e in zip(desc["gravity"], (N.x, N.y, N.z))), 0 * N.x)
    bodies, loads = [], []
    for (m, c, I), F, C in zip(desc["links"], frames, centres):
        mass = sp.sympify(m)
        Ixx, Iyy, Izz = (sp.sympify(x) for x in I)
        b = RigidBody(f"B{F.name}", C, F, mass, (inertia(F, Ixx, Iyy, Izz), C))
        b.potential_energy = -mass * gvec.dot(C.pos_from(O))
        bodies.append(b)
        loads.append((C, mass * gvec))
    time_ = dynamicsymbols._t
    qd, qdd = [x.diff(time_) for x in q], [x.diff(time_, 2) for x in q]
    if method == "lagrange":
        lm = LagrangesMethod(Lagrangian(N, *bodies), q)
        lm.form_lagranges_equations()
        M, f = lm.mass_matrix, lm.forcing
        acc = sp.Matrix(qdd)
    else:
        u = dynamicsymbols(f"u1:{n + 1}")
        km = KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=[a - b for a, b in zip(qd, u)])
        for C in centres:  # velocities in the generalized speeds
            C.set_vel(N, C.vel(N).subs(dict(zip(qd, u))))
        km.kanes_equations(bodies, loads)
        M, f = km.mass_matrix, km.forcing
        acc = sp.Matrix([x.diff(time_) for x in u])
    t1 = clock()
    times = dict(raw=t1 - t0)
    if simplify:
        M, f = _simplify(M, f)
        times["simplified"] = clock() - t0
    _emit(times)
    alias = {**{f"u{k}": f"dq{k}" for k in range(1, n + 1)}, **{f"du{k}": f"ddq{k}" for k in range(1, n + 1)}}
    return dict(values=_values(M * acc - f, points, alias))


def work_rne(name: str, points: list[dict], simplify: bool) -> dict:
    import roboticstoolbox as rtb
    import sympy as sp
    desc = describe(name)
    n = len(desc["rows"])
    gc.freeze()
    t0 = clock()
    links = []
    for (a, al, d, th), (m, c, I) in zip(desc["rows"], desc["links"]):
        links.append(rtb.RevoluteDH(d=sp.sympify(d), a=sp.sympify(a), alpha=sp.sympify(al), m=sp.sympify(m),
                                    r=[sp.sympify(x) for x in c], I=[sp.sympify(x) for x in I], Jm=0, G=1, B=0,
                                    Tc=[0, 0]))
    robot = rtb.DHRobot(links, name=name, symbolic=True)
    q = sp.symbols(f"q1:{n + 1}")
    dq = sp.symbols(f"dq1:{n + 1}")
    ddq = sp.symbols(f"ddq1:{n + 1}")
    tau = robot.rne(list(q), list(dq), list(ddq), gravity=[sp.sympify(x) for x in desc["gravity"]])
    tau = sp.Matrix(list(sp.Matrix(tau)))
    t1 = clock()
    times = dict(raw=t1 - t0)
    if simplify:
        tau = tau.applyfunc(lambda e: sp.trigsimp(sp.expand(e)))
        times["simplified"] = clock() - t0
    _emit(times)
    return dict(values=_values(tau, points))


def worker(kind: str, name: str, points: list[dict], simplify: bool) -> dict:
    if kind == "robosolve":
        return work_robosolve(name, points)
    if kind in ("lagrange", "kane"):
        return work_mechanics(name, points, kind, simplify)
    if kind == "rne":
        return work_rne(name, points, simplify)
    raise SystemExit(f"unknown worker {kind}")


# ------------------------------------------------------------------------------------------------ driver
def run(cmd: list[str], cap: float, stdin: str = "") -> tuple[dict | None, float, str]:
    """A capped process: (its JSON on stdout or None, wall seconds, why it failed)."""
    t = time.perf_counter()
    why = ""
    try:
        r = subprocess.run(cmd, input=stdin, capture_output=True, text=True, timeout=cap, cwd=ROOT,
                           env={**os.environ, "PYTHONPATH": str(ROOT)})
        out = r.stdout
        if r.returncode != 0:
            why = (r.stderr.strip().splitlines() or ["failed"])[-1][:120]
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout.decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
        why = f"> {cap:.0f} s"
    merged: dict = {}
    for line in out.strip().splitlines():
        try:
            merged.update(json.loads(line))
        except json.JSONDecodeError:
            pass
    return (merged or None), time.perf_counter() - t, why


def agreement(ref: list[list[float]], other: list[list[float]]) -> float:
    """Largest |a - b| / max(1, |a|) over points and components."""
    return max(abs(a - b) / max(1.0, abs(a)) for ra, rb in zip(ref, other) for a, b in zip(ra, rb))


def random_points(name: str, k: int, seed: int) -> list[dict]:
    desc = describe(name)
    n = len(desc["rows"])
    rng = random.Random(seed)
    out = []
    for _ in range(k):
        p = {x: rng.uniform(0.5, 1.5) for x in parameters(desc)}
        for i in range(1, n + 1):
            p[f"q{i}"] = rng.uniform(-3.1, 3.1)
            p[f"dq{i}"] = rng.uniform(-1, 1)
            p[f"ddq{i}"] = rng.uniform(-1, 1)
        out.append(p)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robots", default=DEFAULT_ROBOTS, help=f"comma-separated, or 'all' ({ALL_ROBOTS})")
    ap.add_argument("--peers", default="lagrange,kane,rne")
    ap.add_argument("--cap", type=float, default=60.0, help="seconds per run (each peer, raw and simplified)")
    ap.add_argument("--points", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=3, help="runs of robosolve, its CLI and each raw peer, "
                    "interleaved; the fastest of each is reported (the simplified peers run once)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--rtb-python", default=str(ROOT / ".venv-bench" / "bin" / "python"))
    ap.add_argument("--worker", nargs=2, metavar=("KIND", "ROBOT"), help=argparse.SUPPRESS)
    ap.add_argument("--simplify", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        points = json.loads(sys.stdin.read())
        print(json.dumps(worker(args.worker[0], args.worker[1], points, args.simplify)), flush=True)
        return
    robots = (ALL_ROBOTS if args.robots == "all" else args.robots).split(",")
    peers = [p for p in args.peers.split(",") if p]
    have_rtb = "rne" in peers and Path(args.rtb_python).exists() and subprocess.run(
        [args.rtb_python, "-c", "import roboticstoolbox, sympy"], capture_output=True).returncode == 0
    if "rne" in peers and not have_rtb:
        print(f"rne: roboticstoolbox not importable with {args.rtb_python} (skipped)")
        peers.remove("rne")
    me = [sys.executable, str(Path(__file__).resolve()), "--worker"]
    print(f"CPU seconds, the fastest of {args.repeat} interleaved runs (the simplified peers: one); each peer run "
          f"capped at {args.cap:.0f} s wall ('capped'); {args.points} random points; "
          "ratio = peer / robosolve (load + solve + json); agree = largest relative difference from robosolve")
    header = f"{'robot':<6}{'load':>6}{'solve':>7}{'json':>6}{'total':>7}{'cli':>7}"
    for p in peers:
        header += f" | {p + ' raw':>12}{'ratio':>7}{'+simp':>9}{'ratio':>7}{'agree':>9}"
    print(header, flush=True)
    for name in robots:
        points = random_points(name, args.points, args.seed)
        stdin = json.dumps(points)
        ours, raws, failed = None, {p: (None, "") for p in peers}, ""
        stopped: set[str] = set()  # peers capped or failed once: not run again
        for _ in range(args.repeat):  # interleaved: a slow phase of the shared machine hits every tool alike
            run_ours, _, why = run(me + ["robosolve", name], args.cap * 4, stdin)
            if run_ours is None or "values" not in run_ours:
                failed = why
                break
            if ours is None or _total(run_ours) < _total(ours):
                ours = run_ours
            for p in peers:
                if p in stopped:
                    continue
                py = [args.rtb_python, str(Path(__file__).resolve()), "--worker"] if p == "rne" else me
                raw, _, why_raw = run(py + [p, name], args.cap, stdin)
                raw_t = (raw or {}).get("times", {}).get("raw")
                best = raws[p][0]
                if raw_t is None:
                    stopped.add(p)
                    if best is None:
                        raws[p] = (None, why_raw)
                elif best is None or raw_t < best["times"]["raw"]:
                    raws[p] = (raw, "")
        if ours is None:
            print(f"{name:<6} robosolve failed: {failed}", flush=True)
            continue
        t = ours["times"]
        total = _total(ours)
        cli = min(_cli(name) for _ in range(args.repeat))
        line = f"{name:<6}{t['load']:>6.2f}{t['solve']:>7.2f}{t['output']:>6.2f}{total:>7.2f}{cli:>7.2f}"
        for p in peers:
            py = [args.rtb_python, str(Path(__file__).resolve()), "--worker"] if p == "rne" else me
            raw, why_raw = raws[p]
            raw_t = (raw or {}).get("times", {}).get("raw")
            simp, why_simp = None, "skipped"  # no simplification run when the raw model alone took > cap/4
            if raw_t is not None and raw_t < args.cap / 4:
                simp, _, why_simp = run(py + [p, name, "--simplify"], args.cap, stdin)
            simp_t = (simp or {}).get("times", {}).get("simplified")
            cell = (f"{raw_t:>12.2f}{raw_t / total:>6.1f}x" if raw_t is not None
                    else f"{'capped' if why_raw.startswith('>') else why_raw[:12]:>12}{'-':>7}")
            cell += (f"{simp_t:>9.2f}{simp_t / total:>6.1f}x" if simp_t is not None
                     else f"{'capped' if why_simp.startswith('>') else why_simp[:9]:>9}{'-':>7}")
            vals = (raw or simp or {}).get("values")
            cell += f"{agreement(ours['values'], vals):>9.1e}" if vals else f"{'-':>9}"
            line += " | " + cell
        print(line, flush=True)


def _total(run_times: dict) -> float:
    t = run_times["times"]
    return float(t["load"] + t["solve"] + t["output"])


def _cli(name: str) -> float:
    """CPU seconds of the whole `robosolve solve FILE -f json` process on the robot's spec (nan if it failed)."""
    with tempfile.TemporaryDirectory() as tmp:
        spec = Path(tmp) / f"{name}.yaml"
        spec.write_text(spec_text(name, describe(name)))
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        r = subprocess.run([sys.executable, "-m", "solver", "solve", str(spec), "-f", "json"], cwd=ROOT,
                           capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime if r.returncode == 0 \
        else float("nan")

if __name__ == "__main__":
    main()
