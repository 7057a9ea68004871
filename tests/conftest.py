from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PROBLEMS = ROOT / "problems"

RP_ROBOT = """
id: trp
title: planar RP (2004-03-25)
symbols: {m1: m1, m2: m2, d1: d1, l1: l1, I1: I1, I2: I2, g0: g0}
robot:
  joints: [R, P]
  gravity: [g0, 0, 0]
  links:
    - {mass: m1, com: [d1*cos(q1), d1*sin(q1)], angle: q1, inertia: I1}
    - {mass: m2, com: [l1*cos(q1) - q2*sin(q1), l1*sin(q1) + q2*cos(q1)], angle: q1, inertia: I2}
"""  # the planar RP robot of 2004-03-25 (tests append known:/asks:)

R2_ROBOT = """robot:
  joints: [R, R]
  gravity: [0, -g0, 0]
  links:
    - {mass: m1, com: [d1*cos(q1), d1*sin(q1)], angle: q1, inertia: I1}
    - {mass: m2, com: [l1*cos(q1) + d2*cos(q1 + q2), l1*sin(q1) + d2*sin(q1 + q2)], angle: q1 + q2, inertia: I2}
"""  # a planar 2R in a vertical plane (tests prepend id/title/symbols, append the rest)


@pytest.fixture
def write(tmp_path):
    """Write a spec text to a temporary file and return its path."""

    def _write(text: str, name: str = "spec.yaml") -> Path:
        p = tmp_path / name
        p.write_text(text)
        return p

    return _write
