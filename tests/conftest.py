import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "samples"

# Tests write machine files in their tmp_path that name the samples' programs (and the
# test data's): those folders are allowed as the user's --allow-root would allow them
# (plcpred.parser.files). tests/safety/test_untrusted_inputs.py takes them away where it checks
# the rule itself.
os.environ["PLCPRED_ALLOW_ROOTS"] = os.pathsep.join([str(SAMPLES), str(ROOT / "tests" / "data")])


@pytest.fixture
def samples_dir():
    return SAMPLES


def plcpred_in_process(*args):
    """``plcpred ARGS`` run in this process, with its exit code and its output as a
    finished subprocess gives them (returncode, stdout, stderr): a second of interpreter
    start-up and imports saved per call where the test is not about the process itself."""
    import contextlib
    import io
    import subprocess

    from plcpred.cli import main

    out, err = io.StringIO(), io.StringIO()
    argv = [str(a) for a in args]
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as e:          # argparse's usage errors and --help
            code = e.code if isinstance(e.code, int) else 2
    return subprocess.CompletedProcess(["plcpred", *argv], code, out.getvalue(), err.getvalue())
