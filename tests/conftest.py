import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "samples"

# Tests write machine files in their tmp_path that name the samples' programs (and the
# test data's): those folders are allowed as the user's --allow-root would allow them
# (plcpred.parser.files). tests/test_untrusted_inputs.py takes them away where it checks
# the rule itself.
os.environ["PLCPRED_ALLOW_ROOTS"] = os.pathsep.join([str(SAMPLES), str(ROOT / "tests" / "data")])


@pytest.fixture
def samples_dir():
    return SAMPLES
