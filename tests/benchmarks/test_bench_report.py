"""benchmarks/bench_report.py where no browser can be driven: one line saying what is missing,
before any work; never a selenium traceback."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_without_a_browser_or_chromedriver_it_says_what_is_missing(tmp_path):
    bin_dir = Path(sys.executable).parent  # this venv only: no chromium, no chromedriver
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_report.py")],
                          capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PATH": str(bin_dir)}, cwd=tmp_path)
    assert proc.returncode != 0
    assert "Traceback" not in proc.stderr, proc.stderr
    assert "not measured" in proc.stderr and "chromedriver" in proc.stderr, proc.stderr
    assert len(proc.stderr.splitlines()) == 1, proc.stderr
