"""The command line loads only what a command needs (issue #35): loading the CLI, its help and
each command's help import none of the heavy libraries; a run imports matplotlib only when a
PNG or the GIF is asked for. Checked on ``sys.modules`` in a fresh interpreter, not by timing."""

import subprocess
import sys

import pytest

HEAVY = ("matplotlib", "dask", "distributed", "scipy", "scipy.sparse", "shapely", "pydantic",
         "numpy", "PIL", "fmpy", "ompl")
"""What the CLI must not import before a command uses it."""

COMMANDS = ("plan-and-run", "plan", "run", "analyze", "validate", "view", "atlas", "build-fmu",
            "export-ssp", "slip-study", "sweep")


def _loaded_after(code: str) -> list[str]:
    """The heavy modules loaded in a fresh interpreter after ``code`` (which may exit)."""
    probe = (f"import sys, atexit\n"
             f"atexit.register(lambda: print('LOADED', sorted(m for m in {HEAVY!r} "
             f"if m in sys.modules)))\n{code}\n")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          timeout=120)
    lines = [line for line in done.stdout.splitlines() if line.startswith("LOADED")]
    assert lines, done.stdout + done.stderr
    return eval(lines[-1].split(" ", 1)[1])


def test_loading_the_cli_imports_no_heavy_library():
    assert _loaded_after("import pushtrain.cli.main") == []


@pytest.mark.parametrize("args", [["--help"], *[[c, "--help"] for c in COMMANDS]],
                         ids=lambda a: " ".join(a))
def test_help_imports_no_heavy_library(args):
    code = ("import sys\nfrom pushtrain.cli.main import pushtrain_main\n"
            f"sys.argv = ['pushtrain', *{args!r}]\n"
            "try:\n    pushtrain_main()\nexcept SystemExit:\n    pass\n")
    assert _loaded_after(code) == []


def test_plan_and_run_help_imports_no_heavy_library():
    code = ("import sys\nfrom pushtrain.cli.main import plan_and_run_main\n"
            "sys.argv = ['plan-and-run', '--help']\n"
            "try:\n    plan_and_run_main()\nexcept SystemExit:\n    pass\n")
    assert _loaded_after(code) == []
