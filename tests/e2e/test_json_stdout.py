"""With ``--json``, stdout carries exactly one JSON object whatever the libraries print.

Real solvers that print are run inside a real command (HiGHS's banner and log, OSQP's verbose
C output), beside a Python ``print``, a raw write to descriptor 1 and a child process that
inherited it; the command's stdout must still parse as one object, on success and on failure,
and what was printed must be on stderr.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from spm_console.cli.main import main
from spm_console.errors import ExitCode

NOISY = r'''
import os, subprocess, sys
import numpy as np
import scipy.sparse as sp
import highspy, osqp
import spm_console.cli.kin as kin
from spm_console.errors import BadInputError

real = kin.cmd_fk

def noisy(args):
    highspy.Highs().run()                       # C++ banner and log on stdout
    m = osqp.OSQP()
    m.setup(P=sp.csc_matrix(np.eye(1)), q=np.ones(1), A=sp.csc_matrix(np.eye(1)),
            l=-np.ones(1), u=np.ones(1), verbose=True)
    m.solve()                                   # C printf
    print("a dependency's print")               # Python
    os.write(1, b"a raw write to fd 1\n")
    subprocess.run(["echo", "a child's line"], check=True)
    if os.environ.get("FAIL"):
        raise BadInputError("refused on purpose")
    return real(args)

kin.cmd_fk = noisy
from spm_console.cli.main import main
sys.exit(main(["fk", "--theta", "135", "135", "135", "--json"]))
'''


@pytest.mark.slow  # two processes; in make test-slow and make test-newest
@pytest.mark.parametrize("fail", [False, True])
def test_json_stdout_is_one_object_whatever_libraries_print(fail: bool) -> None:
    env = {"FAIL": "1"} if fail else {}
    proc = subprocess.run([sys.executable, "-c", NOISY], capture_output=True, text=True,
                          timeout=120, env={**os.environ, **env})
    assert proc.returncode == (ExitCode.BAD_INPUT if fail else 0), proc.stderr[-2000:]
    obj = json.loads(proc.stdout)  # one object, nothing else (json.loads refuses trailing text)
    assert isinstance(obj, dict)
    if fail:
        assert obj["ok"] is False and "refused on purpose" in obj["error"]
    else:
        assert obj["feasible"] is True
    for noise in ("HiGHS", "OSQP", "a dependency's print", "a raw write to fd 1", "a child's line"):
        assert noise in proc.stderr, noise
        assert noise not in proc.stdout


def test_a_captured_stdout_gets_the_json_and_prints_go_to_stderr(
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    import spm_console.cli.kin as kin

    real = kin.cmd_fk

    def noisy(args):  # type: ignore[no-untyped-def]
        print("a dependency's print")
        return real(args)

    monkeypatch.setattr(kin, "cmd_fk", noisy)
    assert main(["fk", "--theta", "135", "135", "135", "--json"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["feasible"] is True
    assert "a dependency's print" in err
    assert sys.stdout is not sys.stderr  # put back
