"""Grading a class: many submissions in parallel, each bounded, the results written as one atomic set.

    out/summary.csv             one row per submission: student, file, output, one column per item, total, max
    out/<output>.md             feedback (Markdown); <output> is the submission's file name, encoded
    out/<output>.json           the graded items
    out/results.json            with gradescope=True, one submission (Gradescope's autograder schema);
    out/gradescope/<output>/results.json   the same for each submission of a directory

Hostile classes are expected: a link out of the folder is never followed, a folder, a pipe or a device named
like a submission gets a row saying so, each file is read and graded in a worker process with hard time and
memory limits (:mod:`solver.sandbox`), output names are unique and reversible (:func:`output_name`), and the
whole output folder is written aside and swapped in at the end, so that an interrupted run leaves the previous
results intact and two runs never mix.
"""
from __future__ import annotations

import csv
import ctypes
import io
import json
import os
import shutil
import stat
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import jinja2

from solver.grading.grader import INVALID, ItemResult, Reference, Report, grade
from solver.grading.submission import MAX_FILE_BYTES, clean_name, load_submission
from solver.publish.render import template_env
from solver.registry import preload
from solver.sandbox import Limits, Outcome, run_many
from solver.spec.errors import UserError
from solver.spec.problem import Problem

SUBMISSION_SUFFIXES = {".yaml", ".yml", ".json"}
MARKER = ".robosolve-results"  # marks a folder robosolve wrote (and may replace)


@dataclass
class Entry:
    """One submission of a class: the file to open, the name shown, or why it is not read."""

    path: Path
    label: str
    problem: str | None = None


def _entry(path: Path, label: str, folder: Path | None) -> Entry:
    """Classify ``path`` without reading it: links must stay inside ``folder`` (None: a file named explicitly),
    and the target must be a regular file of at most MAX_FILE_BYTES."""
    try:
        st = path.lstat()
    except OSError:
        return Entry(path, label, "cannot be read (it vanished or access is denied)")
    target = path
    if stat.S_ISLNK(st.st_mode):
        real = Path(os.path.realpath(path))
        if folder is not None and not real.is_relative_to(Path(os.path.realpath(folder))):
            return Entry(path, label, "a link to a file outside the class folder: not read")
        try:
            st = real.stat()
        except OSError:
            return Entry(path, label, "a link to nothing (dangling): not read")
        target = real
    if stat.S_ISDIR(st.st_mode):
        return Entry(path, label, "a folder, not a submission file")
    if not stat.S_ISREG(st.st_mode):
        return Entry(path, label, "not a regular file (a pipe, a device or a socket): not read")
    if st.st_size > MAX_FILE_BYTES:
        return Entry(path, label, f"file larger than {MAX_FILE_BYTES // 1000} kB: not read")
    return Entry(target, label)


def submission_entries(path: Path) -> list[Entry]:
    """Every name of a class folder that looks like a submission (*.yaml, *.yml, *.json, any case), sorted, each
    classified; or the single file ``path``."""
    if path.is_dir() and not path.is_symlink():
        names = sorted(p for p in path.iterdir() if p.suffix.lower() in SUBMISSION_SUFFIXES)
        return [_entry(p, p.name, path) for p in names]
    return [_entry(path, path.name, None)]


def submission_files(path: Path) -> list[Path]:
    """The readable submission files of ``path`` (a folder or a file)."""
    return [e.path for e in submission_entries(path) if e.problem is None]


# ------------------------------------------------------------------------------------ parallel grading
_REF: Reference | None = None


def _invalid(ref: Reference, entry: Entry, why: str) -> dict[str, Any]:
    student = clean_name(Path(entry.label).stem) or "student"
    return Report(student, entry.label, ref.problem.id,
                  [ItemResult(n, INVALID, 0.0, it.points, [f"not graded: {why}"]) for n, it in ref.items.items()],
                  [f"submission not read: {why}"]).to_dict()


def _grade_entry(entry: Entry) -> dict[str, Any]:
    assert _REF is not None
    return grade(_REF, load_submission(entry.path, entry.label)).to_dict()


def grade_files(ref: Reference, files: list[Path] | list[Entry], jobs: int = 0,
                progress: Callable[[dict[str, Any]], None] | None = None) -> list[dict[str, Any]]:
    """Grade every submission, ``jobs`` worker processes at a time (0: one per core), each with hard limits:
    time = the item time limit × the items + 15 s, memory 1 GB. Reports in the order of ``files``; a file that
    cannot be read, or exceeds a limit, gets a report with every item invalid and the reason."""
    global _REF
    _REF = ref
    entries = [f if isinstance(f, Entry) else _entry(Path(f), Path(f).name, None) for f in files]
    readable = [i for i, e in enumerate(entries) if e.problem is None]
    reports: list[dict[str, Any] | None] = [None] * len(entries)
    for i, e in enumerate(entries):
        if e.problem is not None:
            reports[i] = _invalid(ref, e, e.problem)
            if progress:
                progress(reports[i])  # type: ignore[arg-type]
    limits = Limits(ref.spec.time_limit * max(1, len(ref.items)) + 15.0, 1024)

    def done(k: int, out: Outcome) -> None:
        i = readable[k]
        rep = out.value if out.ok else _invalid(ref, entries[i], out.message if out.failure != "exception" else
                                                 "internal error while grading: manual review")
        reports[i] = rep
        if progress:
            progress(rep)

    preload(len(readable))
    run_many(_grade_entry, [entries[i] for i in readable], jobs, limits, done)
    return [r for r in reports if r is not None]


def output_name(label: str) -> str:
    """A file-system-safe name, unique and reversible: letters and digits of any script, '.', '_' and '-' are kept,
    every other character (and a leading '.') becomes %XX of its UTF-8 bytes. Longer than 180 bytes: a prefix, '~'
    and a hash of the whole name."""
    import hashlib
    out = []
    for k, ch in enumerate(label):
        if (ch.isalnum() and ch.isprintable()) or ch in "_-" or (ch == "." and k > 0):
            out.append(ch)
        else:
            out.append("".join(f"%{b:02X}" for b in ch.encode("utf-8", "surrogatepass")))
    name = "".join(out) or "%00"
    if len(name.encode("utf-8")) > 180:
        digest = hashlib.sha1(label.encode("utf-8", "surrogatepass")).hexdigest()[:16]
        name = name.encode("utf-8")[:140].decode("utf-8", "ignore") + "~" + digest
    return name


# ------------------------------------------------------------------------------------------ outputs
_MD_SPECIAL = set("\\`*_{}[]<>()#+!|~&")


def md_plain(text: Any) -> str:
    """Text from a submission shown literally in Markdown: one line, every Markdown or HTML metacharacter escaped."""
    return "".join("\\" + ch if ch in _MD_SPECIAL else ch for ch in clean_name(str(text), 200))


def _env(subdir: str = "md") -> jinja2.Environment:
    env = template_env(subdir)
    env.filters["cell"] = lambda s: str(s).replace("|", "\\|").replace("\n", " ")
    env.filters["plain"] = md_plain
    return env


def feedback_markdown(problem: Problem, report: dict[str, Any]) -> str:
    """The feedback page of one submission."""
    return _env().get_template("feedback.md.j2").render(problem=problem, report=report)


def answer_template(ref: Reference) -> str:
    """The blank answer sheet (YAML) of a problem: one commented entry per graded item."""
    env = _env("yaml")
    problem = ref.problem
    names = [k for k, v in problem.names.items() if not k.startswith("_")]
    coords = ", ".join(s.name for s in problem.robot.q) if problem.robot else ""
    items = [(n, it, ref.results[n]) for n, it in ref.items.items()]
    return env.get_template("answers.yaml.j2").render(problem=problem, items=items, names=", ".join(names),
                                                      coords=coords)


def gradescope_json(report: dict[str, Any]) -> dict[str, Any]:
    """Gradescope autograder results: score, output, tests[] with name, score, max_score, status, output."""
    tests = [{"name": it["name"], "score": it["score"], "max_score": it["max_score"],
              "status": "passed" if it["verdict"] == "correct" else "failed",
              "output": f"{it['verdict']}" + (": " + "; ".join(it["feedback"]) if it["feedback"] else "")}
             for it in report["items"]]
    return {"score": report["total"], "output": "\n".join(report["notes"]) or "graded by robosolve",
            "tests": tests}


_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def csv_cell(value: Any) -> str:
    """Text for a spreadsheet cell that a spreadsheet will not run: a leading = + - @ is quoted with '."""
    s = clean_name(value, 500) if isinstance(value, str) else str(value)
    return "'" + s if s.startswith(_FORMULA_START) else s


def summary_csv(reports: list[dict[str, Any]], items: list[str]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["student", "file", "output", *items, "total", "max"])
    for r in reports:
        by = {it["name"]: it for it in r["items"]}
        w.writerow([csv_cell(r["student"]), csv_cell(r["file"]), csv_cell(output_name(r["file"])),
                    *[f"{by[i]['score']:g}" if i in by else "" for i in items], f"{r['total']:g}", f"{r['max']:g}"])
    return buf.getvalue()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file in the same directory and a rename (mode 0666 less the
    umask, as any file the user writes)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as f:
            f.write(text)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _exchange(a: Path, b: Path) -> bool:
    """Atomically swap two paths (Linux renameat2 RENAME_EXCHANGE); False where unsupported."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd, rename_exchange = -100, 2
    return fn(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0


class ResultsFolder:
    """The ``--out`` folder, checked before any grading and replaced as a whole at the end.

    Refused at once: an existing file, a path under a file, a place that cannot be written, a non-empty folder
    robosolve did not write, a folder another run is writing (a lock on the parent folder). The results are
    written into a hidden folder beside it and swapped in by :meth:`commit`; until then the previous results stay
    as they were, and a killed run leaves them intact (its hidden folder is removed by the next run)."""

    def __init__(self, out: Path) -> None:
        self.out = out
        self.fd: int | None = None
        self.tmp: Path | None = None
        if out.is_symlink() or (out.exists() and not out.is_dir()):
            raise UserError(f"--out {out} is an existing file, not a folder", None, "give a folder for the results")
        anc = out.parent
        while not anc.exists():
            anc = anc.parent
        if not anc.is_dir():
            raise UserError(f"--out {out} is under {anc}, which is a file", None, "give a folder for the results")
        if out.is_dir() and any(out.iterdir()) and not (out / MARKER).exists():
            raise UserError(f"--out {out} is a folder with files robosolve did not write; they would be replaced",
                            None, "give a new or empty folder, or one of robosolve's results folders")
        try:
            out.parent.mkdir(parents=True, exist_ok=True)
            self.fd = os.open(out.parent, os.O_RDONLY)
        except OSError as exc:
            raise UserError(f"--out {out}: cannot create its folder ({exc.strerror})", None,
                            "choose a place you can write") from None
        import fcntl
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            self.close()
            raise UserError(f"another robosolve run is writing results in {out.parent}", None,
                            "wait for it to finish, or choose another --out") from None
        for stale in out.parent.glob(f".{out.name}.tmp-*"):
            shutil.rmtree(stale, ignore_errors=True)
        try:
            self.tmp = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{out.name}.tmp-"))
        except OSError as exc:
            self.close()
            raise UserError(f"--out {out}: cannot write in {out.parent} ({exc.strerror})", None,
                            "choose a place you can write") from None

    def write(self, rel: str, text: str) -> Path:
        assert self.tmp is not None
        path = self.tmp / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "w", encoding="utf-8", newline="") as f:
            f.write(text)
        return self.out / rel

    def commit(self) -> None:
        """Swap the new results in (the previous ones, if any, are removed)."""
        assert self.tmp is not None
        (self.tmp / MARKER).write_text(f"results written by robosolve grade at {time.strftime('%Y-%m-%d %H:%M:%S')}\n",
                                       encoding="utf-8")
        mode = 0o777 & ~_umask()
        for d, _, files in os.walk(self.tmp):
            os.chmod(d, mode)
            for f in files:
                os.chmod(os.path.join(d, f), mode & 0o666)
        if self.out.exists():
            if _exchange(self.tmp, self.out):
                shutil.rmtree(self.tmp, ignore_errors=True)
            else:
                old = self.out.parent / f".{self.out.name}.tmp-old"
                os.rename(self.out, old)
                os.rename(self.tmp, self.out)
                shutil.rmtree(old, ignore_errors=True)
        else:
            os.rename(self.tmp, self.out)
        self.tmp = None
        self.close()

    def close(self) -> None:
        """Give up (remove the unfinished results) and release the lock."""
        if self.tmp is not None:
            shutil.rmtree(self.tmp, ignore_errors=True)
            self.tmp = None
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None


def write_outputs(problem: Problem, ref: Reference, reports: list[dict[str, Any]], out: Path | ResultsFolder,
                  gradescope: bool = False) -> list[Path]:
    """summary.csv, <output>.md, <output>.json (and Gradescope results) under ``out``, swapped in as one set."""
    folder = out if isinstance(out, ResultsFolder) else ResultsFolder(out)
    written = []
    try:
        for r in reports:
            name = output_name(r["file"])
            written.append(folder.write(f"{name}.md", feedback_markdown(problem, r)))
            written.append(folder.write(f"{name}.json", json.dumps(r, indent=2, ensure_ascii=False) + "\n"))
            if gradescope:
                rel = "results.json" if len(reports) == 1 else f"gradescope/{name}/results.json"
                written.append(folder.write(rel, json.dumps(gradescope_json(r), indent=2) + "\n"))
        written.append(folder.write("summary.csv", summary_csv(reports, list(ref.items))))
        folder.commit()
    finally:
        folder.close()
    return written
