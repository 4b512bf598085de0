"""examples/python/three_grades.py in its reduced form (--short): it runs, writes its figure,
and the three grades come out in the order of their grades."""

import re
import subprocess
import sys

from conftest import REPO


def test_three_grades_example(tmp_path):
    fig = tmp_path / "three.png"
    script = REPO / "examples" / "python" / "three_grades.py"
    p = subprocess.run([sys.executable, str(script), "--short", "-o", str(fig)],
                       capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert p.returncode == 0, p.stderr
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    err = [float(x) for x in re.findall(r"outage end:\s+([0-9.]+) m", p.stdout)]
    assert len(err) == 3
    # Navigation grade drifts least, MEMS most (seed 1, 30 s outage).
    assert err[0] < err[1] < err[2], p.stdout
