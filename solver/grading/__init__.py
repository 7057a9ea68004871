"""Grading students' answers: submissions (read as untrusted input), LaTeX input, the grader, the gradebook
(a class in parallel, outputs)."""
